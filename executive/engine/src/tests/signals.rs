//! Chapter 13 semantics: signals (rules in docs/engine-semantics.md).

use super::*;
