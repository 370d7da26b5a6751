//! A recording processed slab by slab: events are read in batches and only those of the
//! slab in flight are kept, so memory does not grow with the recording's length.

use super::{process_slab, ProcessParams};
use crate::error::Result;
use crate::estimate::Estimator;
use crate::event::{EventBuffer, Geometry};
use crate::field::{FieldSeries, VectorField};
use crate::io::EventReader;
use crate::volume::Slab;

/// Anything that hands out events in batches, in (nearly) time order.
pub trait BatchSource {
    /// Fill `out` (cleared first) with the next batch; `false` at the end.
    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool>;
}

impl BatchSource for EventReader {
    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        self.read_batch(out)
    }
}

/// Events already in memory, handed out in batches (simulations, tests, benchmarks).
pub struct MemorySource<'a> {
    events: &'a EventBuffer,
    next: usize,
    batch: usize,
}

impl<'a> MemorySource<'a> {
    /// Batches of up to 2¹⁶ events from `events`.
    pub fn new(events: &'a EventBuffer) -> Self {
        MemorySource {
            events,
            next: 0,
            batch: 1 << 16,
        }
    }
}

impl BatchSource for MemorySource<'_> {
    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        out.clear();
        let end = (self.next + self.batch).min(self.events.len());
        if self.next >= end {
            return Ok(false);
        }
        let e = self.events;
        out.t.extend_from_slice(&e.t[self.next..end]);
        out.x.extend_from_slice(&e.x[self.next..end]);
        out.y.extend_from_slice(&e.y[self.next..end]);
        out.p.extend_from_slice(&e.p[self.next..end]);
        self.next = end;
        Ok(true)
    }
}

/// Time range and pixel extent of a recording, from one pass over it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordingExtent {
    /// Time of the first event in file order, µs: the origin of times given relative to the
    /// recording (the earliest time too, unless the file's time stamps run backwards).
    pub first_in_file_us: i64,
    /// Earliest event time, µs.
    pub first_us: i64,
    /// Latest event time, µs.
    pub last_us: i64,
    /// Largest column seen.
    pub max_x: u16,
    /// Largest row seen.
    pub max_y: u16,
    /// Events in the recording.
    pub events: u64,
}

/// Read `source` to the end and return its extent, `None` if it holds no events.
pub fn scan_extent(source: &mut impl BatchSource) -> Result<Option<RecordingExtent>> {
    let mut batch = EventBuffer::new();
    let mut extent: Option<RecordingExtent> = None;
    while source.next_batch(&mut batch)? {
        for i in 0..batch.len() {
            let (t, x, y) = (batch.t[i], batch.x[i], batch.y[i]);
            let e = extent.get_or_insert(RecordingExtent {
                first_in_file_us: t,
                first_us: t,
                last_us: t,
                max_x: x,
                max_y: y,
                events: 0,
            });
            e.first_us = e.first_us.min(t);
            e.last_us = e.last_us.max(t);
            e.max_x = e.max_x.max(x);
            e.max_y = e.max_y.max(y);
            e.events += 1;
        }
    }
    Ok(extent)
}

/// What a run did, for the final summary line.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunSummary {
    /// Fields computed.
    pub fields: usize,
    /// Vectors in all fields.
    pub vectors: usize,
    /// Valid vectors (status 0) in all fields.
    pub valid: usize,
    /// Events read from the source.
    pub events_read: u64,
    /// Vectors flagged by validation, per test, summed over fields.
    pub flagged: usize,
    /// Median-test outliers made valid by a secondary peak, summed over fields.
    pub secondary_peaks: usize,
    /// Fields whose time interval held no event of the selected polarity (all their vectors
    /// are gaps): a `--time` beyond the recording, or a polarity the camera did not record.
    pub empty_fields: usize,
    /// Events of lone persistent pixels (hot pixels) left out of the fields' slabs
    /// ([`crate::volume::Slab::drop_lone_pixels`]), summed over fields (an event in the
    /// slabs of several fields counts in each).
    pub lone_pixel_events: usize,
}

