//! Integration tier `it`: the loader and the engine against external corpora, the shipped
//! missions, hostile input and the `trace` command, all in one test binary.

mod cli;
mod conformance;
mod durability;
mod engine;
mod hostile;
mod missions;
mod tidy;
