//! The operating envelope of the two event estimators: which speeds, seeding densities,
//! window sizes and time slabs each of them measures correctly, on simulated uniform flows
//! whose velocity is known exactly.
//!
//! Every recording is a uniform flow at one speed in a fixed oblique direction
//! ([`FLOW_ANGLE_DEG`], so that both components are non-zero), seeded at one density, imaged
//! by the `ideal` sensor model ([`EnvelopeSpec::scenario`]); one recording per speed, density
//! and seed is simulated in memory and processed with every setting of the study. A setting
//! is built through the settings layer of `ebiv process` ([`RunSetting::settings`]), so the
//! study measures what a user's command line gives, and a value the library rejects (a slab
//! of `auto` where no estimator chooses its own slab) makes its cells "not applicable"
//! instead of stopping the study.
//!
//! Per cell (speed × density × setting), pooled over the seeds and fields, the valid vectors
//! are compared with the true velocity: RMS of the end-point error, the share of valid
//! vectors, and the share of valid vectors off by more than [`gross_limit`] =
//! max(0.2 px/ms, 10 % of |v|). A cell fails when that "gross" share is 1 % or more: its
//! valid vectors are then systematically wrong, which flagging them would have avoided.
//! [`EnvelopeResults::markdown`] and [`EnvelopeResults::csv`] report the cells.

mod cells;
mod report;

pub use cells::{
    gross_limit, Cell, CellStats, EnvelopeResults, ValidVector, FAIL_SHARE, GROSS_ABSOLUTE,
    GROSS_RELATIVE,
};

use crate::error::{Error, Result};
use crate::estimate::Estimator;
use crate::event::{EventBuffer, Geometry};
use crate::field::FieldSeries;
use crate::process::Method;
use crate::settings::{spread_field_times, EstimatorTask, ProcessSettings, Resolved};
use crate::sim::particles::SeedingParams;
use crate::sim::scenario::{Scenario, SensorSection};
use crate::sim::FlowSpec;
use cells::Tally;
use std::collections::BTreeMap;

/// Direction of every flow of the study, degrees from +x, clockwise on screen (y down): both
/// velocity components are non-zero and neither pixel axis is favoured.
pub const FLOW_ANGLE_DEG: f64 = 30.0;
/// Mean e⁻² particle-image diameter, px: small particle images, as in the EBIV paper's
/// recordings.
pub const PARTICLE_DIAMETER_PX: f64 = 1.5;
/// The sensor model of the recordings: no noise, no mismatch, no refractory losses, so that
/// the study measures the estimators rather than the camera.
pub const SENSOR_PRESET: &str = "ideal";
/// Fields evaluated per recording and setting, spread evenly over the recording.
pub const FIELDS_PER_RECORDING: usize = 3;
/// Time left out at each end of a recording, µs, so that no field touches its edges.
pub const MARGIN_US: i64 = 5_000;
/// The longest slab a recording is made long enough for when every slab given is shorter
/// (or `auto`), µs: [`FIELDS_PER_RECORDING`] such slabs fit side by side between the margins.
pub const LONGEST_SLAB_US: i64 = 20_000;
/// The passes of one setting, for a final window of W px.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum PassSchedule {
    /// One pass of W px windows.
    Single,
    /// Two passes, 2W then W px (the halving schedule of multi-pass PIV; `ebiv process`'s
    /// own default is 64 → 40 px), the last pass repeated as `ebiv process` does by default.
    Default,
}

impl PassSchedule {
    /// Parse `single` or `default`.
    pub fn parse(text: &str) -> Option<PassSchedule> {
        match text.trim() {
            "single" => Some(PassSchedule::Single),
            "default" => Some(PassSchedule::Default),
            _ => None,
        }
    }

    /// The window sizes of the passes for a final window of `window` px, first pass first.
    pub fn windows(self, window: u32) -> Vec<u32> {
        match self {
            PassSchedule::Single => vec![window],
            PassSchedule::Default => vec![2 * window, window],
        }
    }
}