/// "left out 25 events of lone hot pixels …": what [`RunSummary::lone_pixel_events`] (or the
/// live summary's) counts, for the commands to print.
pub fn lone_pixel_line(events: usize) -> String {
    format!(
        "left out {events} events of lone hot pixels (pixels that fire through a field's slab while none of their neighbours does; drop-lone-pixels, docs/denoise.md)"
    )
}

/// What the caller sees after each field: for progress bars and figures.
pub struct FieldDone<'a> {
    /// Fields done so far, including this one.
    pub done: usize,
    /// Fields in the run.
    pub total: usize,
    /// This field's centre time, µs.
    pub t0_us: i64,
    /// The field (last pass, validated).
    pub field: &'a VectorField,
    /// The events in memory: at least those of this field's slab, in file order.
    pub events: &'a EventBuffer,
}

/// The events of a sliding time interval of a stream: [`SlidingEvents::advance`] reads
/// batches until the interval's end is covered and drops what lies before its start, so
/// intervals must come in increasing order and memory stays bounded by one interval (plus a
/// batch).
#[derive(Debug, Default)]
pub struct SlidingEvents {
    window: EventBuffer,
    batch: EventBuffer,
    exhausted: bool,
    /// Events read from the source so far.
    pub events_read: u64,
}

impl SlidingEvents {
    /// Read until an event at or after `end_us` (or the end of the source) and drop the
    /// events before `start_us`; [`SlidingEvents::events`] then holds the interval (and
    /// possibly events at or beyond `end_us`).
    pub fn advance(
        &mut self,
        source: &mut impl BatchSource,
        start_us: i64,
        end_us: i64,
    ) -> Result<()> {
        while !self.exhausted && self.window.t.last().is_none_or(|&t| t < end_us) {
            if source.next_batch(&mut self.batch)? {
                self.events_read += self.batch.len() as u64;
                // Batches wholly before the interval are not kept, so a late interval does
                // not hold the recording before it.
                if self.batch.t.last().is_some_and(|&t| t >= start_us) {
                    self.window.extend_from(&self.batch);
                }
            } else {
                self.exhausted = true;
            }
        }
        let keep_from = self
            .window
            .t
            .iter()
            .position(|&t| t >= start_us)
            .unwrap_or(self.window.len());
        if keep_from > 0 {
            let w = &mut self.window;
            w.t.drain(..keep_from);
            w.x.drain(..keep_from);
            w.y.drain(..keep_from);
            w.p.drain(..keep_from);
        }
        Ok(())
    }

    /// The events in memory, in stream order.
    pub fn events(&self) -> &EventBuffer {
        &self.window
    }
}

/// Process `source` at the field times `times_us` (sorted ascending, duplicates dropped):
/// the slab of each time is built from the events read so far, then evaluated by
/// [`process_slab`]. Reading and binning the next field's events overlap with the evaluation
/// of the current one. `on_field` is called after every field; an error from it (a caller's
/// cancellation, a figure that cannot be written) ends the run and is returned.
pub fn process_recording<E: Estimator, S: BatchSource + Send>(
    source: &mut S,
    geometry: Geometry,
    estimator: &E,
    params: &ProcessParams,
    times_us: &[i64],
    on_field: &mut dyn FnMut(&FieldDone) -> Result<()>,
) -> Result<(FieldSeries, RunSummary)> {
    let grids = params.grids(geometry)?;
    let last = grids.last().expect("grids checked non-empty");
    let mut series = FieldSeries::on_grid(last.x_centres(), last.y_centres());
    series.attributes = run_attributes(estimator, params);
    let mut times = times_us.to_vec();
    times.sort_unstable();
    times.dedup();
    let (before, after) = estimator.time_extent_us();
    let mut sliding = SlidingEvents::default();
    let mut summary = RunSummary::default();
    // Read up to the end of field `t0`'s interval, keep what follows `keep_from`, and bin the
    // interval into a slab.
    let mut next_slab = |sliding: &mut SlidingEvents, t0: i64, keep_from: i64| -> Result<Slab> {
        let (start, end) = (t0 - before, t0 + after);
        sliding.advance(source, keep_from.min(start), end)?;
        Ok(params.field_slab(sliding.events(), geometry, start, end))
    };
    let mut slab = match times.first() {
        Some(&t0) => Some(next_slab(&mut sliding, t0, t0 - before)?),
        None => None,
    };
    for (k, &t0) in times.iter().enumerate() {
        let current = slab.take().expect("a slab is built for every field");
        let following = times.get(k + 1).copied();
        // Fields whose intervals overlap or touch: the next slab is read and built while this
        // one is evaluated, keeping this field's events for `on_field` (memory: two
        // overlapping intervals). Fields further apart run one after the other, so the gap
        // between them is never held.
        let overlapping = following.filter(|&t1| t1 - before <= t0 + after);
        let (result, built) = rayon::join(
            || process_slab(estimator, &current, t0, &grids, params),
            || {
                overlapping
                    .map(|t1| next_slab(&mut sliding, t1, t0 - before))
                    .transpose()
            },
        );
        summary.events_read = sliding.events_read;
        summary.fields += 1;
        summary.empty_fields += usize::from(current.is_empty());
        summary.lone_pixel_events += current.lone_pixel_events();
        summary.vectors += result.field.len();
        summary.valid += result.field.status.iter().filter(|s| s.is_valid()).count();
        summary.flagged += result.validation.valid_before - result.validation.valid_after;
        summary.secondary_peaks += result.validation.secondary_peaks;
        series.push(t0, &result.field)?;
        on_field(&FieldDone {
            done: k + 1,
            total: times.len(),
            t0_us: t0,
            field: &result.field,
            events: sliding.events(),
        })?;
        slab = match (built?, following) {
            (Some(next), _) => Some(next),
            (None, Some(t1)) => Some(next_slab(&mut sliding, t1, t1 - before)?),
            (None, None) => None,
        };
    }
    Ok((series, summary))
}

