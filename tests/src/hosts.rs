//! Hosts on one machine for the tests across hosts: network namespaces made by the test (a
//! lander, one or more ground hosts and, for a fleet, a scout), each joined to the lander by its
//! own veth link that the test cuts, restores and shapes; the certificates of `deploy/certs.sh`;
//! and the processes of a deployment started inside them with the `deploy/zenoh/two-hosts/`
//! files.
//!
//! Only loopback and the addresses of the links made here are used: the far end of link `k`
//! (from 1; the grounds first, then the scout) is `10.77.k.2`, the lander's end `10.77.k.1`.
//! Addresses live inside the namespaces, so two labs never collide; namespace names carry the
//! process id and a counter.
//! Everything is removed when the [`Lab`] is dropped (processes killed first).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::{bin, repo};

/// How long a process may take to say it is ready before the test fails naming it.
const READY_WAIT: Duration = Duration::from_secs(60);

/// Network namespaces for one test, and the deployment directory (certificates, logs).
pub struct Lab {
    /// The lander host's namespace.
    pub lander: String,
    /// The ground hosts' namespaces, link `k` joining `grounds[k - 1]` to the lander.
    pub grounds: Vec<String>,
    /// The scout's namespace (a fleet's second vehicle), on the link after the grounds'.
    pub scout: Option<String>,
    /// The deployment directory: `certs/` and one log per process started.
    pub dir: PathBuf,
    procs: Vec<Proc>,
}