impl std::fmt::Display for PassSchedule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PassSchedule::Single => "single",
            PassSchedule::Default => "default",
        })
    }
}

/// Which cells the study evaluates, and how its recordings are made.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvelopeSpec {
    /// Estimators, as `ebiv process --method` takes them: `corrsum`, `motion`.
    pub methods: Vec<String>,
    /// Flow speeds, px/ms.
    pub speeds: Vec<f64>,
    /// Seeding densities, particles per pixel.
    pub densities: Vec<f64>,
    /// Final window sizes, px (square windows at 50 % overlap).
    pub windows: Vec<u32>,
    /// Time slabs T as `ebiv process --slab` takes them (`10ms`, `auto`).
    pub slabs: Vec<String>,
    /// Pass schedules.
    pub passes: Vec<PassSchedule>,
    /// Simulation seeds: one recording per speed, density and seed.
    pub seeds: Vec<u64>,
    /// Side of the square frame, px.
    pub size: u32,
}

impl Default for EnvelopeSpec {
    /// The full study: 7 speeds × 3 densities × 3 seeds = 63 recordings of 256 × 256 px,
    /// each processed by both estimators with 32 and 64 px windows, T = 2, 10, 20 ms and
    /// `auto`, single pass and the default passes.
    fn default() -> Self {
        EnvelopeSpec {
            methods: vec!["corrsum".into(), "motion".into()],
            speeds: vec![0.02, 0.05, 0.2, 1.0, 2.5, 5.0, 10.0],
            densities: vec![0.002, 0.01, 0.05],
            windows: vec![32, 64],
            slabs: vec!["2ms".into(), "10ms".into(), "20ms".into(), "auto".into()],
            passes: vec![PassSchedule::Single, PassSchedule::Default],
            seeds: vec![1, 2, 3],
            size: 256,
        }
    }
}

impl EnvelopeSpec {
    /// Check the lists before anything is simulated: none empty, speeds and densities
    /// positive and finite, the methods the two event estimators.
    pub fn validate(&self) -> Result<()> {
        let empty = |name: &str, len: usize| {
            if len == 0 {
                Err(Error::parameter(name, "give at least one value"))
            } else {
                Ok(())
            }
        };
        empty("methods", self.methods.len())?;
        empty("speeds", self.speeds.len())?;
        empty("densities", self.densities.len())?;
        empty("windows", self.windows.len())?;
        empty("slabs", self.slabs.len())?;
        empty("passes", self.passes.len())?;
        empty("seeds", self.seeds.len())?;
        for method in &self.methods {
            if !matches!(
                Method::parse(method),
                Some(Method::CorrSum | Method::Motion)
            ) {
                return Err(Error::parameter(
                    "methods",
                    format!(
                        "`{method}`: the study compares the event estimators corrsum and motion"
                    ),
                ));
            }
        }
        if let Some(s) = self.speeds.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            return Err(Error::parameter(
                "speeds",
                format!("{s}: speeds must be positive px/ms"),
            ));
        }
        if let Some(d) = self
            .densities
            .iter()
            .find(|d| !(d.is_finite() && **d > 0.0 && **d <= 1.0))
        {
            return Err(Error::parameter(
                "densities",
                format!("{d}: densities are particles per pixel, above 0 and at most 1"),
            ));
        }
        if self.windows.contains(&0) {
            return Err(Error::parameter("windows", "windows must be at least 1 px"));
        }
        if self.size < 16 {
            return Err(Error::parameter(
                "size",
                format!("{} px: the frame must be at least 16 px", self.size),
            ));
        }
        Ok(())
    }

    /// Every setting of the study, in the order of the report: method, passes, window, slab.
    pub fn settings(&self) -> Vec<RunSetting> {
        let mut all = Vec::new();
        for method in &self.methods {
            for &passes in &self.passes {
                for &window in &self.windows {
                    for slab in &self.slabs {
                        all.push(RunSetting {
                            method: method.clone(),
                            passes,
                            window,
                            slab: slab.clone(),
                        });
                    }
                }
            }
        }
        all
    }

    /// Length of every recording, µs: [`FIELDS_PER_RECORDING`] of the longest slab given
    /// (at least [`LONGEST_SLAB_US`]) side by side, plus [`MARGIN_US`] at each end.
    pub fn duration_us(&self) -> i64 {
        let longest = self
            .slabs
            .iter()
            .filter_map(|s| crate::units::parse_us(s).ok())
            .fold(LONGEST_SLAB_US, i64::max);
        2 * MARGIN_US + FIELDS_PER_RECORDING as i64 * longest
    }

    /// The simulated recording of one cell row: a uniform flow at `speed` px/ms in the
    /// direction [`FLOW_ANGLE_DEG`], `density` particles per pixel of
    /// [`PARTICLE_DIAMETER_PX`], on a `size` × `size` [`SENSOR_PRESET`] sensor, lasting
    /// [`EnvelopeSpec::duration_us`].
    pub fn scenario(&self, speed: f64, density: f64, seed: u64) -> Scenario {
        Scenario {
            seed,
            duration: self.duration_us(),
            start: 0,
            sensor: SensorSection {
                width: self.size,
                height: self.size,
                preset: SENSOR_PRESET.into(),
                overrides: BTreeMap::new(),
            },
            flow: FlowSpec::Uniform {
                u: None,
                v: None,
                speed: Some(speed),
                angle_deg: Some(FLOW_ANGLE_DEG),
            },
            particles: SeedingParams {
                density,
                diameter: PARTICLE_DIAMETER_PX,
                ..SeedingParams::default()
            },
            illumination: Default::default(),
            sampling: Default::default(),
            truth: Default::default(),
        }
    }
}

