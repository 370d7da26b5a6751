//! The simulation loop: particles move with the flow, their images are rendered band by band,
//! and each band's pixels run through the sensor model (sensor-model.md §0 pipeline).
//!
//! Time is sampled finely enough that no particle moves more than `step_px` between samples
//! (and at every corner of a light pulse); between samples each pixel's log irradiance follows
//! the [`Interpolation`] (a line, or the cubic Hermite interpolant of the samples and their
//! slopes) and the sensor finds exact threshold-crossing times for it. Bands of rows run in
//! parallel; all randomness is per pixel or per particle, so the result does not depend on
//! the number of threads. The events of each batch of samples are read out
//! ([`StreamingReadout`]) while the bands simulate the next batch.

use super::flow::Flow;
use super::particles::{Particle, ParticleCloud, SeedingParams};
use super::scene::{IlluminationParams, ParticleRenderer, Spot, SpotMotion};
use super::sensor::{
    NoiseStream, ReadoutReport, SensorBand, SensorParams, SimEvent, StreamingReadout,
};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use rayon::prelude::*;

/// Everything that defines a synthetic recording.
#[derive(Debug)]
pub struct Simulation {
    /// Sensor size.
    pub geometry: Geometry,
    /// The flow carrying the particles.
    pub flow: Box<dyn Flow>,
    /// Particles and light sheet.
    pub seeding: SeedingParams,
    /// Light and static scene.
    pub illumination: IlluminationParams,
    /// Pixel model.
    pub sensor: SensorParams,
    /// Camera time of the start, µs.
    pub start_us: i64,
    /// Length of the recording, µs.
    pub duration_us: i64,
    /// Largest particle displacement between two samples, px.
    pub step_px: f64,
    /// Longest time between two samples, µs.
    pub max_step_us: f64,
    /// How a pixel's input runs between samples.
    pub interpolation: Interpolation,
    /// Random seed.
    pub seed: u64,
}

/// How a pixel's log input runs from one time sample to the next (`[sampling] interpolation`;
/// a scenario's default is `Cubic` for continuous light without flicker, `Linear` otherwise,
/// [`super::scenario::Sampling::resolve`]).
///
/// Measured on 50 ms of a 1280×720 uniform flow of (1.5, 0.2) px/ms, 0.00152 particles per
/// pixel, `gen4` model, against a run sampled at 0.025 px per step
/// (docs/simulate.md): `Linear` at 0.25 px per step puts the events a
/// median 3 µs (mean 17 µs, 30 % beyond 5 µs) from the reference's with 0.8 % of the events
/// unpaired; `Cubic` at 0.25 px a median 0 µs (mean 3.1 µs, 3 % beyond 5 µs, 0.1 % unpaired)
/// for 1.6 times the CPU time, at 0.5 px a median 1 µs (mean 7.9 µs, 5 % beyond 5 µs, 0.3 %
/// unpaired) for about the same CPU time, and at 0.75 px about as accurate as `Linear` at
/// 0.25 px (median 3 µs, mean 17 µs, 25 % beyond 5 µs, 0.7 % unpaired) for 0.86 times it
/// (every run with `max_step_us = 1000`: at that scene's 1.5 px/ms the linear default's
/// 200 µs would cut 0.5 px steps to 0.3 px).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// A straight line in log intensity (ESIM's interpolation).
    Linear,
    /// The cubic Hermite interpolant of the log intensity with its exact time derivatives
    /// at the samples (from the particle images' motion and their drift through the light
    /// sheet; limited where the samples do not resolve them). A pixel that a bound on the
    /// cubic shows cannot fire in the step follows the cubic exactly (with the low-pass
    /// corner frozen at the step's mean irradiance, as for a line); any other takes four
    /// straight lines through the cubic's values at quarters of the step, its crossing
    /// times exact for those. For continuous light without flicker, whose own slopes are
    /// not modelled. The first step of a recording starts flat (the pixels are adapted as
    /// to a still scene). Steps longer than `max_step_us` are cut to it: raise it with
    /// `step_px`.
    Cubic,
}

