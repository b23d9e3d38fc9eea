//! Encoding of protocol payloads on Zenoh: JSON with the payload type and version as the
//! encoding schema (`application/json;trace.goal/1`).

use zenoh::bytes::Encoding;

/// The encoding for a payload kind (`goal`, `status`, …).
pub(crate) fn encoding(kind: &str) -> Encoding {
    Encoding::APPLICATION_JSON.with_schema(connector_api::wire::schema(kind))
}

/// Serialises a payload (our own types cannot fail to serialise).
pub(crate) fn json<T: serde::Serialize>(value: &T) -> Vec<u8> {
    serde_json::to_vec(value).unwrap_or_else(|e| {
        tracing::error!(error = %e, "payload did not serialise");
        b"null".to_vec()
    })
}
