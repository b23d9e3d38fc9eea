//! The lander's world model: battery, thermal and arm state, excavation sites, samples, data
//! products and communication windows, advanced by simulated time. No I/O and no clock: time is
//! what the caller says it is.

use serde::{Deserialize, Serialize};

use crate::rng::Rng;

/// One hour of mission time, ms.
pub const HOUR_MS: i64 = 3_600_000;

/// The battery's capacity, Wh (the catalogue declares it too).
pub const CAPACITY_WH: f64 = 45_000.0;

/// Hotel loads and survival heaters, W, drawn all the time (the catalogue declares it too).
pub const IDLE_W: f64 = 55.0;

/// The scout's battery, Wh, and its idle draw, W (its catalogue declares them too).
pub const SCOUT_CAPACITY_WH: f64 = 600.0;
/// The scout's idle draw, W.
pub const SCOUT_IDLE_W: f64 = 4.0;
/// Below this state of charge the scout refuses to survey, %.
pub const SCOUT_RESERVE_PCT: f64 = 20.0;

/// Which vehicle the simulator is: the lander, or the scout that surveys sites for it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Vehicle {
    /// The Europa lander (server `lander_sim`).
    #[default]
    Lander,
    /// A small hopper that flies to candidate sites and surveys them (server `scout_sim`).
    Scout,
}

impl Vehicle {
    /// The server id it serves as.
    pub fn server(self) -> &'static str {
        match self {
            Vehicle::Lander => "lander_sim",
            Vehicle::Scout => "scout_sim",
        }
    }
}

impl std::fmt::Display for Vehicle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Vehicle::Lander => "lander",
            Vehicle::Scout => "scout",
        })
    }
}

/// Surface material of a site (drives slump and dig rate).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Material {
    /// Loose regolith: slumps often.
    LooseRegolith,
    /// Granular ice.
    GranularIce,
    /// Hard ice: slow to dig.
    HardIce,
    /// Salt crust.
    SaltCrust,
}

impl Material {
    /// The name used on the wire.
    pub fn name(self) -> &'static str {
        match self {
            Material::LooseRegolith => "loose_regolith",
            Material::GranularIce => "granular_ice",
            Material::HardIce => "hard_ice",
            Material::SaltCrust => "salt_crust",
        }
    }

    /// Chance that an excavation here slumps.
    pub fn slump_chance(self) -> f64 {
        match self {
            Material::LooseRegolith => 0.30,
            Material::GranularIce => 0.15,
            Material::HardIce => 0.03,
            Material::SaltCrust => 0.10,
        }
    }
}

/// An excavation site.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Site {
    /// Its id.
    pub site_id: i64,
    /// Position east, m.
    pub x_m: f64,
    /// Position north, m.
    pub y_m: f64,
    /// Science score 0..1.
    pub score: f64,
    /// Material.
    pub material: Material,
    /// Depth dug so far, cm.
    pub depth_cm: f64,
}

/// A sample taken.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Its id.
    pub sample_id: i64,
    /// Where from.
    pub site_id: i64,
    /// Volume, cm³.
    pub volume_cc: f64,
    /// Analysed already.
    pub analysed: bool,
}

/// A data product waiting for downlink.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Product {
    /// Its id.
    pub product_id: String,
    /// Size, MB.
    pub size_mb: f64,
    /// Sent to Earth.
    pub downlinked: bool,
}

/// The whole simulated lander.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct World {
    /// Mission time, ms since the epoch.
    pub now_ms: i64,
    /// Battery capacity, Wh.
    pub capacity_wh: f64,
    /// Energy left, Wh.
    pub energy_wh: f64,
    /// Extra draw injected by a `HIGH_POWER_DRAW` fault, W.
    pub extra_draw_w: f64,
    /// Hotel and survival heaters, W.
    pub idle_w: f64,
    /// Arm temperature, K.
    pub arm_temp_k: f64,
    /// `stowed` or `unstowed`.
    pub arm_state: String,
    /// Candidate sites (after a terrain map is built).
    pub sites: Vec<Site>,
    /// Samples taken.
    pub samples: Vec<Sample>,
    /// Data products.
    pub products: Vec<Product>,
    /// Mission start, ms (comm windows are phased from it).
    pub start_ms: i64,
    /// Counter for ids.
    pub next_id: i64,
    /// The fault generator.
    pub rng: Rng,
    /// Which vehicle this is.
    #[serde(default)]
    pub vehicle: Vehicle,
}

impl World {
    /// A lander just landed at `start_ms`.
    pub fn new(start_ms: i64, seed: u64) -> World {
        World {
            now_ms: start_ms,
            capacity_wh: CAPACITY_WH,
            energy_wh: CAPACITY_WH,
            extra_draw_w: 0.0,
            idle_w: IDLE_W,
            arm_temp_k: 110.0,
            arm_state: "stowed".into(),
            sites: Vec::new(),
            samples: Vec::new(),
            products: Vec::new(),
            start_ms,
            next_id: 1,
            rng: Rng::new(seed),
            vehicle: Vehicle::Lander,
        }
    }

    /// The scout, ready at `start_ms` beside the lander, battery full.
    pub fn scout(start_ms: i64, seed: u64) -> World {
        World {
            capacity_wh: SCOUT_CAPACITY_WH,
            energy_wh: SCOUT_CAPACITY_WH,
            idle_w: SCOUT_IDLE_W,
            vehicle: Vehicle::Scout,
            ..World::new(start_ms, seed)
        }
    }

    /// A `vehicle` at `start_ms`.
    pub fn of(vehicle: Vehicle, start_ms: i64, seed: u64) -> World {
        match vehicle {
            Vehicle::Lander => World::new(start_ms, seed),
            Vehicle::Scout => World::scout(start_ms, seed),
        }
    }

    /// State of charge, %.
    pub fn soc_pct(&self) -> f64 {
        100.0 * self.energy_wh / self.capacity_wh
    }

    /// Advances time to `t` with the idle (and injected) draw. Time never goes back.
    pub fn advance(&mut self, t: i64) {
        if t <= self.now_ms {
            return;
        }
        let hours = (t - self.now_ms) as f64 / HOUR_MS as f64;
        self.draw(hours * (self.idle_w + self.extra_draw_w));
        // The arm cools toward ambient when not heated.
        self.arm_temp_k = 110.0 + (self.arm_temp_k - 110.0) * (-hours / 6.0).exp();
        self.now_ms = t;
    }

    /// Takes `wh` from the battery (never below empty).
    pub fn draw(&mut self, wh: f64) {
        self.energy_wh = (self.energy_wh - wh).max(0.0);
    }

    /// The Earth link: 42.6 h visible then 42.6 h blackout, from landing.
    pub fn window_open(&self, t: i64) -> bool {
        let period = 852 * HOUR_MS / 10;
        (t - self.start_ms).rem_euclid(period) < period / 2
    }

    /// When the link next opens at or after `t`.
    pub fn next_window(&self, t: i64) -> i64 {
        if self.window_open(t) {
            return t;
        }
        let period = 852 * HOUR_MS / 10;
        let phase = (t - self.start_ms).rem_euclid(period);
        t + (period - phase)
    }

    /// A fresh id.
    pub fn id(&mut self) -> i64 {
        let id = self.next_id;
        self.next_id += 1;
        id
    }

    /// The site with this id.
    pub fn site_mut(&mut self, id: i64) -> Option<&mut Site> {
        self.sites.iter_mut().find(|s| s.site_id == id)
    }
}
