//! Chapter 13 semantics: message_flows (rules in docs/engine-semantics.md).

use super::*;
