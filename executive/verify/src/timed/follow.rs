//! One observed run (a flight) followed through the engine with the costs, step by step.

use super::*;

/// One step of a run observed outside the verifier (a flight): its label as the exploration
/// names steps (`Task.complete`, `Task.fail[CODE]`, `Timer.fire`), when it happened (mission
/// time since the start, ms), the result it carried, and the energy used by then if a reading
/// says.
#[derive(Clone, Debug)]
pub struct Observed {
    /// The step.
    pub label: String,
    /// A task's result or a ground answer (the data the run's decisions read).
    pub output: Vars,
    /// When, ms since the start.
    pub at_ms: f64,
    /// Energy used by then, Wh, when the step reads the battery.
    pub energy_wh: Option<f64>,
}

/// What the verifier bounds for one observed step, given the run before it.
#[derive(Clone, Debug, Serialize)]
pub struct Bound {
    /// The step.
    pub label: String,
    /// When it could have come, ms since the start.
    pub window_ms: Span,
    /// When it came.
    pub at_ms: f64,
    /// Energy used by then, Wh (every activity so far anywhere within its declared power).
    pub energy_wh: Span,
    /// The most the activities still running have drawn so far, and those that ended at this
    /// same moment, Wh: a system that charges an activity's energy when it ends reads up to
    /// this much less.
    pub in_flight_wh: f64,
    /// The energy used by then as the run read it, if it did.
    pub measured_wh: Option<f64>,
}

/// Follows one observed run through the engine with the costs: for each step, the window in
/// which the verifier says it could come and the energy it says was used by then. The run's
/// data goes to the engine, which makes the run's decisions itself (so loops over data run as
/// often as they did). `Err` names the first step the model and costs do not allow (a step not
/// possible then, or not at that time): a disagreement between the costs and the system. A run
/// that goes on after its battery is certainly empty (a simulator that does not stop there) is
/// followed up to that point.
pub fn follow(g: Arc<ProcessGraph>, costs: &Costs, run: &[Observed]) -> Result<Vec<Bound>, String> {
    let limits = TimedLimits {
        loops: u8::MAX,
        max_states: 0,
    };
    let mut cx = context(&g, costs, &[], limits);
    // One run keeps its exact times, and its data.
    cx.horizon = f64::INFINITY;
    cx.data = true;
    let mut n = start(&cx, &[])?;
    let mut out = Vec::new();
    // What activities ending at the current moment spent (their order against a reading at the
    // same moment is the system's).
    let mut moment = (0.0, 0.0);
    for (i, o) in run.iter().enumerate() {
        let now = n.t().lo;
        let mut offered: Vec<Next> = successors(&cx, &n);
        // A code no boundary names is offered as the one a catch-all catches.
        let code = o
            .label
            .split_once(".fail[")
            .map(|(task, c)| (task.to_owned(), c.trim_end_matches(']').to_owned()));
        let found = offered.iter().position(|x| x.label == o.label).or_else(|| {
            let (task, _) = code.as_ref()?;
            let any = format!("{task}.fail[{}]", crate::explore::UNNAMED);
            offered.iter().position(|x| x.label == any)
        });
        let Some(x) = found else {
            let names: Vec<&str> = offered.iter().map(|x| x.label.as_str()).collect();
            let tokens: Vec<String> = n
                .state
                .tokens
                .values()
                .map(|t| format!("{} {:?}", g.node(t.node).id, t.at))
                .collect();
            let incidents: Vec<&String> = n
                .state
                .instances
                .values()
                .flat_map(|i| i.incidents.iter().map(|(_, why)| why))
                .collect();
            return Err(format!(
                "step {} `{}` at {} ms is not possible then; possible: {names:?}; tokens at \
                 {tokens:?}; incidents {incidents:?}",
                i + 1,
                o.label,
                o.at_ms
            ));
        };
        let mut x = offered.swap_remove(x);
        if let (Some(Event::TaskFailed { code: c, .. }), Some((_, real))) = (&mut x.event, &code) {
            c.clone_from(real);
        }
        if let Some(Event::TaskCompleted { task, .. }) = x.event {
            // The result's data; a ground decision is an answer.
            let user = n
                .state
                .tokens
                .values()
                .any(|t| matches!(t.at, At::UserTask(k) if k == task));
            x.event = Some(if user {
                Event::UserTaskAnswered {
                    task,
                    answer: o.output.clone(),
                    operator: "follow".into(),
                }
            } else {
                Event::TaskCompleted {
                    task,
                    output: o.output.clone(),
                }
            });
        }
        let x = &x;
        let Some((mut z, wait)) = elapse(&cx, &n, &x.when) else {
            return Err(format!("step {} `{}` cannot come next", i + 1, o.label));
        };
        let (lo, hi) = z.bounds(wait);
        let window = Span {
            lo: now + lo,
            hi: now + hi,
        };
        let d = o.at_ms - now;
        if d > death(&cx, &n, 0).hi + 1.0 {
            break;
        }
        // Mission time is kept in ms: a millisecond either way is rounding.
        if d < lo - 1.0 || d > hi + 1.0 {
            return Err(format!(
                "step {} `{}` came at {} ms, outside {:.0}..{:.0} ms",
                i + 1,
                o.label,
                o.at_ms,
                window.lo,
                window.hi
            ));
        }
        let d = d.clamp(lo, hi);
        z.at_most(wait, d);
        z.at_least(wait, d);
        if !z.close() {
            return Err(format!("step {} `{}`: no time fits", i + 1, o.label));
        }
        let c = take(&cx, &n, x, z, wait)
            .ok_or_else(|| format!("step {} `{}` cannot be taken then", i + 1, o.label))?;
        if o.at_ms != moment.0 {
            moment = (o.at_ms, 0.0);
        }
        moment.1 += c.via.as_ref().and_then(|v| v.spent).map_or(0.0, |s| s.hi);
        out.push(Bound {
            label: o.label.clone(),
            window_ms: window,
            at_ms: o.at_ms,
            energy_wh: c.total(),
            in_flight_wh: c.running.values().map(|r| r.spent.hi).sum::<f64>() + moment.1,
            measured_wh: o.energy_wh,
        });
        n = c;
    }
    Ok(out)
}
