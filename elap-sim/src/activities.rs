//! The lander's activities: what each does to the world, how long it takes, how much energy it
//! uses and how it can fail. `Sim::plan` decides an activity when it starts (drawing faults from
//! the seeded generator); `Sim::finish` applies it when it ends — wholly, or in part when it is
//! cancelled.

use std::collections::BTreeMap;

use connector_api::Fields;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use crate::faults::{Profile, Script};
use crate::world::{HOUR_MS, Material, Product, Sample, Site, Vehicle, World};

/// What an activity will do, decided when it starts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The action.
    pub action: String,
    /// Mission time it takes, ms.
    pub duration_ms: i64,
    /// Average power while it runs, W (on top of the idle draw).
    pub power_w: f64,
    /// Result fields on success, or the failure.
    pub outcome: Result<Fields, (String, String)>,
    /// Effect on the world when it ends (scaled by the fraction done).
    pub effect: Effect,
}

/// World changes an activity makes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Effect {
    /// Dig this deep at this site.
    pub dig: Option<(i64, f64)>,
    /// New candidate sites.
    pub sites: Vec<Site>,
    /// A new sample.
    pub sample: Option<Sample>,
    /// A sample analysed.
    pub analysed: Option<i64>,
    /// New data products.
    pub products: Vec<Product>,
    /// Products sent.
    pub sent: Vec<String>,
    /// Arm state after.
    pub arm_state: Option<String>,
    /// Arm temperature after, K.
    pub arm_temp_k: Option<f64>,
}

/// An activity under way: its plan and when it started (mission time), kept with the world so
/// a restarted simulator carries it on instead of starting it over.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Running {
    /// What it does.
    pub plan: Plan,
    /// When it started, ms.
    pub started_ms: i64,
}

/// How an activity ended, kept until its goal's result is recorded: ending the same goal again
/// returns this instead of applying its effects twice.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ended {
    /// It was cancelled (partial effects).
    pub cancelled: bool,
    /// Its outputs, or its failure.
    pub outcome: Result<Fields, (String, String)>,
}

/// The simulator core: world, fault profile, scripted faults, call counts.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Sim {
    /// The world.
    pub world: World,
    /// Calls per action so far (scripted faults count them).
    pub calls: BTreeMap<String, u32>,
    /// Activities under way, by goal id.
    #[serde(default)]
    pub running: BTreeMap<String, Running>,
    /// Activities ended whose results may not be recorded yet, by goal id.
    #[serde(default)]
    pub ended: BTreeMap<String, Ended>,
    #[serde(skip)]
    profile: Option<Profile>,
    #[serde(skip)]
    script: Script,
}

/// Why an activity cannot even start.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("{0}")]
pub struct Refused(pub String);

fn f(v: &Fields, k: &str) -> Option<f64> {
    v.get(k).and_then(Value::as_f64)
}
fn i(v: &Fields, k: &str) -> Option<i64> {
    v.get(k).and_then(Value::as_i64)
}
fn obj(v: Value) -> Fields {
    v.as_object().cloned().unwrap_or_default()
}

impl Sim {
    /// A simulator over `world`.
    pub fn new(world: World, profile: Profile, script: Script) -> Sim {
        Sim {
            world,
            calls: BTreeMap::new(),
            running: BTreeMap::new(),
            ended: BTreeMap::new(),
            profile: Some(profile),
            script,
        }
    }

    /// Re-attaches profile and script after loading a saved simulator.
    pub fn with(mut self, profile: Profile, script: Script) -> Sim {
        self.profile = Some(profile);
        self.script = script;
        self
    }

    fn p(&self, p: f64) -> f64 {
        p * self.profile.unwrap_or(Profile::Nominal).factor()
    }

