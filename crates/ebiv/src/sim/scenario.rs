//! Scenario files: a whole synthetic recording described in TOML, and the ready examples
//! `ebiv simulate --example NAME` runs.

use super::flow::FlowSpec;
use super::particles::SeedingParams;
use super::scene::IlluminationParams;
use super::sensor::{SensorParams, TimestampMode};
use super::simulation::{Interpolation, Simulation};
use crate::error::{Error, Result};
use crate::event::Geometry;
use std::collections::BTreeMap;

/// A scenario as written in TOML. Durations accept units (`"20ms"`, `"1.5s"`; numbers are µs).
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Random seed (particles, sensor mismatch, noise).
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Length of the recording.
    #[serde(deserialize_with = "crate::units::serde_us::deserialize")]
    pub duration: i64,
    /// Camera time of the first sample.
    #[serde(default, deserialize_with = "crate::units::serde_us::deserialize")]
    pub start: i64,
    /// Sensor size, preset and parameter overrides.
    pub sensor: SensorSection,
    /// The flow.
    pub flow: FlowSpec,
    /// Particles and light sheet.
    #[serde(default)]
    pub particles: SeedingParams,
    /// Light and static scene.
    #[serde(default)]
    pub illumination: IlluminationParams,
    /// Time sampling of the simulation.
    #[serde(default)]
    pub sampling: Sampling,
    /// Ground-truth outputs.
    #[serde(default)]
    pub truth: TruthSpec,
}

fn default_seed() -> u64 {
    1
}

/// `[sensor]`: size, a preset, and any [`SensorParams`] field to override.
#[derive(Debug, Clone, serde::Deserialize)]
pub struct SensorSection {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// `ideal`, `gen4` or `noisy`.
    #[serde(default = "default_preset")]
    pub preset: String,
    /// Overrides of the preset's parameters, by [`SensorParams`] field name.
    #[serde(flatten)]
    pub overrides: BTreeMap<String, ParamValue>,
}

/// A value in the `[sensor]` section.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(untagged)]
pub enum ParamValue {
    /// A number.
    Number(f64),
    /// A word (`round`, `truncate`, `none`).
    Text(String),
}

fn default_preset() -> String {
    "gen4".into()
}

/// `[sampling]`: how finely time is sampled. A key left out takes the default for the
/// scenario's light ([`Sampling::resolve`]).
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sampling {
    /// Largest particle displacement between samples, px: by default 0.75 with the cubic
    /// interpolation, 0.25 with the linear. Crossing times are exact for the log intensity
    /// interpolated between samples (`interpolation`); the interpolation is the error
    /// ([`Interpolation`] gives it for both defaults). sensor-model.md §10 recommends at most
    /// 0.05 px per step for a linear interpolation.
    pub step_px: Option<f64>,
    /// Longest interval between samples, µs: by default 600 with the cubic interpolation,
    /// 200 with the linear.
    pub max_step_us: Option<f64>,
    /// How a pixel's input runs between samples: `"cubic"` (the default for continuous
    /// light without flicker) or `"linear"` (the default for pulsed or flickering light, the
    /// only one those allow); see [`Interpolation`].
    pub interpolation: Option<Interpolation>,
}

/// A scenario's time sampling with its defaults filled in ([`Sampling::resolve`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResolvedSampling {
    /// How a pixel's input runs between samples.
    pub interpolation: Interpolation,
    /// Largest particle displacement between samples, px.
    pub step_px: f64,
    /// Longest interval between samples, µs.
    pub max_step_us: f64,
}

impl std::fmt::Display for ResolvedSampling {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = match self.interpolation {
            Interpolation::Linear => "linear",
            Interpolation::Cubic => "cubic",
        };
        write!(
            f,
            "{name}, at most {} px and {} µs per step",
            self.step_px, self.max_step_us
        )
    }
}

