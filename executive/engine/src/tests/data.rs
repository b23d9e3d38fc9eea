//! Chapter 13 semantics: data (rules in docs/engine-semantics.md).

use super::*;
