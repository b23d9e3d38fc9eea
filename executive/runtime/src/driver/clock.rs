//! The mission clocks timers run against: the wall clock (scaled by `--speed`), a clock a
//! system supplies (the paper's alternate clock), or, without outside systems, the virtual
//! clock of the agenda.

use super::*;

/// The mission clock timers run against: the wall clock (possibly scaled), or, with the
/// connectors, a clock a system supplies (the paper's "alternate clock").
pub trait MissionClock {
    /// Mission time now.
    fn now(&self) -> Millis;
    /// How long to wait on the wall clock until mission time `due`.
    fn wall_delay(&self, due: Millis) -> Duration;
    /// Wall time per unit of mission time (to wait out activity durations).
    fn speed(&self) -> f64;
}

/// The wall clock anchored at the mission's first start, running `speed` times faster;
/// downtime counts as mission time (the lander's clock does not stop when the executive does).
#[derive(Clone, Copy, Debug)]
pub struct ScaledWallClock {
    pub(super) wall0: Millis,
    pub(super) mission0: Millis,
    pub(super) speed: f64,
}

impl MissionClock for ScaledWallClock {
    fn now(&self) -> Millis {
        self.mission0 + ((wall_ms() - self.wall0) as f64 * self.speed) as Millis
    }
    fn wall_delay(&self, due: Millis) -> Duration {
        let left = (due.saturating_sub(self.now())).max(0) as f64 / self.speed;
        Duration::from_millis(left as u64)
    }
    fn speed(&self) -> f64 {
        self.speed
    }
}

/// A system's mission clock (the paper's "alternate clock"): the mission time it last reported,
/// advanced at its speed since.
#[derive(Clone, Copy, Debug)]
pub struct SystemClock {
    pub(super) mission0: Millis,
    pub(super) at: std::time::Instant,
    pub(super) speed: f64,
}

impl SystemClock {
    /// The clock as reported now.
    pub fn new(mission_ms: Millis, speed: f64) -> SystemClock {
        SystemClock {
            mission0: mission_ms,
            at: std::time::Instant::now(),
            // 0: the system holds its clock (not started yet); timers wait for the next report.
            speed: if speed.is_finite() && speed >= 0.0 {
                speed
            } else {
                1.0
            },
        }
    }
}

impl MissionClock for SystemClock {
    fn now(&self) -> Millis {
        self.mission0 + (self.at.elapsed().as_secs_f64() * 1000.0 * self.speed) as Millis
    }
    fn wall_delay(&self, due: Millis) -> Duration {
        if self.speed == 0.0 {
            return Duration::from_secs(3600);
        }
        let left = due.saturating_sub(self.now()).max(0) as f64 / self.speed;
        Duration::from_micros((left * 1000.0) as u64)
    }
    fn speed(&self) -> f64 {
        self.speed
    }
}

/// The virtual mission clock of a run without outside systems: it reads the agenda; waiting
/// until a deadline takes its distance in mission time divided by the speed.
pub(super) struct VirtualClock {
    pub(super) agenda: Agenda,
    pub(super) speed: f64,
}

impl MissionClock for VirtualClock {
    fn now(&self) -> Millis {
        self.agenda.now()
    }
    fn wall_delay(&self, due: Millis) -> Duration {
        let left = due.saturating_sub(self.now()).max(0) as f64 / self.speed;
        Duration::from_micros((left * 1000.0).min(1e15) as u64)
    }
    fn speed(&self) -> f64 {
        self.speed
    }
}
