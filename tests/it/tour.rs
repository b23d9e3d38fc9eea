//! The README's ten-minute tour, run as a newcomer runs it: its six commands are read from
//! `README.md` itself (a changed command is the command run here, `target/release/` standing
//! for the built binaries and each `…` for the value the flight printed), and each step is
//! checked for what the README says you should see — a flight and its summary; a slow flight
//! without a ground station that prints the monitor's and the station's commands and waits for
//! the station; the monitor's board, the answer as it happens, and its end with the executive;
//! an answer typed at the terminal station, recorded with its operator; the studio at its address serving
//! `deploy/missions`, Europa played in the token game and the flight followed in the operations
//! view; and `trace verify` holding every property of Europa.

use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use mission_tests::{bin, repo};

use crate::ops::Group;
use crate::protocol::tempdir;
use crate::studio::{Kill, Page, choose, click, until};

/// How long a step may take to show what it should: at `--speed 200` the first site approval
/// comes after about a minute of flight, which a loaded two-core machine may stretch.
const STEP: Duration = Duration::from_secs(240);

/// The tour's text, from its heading to the next section.
fn tour_text() -> String {
    let readme = std::fs::read_to_string(repo().join("README.md")).expect("README.md");
    let (_, tour) = readme
        .split_once("## A ten-minute tour")
        .expect("the README has its tour");
    tour.split("\n## ").next().unwrap_or_default().to_owned()
}

/// The command of each step: the one line of each `sh` block, in order.
fn commands(tour: &str) -> Vec<String> {
    let mut found = Vec::new();
    let mut lines = tour.lines().map(str::trim);
    while let Some(line) = lines.next() {
        if line == "```sh" {
            let command = lines.next().expect("a command").to_owned();
            assert_eq!(
                lines.next(),
                Some("```"),
                "one command per step: `{command}`"
            );
            found.push(command);
        }
    }
    found
}

/// The words the tour asks you to type at the station (`list`, `show N`, `answer N …`), from
/// its inline code.
fn typed<'t>(tour: &'t str, starts: &str) -> &'t str {
    tour.split('`')
        .skip(1)
        .step_by(2)
        .find(|code| code.starts_with(starts))
        .unwrap_or_else(|| panic!("the tour shows `{starts}…`"))
}

/// `line` as a command: `target/release/X` is the built `X`, each `…` the value `join` gives
/// the flag before it.
fn command(line: &str, join: &HashMap<String, String>) -> Command {
    assert!(
        !line.contains(['"', '\'']),
        "a command without quoting: {line}"
    );
    let mut words = line.split_whitespace();
    let program = words.next().expect("a program");
    let name = program
        .strip_prefix("target/release/")
        .unwrap_or_else(|| panic!("`{line}` runs a built binary"));
    let mut c = Command::new(bin(name));
    let mut flag = "";
    for word in words {
        if word == "…" {
            c.arg(
                join.get(flag)
                    .unwrap_or_else(|| panic!("the flight printed no value for {flag}")),
            );
        } else {
            c.arg(word);
        }
        flag = word;
    }
    c.env_remove("TRACE_DEPLOYMENT");
    c
}

/// The flags the flight printed in its `watch with: trace monitor …` line, by name.
fn flags(watch: &str) -> HashMap<String, String> {
    let (_, flags) = watch
        .split_once("trace monitor ")
        .expect("the monitor's command");
    let words: Vec<&str> = flags.split_whitespace().collect();
    words
        .chunks(2)
        .map(|pair| (pair[0].to_owned(), pair.get(1).unwrap_or(&"").to_string()))
        .collect()
}

/// Each stdout line of `child` as it comes; the channel closes when the output does.
fn lines(child: &mut std::process::Child) -> Receiver<String> {
    let out = child.stdout.take().expect("stdout");
    let (tell, said) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if tell.send(line).is_err() {
                break;
            }
        }
    });
    said
}

/// Waits for a line of `said` that `wanted` accepts, failing with everything seen.
fn expect(said: &Receiver<String>, what: &str, wanted: impl Fn(&str) -> bool) -> String {
    let start = Instant::now();
    let mut seen = Vec::new();
    loop {
        let left = STEP.saturating_sub(start.elapsed());
        match said.recv_timeout(left) {
            Ok(line) if wanted(&line) => return line,
            Ok(line) => seen.push(line),
            Err(e) => panic!("{what}: not seen ({e:?}) in:\n{}", seen.join("\n")),
        }
    }
}