/// A process of the deployment, killed when dropped; its stderr goes to `<dir>/<name>.log`.
pub struct Proc {
    /// What the test calls it (also its log's name).
    pub name: String,
    /// The process.
    pub child: Child,
    /// Its log (stderr).
    pub log: PathBuf,
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn ip(args: &[&str]) {
    let out = Command::new("ip").args(args).output().expect("ip runs");
    assert!(
        out.status.success(),
        "ip {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

impl Lab {
    /// Makes a lander and `grounds` ground hosts, each linked to the lander, and the
    /// certificates of every identity the shipped access control knows (the lander router's
    /// naming every link address), in a fresh directory under the system's temp dir.
    pub fn new(name: &str, grounds: usize) -> Lab {
        Lab::hosts(name, grounds, false)
    }

    /// A fleet's lab: the lander, one ground host and the scout, the scout's host linked to
    /// the lander by link 2 (the link between the vehicles).
    pub fn fleet(name: &str) -> Lab {
        Lab::hosts(name, 1, true)
    }

    fn hosts(name: &str, grounds: usize, scout: bool) -> Lab {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let id = format!(
            "t{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        let dir = std::env::temp_dir().join(format!("trace-hosts-{name}-{id}"));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("lab directory");
        let lander = format!("{id}-lander");
        let mut lab = Lab {
            lander: lander.clone(),
            grounds: Vec::new(),
            scout: None,
            dir,
            procs: Vec::new(),
        };
        ip(&["netns", "add", &lander]);
        ip(&["-n", &lander, "link", "set", "lo", "up"]);
        let links = grounds + usize::from(scout);
        for k in 1..=links {
            let ground = if k <= grounds {
                format!("{id}-ground{k}")
            } else {
                format!("{id}-scout")
            };
            ip(&["netns", "add", &ground]);
            if k <= grounds {
                lab.grounds.push(ground.clone());
            } else {
                lab.scout = Some(ground.clone());
            }
            ip(&["-n", &ground, "link", "set", "lo", "up"]);
            let link = format!("link{k}");
            ip(&[
                "link", "add", &link, "netns", &lander, "type", "veth", "peer", "name", &link,
                "netns", &ground,
            ]);
            for (ns, end) in [(&lander, 1), (&ground, 2)] {
                ip(&[
                    "-n",
                    ns,
                    "addr",
                    "add",
                    &format!("10.77.{k}.{end}/24"),
                    "dev",
                    &link,
                ]);
                ip(&["-n", ns, "link", "set", &link, "up"]);
            }
        }
        let mut lander_names = "lander-router=lander".to_owned();
        for k in 1..=links {
            lander_names.push_str(&format!(",10.77.{k}.1"));
        }
        let out = Command::new(repo().join("deploy/certs.sh"))
            .arg(lab.dir.join("certs"))
            .args([
                lander_names.as_str(),
                "ground-router=ground",
                "exec",
                "lander_sim",
                "camera",
                "station-a",
                "station-b",
                "monitor",
                "intruder",
                "scout-router=scout",
                "scout_exec",
                "scout_sim",
            ])
            .output()
            .expect("deploy/certs.sh runs");
        assert!(
            out.status.success(),
            "deploy/certs.sh: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        lab
    }

    /// The lander's address on link `k`, where ground host `k` reaches its router.
    pub fn lander_addr(k: usize) -> String {
        format!("10.77.{k}.1")
    }

    /// The link joining the scout to the lander.
    pub fn scout_link(&self) -> usize {
        self.grounds.len() + 1
    }

    /// The scout's namespace.
    pub fn scout_ns(&self) -> String {
        self.scout.clone().expect("a fleet's lab (Lab::fleet)")
    }

    /// The namespace at the far end of link `k` from the lander.
    fn far(&self, k: usize) -> &str {
        self.grounds
            .get(k - 1)
            .or(self.scout.as_ref().filter(|_| k == self.grounds.len() + 1))
            .unwrap_or_else(|| panic!("no link {k}"))
    }

    /// A shipped two-host Zenoh file.
    pub fn config(file: &str) -> String {
        repo()
            .join("deploy/zenoh/two-hosts")
            .join(file)
            .to_string_lossy()
            .into_owned()
    }

    /// `program args…` inside namespace `ns`, in the deployment directory.
    pub fn command(&self, ns: &str, program: &str, args: &[&str]) -> Command {
        let mut c = Command::new("ip");
        c.args(["netns", "exec", ns])
            .arg(bin(program))
            .args(args)
            .current_dir(&self.dir);
        c
    }

    /// The flags that make a shipped client file (`file`) present the certificate whose
    /// common name is `cert` (from the lab's `certs/`).
    pub fn client_flags(file: &str, cert: &str) -> Vec<String> {
        vec![
            "--zenoh-config".to_owned(),
            Lab::config(file),
            "--zenoh-set".to_owned(),
            format!("transport/link/tls/connect_certificate=\"certs/{cert}.pem\""),
            "--zenoh-set".to_owned(),
            format!("transport/link/tls/connect_private_key=\"certs/{cert}.key\""),
        ]
    }

    /// `zenoh-probe args…` inside `ns` as a client of that host's router, holding the
    /// certificate whose common name is `cert`.
    pub fn probe(&self, ns: &str, cert: &str, args: &[&str]) -> Command {
        let flags = Lab::client_flags("monitor.json5", cert);
        let mut all: Vec<&str> = flags.iter().map(String::as_str).collect();
        all.extend(args);
        self.command(ns, "zenoh-probe", &all)
    }

    /// [`Lab::probe`] started as `name` (see [`Lab::start`]).
    pub fn start_probe(&mut self, name: &str, ns: &str, cert: &str, args: &[&str]) -> String {
        let c = self.probe(ns, cert, args);
        self.start(name, c)
    }

    /// Starts `command` as `name`, waits for its `ready` line on stdout, and keeps it until
    /// the lab is dropped. Returns the ready line.
    pub fn start(&mut self, name: &str, mut command: Command) -> String {
        let log = self.dir.join(format!("{name}.log"));
        let file = std::fs::File::create(&log).expect("log file");
        let mut child = command
            .stdout(Stdio::piped())
            .stderr(file)
            .spawn()
            .unwrap_or_else(|e| panic!("{name} starts: {e}"));
        let stdout = child.stdout.take().expect("stdout");
        let mut out =
            std::fs::File::create(self.dir.join(format!("{name}.out"))).expect("out file");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut sent = false;
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let _ = writeln!(out, "{line}");
                if !sent && (line.starts_with("ready") || line.starts_with("error")) {
                    let _ = tx.send(line);
                    sent = true;
                }
            }
        });
        let proc = Proc {
            name: name.to_owned(),
            child,
            log,
        };
        match rx.recv_timeout(READY_WAIT) {
            Ok(line) if line.starts_with("ready") => {
                self.procs.push(proc);
                line
            }
            Ok(line) => panic!(
                "{name}: {line}; its log:\n{}",
                std::fs::read_to_string(&proc.log).unwrap_or_default()
            ),
            Err(_) => panic!(
                "{name} said no ready line within {READY_WAIT:?}; its log:\n{}",
                std::fs::read_to_string(&proc.log).unwrap_or_default()
            ),
        }
    }

    /// Starts `command` as `name` without waiting for anything (the executive says no
    /// `ready`: its record is what the tests follow); stdout goes to `<name>.out`.
    pub fn spawn(&mut self, name: &str, mut command: Command) {
        let out = std::fs::File::create(self.dir.join(format!("{name}.out"))).expect("out file");
        let log = self.dir.join(format!("{name}.log"));
        let err = std::fs::File::create(&log).expect("log file");
        let child = command
            .stdout(out)
            .stderr(err)
            .spawn()
            .unwrap_or_else(|e| panic!("{name} starts: {e}"));
        self.procs.push(Proc {
            name: name.to_owned(),
            child,
            log,
        });
    }

    /// Waits until the execution record at `record` satisfies `done` (given its complete
    /// lines so far) and returns those lines; fails after `within`, naming `what` and showing
    /// which processes have exited.
    pub fn until_record(
        &mut self,
        record: &Path,
        what: &str,
        within: Duration,
        done: impl Fn(&[serde_json::Value]) -> bool,
    ) -> Vec<serde_json::Value> {
        let lines = || {
            // A line being written may be partial: read only complete ones.
            let text = std::fs::read_to_string(record).unwrap_or_default();
            let complete = text.rfind('\n').map_or("", |i| &text[..i]);
            complete
                .lines()
                .filter_map(|l| serde_json::from_str(l).ok())
                .collect::<Vec<serde_json::Value>>()
        };
        if let Some(found) = poll(within, || Some(lines()).filter(|ls| done(ls))) {
            return found;
        }
        panic!(
            "the record shows no {what} within {within:?} ({} lines); processes:\n{}",
            lines().len(),
            self.procs
                .iter_mut()
                .map(|p| format!("{}: {:?}", p.name, p.child.try_wait()))
                .collect::<Vec<_>>()
                .join("\n")
        );
    }

    /// [`Lab::until_record`] for the first line `pick` accepts; returns it and the lines.
    pub fn until_recorded(
        &mut self,
        record: &Path,
        what: &str,
        within: Duration,
        pick: impl Fn(&serde_json::Value) -> bool,
    ) -> (serde_json::Value, Vec<serde_json::Value>) {
        let lines = self.until_record(record, what, within, |ls| ls.iter().any(&pick));
        let hit = lines.iter().find(|l| pick(l)).cloned().expect("found");
        (hit, lines)
    }

    /// The process started as `name`.
    pub fn proc(&mut self, name: &str) -> &mut Proc {
        self.procs
            .iter_mut()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("no process {name}"))
    }

    /// The log (stderr) of the process started as `name` so far.
    pub fn log(&self, name: &str) -> String {
        std::fs::read_to_string(self.dir.join(format!("{name}.log"))).unwrap_or_default()
    }

    /// The output (stdout) of the process started as `name` so far.
    pub fn output(&self, name: &str) -> String {
        std::fs::read_to_string(self.dir.join(format!("{name}.out"))).unwrap_or_default()
    }

    /// Waits until the log of `name` holds a line containing every one of `needles`, and
    /// returns that line; fails after `within`, showing the log.
    pub fn until_logged(&self, name: &str, needles: &[&str], within: Duration) -> String {
        self.until_in(name, "log", needles, within)
    }

    /// As [`Lab::until_logged`], on the output (stdout) of `name`.
    pub fn until_said(&self, name: &str, needles: &[&str], within: Duration) -> String {
        self.until_in(name, "out", needles, within)
    }

    fn until_in(&self, name: &str, ext: &str, needles: &[&str], within: Duration) -> String {
        let text =
            || std::fs::read_to_string(self.dir.join(format!("{name}.{ext}"))).unwrap_or_default();
        let line = |t: &str| {
            t.lines()
                .find(|l| needles.iter().all(|n| l.contains(n)))
                .map(str::to_owned)
        };
        poll(within, || line(&text())).unwrap_or_else(|| {
            panic!(
                "{name}.{ext} has no line with {needles:?} within {within:?}:\n{}",
                text()
            )
        })
    }

    /// Starts the lander's, the ground hosts' and the scout's routers (QUIC with mutual TLS,
    /// access control on), each waited for until it says `ready`; the ground's and the scout's
    /// routers connect to the lander's on their own.
    pub fn routers(&mut self) {
        self.lander_router("lander-router");
        for k in 1..=self.grounds.len() {
            self.ground_router(k, &format!("ground-router{k}"));
        }
        if let Some(scout) = self.scout.clone() {
            let to = format!("quic/{}:7447", Lab::lander_addr(self.scout_link()));
            let c = self.command(
                &scout,
                "trace",
                &[
                    "router",
                    "--zenoh-config",
                    &Lab::config("scout-router.json5"),
                    "-e",
                    &to,
                ],
            );
            self.start("scout-router", c);
        }
    }

    /// Starts the lander's router as `name` (see [`Lab::start`]).
    pub fn lander_router(&mut self, name: &str) {
        self.lander_router_with(name, &[]);
    }

    /// [`Lab::lander_router`] with `extra` arguments.
    pub fn lander_router_with(&mut self, name: &str, extra: &[&str]) {
        let mut c = self.command(
            &self.lander.clone(),
            "trace",
            &[
                "router",
                "--zenoh-config",
                &Lab::config("lander-router.json5"),
            ],
        );
        c.args(extra);
        self.start(name, c);
    }

    /// Starts ground host `k`'s router as `name`, connecting to the lander's router over link
    /// `k`.
    pub fn ground_router(&mut self, k: usize, name: &str) {
        let to = format!("quic/{}:7447", Lab::lander_addr(k));
        self.ground_router_to(k, name, &to, &[]);
    }

    /// Starts ground host `k`'s router as `name`, connecting to the lander's router at
    /// endpoint `to` (a relay, say), with `extra` arguments.
    pub fn ground_router_to(&mut self, k: usize, name: &str, to: &str, extra: &[&str]) {
        let mut c = self.command(
            &self.grounds[k - 1].clone(),
            "trace",
            &[
                "router",
                "--zenoh-config",
                &Lab::config("ground-router.json5"),
                "-e",
                to,
            ],
        );
        c.args(extra);
        self.start(name, c);
    }

    /// SIGKILLs the process started as `name` and forgets it (its log stays).
    pub fn kill(&mut self, name: &str) {
        let i = self
            .procs
            .iter()
            .position(|p| p.name == name)
            .unwrap_or_else(|| panic!("no process {name}"));
        self.procs.remove(i);
    }

    /// Takes link `k` down (both ends lose carrier) or brings it up again.
    pub fn link(&self, k: usize, up: bool) {
        ip(&[
            "-n",
            self.far(k),
            "link",
            "set",
            &format!("link{k}"),
            if up { "up" } else { "down" },
        ]);
    }
}

impl Lab {
    /// Shapes link `k` at both ends to `rate` (a `tc` rate such as `256kbit`) with a token
    /// bucket filter: a narrow link to the lander.
    pub fn shape(&self, k: usize, rate: &str) {
        for ns in [self.lander.as_str(), self.far(k)] {
            let out = Command::new("ip")
                .args(["netns", "exec", ns, "tc", "qdisc", "replace", "dev"])
                .arg(format!("link{k}"))
                .args([
                    "root", "tbf", "rate", rate, "burst", "32kb", "latency", "2s",
                ])
                .output()
                .expect("tc runs");
            assert!(
                out.status.success(),
                "tc on link{k} in {ns}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
}

impl Drop for Lab {
    fn drop(&mut self) {
        self.procs.clear();
        for ns in self.grounds.iter().chain(&self.scout).chain([&self.lander]) {
            let _ = Command::new("ip").args(["netns", "del", ns]).status();
        }
        // Kept when the test failed, or when asked (`TRACE_KEEP_LAB=1`), for its logs.
        if !std::thread::panicking() && std::env::var_os("TRACE_KEEP_LAB").is_none() {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// Reads `probe` until it finds something or `within` has passed. What is waited for is a line
/// in a file another process writes (a record entry, a log or output line): the file is the
/// event, and the 20 ms between two reads only spares the CPU the processes run on.
pub fn poll<T>(within: Duration, mut probe: impl FnMut() -> Option<T>) -> Option<T> {
    let start = Instant::now();
    loop {
        if let Some(found) = probe() {
            return Some(found);
        }
        if start.elapsed() >= within {
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}