/// A sampled particle position for the ground-truth tracks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackPoint {
    /// Particle identity.
    pub id: u64,
    /// Time, µs.
    pub t_us: f64,
    /// Position, px.
    pub x: f64,
    /// Position, px.
    pub y: f64,
    /// Out-of-plane position, px.
    pub z: f64,
    /// Velocity, px/ms.
    pub u: f64,
    /// Velocity, px/ms.
    pub v: f64,
}

/// The result of a run.
#[derive(Debug)]
pub struct SimOutput {
    /// Events in time order, 1 µs time stamps.
    pub events: EventBuffer,
    /// What the readout dropped.
    pub readout: ReadoutReport,
    /// Particle positions in view, every `track_interval_us` (empty unless requested).
    pub tracks: Vec<TrackPoint>,
    /// Number of time samples simulated.
    pub samples: u64,
}

/// Where [`Simulation::run_streaming`] hands the events: called from a worker thread while
/// the bands simulate the next samples, and a last time on the caller's thread once the
/// simulation has ended.
pub type EventSink<'a> = dyn FnMut(&EventBuffer) -> Result<()> + Send + 'a;

/// Largest flow speed simulated, px/ms.
const MAX_SPEED: f64 = 1e4;

/// Most particles seeded: about 4 GB for the particles (56 bytes each), their cached images
/// (80) and one sample of their images in each of the two batches in flight (2 × 48; 2 × 72
/// and about 4.7 GB in all with the motions of [`Interpolation::Cubic`];
/// [`samples_per_batch`]).
const MAX_PARTICLES: u64 = 1 << 24;

/// Rows per band: small enough for both cores to stay busy, large enough to amortise.
const BAND_ROWS: u32 = 60;

/// Events this close before the end of a batch are read out with the next batch, µs: a
/// margin on the argument that no later event precedes the batch's end (see
/// [`Simulation::run`]).
const READOUT_HOLD_US: f64 = 1.0;

/// Samples each band processes per parallel task, unless the particle images of a batch
/// would exceed [`BATCH_IMAGE_BYTES`] ([`samples_per_batch`]).
const SAMPLES_PER_BATCH: usize = 64;

/// Memory the particle images of the two batches in flight should take, bytes: a scene of many
/// particles is simulated in shorter batches rather than running out of memory (the 1 400 particles
/// of 0.00152 per pixel over 1280×720 px take 8.6 MB at 64 samples per batch). Beyond about 11 M
/// particles one sample per batch takes more (1.6 GB at the most particles seeded,
/// [`MAX_PARTICLES`]).
const BATCH_IMAGE_BYTES: usize = 1 << 30;

/// Samples per batch for a scene of `particles` particles: [`SAMPLES_PER_BATCH`], or fewer
/// (at least one) so that two batches of their images fit in [`BATCH_IMAGE_BYTES`]. The
/// noise is drawn batch by batch, so this is part of what a scenario's events depend on (a
/// function of the scenario alone, not of the machine).
fn samples_per_batch(particles: usize, interpolation: Interpolation) -> usize {
    let image = match interpolation {
        Interpolation::Linear => std::mem::size_of::<Spot>(),
        Interpolation::Cubic => std::mem::size_of::<Spot>() + std::mem::size_of::<SpotMotion>(),
    };
    let per_sample = particles.max(1).saturating_mul(2 * image);
    (BATCH_IMAGE_BYTES / per_sample).clamp(1, SAMPLES_PER_BATCH)
}

/// One band of rows with its sensor pixels and the irradiance of its last sample.
struct Band {
    rows: std::ops::Range<u32>,
    sensor: SensorBand,
    /// Current irradiance per band pixel.
    value: Vec<f32>,
    /// Particle contribution being accumulated for the new sample (0 where none: see
    /// [`ParticleRenderer::add`]).
    acc: Vec<f32>,
    /// Irradiance slopes (per µs) accumulated with `acc` for [`Interpolation::Cubic`];
    /// empty for [`Interpolation::Linear`].
    dacc: Vec<f32>,
    /// Pixels with particle light at the previous sample (band indices).
    lit: Vec<u32>,
    touched: Vec<u32>,
    /// Background activity, drawn batch by batch.
    noise: NoiseStream,
    /// Events of the batch being simulated.
    events: Vec<SimEvent>,
}