#[test]
fn the_readme_tour_shows_what_it_says() {
    let tour = tour_text();
    let steps = commands(&tour);
    let kinds: Vec<String> = steps
        .iter()
        .map(|c| c.split_whitespace().take(2).collect::<Vec<_>>().join(" "))
        .collect();
    assert_eq!(
        kinds,
        [
            "target/release/trace fly",
            "target/release/trace fly",
            "target/release/trace monitor",
            "target/release/ground-station --interactive",
            "target/release/trace studio",
            "target/release/trace verify",
        ],
        "the tour's steps, in order: {steps:#?}"
    );
    let none = HashMap::new();

    // 1. Fly Europa: the deployment and the monitor's command first, then a summary, and the
    // flight's files in `flights/<flight id>/`.
    let here = tempdir("tour-fly");
    let out = command(&steps[0], &none)
        .current_dir(&here)
        .output()
        .expect("trace fly");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let first: Vec<&str> = text.lines().take(2).collect();
    assert!(
        first[0].starts_with("flying ") && first[0].contains("deployment "),
        "{text}"
    );
    assert!(first[1].contains("watch with:") && first[1].contains("trace monitor -e "));
    let summary = text.split_once("\nmission summary\n").expect("a summary").1;
    for part in [
        "outcome:",
        "samples analysed:",
        "faults:",
        "energy left:",
        "execution record:",
    ] {
        assert!(summary.contains(part), "{part}: {summary}");
    }
    let record = summary
        .lines()
        .find_map(|l| l.trim().strip_prefix("execution record:"))
        .expect("the record's path")
        .trim();
    assert!(record.starts_with("flights/"), "{record}");
    assert!(
        here.join(record).is_file(),
        "{record} is written in the directory flown from"
    );

    // 2. A slow flight with no ground station: the station's and the monitor's commands.
    let slow = tempdir("tour-slow");
    let mut fly = command(&steps[1], &none);
    fly.current_dir(&slow)
        .stdout(Stdio::piped())
        .process_group(0);
    let mut fly = fly.spawn().expect("trace fly --no-ground");
    let flight = lines(&mut fly);
    let fly = Group(Kill(fly));
    expect(&flight, "the station's command", |l| {
        l.contains("answer the user tasks with: ground-station --interactive -e ")
    });
    let join = flags(&expect(&flight, "the monitor's command", |l| {
        l.contains("watch with:")
    }));
    std::thread::spawn(move || for _ in flight {});

    // 3. The monitor, started before the mission has: it waits for the executive, which
    // waits for a ground station.
    let mut monitor = command(&steps[2], &join);
    monitor.stdout(Stdio::piped());
    let mut monitor = monitor.spawn().expect("trace monitor");
    let watched = lines(&mut monitor);
    let mut monitor = Kill(monitor);

    // 4. The terminal station: the mission starts once it has joined.
    let mut station = command(&steps[3], &join);
    station.env("USER", "tourist");
    let mut tty = rexpect::session::spawn_command(station, Some(STEP.as_millis() as u64))
        .expect("ground-station in a pseudo-terminal");
    tty.exp_string("ground> ").expect("the prompt");

    // The monitor's board, then each entry as it happens.
    let header = expect(&watched, "the board", |l| l.starts_with("── "));
    let mission = header
        .trim_start_matches("── ")
        .split(" · ")
        .next()
        .expect("the mission's id")
        .to_owned();
    expect(&watched, "the instance running", |l| {
        l == "   instance 1: running"
    });
    expect(&watched, "the active tokens", |l| {
        l.starts_with("   active: ")
    });

    // The approval listed, shown and answered as the tour types it.
    let (_, opened) = tty.exp_regex(r"task \d+ open: ").expect("a task arrives");
    let number = opened
        .trim()
        .trim_start_matches("task ")
        .split(' ')
        .next()
        .expect("its number")
        .to_owned();
    tty.send_line(typed(&tour, "list")).expect("list");
    tty.exp_string(&format!("{number}  ")).expect("listed");
    tty.send_line(&typed(&tour, "show N").replace('N', &number))
        .expect("show");
    tty.exp_string("  deadline  ").expect("its deadline");
    tty.exp_string("approve: bool").expect("its form");
    let answer = typed(&tour, "answer N ").replacen(" N ", &format!(" {number} "), 1);
    tty.send_line(&answer).expect("answer");
    tty.exp_regex(&format!(
        r"task {number} answered: applied \(tourist@station-\d+\)"
    ))
    .expect("the answer applied");
    let answered = expect(&watched, "the answer in the monitor", |l| {
        l.contains("user_task_answered")
    });
    assert!(
        answered.contains("by tourist@station-") && answered.contains("ice at 3 m"),
        "{answered}"
    );

    // 5. The studio at the address the tour gives, serving `deploy/missions` and following the
    // flight.
    let mut studio = command(&steps[4], &join);
    studio.current_dir(repo());
    let page = Page::start(studio);
    let url = tour
        .split_whitespace()
        .find_map(|w| {
            w.strip_prefix("`http://")
                .map(|a| format!("http://{}", a.trim_end_matches(['`', '.'])))
        })
        .expect("the studio's address in the tour");
    assert_eq!(page.url, url, "the studio serves where the tour says");
    page.play(move |c, url| async move {
        c.goto(&url).await.expect("the studio's page");
        until(
            &c,
            "the page ready",
            "return document.body.dataset.ready === 'true'",
        )
        .await;
        choose(&c, "missions", "europa-bsm1.bpmn").await;
        until(
            &c,
            "Europa drawn",
            "return !!studio.modeler.get('elementRegistry').get('ApproveSite')",
        )
        .await;
        click(&c, "#simulate").await;
        until(
            &c,
            "the token game playing",
            "return document.body.dataset.simulation === 'playing'",
        )
        .await;
        click(&c, "#ops-toggle").await;
        until(
            &c,
            "the flight listed",
            &format!("return document.body.dataset.executives === '{mission}'"),
        )
        .await;
        until(
            &c,
            "the flight drawn with its state and timeline",
            "return studio.ops.viewer.get('elementRegistry').get('ApproveSite')
               && document.body.dataset.opsSeq
               && !document.getElementById('ops-timeline').hidden",
        )
        .await;
    });

    // The monitor ends when the executive goes away.
    drop(fly);
    let start = Instant::now();
    loop {
        match watched.recv_timeout(STEP.saturating_sub(start.elapsed())) {
            Ok(_) => continue,
            Err(RecvTimeoutError::Disconnected) => break,
            Err(RecvTimeoutError::Timeout) => panic!("the monitor outlived the executive"),
        }
    }
    assert!(monitor.0.wait().expect("the monitor's status").success());
    tty.send_line("quit").expect("quit");
    tty.exp_eof().expect("the station leaves");

    // 6. Verify: every property holds, each with its states and time, and the exit status is 0.
    let out = command(&steps[5], &none)
        .current_dir(repo())
        .output()
        .expect("trace verify");
    let text = String::from_utf8_lossy(&out.stdout);
    let verdicts: Vec<&str> = text
        .lines()
        .map(str::trim_start)
        .filter(|l| {
            ["holds", "VIOLATED", "incomplete"]
                .iter()
                .any(|v| l.starts_with(v))
        })
        .collect();
    // Five built-in properties, five requirements, three time and energy requirements.
    assert_eq!(verdicts.len(), 13, "{text}");
    assert!(
        verdicts
            .iter()
            .all(|v| v.starts_with("holds") && v.contains(" states, ")),
        "{text}"
    );
    assert!(
        text.contains(" with ") && text.contains("europa-bsm1.req.toml"),
        "the requirements beside the model are read: {text}"
    );
    let work = text
        .lines()
        .find_map(|l| l.strip_prefix("work files (PROMELA, pan's output, trails): "))
        .unwrap_or_else(|| panic!("the work directory is named: {text}"));
    assert!(
        !std::path::Path::new(work).starts_with(repo()),
        "{work}: the work files go outside the repository"
    );
    assert_eq!(out.status.code(), Some(0), "{text}");
}