    /// Decides an activity starting now. Faults are drawn here.
    pub fn plan(&mut self, action: &str, goal: &Fields) -> Result<Plan, Refused> {
        // Each vehicle does its own activities (the scout's are `hop.*` and `survey.*`, and it
        // reads its battery).
        let scouting = action.starts_with("hop.") || action.starts_with("survey.");
        let own = match self.world.vehicle {
            Vehicle::Lander => !scouting,
            Vehicle::Scout => scouting || action == "power.read_battery",
        };
        if !own {
            return Err(Refused(format!(
                "the {} has no activity `{action}`",
                self.world.vehicle
            )));
        }
        let call = {
            let c = self.calls.entry(action.to_owned()).or_default();
            *c += 1;
            *c
        };
        let forced = self.script.forced(action, call).cloned();
        if let Some(s) = &forced
            && s.code == "HIGH_POWER_DRAW"
        {
            self.world.extra_draw_w += s.draw_w;
        }
        let forced_code = forced.map(|s| s.code).filter(|c| c != "HIGH_POWER_DRAW");
        let fail = |sim: &mut Sim, code: &str, p: f64| -> bool {
            match &forced_code {
                Some(c) => c == code,
                None => {
                    let p = sim.p(p);
                    sim.world.rng.chance(p)
                }
            }
        };
        let now = self.world.now_ms;
        let mut effect = Effect::default();
        let min = |m: i64| m * 60_000;
        let (duration_ms, power_w, outcome): (i64, f64, Result<Fields, (String, String)>) =
            match action {
                "camera.take_panorama" => {
                    let id = format!("img-{}", self.world.id());
                    effect.products.push(Product {
                        product_id: id.clone(),
                        size_mb: 120.0,
                        downlinked: false,
                    });
                    let r = if fail(self, "CAMERA_TRIGGER_FAILURE", 0.02) {
                        Err((
                            "CAMERA_TRIGGER_FAILURE".into(),
                            "camera did not trigger".into(),
                        ))
                    } else {
                        Ok(obj(json!({"image": {"image_id": id, "size_mb": 120.0}})))
                    };
                    (min(20), 45.0, r)
                }
                "world_model.build_terrain_map" => {
                    let n = 8;
                    for k in 0..n {
                        let material = match self.world.rng.next_u64() % 4 {
                            0 => Material::LooseRegolith,
                            1 => Material::GranularIce,
                            2 => Material::HardIce,
                            _ => Material::SaltCrust,
                        };
                        let site_id = self.world.id();
                        effect.sites.push(Site {
                            site_id,
                            x_m: 1.0 + k as f64 * 0.4,
                            y_m: (self.world.rng.unit() - 0.5) * 2.0,
                            score: 0.35 + 0.6 * self.world.rng.unit(),
                            material,
                            depth_cm: 0.0,
                        });
                    }
                    let map = format!("map-{}", self.world.id());
                    let r = if fail(self, "STEREO_MATCH_FAIL", 0.03) {
                        Err(("STEREO_MATCH_FAIL".into(), "stereo matching failed".into()))
                    } else {
                        Ok(obj(json!({"map_id": map, "num_candidates": n})))
                    };
                    (min(15), 40.0, r)
                }
                "world_model.select_site" => {
                    let exclude: Vec<i64> = goal
                        .get("exclude_ids")
                        .and_then(Value::as_array)
                        .map(|a| a.iter().filter_map(Value::as_i64).collect())
                        .unwrap_or_default();
                    let min_score = f(goal, "min_score").unwrap_or(0.0);
                    let best = self
                        .world
                        .sites
                        .iter()
                        .filter(|s| !exclude.contains(&s.site_id) && s.score >= min_score)
                        .max_by(|a, b| a.score.total_cmp(&b.score));
                    let r = match best {
                        Some(s) => Ok(obj(json!({"selected_site": {
                            "site_id": s.site_id, "x_m": s.x_m, "y_m": s.y_m,
                            "score": s.score, "material": s.material.name()}}))),
                        None => Err((
                            "NO_VALID_SITE".into(),
                            "no untried site above the minimum score".into(),
                        )),
                    };
                    (min(1), 5.0, r)
                }
                "thermal.warm_up" => {
                    let target = f(goal, "target_temp_k").unwrap_or(250.0);
                    let slow = fail(self, "SLOW_WARMUP", 0.05);
                    let dur = if slow { min(90) } else { min(45) };
                    effect.arm_temp_k = Some(target);
                    let r = if fail(self, "HEATER_STUCK_OFF", 0.02) {
                        effect.arm_temp_k = None;
                        Err((
                            "HEATER_STUCK_OFF".into(),
                            "arm heater did not switch on".into(),
                        ))
                    } else {
                        Ok(obj(
                            json!({"reached_temp_k": target, "energy_used_wh": 80.0}),
                        ))
                    };
                    (dur, 107.0, r)
                }
                "arm.unstow" | "arm.stow" => {
                    let state = if action == "arm.unstow" {
                        "unstowed"
                    } else {
                        "stowed"
                    };
                    effect.arm_state = Some(state.into());
                    let r = if fail(self, "ARM_JOINT_FROZEN", 0.01) {
                        effect.arm_state = None;
                        Err(("ARM_JOINT_FROZEN".into(), "shoulder joint frozen".into()))
                    } else {
                        Ok(obj(json!({"arm_state": state})))
                    };
                    (min(10), 60.0, r)
                }
                "arm.approach_site" => {
                    let r = if fail(self, "GROUND_NOT_FOUND", 0.03) {
                        Err(("GROUND_NOT_FOUND".into(), "no surface contact".into()))
                    } else {
                        Ok(obj(
                            json!({"contact": {"found": true, "force_n": 12.0}, "surface_z_m": -0.8}),
                        ))
                    };
                    (min(10), 48.0, r)
                }
                "excavation.remove_tailings" => (
                    min(20),
                    120.0,
                    Ok(obj(json!({"cleared": true, "tailings_volume_cc": 40.0}))),
                ),
                "excavation.excavate" => {
                    let site = i(goal, "site_id").unwrap_or(0);
                    let target = f(goal, "target_depth_cm").unwrap_or(10.0);
                    let bite = f(goal, "bite_depth_cm").unwrap_or(2.0).max(0.1);
                    let max_bites = i(goal, "max_bites").unwrap_or(8).max(1);
                    let hard = self
                        .world
                        .sites
                        .iter()
                        .find(|s| s.site_id == site)
                        .is_some_and(|s| s.material == Material::HardIce);
                    let rate = if hard { bite / 2.0 } else { bite };
                    let needed = (target / rate).ceil() as i64;
                    let mut bites = 0;
                    let mut stuck = false;
                    while bites < needed.min(max_bites) {
                        bites += 1;
                        if fail(self, "TOOL_STUCK", 0.015) {
                            stuck = true;
                            break;
                        }
                    }
                    let depth = (bites as f64 * rate).min(target);
                    effect.dig = Some((site, depth));
                    let r = if stuck {
                        Err((
                            "TOOL_STUCK".into(),
                            format!("tool stuck at {depth:.1} cm, bite {bites}"),
                        ))
                    } else if depth < target {
                        Err((
                            "TIMEOUT".into(),
                            format!("{depth:.1} of {target} cm after {bites} bites"),
                        ))
                    } else {
                        Ok(obj(json!({"achieved_depth_cm": depth, "bites": bites,
                            "energy_used_wh": bites as f64 * 104.0, "tool_temp_k": 140.0})))
                    };
                    (bites * min(25), 250.0, r)
                }
                "excavation.unstick_tool" => {
                    let freed = match &forced_code {
                        Some(_) => false,
                        None => self.world.rng.chance(0.7),
                    };
                    let attempt = self.calls[action];
                    let r = if forced_code.as_deref() == Some("TOOL_LOST") {
                        Err(("TOOL_LOST".into(), "tool abandoned".into()))
                    } else {
                        Ok(obj(json!({"freed": freed, "attempt": attempt})))
                    };
                    (min(10), 180.0, r)
                }
                "excavation.assess_slump" => {
                    let site = i(goal, "site_id").unwrap_or(0);
                    let (material, depth) = self
                        .world
                        .sites
                        .iter()
                        .find(|s| s.site_id == site)
                        .map_or((Material::GranularIce, 0.0), |s| (s.material, s.depth_cm));
                    let slumped = match &forced_code {
                        Some(c) => c == "SLUMP",
                        None => {
                            let p = self.p(material.slump_chance());
                            self.world.rng.chance(p)
                        }
                    };
                    let usable = if slumped { depth * 0.5 } else { depth };
                    if slumped {
                        effect.dig = Some((site, -depth * 0.5));
                    }
                    (
                        min(10),
                        48.0,
                        Ok(obj(json!({"slump": {"detected": slumped,
                        "volume_cc": if slumped { 30.0 } else { 0.0 }, "usable_depth_cm": usable}}))),
                    )
                }
                "sampling.find_targets" => {
                    let n = 1 + (self.world.rng.next_u64() % 2) as i64;
                    let targets: Vec<i64> = (0..n).map(|_| self.world.id()).collect();
                    (
                        min(10),
                        48.0,
                        Ok(obj(
                            json!({"collection_targets": targets, "num_targets": n}),
                        )),
                    )
                }
                "sampling.collect_sample" => {
                    let site = i(goal, "site_id").unwrap_or(0);
                    let volume = f(goal, "target_volume_cc").unwrap_or(7.0);
                    let id = self.world.id();
                    let r = if fail(self, "INSUFFICIENT_VOLUME", 0.08) {
                        Err(("INSUFFICIENT_VOLUME".into(), "scoop came back short".into()))
                    } else {
                        effect.sample = Some(Sample {
                            sample_id: id,
                            site_id: site,
                            volume_cc: volume,
                            analysed: false,
                        });
                        Ok(obj(
                            json!({"sample": {"sample_id": id, "volume_cc": volume, "depth_cm": 10.0}}),
                        ))
                    };
                    (min(60), 120.0, r)
                }
                "sampling.transfer_sample" => {
                    let r = if fail(self, "PORT_JAM", 0.02) {
                        Err(("PORT_JAM".into(), "instrument port jammed".into()))
                    } else {
                        Ok(obj(json!({"delivered": true, "delivered_volume_cc": 6.8})))
                    };
                    (min(15), 80.0, r)
                }
                "instrument.analyze" => {
                    let sample = i(goal, "sample_id").unwrap_or(0);
                    let id = format!("ana-{sample}");
                    effect.analysed = Some(sample);
                    effect.products.push(Product {
                        product_id: id.clone(),
                        size_mb: 40.0,
                        downlinked: false,
                    });
                    let score = self.world.rng.unit() * 0.2;
                    let r = if fail(self, "INSTRUMENT_FAULT", 0.02) {
                        effect.analysed = None;
                        effect.products.clear();
                        Err(("INSTRUMENT_FAULT".into(), "analyser fault".into()))
                    } else {
                        Ok(obj(
                            json!({"analysis": {"product_id": id, "size_mb": 40.0, "biosignature_score": score}}),
                        ))
                    };
                    (3 * HOUR_MS, 150.0, r)
                }
                "data.prioritize" => {
                    let queue: Vec<String> = self
                        .world
                        .products
                        .iter()
                        .filter(|p| !p.downlinked)
                        .map(|p| p.product_id.clone())
                        .collect();
                    let mb: f64 = self
                        .world
                        .products
                        .iter()
                        .filter(|p| !p.downlinked)
                        .map(|p| p.size_mb)
                        .sum();
                    (
                        min(1),
                        5.0,
                        Ok(obj(json!({"downlink_queue": queue, "queue_mb": mb}))),
                    )
                }
                "comm.downlink" => {
                    if !self.world.window_open(now) || forced_code.as_deref() == Some("NO_WINDOW") {
                        (
                            min(1),
                            0.0,
                            Err(("NO_WINDOW".into(), "no link to Earth now".into())),
                        )
                    } else {
                        let max = f(goal, "max_mb").unwrap_or(500.0);
                        let mut sent = 0.0;
                        for p in self.world.products.iter().filter(|p| !p.downlinked) {
                            if sent + p.size_mb > max {
                                break;
                            }
                            sent += p.size_mb;
                            effect.sent.push(p.product_id.clone());
                        }
                        let left: f64 = self
                            .world
                            .products
                            .iter()
                            .filter(|p| !p.downlinked)
                            .map(|p| p.size_mb)
                            .sum::<f64>()
                            - sent;
                        // 1 MB per minute, at least an hour of link time per pass.
                        let dur = min(60).max(min(sent as i64));
                        (
                            dur,
                            120.0,
                            Ok(obj(
                                json!({"sent_mb": sent, "remaining_mb": left, "ground_ack": true}),
                            )),
                        )
                    }
                }
                "comm.await_window" => {
                    let next = self.world.next_window(now + 1);
                    let end = next + 852 * HOUR_MS / 20;
                    (
                        next - now,
                        0.0,
                        Ok(obj(json!({"window": {"start": next, "end": end}}))),
                    )
                }
                "power.read_battery" => (
                    0,
                    0.0,
                    Ok(obj(json!({"battery": {
                    "soc_pct": self.world.soc_pct(), "energy_wh": self.world.energy_wh,
                    "temp_k": 250.0, "rul_h": self.world.energy_wh / (self.world.idle_w + self.world.extra_draw_w).max(1.0)}}))),
                ),
                "seismometer.record" => {
                    let secs = i(goal, "duration_s").unwrap_or(3600).max(1);
                    let id = format!("seis-{}", self.world.id());
                    effect.products.push(Product {
                        product_id: id.clone(),
                        size_mb: 5.0,
                        downlinked: false,
                    });
                    (
                        secs * 1000,
                        5.0,
                        Ok(obj(json!({"product_id": id, "events": 0}))),
                    )
                }
                // The scout (`--vehicle scout`): a hopper that surveys candidate sites.
                "hop.to_site" => {
                    let site = i(goal, "site_id").unwrap_or(0);
                    let r = if fail(self, "HOP_ABORTED", 0.03) {
                        Err((
                            "HOP_ABORTED".into(),
                            format!("landing zone at site {site} unsafe to touch down"),
                        ))
                    } else {
                        Ok(obj(
                            json!({"arrived": true, "distance_m": 40.0 + 3.0 * site as f64}),
                        ))
                    };
                    (min(10), 300.0, r)
                }
                "survey.site" => {
                    let site = i(goal, "site_id").unwrap_or(0);
                    let r = if self.world.soc_pct() < crate::world::SCOUT_RESERVE_PCT {
                        Err((
                            "LOW_BATTERY".into(),
                            format!(
                                "battery at {:.0} %, below the {:.0} % reserve",
                                self.world.soc_pct(),
                                crate::world::SCOUT_RESERVE_PCT
                            ),
                        ))
                    } else if fail(self, "SENSOR_FAULT", 0.02) {
                        Err((
                            "SENSOR_FAULT".into(),
                            "ground-penetrating radar fault".into(),
                        ))
                    } else {
                        // What the scout sees of a site: drawn from the seeded generator, so
                        // a seed gives the same report.
                        let safe = match forced_code.as_deref() {
                            Some("UNSAFE") => false,
                            Some("SAFE") => true,
                            _ => !self.world.rng.chance(0.3),
                        };
                        let ice = 5.0 + 40.0 * self.world.rng.unit();
                        Ok(obj(json!({"survey": {"site_id": site, "safe": safe,
                            "ice_depth_cm": ice, "slope_deg": if safe { 4.0 } else { 19.0 }}})))
                    };
                    (min(15), 60.0, r)
                }
                other => {
                    return Err(Refused(format!(
                        "the {} has no activity `{other}`",
                        self.world.vehicle
                    )));
                }
            };
        // A scripted stall: the activity makes no progress and draws nothing extra until it
        // is cancelled (a wedged mechanism the mission deadline must rescue).
        let (duration_ms, power_w) = if forced_code.as_deref() == Some("STALL") {
            (30 * 24 * HOUR_MS, 0.0)
        } else {
            (duration_ms, power_w)
        };
        Ok(Plan {
            action: action.to_owned(),
            duration_ms,
            power_w,
            outcome,
            effect,
        })
    }