impl Simulation {
    /// Check the parameters, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        self.seeding.validate()?;
        self.illumination.validate()?;
        self.sensor.validate()?;
        let g = self.geometry;
        if g.width == 0 || g.height == 0 || g.width > 4096 || g.height > 4096 {
            return Err(Error::parameter(
                "sensor.width/height",
                format!("{g} is not a sensor size ebiv simulates (1..=4096)"),
            ));
        }
        if !(self.duration_us > 0 && self.duration_us <= 3_600_000_000) {
            return Err(Error::parameter(
                "duration",
                format!(
                    "{} µs is out of range: must be above 0 and at most one hour",
                    self.duration_us
                ),
            ));
        }
        if !(self.step_px > 0.0 && self.step_px <= 1.0) {
            return Err(Error::parameter(
                "sampling.step_px",
                format!("{} must be in (0, 1]", self.step_px),
            ));
        }
        if !(self.max_step_us >= 0.5 && self.max_step_us <= 1000.0) {
            return Err(Error::parameter(
                "sampling.max_step_us",
                format!("{} must be in [0.5, 1000]", self.max_step_us),
            ));
        }
        if self.interpolation == Interpolation::Cubic && !self.illumination.steady() {
            return Err(Error::parameter(
                "sampling.interpolation",
                "\"cubic\" needs continuous light without flicker (the slopes of pulses and \
                 flicker are not modelled); use \"linear\"",
            ));
        }
        let speed = self.start_speed();
        if speed.is_nan() || speed > MAX_SPEED {
            return Err(Error::parameter(
                "flow",
                format!(
                    "its largest speed over the sensor at the start, {speed:.4e} px/ms, is beyond \
                     {MAX_SPEED} px/ms (10 px per µs, far past what 1 µs time stamps resolve)"
                ),
            ));
        }
        let margin = self.seeding_margin(speed);
        let (w, h) = (g.width as f64, g.height as f64);
        let particles = self.seeding.density * (w + 2.0 * margin) * (h + 2.0 * margin);
        if particles > MAX_PARTICLES as f64 {
            return Err(Error::parameter(
                "particles.density",
                format!(
                    "{} particles per pixel over the sensor and its seeding margin of \
                     {margin} px (which grows with the flow's speed and max_step_us) make \
                     {particles:.3e} particles, more than {MAX_PARTICLES}",
                    self.seeding.density
                ),
            ));
        }
        Ok(())
    }

    /// The true velocity (u, v), px/ms, at `(x, y)` px (image axes, y down) and time `t_us`:
    /// the flow's, along which the particles move exactly (sensor-model.md §6). For a grid of
    /// it over the recording, see [`super::truth::velocity_field`].
    pub fn velocity(&self, x: f64, y: f64, t_us: f64) -> (f64, f64) {
        self.flow.velocity(x, y, t_us)
    }

    /// The flow's largest speed over the sensor at the start, px/ms.
    fn start_speed(&self) -> f64 {
        let (w, h) = (self.geometry.width as f64, self.geometry.height as f64);
        self.flow.max_speed(w, h, self.start_us as f64)
    }

    /// How far beyond the sensor particles are seeded, px, for a flow whose largest speed is
    /// `speed` ([`Simulation::start_speed`]): an image's reach plus the distance the fastest
    /// particle moves in the longest time step, so that particles enter the view from the
    /// seeded volume.
    fn seeding_margin(&self, speed: f64) -> f64 {
        let speed = speed.max(1e-6);
        (3.0 * self.seeding.diameter + 2.0 + speed * self.max_step_us * 1e-3).ceil()
    }

    /// Run the simulation. `track_interval_us` > 0 records particle tracks; `progress` is
    /// called with the fraction done. All events are kept in memory (13 bytes each: 260 MB
    /// per second at the paper's 20 M events/s); [`Simulation::run_streaming`] hands them
    /// over as they are read out instead.
    pub fn run(
        &self,
        track_interval_us: Option<f64>,
        progress: &(dyn Fn(f64) + Sync),
    ) -> Result<SimOutput> {
        self.run_with(track_interval_us, progress, None)
    }

    /// [`Simulation::run`] handing the events to `sink` as they are read out, a batch of
    /// samples at a time (about 10 ms of the `paper-rate` example), in time order: the
    /// concatenation of its calls is [`Simulation::run`]'s `events`, and memory holds a
    /// window of events rather than the recording (the tracks, if asked for, are still
    /// kept). `sink` runs beside the simulation of the next batch (on a worker thread), and
    /// for the last events on the caller's thread. The output's `events` are empty. An error
    /// of `sink` ends the run (after at most the batch being simulated) and is returned.
    pub fn run_streaming(
        &self,
        track_interval_us: Option<f64>,
        progress: &(dyn Fn(f64) + Sync),
        sink: &mut EventSink,
    ) -> Result<SimOutput> {
        self.run_with(track_interval_us, progress, Some(sink))
    }

    /// [`Simulation::run`], or with `sink` [`Simulation::run_streaming`].
    fn run_with(
        &self,
        track_interval_us: Option<f64>,
        progress: &(dyn Fn(f64) + Sync),
        mut sink: Option<&mut EventSink>,
    ) -> Result<SimOutput> {
        self.validate()?;
        let g = self.geometry;
        let (w, h) = (g.width as f64, g.height as f64);
        let t0 = self.start_us as f64;
        let t_end = t0 + self.duration_us as f64;
        let margin = self.seeding_margin(self.start_speed());
        let mut cloud = ParticleCloud::seed(&self.seeding, w, h, margin, self.seed);
        // The sensor starts adapted to the scene at t0: each band renders its first sample
        // and builds its pixels adapted to it, in one pass.
        let sorter = ParticleRenderer::new(&self.seeding, &self.illumination, g);
        let mut buckets = Vec::new();
        let mut images = ImageCache::default();
        let n_bands = g.height.div_ceil(BAND_ROWS) as usize;
        bucket_by_band(
            &cloud.particles,
            &sorter,
            &mut images,
            self.illumination.sheet(t0),
            n_bands,
            &mut buckets,
            None,
        );
        let mut tracks = Vec::new();
        let mut next_track = t0;
        let mut t = t0;
        let mut samples = 0u64;
        let flicker = self.illumination.flicker_hz > 0.0;
        // Validated: continuous light without flicker.
        let cubic = self.interpolation == Interpolation::Cubic;
        // Samples are taken in batches: the particle motion of a batch is computed first, then
        // every band runs through all the samples of the batch in one task, so that its pixels
        // stay in cache and the scheduling cost is paid once per batch. Each band sees exactly
        // the same sequence of samples as one step at a time would give it. The next batch's
        // particle motion is computed while the bands process the current one.
        let batch_samples = samples_per_batch(cloud.particles.len(), self.interpolation);
        let mut fill = |batch: &mut Vec<Sample>| -> usize {
            let mut used = 0;
            while used < batch_samples && t < t_end {
                if let Some(interval) = track_interval_us.filter(|&i| i > 0.0) {
                    while next_track <= t {
                        self.record_tracks(&cloud.particles, t, &mut tracks);
                        next_track += interval;
                    }
                }
                let speed = self.flow.max_speed(w, h, t).max(1e-6);
                let mut dt = (self.step_px / speed * 1e3).min(self.max_step_us);
                if let Some(&c) = self.illumination.corners(t, t + dt).first() {
                    dt = c - t;
                }
                let t_next = (t + dt).min(t_end);
                cloud.advance(self.flow.as_ref(), t, t_next);
                let t_prev = t;
                t = t_next;
                samples += 1;
                if batch.len() <= used {
                    batch.push(Sample {
                        t: 0.0,
                        light: 0.0,
                        buckets: Vec::new(),
                        motions: Vec::new(),
                    });
                }
                let sample = &mut batch[used];
                sample.t = t;
                sample.light = self.illumination.sheet(t);
                bucket_by_band(
                    &cloud.particles,
                    &sorter,
                    &mut images,
                    sample.light,
                    n_bands,
                    &mut sample.buckets,
                    cubic.then_some(ImageMotions {
                        flow: self.flow.as_ref(),
                        t,
                        step: t - t_prev,
                        motions: &mut sample.motions,
                    }),
                );
                used += 1;
            }
            used
        };
        // The pixels are set up while the first batch's particle motion is computed.
        let mut current: Vec<Sample> = Vec::new();
        let mut next: Vec<Sample> = Vec::new();
        let (mut bands, (mut used, mut readout)) = rayon::join(
            || {
                buckets
                    .par_iter()
                    .enumerate()
                    .map_init(
                        || ParticleRenderer::new(&self.seeding, &self.illumination, g),
                        |renderer, (b, bucket)| {
                            let b = b as u32;
                            let rows = b * BAND_ROWS..((b + 1) * BAND_ROWS).min(g.height);
                            Band::start(self, rows, renderer, bucket, t0)
                        },
                    )
                    .collect::<Vec<Band>>()
            },
            || (fill(&mut current), StreamingReadout::new(&self.sensor, g)),
        );
        // The events of each batch are read out while the bands simulate the next one: all
        // events found later lie at or after the batch's end (an event is never earlier than
        // the threshold crossing that causes it, nor a crossing than the step that finds it;
        // a sleeping pixel's crossing is computed as its wake-up time was), so those before
        // it are final. The cutoff `READOUT_HOLD_US` before the end is a margin on that
        // argument; an event that broke it would be read out at the cutoff (counted by
        // `late_events`, asserted zero in tests).
        let mut window: Vec<Vec<SimEvent>> = vec![Vec::new(); bands.len()];
        let mut window_end = None;
        while used > 0 {
            let batch = &current[..used];
            let batch_end = batch[used - 1].t;
            let ((), (next_used, drained)) = rayon::join(
                || {
                    bands.par_iter_mut().enumerate().for_each_init(
                        || ParticleRenderer::new(&self.seeding, &self.illumination, g),
                        |renderer, (b, band)| {
                            for sample in batch {
                                band.sensor.begin_step(sample.t);
                                band.render_scaled(
                                    renderer,
                                    &sample.buckets[b],
                                    sample.motions.get(b).map_or(&[], Vec::as_slice),
                                    sample.t,
                                    g,
                                    &self.illumination,
                                    flicker,
                                );
                                band.sensor.advance_marked(&mut band.events);
                            }
                            band.sensor
                                .noise_until(&mut band.noise, batch_end, &mut band.events);
                        },
                    )
                },
                || {
                    let mut drained = Ok(());
                    if let Some(end) = window_end {
                        readout.read_until(&mut window, end - READOUT_HOLD_US);
                        if let Some(sink) = sink.as_mut() {
                            drained = readout.drain(*sink);
                        }
                    }
                    (fill(&mut next), drained)
                },
            );
            drained?;
            for (band, events) in bands.iter_mut().zip(&mut window) {
                std::mem::swap(&mut band.events, events);
            }
            window_end = Some(batch_end);
            progress((batch_end - t0) / (t_end - t0));
            std::mem::swap(&mut current, &mut next);
            used = next_used;
        }
        // The last batch's events are handed in (and checked for lateness), then all read out.
        readout.read_until(&mut window, f64::INFINITY);
        debug_assert_eq!(
            readout.late_events(),
            0,
            "an event came after its batch's cutoff"
        );
        let (mut events, mut readout) = readout.finish(&mut []);
        if let Some(sink) = sink {
            if !events.is_empty() {
                sink(&events)?;
            }
            events = EventBuffer::new();
        }
        for band in &bands {
            readout.absorb(&band.sensor.counters());
        }
        Ok(SimOutput {
            events,
            readout,
            tracks,
            samples,
        })
    }

    fn record_tracks(&self, particles: &[Particle], t: f64, out: &mut Vec<TrackPoint>) {
        let (w, h) = (self.geometry.width as f64, self.geometry.height as f64);
        for p in particles {
            if p.x >= -0.5 && p.x < w - 0.5 && p.y >= -0.5 && p.y < h - 0.5 {
                let (u, v) = self.flow.velocity(p.x, p.y, t);
                out.push(TrackPoint {
                    id: p.id,
                    t_us: t,
                    x: p.x,
                    y: p.y,
                    z: p.z,
                    u,
                    v,
                });
            }
        }
    }
}

