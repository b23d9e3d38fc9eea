//! The server's publications: status, feedback and result streams, telemetry and the mission
//! clock, each typed at the door and dropped (logged, counted) when it cannot be used.

use super::*;

impl Shared {
    pub(super) fn on_status(self: &Arc<Shared>, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let bytes = payload(sample);
        let m = match wire::parse::<StatusMsg>("status", key, &bytes) {
            Ok(m) => m,
            Err(e) => {
                return self.drops.drop(
                    Reason::Garbage,
                    key,
                    "status",
                    &goal_id_in(&bytes),
                    &e.to_string(),
                );
            }
        };
        if !self.state().flights.contains_key(&m.goal_id) {
            return self.stray(key, Stream::Status, &m.goal_id);
        }
        match m.status {
            Status::Accepted | Status::Executing | Status::Canceling => self.acked(&m.goal_id),
            Status::Unknown | Status::Lost => self.drops.drop(
                Reason::InvalidStatus,
                key,
                "status",
                &m.goal_id,
                &format!("a server never publishes {}", status_name(m.status)),
            ),
            // Ended: the result is published before the status, so normally it has ended the
            // goal already. It has not: ask for it (the result may have been lost).
            _ if !self.opts.config.answers => {
                self.acked(&m.goal_id);
                self.start_asking(&m.goal_id);
            }
            _ => {}
        }
    }

    pub(super) fn on_feedback(self: &Arc<Shared>, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let bytes = payload(sample);
        let m = match wire::parse::<FeedbackMsg>("feedback", key, &bytes) {
            Ok(m) => m,
            Err(e) => {
                return self.drops.drop(
                    Reason::Garbage,
                    key,
                    "feedback",
                    &goal_id_in(&bytes),
                    &e.to_string(),
                );
            }
        };
        let Some(action) = self
            .state()
            .flights
            .get(&m.goal_id)
            .map(|f| f.command.action.clone())
        else {
            return self.stray(key, Stream::Feedback, &m.goal_id);
        };
        let refused = match (m.progress_pct, self.spec(&action)) {
            (Some(p), _) if !(0.0..=100.0).contains(&p) => {
                Some(format!("progress_pct {p} is outside 0–100"))
            }
            (_, Some(spec)) => spec.check_feedback(&m.fields).err(),
            (_, None) => None,
        };
        if let Some(why) = refused {
            return self
                .drops
                .drop(Reason::Mistyped, key, "feedback", &m.goal_id, &why);
        }
        self.report(Report::Feedback {
            goal_id: m.goal_id,
            progress_pct: m.progress_pct,
            fields: m.fields,
        });
    }

    pub(super) fn on_result(self: &Arc<Shared>, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let bytes = payload(sample);
        match wire::parse::<ResultMsg>("result", key, &bytes) {
            Ok(r) => {
                self.deliver(r, Source::Stream(key));
            }
            Err(e) => {
                let goal_id = goal_id_in(&bytes);
                self.drops
                    .drop(Reason::Garbage, key, "result", &goal_id, &e.to_string());
                // A result naming one of our goals that we cannot read: the server is asked
                // (anyone may publish on the stream, so it counts for nothing by itself).
                self.recheck(&goal_id);
            }
        }
    }

    pub(super) fn on_telemetry(&self, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let t = match wire::parse::<Telemetry>("telemetry", key, &payload(sample)) {
            Ok(t) => t,
            Err(e) => {
                return self
                    .drops
                    .drop(Reason::Garbage, key, "telemetry", "", &e.to_string());
            }
        };
        let config = &self.opts.config;
        if config.clock && Keys::last_chunk(key) == "clock" {
            self.on_clock(key, &t);
        }
        let catalogue = self
            .catalogue
            .lock()
            .ok()
            .and_then(|c| c.clone())
            .unwrap_or_default();
        for k in &config.data {
            let Some(v) = t.values.get(k) else { continue };
            let mut s = self.state();
            if let Err(why) = catalogue.check_telemetry(k, v, s.last_data.get(k)) {
                drop(s);
                self.drops
                    .drop(Reason::Mistyped, key, "telemetry", "", &why);
                continue;
            }
            let changed = match (s.last_data.get(k), config.deadband.get(k)) {
                (None, _) => true,
                (Some(old), Some(band)) => match (old.as_f64(), v.as_f64()) {
                    (Some(a), Some(b)) => (a - b).abs() >= *band,
                    _ => old != v,
                },
                (Some(old), None) => old != v,
            };
            if changed {
                s.last_data.insert(k.clone(), v.clone());
                drop(s);
                self.report(Report::Data {
                    key: k.clone(),
                    value: v.clone(),
                });
            }
        }
    }

    /// A mission clock report: believed only if plausible after the last one believed
    /// ([`wire::check_clock`]).
    pub(super) fn on_clock(&self, key: &str, t: &Telemetry) {
        let Some(speed) = t.values.get("speed").and_then(Value::as_f64) else {
            return self.drops.drop(
                Reason::ImplausibleClock,
                key,
                "clock report",
                "",
                "a clock report needs a number `speed`",
            );
        };
        let reading = ClockReading {
            mission_ms: t.mission_ms,
            speed,
        };
        let now = Instant::now();
        let verdict = {
            let mut s = self.state();
            let last = s.clock;
            let wall = last.map_or(Duration::ZERO, |(_, at)| now.duration_since(at));
            let verdict = wire::check_clock(
                last.map(|(r, _)| r),
                reading,
                wall,
                Duration::from_millis(self.limits.clock_slack_ms),
            );
            if verdict.is_ok() {
                s.clock = Some((reading, now));
            }
            verdict
        };
        match verdict {
            Ok(()) => self.report(Report::Clock {
                mission_ms: t.mission_ms,
                speed,
            }),
            Err(e) => self.drops.drop(
                Reason::ImplausibleClock,
                key,
                "clock report",
                "",
                &e.to_string(),
            ),
        }
    }
}
