//! The lander's action catalogue (design `elap-sim.md` §5): typed goals and results, declared
//! error codes, and what each costs in time and energy (`cost`: the bounds of what `activities.rs`
//! simulates, for every outcome, checked by the tests against the simulator's own plans; scripted
//! faults — a stall, an injected extra draw — are outside them). Served on `<root>/cat/lander_sim`;
//! missions are checked against it at load.

use connector_api::Catalogue;
use connector_api::cost::Battery;

use crate::world::{CAPACITY_WH, IDLE_W};
use serde_json::json;

/// The server id.
pub const SERVER: &str = "lander_sim";

/// The catalogue `vehicle` serves.
pub fn of(vehicle: crate::world::Vehicle) -> Catalogue {
    match vehicle {
        crate::world::Vehicle::Lander => catalogue(),
        crate::world::Vehicle::Scout => scout(),
    }
}

/// The scout's activities (`elap-sim --vehicle scout`, server `scout_sim`): hop to a site,
/// survey it, read the battery.
pub fn scout() -> Catalogue {
    let actions = json!([
        {"name": "hop.to_site", "goal": {"site_id": "int"},
         "result": {"arrived": "bool", "distance_m": "f64"},
         "errors": {"HOP_ABORTED": "the landing zone is unsafe"},
         "cost": {"duration_s": 600, "power_w": 300}},
        {"name": "survey.site", "goal": {"site_id": "int"},
         "result": {"survey": {"site_id": "int", "safe": "bool", "ice_depth_cm": "f64", "slope_deg": "f64"}},
         "errors": {"LOW_BATTERY": "battery below the survey reserve", "SENSOR_FAULT": "radar fault"},
         "cost": {"duration_s": 900, "power_w": 60}},
        {"name": "power.read_battery",
         "result": {"battery": {"soc_pct": "f64", "energy_wh": "f64", "temp_k": "f64", "rul_h": "f64"}},
         "cost": {"duration_s": 0, "reads": {"battery.soc_pct": "soc_pct", "battery.energy_wh": "energy_wh"}}}
    ]);
    Catalogue {
        server: crate::world::Vehicle::Scout.server().into(),
        actions: serde_json::from_value(actions).unwrap_or_default(),
        telemetry: serde_json::from_value(json!({
            "battery_soc_pct": "f64",
            "battery_energy_wh": "f64",
        }))
        .unwrap_or_default(),
        battery: Some(Battery {
            capacity_wh: crate::world::SCOUT_CAPACITY_WH,
            idle_w: crate::world::SCOUT_IDLE_W,
        }),
    }
}