/// Where [`bucket_by_band`] puts the images' [`SpotMotion`]s at the sample `t`, `step` µs
/// after the one before.
struct ImageMotions<'a> {
    flow: &'a dyn Flow,
    t: f64,
    step: f64,
    /// Laid out as the buckets of spots.
    motions: &'a mut Vec<Vec<SpotMotion>>,
}

impl ImageMotions<'_> {
    /// The motion of `p`'s image. Its brightness change through the sheet is limited to a
    /// factor e per step: a particle crossing the sheet faster is not resolved by the
    /// samples, and the cubic through them would swing far beyond what they show.
    fn of(&self, p: &Particle, renderer: &ParticleRenderer) -> SpotMotion {
        let (u, v) = self.flow.velocity(p.x, p.y, self.t);
        let limit = 1.0 / self.step.max(1e-6);
        SpotMotion {
            vx: u * 1e-3,
            vy: v * 1e-3,
            fade: renderer.fade_rate(p).clamp(-limit, limit),
        }
    }
}

/// The images of the particles at light factor `light`, sorted into the `bands` bands they
/// may reach (so that each band reads its spots from contiguous memory). A particle goes to
/// exactly the bands in which [`ParticleRenderer::draw`] may draw something. With `motion`,
/// each image's [`SpotMotion`] goes to its `motions`, laid out as `buckets`.
fn bucket_by_band(
    particles: &[Particle],
    renderer: &ParticleRenderer,
    images: &mut ImageCache,
    light: f64,
    bands: usize,
    buckets: &mut Vec<Vec<Spot>>,
    mut motion: Option<ImageMotions>,
) {
    buckets.resize_with(bands, Vec::new);
    buckets.iter_mut().for_each(Vec::clear);
    if let Some(m) = motion.as_mut() {
        m.motions.resize_with(bands, Vec::new);
        m.motions.iter_mut().for_each(Vec::clear);
    }
    images.entries.resize(particles.len(), None);
    let last = bands as i64 - 1;
    for (p, entry) in particles.iter().zip(&mut images.entries) {
        let Some(spot) = ImageCache::spot(entry, renderer, p, light) else {
            continue;
        };
        let (y0, y1) = spot.rows();
        let lo = y0.max(0) / BAND_ROWS as i64;
        let hi = (y1.max(0) / BAND_ROWS as i64).min(last);
        if lo > hi {
            continue;
        }
        for b in lo..=hi {
            buckets[b as usize].push(spot);
        }
        if let Some(m) = motion.as_mut() {
            let image = m.of(p, renderer);
            for b in lo..=hi {
                m.motions[b as usize].push(image);
            }
        }
    }
}

