//! Particle tracks from events (Lagrangian particle tracking, PTV).
//!
//! The events are cut into short time slabs (their length chosen from the first events by
//! [`slab`]); in each, the tracks claim the events near their predicted particles, and the
//! rest of the events of touching pixels form clusters, one per particle image ([`detect`]).
//! Clusters are linked into tracks slab by slab with a constant-velocity predictor, a gate
//! and one-to-one assignment, gaps bridged up to `max_gap`, tracks on one particle merged
//! ([`link`]). A track that has ended is fitted with a local cubic in time through
//! its events, which gives position, velocity and acceleration at every sample with their
//! uncertainties ([`fit`]). Memory holds only the tracks alive; each track is handed over as
//! it ends ([`Tracker`]). Tracks binned on a grid give a mean vector field ([`bin`]); tracks
//! are scored against the simulator's particle paths by [`score`].
//!
//! Related work: Wang, Idoughi & Heidrich (ECCV 2020) cluster events per slab and match
//! particles one-to-one; Borer et al. (Exp. Fluids, 2017) and TrackAER (Rusch & Rösgen,
//! Exp. Fluids, 2023) follow tracers event by event in real time; STELLA (Sachs, Willert,
//! Cierpka et al.) fits tracks with Kalman and spline filters.

pub mod bin;
pub mod detect;
pub mod fit;
pub mod link;
mod matrix;
pub mod params;
pub mod run;
pub mod score;
pub mod slab;

pub use detect::TrackEvent;
pub use fit::{Track, TrackSample};
pub use params::{TrackParams, TRACK_SETTINGS};

use crate::error::Result;
use crate::event::{EventBuffer, Geometry};
use detect::Detector;
use link::{Linker, LiveTrack};
use rayon::prelude::*;

/// Largest sensor tracked, pixels (its maps take 8 bytes a pixel: 512 MiB).
pub const MAX_PIXELS: u64 = 1 << 26;

/// Samples closer than this to the outermost pixel centres are left out, px: there the
/// sensor's edge cuts the particle image, its events' centroid stays inside while the
/// particle leaves, and a track would follow the cut image along the edge.
pub const EDGE_MARGIN_PX: f64 = 1.0;

/// Counts of a tracking run.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct TrackSummary {
    /// Events read.
    pub events: u64,
    /// Events in the tracks kept.
    pub events_tracked: u64,
    /// Slabs processed.
    pub slabs: u64,
    /// Particle detections (clusters of at least `min_events` events).
    pub detections: u64,
    /// Tracks kept.
    pub tracks: u64,
    /// Tracks dropped: shorter than `min_duration`, with fewer than three detections, or
    /// travelling less than 1 px (a hot pixel, not a particle).
    pub dropped: u64,
    /// Events left out of the fits as outliers.
    pub outliers: u64,
    /// Samples written.
    pub samples: u64,
    /// Most tracks alive at once.
    pub peak_live: u64,
    /// The detection slab used, µs (chosen from the first events for `slab = auto`).
    pub slab_us: i64,
}

/// Tracks particles through a stream of events: [`Tracker::push`] batches in time order,
/// then [`Tracker::finish`]; every track is handed to the sink as it ends, in order of
/// creation within the tracks ending together.
pub struct Tracker {
    params: TrackParams,
    geometry: Geometry,
    detector: Detector,
    linker: Linker,
    slab: Vec<TrackEvent>,
    /// Index of the slab being filled (time / slab length).
    slab_index: Option<i64>,
    /// With `slab = auto`, the first events, held until the slab is chosen.
    probe: Vec<TrackEvent>,
    summary: TrackSummary,
}

impl Tracker {
    /// A tracker for a sensor of `geometry`; checks the settings.
    pub fn new(geometry: Geometry, params: TrackParams) -> Result<Self> {
        params.validate()?;
        let pixels = u64::from(geometry.width) * u64::from(geometry.height);
        if pixels == 0 || pixels > MAX_PIXELS {
            return Err(crate::Error::parameter(
                "geometry",
                format!(
                    "{geometry}: tracking needs a sensor of 1 to {MAX_PIXELS} pixels (it keeps 8 bytes per pixel)"
                ),
            ));
        }
        Ok(Tracker {
            detector: Detector::new(geometry.width, geometry.height),
            linker: Linker::new(params.clone(), geometry),
            summary: TrackSummary {
                slab_us: params.slab_us,
                ..TrackSummary::default()
            },
            params,
            geometry,
            slab: Vec::new(),
            slab_index: None,
            probe: Vec::new(),
        })
    }

    /// The settings (`slab_us` 0 until an automatic slab is chosen).
    pub fn params(&self) -> &TrackParams {
        &self.params
    }

    /// Counts so far.
    pub fn summary(&self) -> TrackSummary {
        self.summary
    }

    /// Take a batch of events (time order; an event earlier than the slab being filled
    /// joins that slab). Tracks that end are fitted and passed to `sink`.
    pub fn push(&mut self, events: &EventBuffer, sink: &mut dyn FnMut(Track)) {
        self.summary.events += events.len() as u64;
        let polarity = self.params.polarity;
        let selected = (0..events.len())
            .filter(|&i| polarity.accepts(events.p[i]))
            .map(|i| TrackEvent {
                t: events.t[i],
                x: events.x[i],
                y: events.y[i],
                p: events.p[i],
            });
        if self.params.slab_us == 0 {
            self.probe.extend(selected);
            let span = match (self.probe.first(), self.probe.last()) {
                (Some(a), Some(b)) => b.t.saturating_sub(a.t),
                _ => 0,
            };
            if span >= slab::PROBE_US || self.probe.len() >= slab::PROBE_EVENTS {
                self.resolve_slab(sink);
            }
            return;
        }
        for e in selected {
            self.take(e, sink);
        }
    }