/// The processing parameters as output attributes (the writers add the software, the time
/// basis and the status legend).
pub(crate) fn run_attributes<E: Estimator>(
    estimator: &E,
    params: &ProcessParams,
) -> Vec<(String, String)> {
    let mut a = vec![
        ("method".to_string(), estimator.name().to_string()),
        ("polarity".to_string(), params.polarity.name().to_string()),
        (
            "passes".to_string(),
            params
                .passes
                .iter()
                .map(|p| {
                    format!(
                        "{}x{} px step {}x{}",
                        p.window[0], p.window[1], p.step[0], p.step[1]
                    )
                })
                .collect::<Vec<_>>()
                .join(", "),
        ),
        (
            "position".to_string(),
            "window centroid, image coordinates: x right, y down, pixel centres at integers"
                .to_string(),
        ),
        (
            "validation".to_string(),
            params.validation.describe("px/ms"),
        ),
        (
            "predictor_smoothing_nodes".to_string(),
            params.predictor_smoothing.to_string(),
        ),
        ("deform".to_string(), params.deform.to_string()),
        (
            "last_pass_repeats".to_string(),
            format!(
                "{} (until mean change < {} px/ms)",
                params.last_pass_repeats, params.repeat_tolerance
            ),
        ),
        (
            "replace_final".to_string(),
            params.replace_final.to_string(),
        ),
        (
            "secondary_peaks".to_string(),
            (params.secondary_peaks && estimator.finds_secondary_peaks()).to_string(),
        ),
        ("uncertainty".to_string(), params.uncertainty.to_string()),
        (
            "drop_lone_pixels".to_string(),
            params.drop_lone_pixels.to_string(),
        ),
    ];
    a.extend(estimator.parameters());
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Batches of event times handed out in order, some of them empty (as a reader may
    /// return between packets).
    struct Batches(Vec<Vec<i64>>);

    impl BatchSource for Batches {
        fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
            out.clear();
            if self.0.is_empty() {
                return Ok(false);
            }
            for t in self.0.remove(0) {
                out.push(t, 0, 0, 1);
            }
            Ok(true)
        }
    }

    #[test]
    fn the_extent_keeps_the_first_time_in_file_order_and_the_range() {
        let mut source = Batches(vec![vec![], vec![7, 3], vec![9]]);
        let e = scan_extent(&mut source).unwrap().unwrap();
        assert_eq!((e.first_in_file_us, e.first_us, e.last_us), (7, 3, 9));
        assert_eq!(e.events, 3);
        assert_eq!(scan_extent(&mut Batches(vec![vec![]])).unwrap(), None);
    }
}