/// The last image of each particle (by its index in the cloud) with what it was made from:
/// the particle's identity, its out-of-plane position and the light factor. An image depends
/// on the particle's position only through its centre, so while the rest is unchanged (a
/// continuous sheet and no out-of-plane motion: every sample) the image is the last one
/// moved, the same values [`ParticleRenderer::spot`] would compute again (its logarithm,
/// square root, erf and divisions per particle and sample).
#[derive(Default)]
struct ImageCache {
    entries: Vec<Option<CachedImage>>,
}

#[derive(Clone, Copy)]
struct CachedImage {
    id: u64,
    z: f64,
    light: f64,
    spot: Option<Spot>,
}

impl ImageCache {
    /// [`ParticleRenderer::spot`]`(p, light)`, from `entry` if it was made from the same
    /// particle, out-of-plane position and light (compared bit for bit), else computed and
    /// kept in `entry`.
    fn spot(
        entry: &mut Option<CachedImage>,
        renderer: &ParticleRenderer,
        p: &Particle,
        light: f64,
    ) -> Option<Spot> {
        match entry {
            Some(c)
                if c.id == p.id
                    && c.z.to_bits() == p.z.to_bits()
                    && c.light.to_bits() == light.to_bits() =>
            {
                c.spot.map(|s| s.centred_at(p.x, p.y))
            }
            _ => {
                let spot = renderer.spot(p, light);
                *entry = Some(CachedImage {
                    id: p.id,
                    z: p.z,
                    light,
                    spot,
                });
                spot
            }
        }
    }
}