    /// Choose the automatic slab on the probe, then track the probe's events.
    fn resolve_slab(&mut self, sink: &mut dyn FnMut(Track)) {
        let mut probe = std::mem::take(&mut self.probe);
        // The choice clusters slab by slab: time order, as the stream is tracked.
        probe.sort_by_key(|e| e.t);
        let slab_us = slab::choose_slab(&probe, &mut self.detector, self.params.min_events);
        self.params.slab_us = slab_us;
        self.linker.set_slab(slab_us);
        self.summary.slab_us = slab_us;
        for e in probe {
            self.take(e, sink);
        }
    }

    /// One event (time order; one earlier than the slab being filled joins that slab).
    fn take(&mut self, e: TrackEvent, sink: &mut dyn FnMut(Track)) {
        let index = e.t.div_euclid(self.params.slab_us);
        match self.slab_index {
            None => self.slab_index = Some(index),
            Some(current) if index > current => {
                self.close_slab(sink);
                self.slab_index = Some(index);
            }
            _ => {}
        }
        self.slab.push(e);
    }

    /// End the stream: the last slab is processed and every track still alive is fitted and
    /// passed to `sink`.
    pub fn finish(mut self, sink: &mut dyn FnMut(Track)) -> TrackSummary {
        if self.params.slab_us == 0 {
            self.resolve_slab(sink);
        }
        if !self.slab.is_empty() {
            self.close_slab(sink);
        }
        let rest = self.linker.finish();
        self.emit(rest, sink);
        self.summary
    }

    fn close_slab(&mut self, sink: &mut dyn FnMut(Track)) {
        let index = self.slab_index.unwrap_or(0);
        let (claimed, rest) = self.linker.claim(&self.slab);
        let detections = self.detector.detect(&rest, self.params.min_events);
        self.slab.clear();
        self.summary.slabs += 1;
        self.summary.detections += (claimed.len() + detections.len()) as u64;
        let slab_end = index.saturating_add(1).saturating_mul(self.params.slab_us) as f64;
        let ended = self.linker.step(claimed, detections, slab_end);
        self.summary.peak_live = self.summary.peak_live.max(self.linker.live_count() as u64);
        if !ended.is_empty() {
            self.emit(ended, sink);
        }
    }

    /// Fit the ended tracks long enough to keep (in parallel) and pass them on by id.
    fn emit(&mut self, ended: Vec<LiveTrack>, sink: &mut dyn FnMut(Track)) {
        let params = &self.params;
        let geometry = self.geometry;
        let (keep, drop): (Vec<LiveTrack>, Vec<LiveTrack>) =
            ended.into_iter().partition(|t| long_enough(t, params));
        self.summary.dropped += drop.len() as u64;
        let mut fitted: Vec<Track> = keep
            .into_par_iter()
            .map(|t| fit_track(t, params, geometry))
            .collect();
        fitted.sort_by_key(|t| t.id);
        for track in fitted {
            if track.samples.is_empty() {
                self.summary.dropped += 1;
                continue;
            }
            self.summary.tracks += 1;
            self.summary.events_tracked += track.events as u64;
            self.summary.outliers += track.outliers as u64;
            self.summary.samples += track.samples.len() as u64;
            sink(track);
        }
    }
}

fn long_enough(track: &LiveTrack, params: &TrackParams) -> bool {
    let (Some(first), Some(last)) = (track.events.first(), track.events.last()) else {
        return false;
    };
    track.detections.len() >= 3
        && last.t - first.t >= params.min_duration_us
        && track.travel() >= link::MIN_TRAVEL_PX
}

fn fit_track(mut track: LiveTrack, params: &TrackParams, geometry: Geometry) -> Track {
    // Detections of successive slabs are in time order; events within them too.
    track.events.sort_by_key(|e| e.t);
    let span_us = (track.events[0].t, track.events[track.events.len() - 1].t);
    let (mut samples, outliers) = fit::PathFitter::new(&track.events, params).fit();
    samples.retain(|s| away_from_edge(s, geometry));
    Track {
        id: track.id,
        samples,
        events: track.events.len() as u32,
        outliers,
        span_us,
    }
}

/// Whether a sample lies at least [`EDGE_MARGIN_PX`] inside the outermost pixel centres.
fn away_from_edge(sample: &TrackSample, geometry: Geometry) -> bool {
    let inside = |position: f64, pixels: u32| {
        position >= EDGE_MARGIN_PX && position <= f64::from(pixels) - 1.0 - EDGE_MARGIN_PX
    };
    inside(sample.x, geometry.width) && inside(sample.y, geometry.height)
}

/// Track every particle in `events` (time order): the tracks in order of their end.
pub fn track_events(
    events: &EventBuffer,
    geometry: Geometry,
    params: &TrackParams,
) -> Result<(Vec<Track>, TrackSummary)> {
    let mut tracker = Tracker::new(geometry, params.clone())?;
    let mut tracks = Vec::new();
    tracker.push(events, &mut |t| tracks.push(t));
    let summary = tracker.finish(&mut |t| tracks.push(t));
    Ok((tracks, summary))
}
