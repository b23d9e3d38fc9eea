//! Base64 built-ins, Camunda extensions: `to base64(value)` (Camunda 8.6, feel-scala 1.18)
//! encodes a string's UTF-8 bytes; `from base64(value)` (feel-scala's newer counterpart,
//! camunda/feel-scala#1152) decodes them back.
//!
//! The coding is the `base64` crate's: the de-facto standard Rust implementation (already in
//! the workspace's lock file through other dependencies), constant-time table lookups,
//! exhaustively tested against RFC 4648, and it refuses malformed input instead of guessing.
//! Its configuration here matches `java.util.Base64`'s basic coder, which feel-scala uses: the
//! standard alphabet, padding written when encoding, padding optional when decoding (but
//! checked if present), no line breaks or other white space accepted.

use base64::Engine as _;
use base64::alphabet::STANDARD;
use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};

use super::{Out, null, take, text};
use crate::host::Host;
use crate::value::Value;

/// `java.util.Base64.getEncoder()` / `getDecoder()` for text with padding: padding written when
/// encoding and, when decoding, the right amount of it required; bits left over in the last
/// character are ignored, as Java does.
const PADDED: GeneralPurpose = GeneralPurpose::new(
    &STANDARD,
    GeneralPurposeConfig::new()
        .with_encode_padding(true)
        .with_decode_padding_mode(DecodePaddingMode::RequireCanonical)
        .with_decode_allow_trailing_bits(true),
);

/// `java.util.Base64.getDecoder()` for text without padding, which Java accepts too.
const UNPADDED: GeneralPurpose = GeneralPurpose::new(
    &STANDARD,
    GeneralPurposeConfig::new()
        .with_encode_padding(false)
        .with_decode_padding_mode(DecodePaddingMode::RequireNone)
        .with_decode_allow_trailing_bits(true),
);

/// `to base64(value)`: the Base64 text of a string's UTF-8 bytes (`to base64("FEEL")` is
/// `"RkVFTA=="`).
pub(super) fn to_base64(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [value] = take(args);
    let s = text(&value, "value")?;
    host.spend(s.len() / 64)?;
    Ok(Value::String(PADDED.encode(s)))
}

/// `from base64(value)`: the string whose UTF-8 bytes the Base64 text encodes; null if the
/// text is not Base64, or if the bytes are not UTF-8 text (feel-scala would put U+FFFD in
/// their place; a null with the reason is the more honest answer for binary data).
pub(super) fn from_base64(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [value] = take(args);
    let s = text(&value, "value")?;
    host.spend(s.len() / 64)?;
    // Java: "padding is not required; if present, the correct number of it must be".
    let engine = if s.contains('=') { &PADDED } else { &UNPADDED };
    let bytes = match engine.decode(s) {
        Ok(bytes) => bytes,
        Err(why) => return null(format!("not Base64: {why}")),
    };
    match String::from_utf8(bytes) {
        Ok(text) => Ok(Value::String(text)),
        Err(e) => null(format!(
            "the decoded bytes are not UTF-8 text (byte {} is not)",
            e.utf8_error().valid_up_to() + 1
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::{Mock, check, nulls};
    use super::{from_base64, to_base64};
    use crate::value::Value;

    #[test]
    fn to_base64_encodes_utf8() {
        check(&[
            ("to base64(\"FEEL\")", "\"RkVFTA==\""),
            ("to base64(\"Camunda\")", "\"Q2FtdW5kYQ==\""),
            ("to base64(\"\")", "\"\""),
            ("to base64(\"a\")", "\"YQ==\""),
            ("to base64(\"ab\")", "\"YWI=\""),
            ("to base64(\"abc\")", "\"YWJj\""),
            ("to base64(\"é\")", "\"w6k=\""),
            ("to base64(\"🐎\")", "\"8J+Qjg==\""),
            ("to base64(\"???\")", "\"Pz8/\""),
            ("to base64(\"~~~\")", "\"fn5+\""),
        ]);
        nulls(&[
            ("to base64(null)", "`value` is null"),
            ("to base64(1)", "`value` must be a string, not a number"),
            ("to base64([\"a\"])", "`value` must be a string, not a list"),
        ]);
    }

    #[test]
    fn from_base64_decodes_utf8() {
        check(&[
            ("from base64(\"RkVFTA==\")", "\"FEEL\""),
            ("from base64(\"Q2FtdW5kYQ==\")", "\"Camunda\""),
            ("from base64(\"\")", "\"\""),
            // Padding is optional, as in java.util.Base64.
            ("from base64(\"RkVFTA\")", "\"FEEL\""),
            ("from base64(\"YWI\")", "\"ab\""),
            ("from base64(\"w6k=\")", "\"é\""),
            ("from base64(\"8J+Qjg==\")", "\"🐎\""),
            ("from base64(\"Pz8/\")", "\"???\""),
        ]);
        nulls(&[
            ("from base64(\"!!!\")", "from base64: not Base64"),
            ("from base64(\"RkVF TA==\")", "not Base64"),
            ("from base64(\"RkVFTA=\")", "not Base64"),
            ("from base64(\"RkVFTA===\")", "not Base64"),
            ("from base64(\"Rk=VFTA=\")", "not Base64"),
            ("from base64(\"R\")", "not Base64"),
            // The URL-safe alphabet is not the basic one.
            ("from base64(\"_-_-\")", "not Base64"),
            // 0xFF 0xFE: bytes, not text.
            ("from base64(\"//4=\")", "not UTF-8 text (byte 1 is not)"),
            ("from base64(\"Yf8=\")", "byte 2 is not"),
            ("from base64(null)", "`value` is null"),
            ("from base64(1)", "`value` must be a string, not a number"),
        ]);
    }

    #[test]
    fn round_trip_and_budget() {
        let text = "Grüße, 世界! ".repeat(100);
        let mut host = Mock::new(1_000);
        let encoded = to_base64(&mut host, vec![Value::String(text.clone())]);
        let Ok(encoded) = encoded else {
            panic!("encoded")
        };
        let decoded = from_base64(&mut host, vec![encoded]);
        assert!(matches!(decoded, Ok(Value::String(ref s)) if *s == text));
        assert!(host.spent >= 2 * (text.len() / 64), "spent {}", host.spent);
    }
}
