//! libFuzzer target `config`: the body is `mission_tests::fuzz::config` (see there for what it reads).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mission_tests::fuzz::config(data));
