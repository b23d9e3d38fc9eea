//! Integration tier `it`: the loader and the engine against external corpora, the shipped
//! missions, hostile input, the Zenoh activity protocol, ground stations and the `trace` command, all in one
//! test binary.

mod black_box;
mod cli;
mod conformance;
mod connectors;
mod constructs;
mod crash;
mod dataflow;
mod durability;
mod engine;
mod europa;
mod examples;
mod feel;
mod fleet;
mod fleet_hosts;
mod flood;
mod fly;
mod fuzz;
mod generated;
mod ground;
mod hostile;
mod hosts;
mod missions;
mod ops;
mod ops_ground;
mod protocol;
mod python;
mod realworld;
mod resources;
mod ros2;
mod ros2_europa;
mod run;
mod simulated;
mod studio;
mod studio_compose;
mod studio_draw;
mod tidy;
mod timeline;
mod tour;
mod verify;
mod waves;