impl Sampling {
    /// This table for a scene lit by `light`, defaults filled in: the cubic interpolation at
    /// 0.75 px and 600 µs where the light is continuous without flicker (about as accurate as
    /// the linear at 0.25 px and 200 µs: mean |Δt| to a fine sampling 0.79–1.04 of the
    /// linear's on the five examples, 1.01 pooled over eight seeds of a test scene, for
    /// 0.6–0.88 of its CPU time; docs/simulate.md),
    /// otherwise the linear at 0.25 px and 200 µs. The step's defaults follow the interpolation, also where it is
    /// given.
    pub fn resolve(&self, light: &IlluminationParams) -> ResolvedSampling {
        let interpolation = self.interpolation.unwrap_or(if light.steady() {
            Interpolation::Cubic
        } else {
            Interpolation::Linear
        });
        let (step_px, max_step_us) = match interpolation {
            Interpolation::Cubic => (0.75, 600.0),
            Interpolation::Linear => (0.25, 200.0),
        };
        ResolvedSampling {
            interpolation,
            step_px: self.step_px.unwrap_or(step_px),
            max_step_us: self.max_step_us.unwrap_or(max_step_us),
        }
    }
}

/// `[truth]`: where and when the true velocity field is sampled.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TruthSpec {
    /// Grid spacing of the velocity truth, px (at least 1; [`TruthSpec::validate_field`]).
    pub grid_step: f64,
    /// Time between truth fields.
    #[serde(deserialize_with = "crate::units::serde_us::deserialize")]
    pub interval: i64,
    /// Time between samples of the particle tracks.
    #[serde(deserialize_with = "crate::units::serde_us::deserialize")]
    pub track_interval: i64,
}

/// Most values (grid nodes × fields) of a truth velocity series: about 1.4 GB in memory
/// (a [`crate::field::FieldSeries`] holds 21 bytes per value), 1.8 GB while it is written as
/// NetCDF.
pub const MAX_TRUTH_VALUES: u64 = 1 << 26;

/// Most particle track points expected (56 bytes each in memory): about 7.5 GB.
pub const MAX_TRACK_POINTS: u64 = 1 << 27;

impl TruthSpec {
    /// Check the velocity truth's sampling for a recording of `geometry` lasting
    /// `duration_us`: a grid step of at least 1 px, an interval of at least 1 µs, and at
    /// most [`MAX_TRUTH_VALUES`] values in all (checked before the simulation runs, so that
    /// a mistyped step fails at once instead of exhausting the memory after it).
    pub fn validate_field(&self, geometry: Geometry, duration_us: i64) -> Result<()> {
        if !(self.grid_step >= 1.0 && self.grid_step.is_finite()) {
            return Err(Error::parameter(
                "truth.grid_step",
                format!("{} px: must be at least 1 px", self.grid_step),
            ));
        }
        if self.interval < 1 {
            return Err(Error::parameter(
                "truth.interval",
                format!("{} µs: must be at least 1 µs", self.interval),
            ));
        }
        let nodes = |side: u32| ((side as f64 - 0.5) / self.grid_step).floor().max(0.0) + 1.0;
        let fields = (duration_us.max(0) / self.interval) as f64 + 1.0;
        let values = nodes(geometry.width) * nodes(geometry.height) * fields;
        if values > MAX_TRUTH_VALUES as f64 {
            return Err(Error::parameter(
                "truth",
                format!(
                    "grid_step {} px every {} µs over {} gives {values:.3e} velocity values, \
                     more than {MAX_TRUTH_VALUES}: use a coarser grid_step or a longer interval",
                    self.grid_step,
                    self.interval,
                    crate::units::format_us(duration_us),
                ),
            ));
        }
        Ok(())
    }

    /// Check the particle tracks' sampling for a recording of `geometry` lasting
    /// `duration_us` seeded with `density` particles per pixel: an interval of at least
    /// 1 µs and at most [`MAX_TRACK_POINTS`] points expected (the mean number of particles in
    /// view times the samples; a converging flow may gather more in view).
    pub fn validate_tracks(
        &self,
        geometry: Geometry,
        duration_us: i64,
        density: f64,
    ) -> Result<()> {
        if self.track_interval < 1 {
            return Err(Error::parameter(
                "truth.track_interval",
                format!("{} µs: must be at least 1 µs", self.track_interval),
            ));
        }
        let particles = density * geometry.width as f64 * geometry.height as f64;
        let samples = (duration_us.max(0) / self.track_interval) as f64 + 1.0;
        let points = particles * samples;
        if points > MAX_TRACK_POINTS as f64 {
            return Err(Error::parameter(
                "truth.track_interval",
                format!(
                    "{} µs over {} with about {particles:.0} particles in view gives about \
                     {points:.3e} track points, more than {MAX_TRACK_POINTS}: use a longer \
                     track_interval or a shorter duration",
                    self.track_interval,
                    crate::units::format_us(duration_us),
                ),
            ));
        }
        Ok(())
    }
}

