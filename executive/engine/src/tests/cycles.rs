//! Chapter 13 semantics: cycles (rules in docs/engine-semantics.md).

use super::*;
