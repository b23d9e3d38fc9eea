//! libFuzzer target `answers`: the body is `mission_tests::fuzz::answers` (see there for what it reads).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mission_tests::fuzz::answers(data));