    /// Starts the activity of goal `goal_id` at `now`, or, if that goal is already under way
    /// (the simulator restarted), carries on with the plan it had: each goal is planned once,
    /// so a restart neither redraws its faults nor restarts its clock.
    pub fn begin(
        &mut self,
        goal_id: &str,
        action: &str,
        goal: &Fields,
        now: i64,
    ) -> Result<Running, Refused> {
        if let Some(r) = self.running.get(goal_id) {
            return Ok(r.clone());
        }
        let running = Running {
            plan: self.plan(action, goal)?,
            started_ms: now,
        };
        self.running.insert(goal_id.to_owned(), running.clone());
        Ok(running)
    }

    /// Ends goal `goal_id`'s activity at `t`, cancelled or not, applying its effects once:
    /// a goal that already ended gets the same outcome back and changes nothing. `None` for a
    /// goal that was never begun.
    pub fn end(&mut self, goal_id: &str, cancelled: bool, t: i64) -> Option<Ended> {
        if let Some(e) = self.ended.get(goal_id) {
            return Some(e.clone());
        }
        let r = self.running.remove(goal_id)?;
        let fraction = if cancelled {
            ((t - r.started_ms) as f64 / r.plan.duration_ms.max(1) as f64).min(0.99)
        } else {
            1.0
        };
        let done = r.started_ms + (r.plan.duration_ms as f64 * fraction) as i64;
        let outcome = self.finish(&r.plan, fraction, t.max(done));
        let e = Ended { cancelled, outcome };
        self.ended.insert(goal_id.to_owned(), e.clone());
        Some(e)
    }