/// Every activity the simulator serves.
pub fn catalogue() -> Catalogue {
    let actions = json!([
        {"name": "camera.take_panorama", "goal": {"camera": "string", "exposure_ms": "int", "use_led": "bool"},
         "result": {"image": {"image_id": "string", "size_mb": "f64"}},
         "errors": {"CAMERA_TRIGGER_FAILURE": "the camera did not trigger", "UNDEREXPOSED": "image too dark"},
         "cost": {"duration_s": 1200, "power_w": 45}},
        {"name": "world_model.build_terrain_map", "goal": {"image_ids": "[string]"},
         "result": {"map_id": "string", "num_candidates": "int"},
         "errors": {"STEREO_MATCH_FAIL": "stereo matching failed"},
         "cost": {"duration_s": 900, "power_w": 40}},
        {"name": "world_model.select_site", "goal": {"map_id": "string", "exclude_ids": "[int]", "min_score": "f64"},
         "result": {"selected_site": {"site_id": "int", "x_m": "f64", "y_m": "f64", "score": "f64", "material": "string"}},
         "errors": {"NO_VALID_SITE": "candidates exhausted"},
         "cost": {"duration_s": 60, "power_w": 5}},
        {"name": "thermal.warm_up", "goal": {"component": "string", "target_temp_k": "f64", "timeout_s": "int"},
         "result": {"reached_temp_k": "f64", "energy_used_wh": "f64"},
         "errors": {"HEATER_STUCK_OFF": "heater failed", "SLOW_WARMUP": "warm-up took twice as long"},
         "cost": {"duration_s": [2700, 5400], "power_w": 107}},
        {"name": "arm.unstow", "result": {"arm_state": "string"}, "errors": {"ARM_JOINT_FROZEN": "joint fault"},
         "cost": {"duration_s": 600, "power_w": 60}},
        {"name": "arm.stow", "result": {"arm_state": "string"}, "errors": {"ARM_JOINT_FROZEN": "joint fault"},
         "cost": {"duration_s": 600, "power_w": 60}},
        {"name": "arm.approach_site", "goal": {"site_id": "int"},
         "result": {"contact": {"found": "bool", "force_n": "f64"}, "surface_z_m": "f64"},
         "errors": {"GROUND_NOT_FOUND": "no surface contact", "COLLISION": "unexpected contact"},
         "cost": {"duration_s": 600, "power_w": 48}},
        {"name": "excavation.remove_tailings", "goal": {"site_id": "int"},
         "result": {"cleared": "bool", "tailings_volume_cc": "f64"}, "errors": {"TAILINGS_REMAIN": "not cleared"},
         "cost": {"duration_s": 1200, "power_w": 120}},
        {"name": "excavation.excavate", "goal": {"site_id": "int", "target_depth_cm": "f64", "bite_depth_cm": "f64", "max_bites": "int"},
         "result": {"achieved_depth_cm": "f64", "bites": "int", "energy_used_wh": "f64", "tool_temp_k": "f64"},
         "errors": {"TOOL_STUCK": "the tool is stuck", "TIMEOUT": "depth not reached in the allowed bites",
                    "HARD_MATERIAL": "hard ice", "FT_SENSOR_BIAS": "force-torque sensor bias"},
         "cost": {"duration_s": [1500, {"field": "max_bites", "times": 1500, "default": 8}], "power_w": 250}},
        {"name": "excavation.unstick_tool", "goal": {"site_id": "int", "strategy": "string"},
         "result": {"freed": "bool", "attempt": "int"}, "errors": {"TOOL_LOST": "tool abandoned"},
         "cost": {"duration_s": 600, "power_w": 180}},
        {"name": "excavation.assess_slump", "goal": {"site_id": "int", "image_id": "string"},
         "result": {"slump": {"detected": "bool", "volume_cc": "f64", "usable_depth_cm": "f64"}},
         "cost": {"duration_s": 600, "power_w": 48}},
        {"name": "sampling.find_targets", "goal": {"site_id": "int", "image_id": "string"},
         "result": {"collection_targets": "[int]", "num_targets": "int"},
         "cost": {"duration_s": 600, "power_w": 48}},
        {"name": "sampling.collect_sample", "goal": {"site_id": "int", "target_volume_cc": "f64"},
         "result": {"sample": {"sample_id": "int", "volume_cc": "f64", "depth_cm": "f64"}},
         "errors": {"INSUFFICIENT_VOLUME": "short sample", "SAMPLE_CONTAMINATED": "contaminated"},
         "cost": {"duration_s": 3600, "power_w": 120}},
        {"name": "sampling.transfer_sample", "goal": {"sample_id": "int", "instrument": "string"},
         "result": {"delivered": "bool", "delivered_volume_cc": "f64"}, "errors": {"PORT_JAM": "port jammed", "SPILL": "spilled"},
         "cost": {"duration_s": 900, "power_w": 80}},
        {"name": "instrument.analyze", "goal": {"sample_id": "int", "instrument": "string"},
         "result": {"analysis": {"product_id": "string", "size_mb": "f64", "biosignature_score": "f64"}},
         "errors": {"INSTRUMENT_FAULT": "instrument fault", "DATA_CORRUPT": "corrupt data"},
         "cost": {"duration_s": 10800, "power_w": 150}},
        {"name": "data.prioritize", "goal": {"product_ids": "[string]"},
         "result": {"downlink_queue": "[string]", "queue_mb": "f64"},
         "cost": {"duration_s": 60, "power_w": 5}},
        {"name": "comm.downlink", "goal": {"queue": "[string]", "link": "string", "max_mb": "f64"},
         "result": {"sent_mb": "f64", "remaining_mb": "f64", "ground_ack": "bool"},
         "errors": {"NO_WINDOW": "no link now", "LINK_DROPOUT": "partial send", "ANTENNA_POINTING": "antenna fault"},
         "cost": {"duration_s": [3600, {"field": "max_mb", "times": 60, "plus": 3600, "default": 500}], "power_w": 120,
                  "errors": {"NO_WINDOW": {"duration_s": 60}}}},
        {"name": "comm.await_window", "goal": {"link": "string"}, "result": {"window": {"start": "int", "end": "int"}},
         "cost": {"duration_s": [0, 153360]}},
        {"name": "power.read_battery",
         "result": {"battery": {"soc_pct": "f64", "energy_wh": "f64", "temp_k": "f64", "rul_h": "f64"}},
         "cost": {"duration_s": 0, "reads": {"battery.soc_pct": "soc_pct", "battery.energy_wh": "energy_wh"}}},
        {"name": "seismometer.record", "goal": {"duration_s": "int"}, "result": {"product_id": "string", "events": "int"},
         "cost": {"duration_s": [1, {"field": "duration_s", "default": 3600}], "power_w": 5}}
    ]);
    Catalogue {
        server: SERVER.into(),
        actions: serde_json::from_value(actions).unwrap_or_default(),
        // What `elap-sim` publishes on `tm/lander_sim/{power,thermal,comm}` (the executive
        // checks system data against these before it reaches the mission).
        telemetry: serde_json::from_value(json!({
            "battery_soc_pct": "f64",
            "battery_energy_wh": "f64",
            "arm_temp_c": "f64",
            "comm_window_open": "bool",
        }))
        .unwrap_or_default(),
        // What verification before flight reckons with (`trace verify`'s resource
        // requirements): the same battery the world model starts with.
        battery: Some(Battery {
            capacity_wh: CAPACITY_WH,
            idle_w: IDLE_W,
        }),
    }
}
