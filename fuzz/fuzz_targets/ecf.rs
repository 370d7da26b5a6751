//! Fuzz target: `cargo fuzz run ecf -- -max_total_time=180`. A decoded ECF buffer holds the
//! events it declares, and encoding them again round-trips.
#![no_main]

use ebiv::io::ecf;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let mut events = ecf::EcfEvents::default();
    if ecf::decode(data, &mut events).is_ok() {
        assert_eq!(Some(events.len()), ecf::declared_events(data));
        let again = ecf::encode(&events).expect("decoded events encode");
        let mut back = ecf::EcfEvents::default();
        ecf::decode(&again, &mut back).expect("encoded events decode");
        assert_eq!(back, events);
    }
});
