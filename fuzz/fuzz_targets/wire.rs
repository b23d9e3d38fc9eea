//! libFuzzer target `wire`: the body is `mission_tests::fuzz::wire` (see there for what it reads).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mission_tests::fuzz::wire(data));