impl Default for TruthSpec {
    fn default() -> Self {
        TruthSpec {
            grid_step: 16.0,
            interval: 1000,
            track_interval: 100,
        }
    }
}

/// The ready scenarios: name, one-line description, TOML.
pub const EXAMPLES: [(&str, &str, &str); 7] = [
    (
        "uniform",
        "uniform flow at 2 px/ms, 640x480, gen4 sensor",
        include_str!("examples/uniform.toml"),
    ),
    (
        "turntable",
        "solid-body rotation (a turntable), 640x480",
        include_str!("examples/turntable.toml"),
    ),
    (
        "vortex",
        "Lamb-Oseen vortex in a uniform stream, 640x480",
        include_str!("examples/vortex.toml"),
    ),
    (
        "shear-layer",
        "Couette shear with a bright wall at the bottom, 640x480",
        include_str!("examples/shear_layer.toml"),
    ),
    (
        "mixing-layer",
        "tanh mixing layer from 0.05 to 5 px/ms, 256x128, ideal sensor, 400 ms",
        include_str!("examples/mixing_layer.toml"),
    ),
    (
        "paper-rate",
        "1280x720 at about 20 M events/s, the EBIV paper's data rate (benchmark scene)",
        include_str!("examples/paper_rate.toml"),
    ),
    (
        "wallflow",
        "the EBIV paper's wall flow as its camera saw it: stream with eddies, 1280x720, imx636 sensor",
        include_str!("examples/wallflow.toml"),
    ),
];

impl Scenario {
    /// A scenario of `flow` seen for `duration_us` by a `width` × `height` sensor of the
    /// preset `preset` (`ideal`, `gen4`, `imx636` or `noisy`), everything else at the defaults of a
    /// scenario file that leaves it out: seed 1, start 0, the default [`SeedingParams`],
    /// continuous light ([`IlluminationParams`]), the sampling for that light
    /// ([`Sampling::resolve`]) and the default [`TruthSpec`]. Change the public fields to
    /// set the rest (`scenario.particles.density = 0.05`); [`Scenario::simulation`] checks
    /// them all.
    pub fn new(width: u32, height: u32, preset: &str, flow: FlowSpec, duration_us: i64) -> Self {
        Scenario {
            seed: default_seed(),
            duration: duration_us,
            start: 0,
            sensor: SensorSection {
                width,
                height,
                preset: preset.to_string(),
                overrides: BTreeMap::new(),
            },
            flow,
            particles: SeedingParams::default(),
            illumination: IlluminationParams::default(),
            sampling: Sampling::default(),
            truth: TruthSpec::default(),
        }
    }

    /// Read a scenario from TOML; `origin` (a file name, or `example NAME`) and the line of
    /// the offending key name the place of an error.
    pub fn from_toml(text: &str, origin: &str) -> Result<Scenario> {
        toml::from_str(text).map_err(|e| Error::Parse {
            context: origin.to_string(),
            line: e.span().map_or(0, |s| line_of(text, s.start)),
            message: e.message().to_string(),
        })
    }