/// One processing setting of the study: what `ebiv process --method M --window … --slab T`
/// would run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSetting {
    /// `corrsum` or `motion`.
    pub method: String,
    /// Single pass or the default passes.
    pub passes: PassSchedule,
    /// Final window size, px.
    pub window: u32,
    /// The slab as typed (`10ms`, `auto`).
    pub slab: String,
}

impl RunSetting {
    /// The settings of this run as `ebiv process` builds them from its flags: `method`,
    /// `window` (one size per pass; steps from the default 50 % overlap), `slab`; everything
    /// else at its default, except the delay τ of sum of correlation, which must fit in the
    /// slab: a slab shorter than the default τ gets τ = 0.3 T (the paper's 3 ms in 10 ms).
    pub fn settings(&self) -> Result<ProcessSettings> {
        let mut s = ProcessSettings {
            input: Some("simulated recording".into()),
            ..ProcessSettings::default()
        };
        let windows: Vec<String> = self
            .passes
            .windows(self.window)
            .iter()
            .map(u32::to_string)
            .collect();
        s.set_flag("method", std::slice::from_ref(&self.method))?;
        s.set_flag("window", &[windows.join(",")])?;
        s.set_flag("slab", std::slice::from_ref(&self.slab))?;
        let default_tau = ProcessSettings::default().tau.0;
        if Method::parse(&self.method) == Some(Method::CorrSum) {
            if let Ok(slab_us) = crate::units::parse_us(&self.slab) {
                if slab_us > 0 && slab_us < default_tau {
                    s.set_flag("tau", &[format!("{}us", (slab_us * 3 / 10).max(1))])?;
                }
            }
        }
        Ok(s)
    }

    /// The run's parameters, resolved and checked by the settings layer.
    pub fn resolve(&self) -> Result<Resolved> {
        self.settings()?.resolve()
    }

    /// `corrsum, single pass, W 32, T 10ms`.
    pub fn describe(&self) -> String {
        format!(
            "{}, {} passes, W {}, T {}",
            self.method, self.passes, self.window, self.slab
        )
    }
}

