//! Chapter 13 semantics: conditional_events (rules in docs/engine-semantics.md).

use super::*;