    /// The goal's result is recorded where it cannot be lost: its outcome need not be kept.
    pub fn forget(&mut self, goal_id: &str) {
        self.ended.remove(goal_id);
    }

    /// Applies a plan that ran `fraction` of its duration (1 when it ended on its own) at time
    /// `t`; returns the outcome, with partial outputs for a cancelled excavation.
    pub fn finish(
        &mut self,
        plan: &Plan,
        fraction: f64,
        t: i64,
    ) -> Result<Fields, (String, String)> {
        let fraction = fraction.clamp(0.0, 1.0);
        let start = t - (plan.duration_ms as f64 * fraction) as i64;
        self.world.advance(start.max(self.world.now_ms));
        self.world
            .draw(plan.power_w * (t - start) as f64 / HOUR_MS as f64);
        self.world.advance(t);
        let e = &plan.effect;
        if let Some((site, depth)) = e.dig
            && let Some(s) = self.world.site_mut(site)
        {
            s.depth_cm = (s.depth_cm + depth * fraction).max(0.0);
        }
        if fraction < 1.0 {
            let depth = e.dig.map_or(0.0, |(_, d)| d * fraction);
            return Ok(obj(json!({"achieved_depth_cm": depth})));
        }
        self.world.sites.extend(e.sites.iter().cloned());
        if let Some(s) = &e.sample {
            self.world.samples.push(s.clone());
        }
        if let Some(id) = e.analysed
            && let Some(s) = self.world.samples.iter_mut().find(|s| s.sample_id == id)
        {
            s.analysed = true;
        }
        self.world.products.extend(e.products.iter().cloned());
        for id in &e.sent {
            if let Some(p) = self.world.products.iter_mut().find(|p| &p.product_id == id) {
                p.downlinked = true;
            }
        }
        if let Some(a) = &e.arm_state {
            self.world.arm_state = a.clone();
        }
        if let Some(k) = e.arm_temp_k {
            self.world.arm_temp_k = k;
        }
        plan.outcome.clone()
    }
}