/// A setting ready to run: its resolved parameters, from which every run builds its
/// estimator (one slab, or a slab per window with `slab = auto`).
struct Prepared {
    run: Resolved,
}

impl Prepared {
    /// The parameters of `setting`, or why the library rejects them (the estimator is built
    /// once to check them).
    fn new(setting: &RunSetting) -> Result<Prepared> {
        let run = setting.resolve()?;
        if !matches!(run.method, Method::CorrSum | Method::Motion) {
            return Err(Error::parameter(
                "methods",
                "the study compares the event estimators corrsum and motion",
            ));
        }
        run.with_event_estimator(Built)?;
        Ok(Prepared { run })
    }

    /// The delay over which a vector of a slab of `slab_us` µs claims its displacement, ms:
    /// sum of correlation's τ (in proportion to the slab where the slab is not the one
    /// configured), motion compensation's whole slab.
    fn delay_ms(&self, slab_us: u32) -> f64 {
        match self.run.method {
            Method::CorrSum => {
                let p = &self.run.corrsum;
                let scale = match slab_us {
                    0 => 1.0,
                    t => f64::from(t) / p.slab_us as f64,
                };
                p.tau_us as f64 * scale / 1000.0
            }
            _ => f64::from(slab_us) / 1000.0,
        }
    }

    /// The fields of `events` (a recording of `duration_us` on `geometry`):
    /// [`FIELDS_PER_RECORDING`] fields spread evenly between its margins.
    fn process(
        &self,
        events: &EventBuffer,
        geometry: Geometry,
        duration_us: i64,
    ) -> Result<FieldSeries> {
        let times = |extent| field_times(extent, duration_us);
        Ok(self.run.process_in_memory(events, geometry, &times)?.0)
    }
}

/// Building the estimator, and nothing more.
struct Built;

impl EstimatorTask for Built {
    type Output = ();
    fn run<E: Estimator>(self, _: &E) {}
}

/// Field centre times for fields needing `(before, after)` µs of events, evenly spread over
/// a recording of `duration_us` less [`MARGIN_US`] at each end.
fn field_times(extent: (i64, i64), duration_us: i64) -> Result<Vec<i64>> {
    spread_field_times(
        extent,
        MARGIN_US,
        duration_us - MARGIN_US,
        FIELDS_PER_RECORDING,
    )
}

/// How far the study has got, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// Recording `index` (from 1) of `total` is simulated and about to be processed.
    Simulated {
        /// Which recording, from 1.
        index: usize,
        /// Recordings in the study.
        total: usize,
        /// Its speed, px/ms.
        speed: f64,
        /// Its density, particles per pixel.
        density: f64,
        /// Its seed.
        seed: u64,
        /// Its events.
        events: usize,
    },
    /// A processing run (one setting on one recording) is done.
    Processed {
        /// Runs done.
        done: usize,
        /// Runs in the study.
        total: usize,
    },
}

/// Run the study of `spec`: simulate each recording, process it with every setting, and
/// tally each cell. `on_step` hears of every recording and run; an error it returns (an
/// interrupt) stops the study and is returned. A setting the library rejects, or a run that
/// fails, makes its cells not applicable (with the library's message) rather than an error.
pub fn run_study(
    spec: &EnvelopeSpec,
    on_step: &mut dyn FnMut(Step) -> Result<()>,
) -> Result<EnvelopeResults> {
    run_study_with_vectors(spec, on_step, &mut |_| {})
}

