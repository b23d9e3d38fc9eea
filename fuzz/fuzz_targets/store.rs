//! libFuzzer target `store`: the body is `mission_tests::fuzz::store` (see there for what it reads).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mission_tests::fuzz::store(data));
