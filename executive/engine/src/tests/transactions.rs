//! Chapter 13 semantics: transactions (rules in docs/engine-semantics.md).

use super::*;