/// One time sample of a batch: its time, light factor and the particles of each band.
struct Sample {
    t: f64,
    light: f64,
    buckets: Vec<Vec<Spot>>,
    /// The images' [`SpotMotion`]s, laid out as `buckets` ([`Interpolation::Cubic`] only).
    motions: Vec<Vec<SpotMotion>>,
}

impl Band {
    /// The band of rows `rows` at the first sample `t0` (particle images `bucket`), its
    /// pixels adapted to it.
    fn start(
        sim: &Simulation,
        rows: std::ops::Range<u32>,
        r: &mut ParticleRenderer,
        bucket: &[Spot],
        t0: f64,
    ) -> Band {
        let (g, illumination) = (sim.geometry, &sim.illumination);
        let w = g.width as usize;
        let n = rows.len() * w;
        // Every pixel starts at its ambient irradiance, plus the particle light.
        let mut value: Vec<f32> = Vec::with_capacity(n);
        for y in rows.clone() {
            value.extend((0..w as u32).map(|x| illumination.ambient(x, y, t0)));
        }
        // Zeroed memory: paged in where particles pass, not up front.
        let mut acc = vec![0.0; n];
        let mut lit = Vec::new();
        for spot in bucket {
            r.draw(spot, rows.clone(), &mut acc, &mut lit);
        }
        for &k in &lit {
            let k = k as usize;
            value[k] += acc[k];
            acc[k] = 0.0;
        }
        let mut sensor =
            SensorBand::new_adapted(g, rows.clone(), &sim.sensor, sim.seed, t0, |x, y| {
                value[(y - rows.start) as usize * w + x as usize]
            });
        let noise = sensor.noise_stream(t0);
        Band {
            rows,
            sensor,
            value,
            dacc: match sim.interpolation {
                Interpolation::Linear => Vec::new(),
                Interpolation::Cubic => vec![0.0; acc.len()],
            },
            acc,
            lit,
            touched: Vec::new(),
            noise,
            events: Vec::new(),
        }
    }