/// [`run_study`], handing every valid vector of every run to `on_vector` with its cell,
/// seed, evidence and error ([`ValidVector`]), so that validation thresholds can be chosen
/// from what separates the gross errors from the rest.
pub fn run_study_with_vectors(
    spec: &EnvelopeSpec,
    on_step: &mut dyn FnMut(Step) -> Result<()>,
    on_vector: &mut dyn FnMut(&ValidVector),
) -> Result<EnvelopeResults> {
    spec.validate()?;
    let settings = spec.settings();
    let prepared: Vec<std::result::Result<Prepared, String>> = settings
        .iter()
        .map(|s| Prepared::new(s).map_err(|e| e.to_string()))
        .collect();
    let runnable = prepared.iter().filter(|p| p.is_ok()).count();
    let recordings = spec.speeds.len() * spec.densities.len() * spec.seeds.len();
    let runs_total = recordings * runnable;
    let duration_us = spec.duration_us();
    let mut cells = Vec::new();
    let (mut recording, mut runs_done) = (0, 0);
    for &speed in &spec.speeds {
        for &density in &spec.densities {
            let mut tallies: Vec<std::result::Result<Tally, String>> = prepared
                .iter()
                .map(|p| p.as_ref().map(|_| Tally::default()).map_err(Clone::clone))
                .collect();
            let angle = FLOW_ANGLE_DEG.to_radians();
            let truth = [speed * angle.cos(), speed * angle.sin()];
            for &seed in &spec.seeds {
                let sim = spec.scenario(speed, density, seed).simulation()?;
                let events = sim.run(None, &|_| {})?.events;
                recording += 1;
                on_step(Step::Simulated {
                    index: recording,
                    total: recordings,
                    speed,
                    density,
                    seed,
                    events: events.len(),
                })?;
                for ((p, tally), setting) in prepared.iter().zip(&mut tallies).zip(&settings) {
                    let (Ok(p), Ok(t)) = (p, &mut *tally) else {
                        continue;
                    };
                    let started = std::time::Instant::now();
                    match p.process(&events, sim.geometry, duration_us) {
                        Ok(series) => {
                            t.seconds += started.elapsed().as_secs_f64();
                            t.add(&series, truth);
                            let cell = (setting, speed, density, seed);
                            ValidVector::each(&series, truth, cell, |slab_us| p.delay_ms(slab_us))
                                .for_each(|v| on_vector(&v));
                        }
                        Err(e) => *tally = Err(e.to_string()),
                    }
                    runs_done += 1;
                    on_step(Step::Processed {
                        done: runs_done,
                        total: runs_total,
                    })?;
                }
            }
            cells.extend(settings.iter().zip(tallies).map(|(s, t)| Cell {
                speed,
                density,
                setting: s.clone(),
                outcome: t.map(|t| t.stats()),
            }));
        }
    }
    Ok(EnvelopeResults {
        spec: spec.clone(),
        cells,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_spread_between_the_margins() {
        let spec = EnvelopeSpec::default();
        assert_eq!(spec.duration_us(), 70_000);
        let times = field_times((10_000, 10_000), spec.duration_us()).unwrap();
        assert_eq!(times, [15_000, 35_000, 55_000]);
        let times = field_times((1_000, 1_000), spec.duration_us()).unwrap();
        assert_eq!(times, [6_000, 35_000, 64_000]);
        assert!(field_times((40_000, 40_000), spec.duration_us()).is_err());
    }

    #[test]
    fn settings_are_those_of_the_command_line() {
        let setting = RunSetting {
            method: "corrsum".into(),
            passes: PassSchedule::Default,
            window: 32,
            slab: "2ms".into(),
        };
        let run = setting.resolve().unwrap();
        let windows: Vec<u32> = run.process.passes.iter().map(|g| g.window[0]).collect();
        assert_eq!(windows, [64, 32]);
        assert_eq!(run.process.passes[1].step, [16, 16]);
        assert_eq!((run.corrsum.slab_us, run.corrsum.tau_us), (2_000, 600));
        let setting = RunSetting {
            slab: "10ms".into(),
            ..setting
        };
        assert_eq!(setting.resolve().unwrap().corrsum.tau_us, 3_000);
        let rejected = RunSetting {
            slab: "0ms".into(),
            ..setting
        };
        assert!(Prepared::new(&rejected).is_err());
    }
}
