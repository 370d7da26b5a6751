//! Simulate a sweep of synthetic recordings in memory, as a study of an estimator's operating
//! envelope does: uniform flows of several speeds and seeding densities, 1 px particles, the
//! `ideal` sensor, each recording's events kept in an `EventBuffer` beside its true velocity.
//!
//! `cargo run --release --example simulate_sweep`

use ebiv::sim::flow::FlowSpec;
use ebiv::sim::scenario::Scenario;

fn main() -> Result<(), ebiv::Error> {
    for speed in [0.1, 1.0, 5.0] {
        for density in [0.01, 0.05] {
            let mut scenario =
                Scenario::new(128, 128, "ideal", FlowSpec::uniform(speed, 0.0), 40_000);
            scenario.particles.density = density;
            scenario.particles.diameter = 1.0;
            scenario.seed = 7;
            let sim = scenario.simulation()?;
            let events = sim.run(None, &|_| {})?.events;
            let (u, v) = sim.velocity(63.5, 63.5, 20_000.0);
            println!(
                "{speed:4} px/ms, {density} particles/px: {:8} events ({} ON); true velocity ({u}, {v}) px/ms",
                events.len(),
                events.count_on()
            );
        }
    }
    Ok(())
}
