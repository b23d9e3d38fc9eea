//! Chapter 13 semantics: event_subprocesses (rules in docs/engine-semantics.md).

use super::*;
