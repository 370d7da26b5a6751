//! Fuzz target: `cargo fuzz run hdf5 -- -max_total_time=180`.
#![no_main]

#[path = "common.rs"]
mod common;
#[allow(unused_imports)]
use ebiv::io::Format;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::run(data, Some(Format::Hdf5)));