    /// Render a new sample and give the sensor the pixels whose irradiance changed; with the
    /// images' `motions` (laid out as `bucket`; [`Interpolation::Cubic`]), also their slopes.
    #[allow(clippy::too_many_arguments)]
    fn render_scaled(
        &mut self,
        r: &mut ParticleRenderer,
        bucket: &[Spot],
        motions: &[SpotMotion],
        t: f64,
        g: Geometry,
        illumination: &IlluminationParams,
        flicker: bool,
    ) {
        // The slopes of the cubic interpolation, where they are kept.
        let sloped = !self.dacc.is_empty() && motions.len() == bucket.len();
        if sloped {
            for (spot, motion) in bucket.iter().zip(motions) {
                r.draw_sloped(
                    spot,
                    motion,
                    self.rows.clone(),
                    &mut self.acc,
                    &mut self.dacc,
                    &mut self.touched,
                );
            }
        } else {
            for spot in bucket {
                r.draw(spot, self.rows.clone(), &mut self.acc, &mut self.touched);
            }
        }
        let w = g.width as usize;
        let row0 = self.rows.start;
        // Without walls the ambient level is the same for every pixel.
        let flat = illumination
            .walls
            .is_empty()
            .then(|| illumination.ambient(0, row0, t));
        let ambient = |k: usize| match flat {
            Some(a) => a,
            None => illumination.ambient((k % w) as u32, row0 + (k / w) as u32, t),
        };
        let (value, sensor, dacc) = (&mut self.value, &mut self.sensor, &mut self.dacc);
        // Each pixel gets at most one new sample per step: the lit pixels and the ones lit
        // before are disjoint, and each appears once in its list.
        let mut update = |k: usize, new: f32| {
            if sloped {
                if new != value[k] {
                    value[k] = new;
                    sensor.push_input_sloped(k, new, dacc[k]);
                }
                dacc[k] = 0.0;
            } else if new != value[k] {
                value[k] = new;
                sensor.push_input(k, new);
            }
        };
        if flicker {
            for k in 0..self.acc.len() {
                update(k, ambient(k) + self.acc[k]);
            }
            for &k in &self.touched {
                self.acc[k as usize] = 0.0;
            }
        } else {
            // Pixels lit before but not now fall back to the ambient level.
            for &k in &self.lit {
                if self.acc[k as usize] == 0.0 {
                    update(k as usize, ambient(k as usize));
                }
            }
            for &k in &self.touched {
                let k = k as usize;
                update(k, ambient(k) + self.acc[k]);
                self.acc[k] = 0.0;
            }
        }
        std::mem::swap(&mut self.lit, &mut self.touched);
        self.touched.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::{
        samples_per_batch, ImageCache, Interpolation, Particle, ParticleRenderer, SeedingParams,
    };
    use crate::event::Geometry;
    use crate::sim::scene::IlluminationParams;

    /// The cache gives what the renderer computes, whether the particle only moved (reused),
    /// changed its out-of-plane position or the light (recomputed), or was replaced by a new
    /// particle at the same index (recomputed), including images too dim to draw.
    #[test]
    fn cached_images_are_the_renderers() {
        let seeding = SeedingParams::default();
        let illumination = IlluminationParams::default();
        let renderer = ParticleRenderer::new(&seeding, &illumination, Geometry::new(64, 64));
        let mut p = Particle {
            id: 7,
            x: 10.0,
            y: 20.0,
            z: 0.0,
            w: 0.0,
            diameter: 2.5,
            brightness: 5.0,
        };
        let mut entry = None;
        let mut check = |p: &Particle, light: f64| {
            let cached = ImageCache::spot(&mut entry, &renderer, p, light);
            assert_eq!(cached, renderer.spot(p, light), "{p:?} at light {light}");
        };
        check(&p, 1.0);
        p.x += 0.25;
        p.y -= 0.1;
        check(&p, 1.0);
        check(&p, 0.5);
        p.z = 3.0;
        check(&p, 0.5);
        check(&p, 0.0);
        p.x += 1.0;
        check(&p, 0.0);
        check(&p, 1.0);
        p = Particle {
            id: 8,
            diameter: 4.0,
            brightness: 20.0,
            ..p
        };
        check(&p, 1.0);
        p.x -= 3.0;
        check(&p, 1.0);
    }

    /// Scenes of many particles are simulated in shorter batches; the examples keep 64.
    #[test]
    fn batches_shrink_for_scenes_of_many_particles() {
        assert_eq!(samples_per_batch(0, Interpolation::Linear), 64);
        assert_eq!(samples_per_batch(1_400, Interpolation::Linear), 64);
        assert_eq!(samples_per_batch(170_000, Interpolation::Linear), 64);
        assert_eq!(samples_per_batch(1_000_000, Interpolation::Linear), 11);
        assert_eq!(samples_per_batch(1 << 24, Interpolation::Linear), 1);
        assert_eq!(
            samples_per_batch(usize::MAX / 4096, Interpolation::Linear),
            1
        );
        // The cubic interpolation's image motions take their share.
        assert_eq!(samples_per_batch(1_400, Interpolation::Cubic), 64);
        assert_eq!(samples_per_batch(1_000_000, Interpolation::Cubic), 7);
    }
}