    /// Read the scenario file at `path`; files its flow names (measured fields) are found
    /// beside it.
    pub fn from_file(path: &std::path::Path) -> Result<Scenario> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut scenario = Scenario::from_toml(&text, &path.display().to_string())?;
        if let Some(dir) = path.parent() {
            scenario.flow = scenario.flow.with_base_dir(dir);
        }
        Ok(scenario)
    }

    /// The ready scenario `name` ([`EXAMPLES`]), to run as it is or to change.
    pub fn from_example(name: &str) -> Result<Scenario> {
        Scenario::from_toml(Scenario::example_text(name)?, &format!("example `{name}`"))
    }

    /// The TOML of a ready scenario.
    pub fn example(name: &str) -> Option<&'static str> {
        EXAMPLES.iter().find(|e| e.0 == name).map(|e| e.2)
    }

    /// The TOML of a ready scenario, or an error listing the ready scenarios.
    pub fn example_text(name: &str) -> Result<&'static str> {
        Scenario::example(name).ok_or_else(|| {
            let names: Vec<&str> = EXAMPLES.iter().map(|e| e.0).collect();
            Error::parameter(
                "example",
                format!("`{name}` is not one of {}", names.join(", ")),
            )
        })
    }

    /// The sensor parameters: the preset with the overrides applied, validated.
    pub fn sensor_params(&self) -> Result<SensorParams> {
        let preset = SensorParams::preset(&self.sensor.preset).ok_or_else(|| {
            Error::parameter(
                "sensor.preset",
                format!(
                    "`{}` is not a preset; use ideal, gen4, imx636 or noisy",
                    self.sensor.preset
                ),
            )
        })?;
        let mut params = preset;
        for (key, value) in &self.sensor.overrides {
            apply_override(&mut params, key, value)?;
        }
        params.validate()?;
        Ok(params)
    }

    /// The simulation this scenario describes.
    pub fn simulation(&self) -> Result<Simulation> {
        let ResolvedSampling {
            interpolation,
            step_px,
            max_step_us,
        } = self.sampling.resolve(&self.illumination);
        let sim = Simulation {
            geometry: Geometry::new(self.sensor.width, self.sensor.height),
            flow: self.flow.build()?,
            seeding: self.particles.clone(),
            illumination: self.illumination.clone(),
            sensor: self.sensor_params()?,
            start_us: self.start,
            duration_us: self.duration,
            step_px,
            max_step_us,
            interpolation,
            seed: self.seed,
        };
        sim.validate()?;
        Ok(sim)
    }

    /// The true velocity field of `sim` (this scenario's simulation) on the scenario's
    /// truth grid and interval, its flow described in the attribute `flow`.
    pub fn truth_field(&self, sim: &Simulation) -> crate::field::FieldSeries {
        let mut field = super::truth::velocity_field(
            sim.flow.as_ref(),
            sim.geometry,
            self.truth.grid_step,
            self.start,
            self.start + self.duration,
            self.truth.interval,
        );
        field.attributes.push(("flow".into(), self.flow.describe()));
        field
    }
}

/// The 1-based line holding byte `offset` of `text` (the last line for an offset past the end).
pub(crate) fn line_of(text: &str, offset: usize) -> u64 {
    let before = &text.as_bytes()[..offset.min(text.len())];
    before.iter().filter(|&&b| b == b'\n').count() as u64 + 1
}

/// Set the [`SensorParams`] field named `key`.
fn apply_override(p: &mut SensorParams, key: &str, value: &ParamValue) -> Result<()> {
    let name = format!("sensor.{key}");
    let number = || match value {
        ParamValue::Number(n) => Ok(*n),
        ParamValue::Text(t) => Err(Error::parameter(&name, format!("`{t}` is not a number"))),
    };
    let field: &mut f64 = match key {
        "threshold_on" => &mut p.threshold_on,
        "threshold_off" => &mut p.threshold_off,
        "threshold_sigma" => &mut p.threshold_sigma,
        "linlog_threshold" => &mut p.linlog_threshold,
        "log_eps" => &mut p.log_eps,
        "cutoff_hz" => &mut p.cutoff_hz,
        "cutoff_reference_irradiance" => &mut p.cutoff_reference_irradiance,
        "cutoff_dark_irradiance" => &mut p.cutoff_dark_irradiance,
        "latency_us" => &mut p.latency_us,
        "jitter_us" => &mut p.jitter_us,
        "refractory_us" => &mut p.refractory_us,
        "leak_rate_hz" => &mut p.leak_rate_hz,
        "shot_noise_rate_hz" => &mut p.shot_noise_rate_hz,
        "noise_rate_cov_decades" => &mut p.noise_rate_cov_decades,
        "hot_pixel_fraction" => &mut p.hot_pixel_fraction,
        "hot_pixel_rate_hz" => &mut p.hot_pixel_rate_hz,
        "bandwidth_burst_events" => &mut p.bandwidth_burst_events,
        "bandwidth_ev_per_s" => {
            p.bandwidth_ev_per_s = match value {
                ParamValue::Text(t) if t == "none" => None,
                _ => Some(number()?),
            };
            return Ok(());
        }
        "timestamp" => {
            p.timestamp = match value {
                ParamValue::Text(t) if t == "round" => TimestampMode::Round,
                ParamValue::Text(t) if t == "truncate" => TimestampMode::Truncate,
                _ => return Err(Error::parameter(&name, "use \"round\" or \"truncate\"")),
            };
            return Ok(());
        }
        _ => {
            return Err(Error::parameter(
                &name,
                "is not a sensor parameter (see `SensorParams` in the documentation, or `ebiv simulate --print-example uniform`)",
            ))
        }
    };
    *field = number()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::scene::LightMode;

    fn parse(text: &str, origin: &str) -> Result<Scenario> {
        Scenario::from_toml(text, origin)
    }

    #[test]
    fn lines_count_from_one_and_a_line_starts_after_its_newline() {
        let text = "a = 1\nb = 2\n\nc";
        assert_eq!(line_of(text, 0), 1);
        assert_eq!(line_of(text, 5), 1);
        assert_eq!(line_of(text, 6), 2);
        assert_eq!(line_of(text, 12), 3);
        assert_eq!(line_of(text, 13), 4);
        assert_eq!(line_of(text, 1000), 4);
    }

    #[test]
    fn a_scenario_error_names_the_line_of_the_offending_key() {
        let text = "seed = 1\n\n[illumination]\nbackground = 1.0\nflicker_depth = 0.2\n";
        let err = Scenario::from_toml(text, "s.toml").unwrap_err().to_string();
        assert!(err.contains("s.toml, line 5:"), "{err}");
        assert!(err.contains("flicker_depth"), "{err}");
        let err = Scenario::from_example("tornado").unwrap_err().to_string();
        assert!(
            err.contains("tornado") && err.contains("mixing-layer"),
            "{err}"
        );
    }

    /// A scenario built in code is the scenario file that gives only the same keys.
    #[test]
    fn a_scenario_built_in_code_takes_the_file_defaults() {
        let text = "duration = \"40ms\"\n[sensor]\nwidth = 192\nheight = 96\npreset = \"ideal\"\n\
                    [flow]\ntype = \"uniform\"\nu = 2.0\nv = -0.5\n";
        let file = Scenario::from_toml(text, "t").unwrap();
        let code = Scenario::new(192, 96, "ideal", FlowSpec::uniform(2.0, -0.5), 40_000);
        assert_eq!(format!("{code:?}"), format!("{file:?}"));
        let sim = code.simulation().unwrap();
        assert_eq!(sim.sensor, SensorParams::ideal());
        assert_eq!(sim.velocity(10.0, 20.0, 5_000.0), (2.0, -0.5));
        let mixing = Scenario::from_example("mixing-layer").unwrap();
        let sim = mixing.simulation().unwrap();
        assert_eq!((sim.geometry.width, sim.geometry.height), (256, 128));
        let (top, bottom) = (sim.velocity(0.0, 0.0, 0.0), sim.velocity(0.0, 127.0, 0.0));
        assert!((top.0 - 0.05).abs() < 1e-6 && (bottom.0 - 5.0).abs() < 1e-6);
    }

    #[test]
    fn every_example_parses_and_builds() {
        for (name, _, text) in EXAMPLES {
            let s = parse(text, name).unwrap_or_else(|e| panic!("{name}: {e}"));
            s.simulation().unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }

    #[test]
    fn overrides_apply_and_typos_are_named() {
        let text = Scenario::example("uniform").unwrap().replace(
            "preset = \"gen4\"",
            "preset = \"ideal\"\nthreshold_on = 0.3",
        );
        let s = parse(&text, "t").unwrap();
        assert_eq!(s.sensor_params().unwrap().threshold_on, 0.3);
        let typo = text.replace("threshold_on = 0.3", "treshold_on = 0.3");
        let err = parse(&typo, "t")
            .unwrap()
            .sensor_params()
            .unwrap_err()
            .to_string();
        assert!(err.contains("treshold_on"), "{err}");
        let bad = text.replace("duration = ", "duration = \"ten\" #");
        let err = parse(&bad, "s.toml").unwrap_err().to_string();
        assert!(err.contains("not a time"), "{err}");
    }

    #[test]
    fn the_interpolation_is_read_from_the_sampling_table() {
        let text = Scenario::example("uniform").unwrap();
        let steps = |sim: &Simulation| (sim.interpolation, sim.step_px, sim.max_step_us);
        // Continuous light without flicker: the cubic by default, with its own steps.
        use Interpolation::{Cubic, Linear};
        for (sampling, expected) in [
            ("", (Cubic, 0.75, 600.0)),
            ("interpolation = \"linear\"", (Linear, 0.25, 200.0)),
            ("step_px = 0.5", (Cubic, 0.5, 600.0)),
            ("max_step_us = 100", (Cubic, 0.75, 100.0)),
            ("interpolation = \"cubic\"", (Cubic, 0.75, 600.0)),
        ] {
            let given = format!("{text}\n[sampling]\n{sampling}\n");
            let sim = parse(&given, "t").unwrap().simulation().unwrap();
            assert_eq!(steps(&sim), expected, "{sampling}");
        }
        let shown = parse(text, "t").unwrap().sampling;
        let shown = shown.resolve(&IlluminationParams::default()).to_string();
        assert_eq!(shown, "cubic, at most 0.75 px and 600 µs per step");
        // Pulsed or flickering light: only the linear, which is then the default.
        let pulsed = |s: &mut Scenario| s.illumination.mode = LightMode::Pulsed;
        let flicker = |s: &mut Scenario| s.illumination.flicker_hz = 100.0;
        for light in [pulsed, flicker] {
            let mut lit = parse(text, "t").unwrap();
            light(&mut lit);
            let sim = lit.simulation().unwrap();
            assert_eq!(steps(&sim), (Interpolation::Linear, 0.25, 200.0));
            lit.sampling.step_px = Some(0.1);
            let sim = lit.simulation().unwrap();
            assert_eq!(steps(&sim), (Interpolation::Linear, 0.1, 200.0));
            lit.sampling.interpolation = Some(Interpolation::Cubic);
            let err = lit.simulation().unwrap_err().to_string();
            assert!(err.contains("sampling.interpolation"), "{err}");
            assert!(err.contains("use \"linear\""), "{err}");
        }
        let bad = format!("{text}\n[sampling]\ninterpolation = \"quadratic\"\n");
        let err = parse(&bad, "t").unwrap_err().to_string();
        assert!(err.contains("quadratic") && err.contains("cubic"), "{err}");
    }

    #[test]
    fn truth_sampling_too_fine_for_memory_is_refused_before_the_run() {
        let g = Geometry::new(1280, 720);
        let ok = TruthSpec::default();
        ok.validate_field(g, 1_000_000).unwrap();
        ok.validate_tracks(g, 1_000_000, 0.005).unwrap();
        // A grid of 1 px is allowed for a short recording, not for a long one.
        let fine = TruthSpec {
            grid_step: 1.0,
            ..ok.clone()
        };
        fine.validate_field(g, 10_000).unwrap();
        let err = fine.validate_field(g, 1_000_000).unwrap_err().to_string();
        assert!(err.contains("coarser grid_step"), "{err}");
        for (grid_step, interval, key) in [
            (0.0, 1000, "truth.grid_step"),
            (0.5, 1000, "truth.grid_step"),
            (f64::NAN, 1000, "truth.grid_step"),
            (16.0, 0, "truth.interval"),
            (16.0, -5, "truth.interval"),
        ] {
            let spec = TruthSpec {
                grid_step,
                interval,
                ..ok.clone()
            };
            let err = spec.validate_field(g, 1000).unwrap_err().to_string();
            assert!(err.contains(key), "{grid_step} {interval}: {err}");
        }
        let dense = TruthSpec {
            track_interval: 1,
            ..ok.clone()
        };
        let err = dense
            .validate_tracks(g, 100_000, 0.005)
            .unwrap_err()
            .to_string();
        assert!(err.contains("longer track_interval"), "{err}");
        let none = TruthSpec {
            track_interval: 0,
            ..ok
        };
        let err = none
            .validate_tracks(g, 1000, 0.005)
            .unwrap_err()
            .to_string();
        assert!(err.contains("truth.track_interval"), "{err}");
    }
}
