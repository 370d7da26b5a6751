//! Frames rebuilt from events: the pseudo-images of frame-based EBIV processing
//! (Willert & Klinner, Exp. Fluids 63:101, 2022, §2; `docs/algorithms.md` §6), to be
//! correlated by conventional PIV or inspected.
//!
//! A frame collects the events of the half-open interval `[start, start + exposure)`, so an
//! event on a boundary belongs to exactly one of two abutting frames, and renders them as an
//! event count, a binary occupancy map or a time surface (the reference code's
//! `pseudoImage`, without its inclusive end and its "0 = no event" ambiguity). Events may be
//! spread by a normalised Gaussian (splatting), which smooths the single-pixel events into
//! particle-like images for correlation.

use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry, PolaritySelection};
use crate::frame::Frame;
use crate::io::EventReader;
use std::collections::VecDeque;

/// What a pixel of a frame rebuilt from events holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FrameKind {
    /// Number of events at the pixel.
    #[default]
    Count,
    /// 1 where the pixel has at least one event, else 0.
    Binary,
    /// Time of the pixel's last event, `(t_last − start + 1) / exposure` in `(0, 1]`; 0 only
    /// where there is no event (the reference `pseudoImage` time surface, made unambiguous).
    TimeSurface,
}

impl FrameKind {
    /// Parse `count`, `binary` or `time-surface` (also `time_surface`, `timesurface`).
    pub fn parse(text: &str) -> Result<Self> {
        match text.trim().to_ascii_lowercase().as_str() {
            "count" | "counts" => Ok(FrameKind::Count),
            "binary" => Ok(FrameKind::Binary),
            "time-surface" | "time_surface" | "timesurface" => Ok(FrameKind::TimeSurface),
            _ => Err(Error::parameter(
                "kind",
                format!("`{text}` is not a frame kind; use count, binary or time-surface"),
            )),
        }
    }

    /// The name [`FrameKind::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            FrameKind::Count => "count",
            FrameKind::Binary => "binary",
            FrameKind::TimeSurface => "time-surface",
        }
    }
}

/// The largest splatting σ accepted, px: beyond it a frame is mostly blur.
pub const MAX_SPLAT_SIGMA: f64 = 32.0;

/// How frames are rebuilt from events.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameSpec {
    /// What each pixel holds.
    pub kind: FrameKind,
    /// Length of the interval collected into one frame, µs.
    pub exposure_us: i64,
    /// Which events are used.
    pub polarity: PolaritySelection,
    /// Standard deviation, px, of the Gaussian each pixel's value is spread over (truncated
    /// at 3σ, weights normalised so that nothing is lost, also at the frame's edges); 0 = no
    /// splatting.
    pub splat_sigma: f64,
}

/// The defaults of `ebiv frames`: count frames of 1 ms. (`ebiv process --method piv` has its
/// own, [`crate::settings::ProcessSettings::exposure`].)
impl Default for FrameSpec {
    fn default() -> Self {
        FrameSpec {
            kind: FrameKind::Count,
            exposure_us: 1000,
            polarity: PolaritySelection::Both,
            splat_sigma: 0.0,
        }
    }
}

impl FrameSpec {
    /// Check every value, naming the offending one.
    pub fn check(&self) -> Result<()> {
        if self.exposure_us <= 0 {
            return Err(Error::parameter(
                "exposure",
                format!(
                    "{} µs: the exposure must be longer than 0",
                    self.exposure_us
                ),
            ));
        }
        if !(self.splat_sigma >= 0.0 && self.splat_sigma <= MAX_SPLAT_SIGMA) {
            return Err(Error::parameter(
                "splat",
                format!(
                    "σ = {} px is out of range 0..={MAX_SPLAT_SIGMA} (0 = no splatting)",
                    self.splat_sigma
                ),
            ));
        }
        Ok(())
    }
}

/// A frame being filled: the pixel values of `[start, end)` and how many events went in.
struct Accumulator {
    start: i64,
    end: i64,
    data: Vec<f32>,
    events: u64,
}

impl Accumulator {
    fn new(geometry: Geometry, start: i64, exposure_us: i64) -> Self {
        Accumulator {
            start,
            end: start.saturating_add(exposure_us.max(0)),
            data: vec![0.0; geometry.pixels()],
            events: 0,
        }
    }

    /// Add one event already known to be selected, on the sensor and inside `[start, end)`.
    #[inline]
    fn add(&mut self, index: usize, t: i64, spec: &FrameSpec) {
        let v = &mut self.data[index];
        match spec.kind {
            FrameKind::Count => *v += 1.0,
            FrameKind::Binary => *v = 1.0,
            FrameKind::TimeSurface => {
                let s = ((t - self.start + 1) as f64 / spec.exposure_us as f64) as f32;
                *v = v.max(s);
            }
        }
        self.events += 1;
    }

    fn finish(self, geometry: Geometry, spec: &FrameSpec) -> (Frame, u64) {
        let mut frame = Frame {
            width: geometry.width,
            height: geometry.height,
            data: self.data,
        };
        splat(&mut frame, spec.splat_sigma);
        (frame, self.events)
    }
}

/// The pixel index of an event, if it is on the sensor.
#[inline]
fn pixel(geometry: Geometry, x: u16, y: u16) -> Option<usize> {
    let (x, y) = (x as u32, y as u32);
    geometry
        .contains(x, y)
        .then(|| y as usize * geometry.width as usize + x as usize)
}

/// The frame of the events of `[start_us, start_us + spec.exposure_us)` in `events` (any
/// order), on a sensor of `geometry`; events off the sensor or of the other polarity are
/// ignored. A spec that fails [`FrameSpec::check`] gives an empty frame (non-positive
/// exposure) or no splatting (unusable σ).
pub fn build_frame(
    events: &EventBuffer,
    geometry: Geometry,
    start_us: i64,
    spec: &FrameSpec,
) -> Frame {
    build_frame_counted(events, geometry, start_us, spec).0
}

/// [`build_frame`], also returning how many events went into the frame.
pub fn build_frame_counted(
    events: &EventBuffer,
    geometry: Geometry,
    start_us: i64,
    spec: &FrameSpec,
) -> (Frame, u64) {
    let mut acc = Accumulator::new(geometry, start_us, spec.exposure_us);
    for i in 0..events.len() {
        let t = events.t[i];
        if t < acc.start || t >= acc.end || !spec.polarity.accepts(events.p[i]) {
            continue;
        }
        if let Some(index) = pixel(geometry, events.x[i], events.y[i]) {
            acc.add(index, t, spec);
        }
    }
    acc.finish(geometry, spec)
}

/// Spread every pixel's value over a Gaussian of `sigma` px truncated at 3σ, with the weights
/// of each source pixel normalised over the pixels inside the frame, so the frame's sum is
/// kept: for a count frame, each event becomes a blob of total weight 1 (the splatting of
/// [`FrameSpec::splat_sigma`], for use after other steps such as [`despeckle`]). Done as two
/// separable passes (rows, then columns); the product of the two normalised 1-D weights is
/// the normalised 2-D weight. A σ that is not positive, finite and at most
/// [`MAX_SPLAT_SIGMA`] leaves the frame as it is.
pub fn splat(frame: &mut Frame, sigma: f64) {
    let (w, h) = (frame.width as usize, frame.height as usize);
    if w == 0 || h == 0 || frame.data.len() != w * h || !(sigma > 0.0 && sigma <= MAX_SPLAT_SIGMA) {
        return;
    }
    let radius = ((3.0 * sigma).ceil() as usize).clamp(1, w.max(h));
    let kernel: Vec<f64> = (0..=2 * radius)
        .map(|i| {
            let d = i as f64 - radius as f64;
            (-0.5 * d * d / (sigma * sigma)).exp()
        })
        .collect();
    let mut line = Vec::new();
    // Rows.
    let norms = inside_sums(&kernel, radius, w);
    for row in frame.data.chunks_exact_mut(w) {
        scatter_line(row, 1, &kernel, radius, &norms, &mut line);
    }
    // Columns.
    let norms = inside_sums(&kernel, radius, h);
    for x in 0..w {
        let column = &mut frame.data[x..];
        scatter_line(column, w, &kernel, radius, &norms, &mut line);
    }
}

/// For each position of a line of `n` pixels, the sum of the kernel weights that land
/// inside the line.
fn inside_sums(kernel: &[f64], radius: usize, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let lo = radius.saturating_sub(i);
            let hi = (n - 1 - i).min(radius) + radius;
            kernel[lo..=hi].iter().sum()
        })
        .collect()
}

/// Scatter the `norms.len()` values at `data[0], data[stride], …` with the kernel, in place.
fn scatter_line(
    data: &mut [f32],
    stride: usize,
    kernel: &[f64],
    radius: usize,
    norms: &[f64],
    line: &mut Vec<f64>,
) {
    let n = norms.len();
    line.clear();
    line.resize(n, 0.0);
    for (i, &norm) in norms.iter().enumerate() {
        let v = data[i * stride];
        if v == 0.0 {
            continue;
        }
        let v = v as f64 / norm;
        let lo = i.saturating_sub(radius);
        let hi = (i + radius).min(n - 1);
        for (j, out) in line[lo..=hi].iter_mut().enumerate() {
            *out += v * kernel[lo + j + radius - i];
        }
    }
    for (i, &v) in line.iter().enumerate() {
        data[i * stride] = v as f32;
    }
}

/// Clear isolated pixels: every non-zero pixel without a non-zero 8-neighbour becomes 0 (the
/// reference `EventImage.despeckle`). Removes single noise events from sparse frames; returns
/// how many pixels were cleared.
pub fn despeckle(frame: &mut Frame) -> usize {
    let (w, h) = (frame.width as usize, frame.height as usize);
    if frame.data.len() != w * h {
        return 0;
    }
    let lit = |data: &[f32], x: usize, y: usize| data[y * w + x] != 0.0;
    let mut clear = Vec::new();
    for y in 0..h {
        for x in 0..w {
            if !lit(&frame.data, x, y) {
                continue;
            }
            let mut neighbour = false;
            'search: for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    if (nx, ny) != (x, y) && lit(&frame.data, nx, ny) {
                        neighbour = true;
                        break 'search;
                    }
                }
            }
            if !neighbour {
                clear.push(y * w + x);
            }
        }
    }
    for &i in &clear {
        frame.data[i] = 0.0;
    }
    clear.len()
}

/// Frame start times `start, start + every, …` before `end` (µs). Empty when `every_us` is
/// not positive or `end <= start`.
pub fn frame_starts(start: i64, end: i64, every_us: i64) -> Vec<i64> {
    let mut out = Vec::new();
    if every_us <= 0 {
        return out;
    }
    let mut t = start;
    while t < end {
        out.push(t);
        match t.checked_add(every_us) {
            Some(next) => t = next,
            None => break,
        }
    }
    out
}

/// One frame finished by [`stream_frames`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameRecord {
    /// Position of the frame's start in the list of starts.
    pub index: usize,
    /// Start of the frame's interval, µs.
    pub start_us: i64,
    /// Exposure, µs: the frame holds `[start_us, start_us + exposure_us)`.
    pub exposure_us: i64,
    /// Number of events that went into the frame.
    pub events: u64,
}

/// What [`stream_frames`] saw besides the frames.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamSummary {
    /// Events that arrived after a frame they belonged to had been finished (the file's
    /// time stamps went backwards by more than the frames' spacing); they are not in any
    /// frame.
    pub late_events: u64,
    /// Selected events off the sensor geometry.
    pub off_sensor: u64,
}

/// The most memory the frames in flight may take, bytes.
const MAX_IN_FLIGHT_BYTES: usize = 4 << 30;

/// Build the frames starting at `starts` (non-decreasing, µs) from `reader`, reading the
/// file once and only as far as needed, and hand each to `sink` as soon as it is complete,
/// in order. Exposures may overlap or leave gaps; memory holds only the frames whose
/// interval spans the current time. Events are expected in time order, as cameras write
/// them; an event older than an already finished frame is counted in
/// [`StreamSummary::late_events`].
pub fn stream_frames(
    reader: &mut EventReader,
    geometry: Geometry,
    spec: &FrameSpec,
    starts: &[i64],
    mut sink: impl FnMut(FrameRecord, Frame) -> Result<()>,
) -> Result<StreamSummary> {
    spec.check()?;
    if geometry.pixels() == 0 {
        return Err(Error::parameter("geometry", "the sensor has no pixels"));
    }
    if let Some(i) = starts.windows(2).position(|w| w[1] < w[0]) {
        return Err(Error::parameter(
            "starts",
            format!(
                "frame starts must not decrease: {} µs follows {} µs (frame {})",
                starts[i + 1],
                starts[i],
                i + 1
            ),
        ));
    }
    let in_flight = max_in_flight(starts, spec.exposure_us);
    let bytes = in_flight.saturating_mul(geometry.pixels() * 4);
    if bytes > MAX_IN_FLIGHT_BYTES {
        return Err(Error::parameter(
            "exposure",
            format!(
                "{in_flight} overlapping frames of {geometry} px would need {:.1} GB; \
                 use a shorter exposure or space the frames further apart",
                bytes as f64 / 1e9
            ),
        ));
    }
    let mut summary = StreamSummary::default();
    let Some(&first) = starts.first() else {
        return Ok(summary);
    };
    reader.skip_to(first)?;
    let mut next = 0usize;
    let mut active: VecDeque<(usize, Accumulator)> = VecDeque::new();
    let mut now = i64::MIN;
    let mut batch = EventBuffer::new();
    let mut emit = |index: usize, acc: Accumulator| -> Result<()> {
        let start_us = acc.start;
        let (frame, events) = acc.finish(geometry, spec);
        let record = FrameRecord {
            index,
            start_us,
            exposure_us: spec.exposure_us,
            events,
        };
        sink(record, frame)
    };
    'read: while reader.read_batch(&mut batch)? {
        for i in 0..batch.len() {
            let t = batch.t[i];
            if t > now {
                now = t;
                while next < starts.len() && starts[next] <= now {
                    active.push_back((
                        next,
                        Accumulator::new(geometry, starts[next], spec.exposure_us),
                    ));
                    next += 1;
                }
                while active.front().is_some_and(|(_, a)| a.end <= now) {
                    let (index, acc) = active.pop_front().expect("front exists");
                    emit(index, acc)?;
                }
                if active.is_empty() && next == starts.len() {
                    break 'read;
                }
            }
            if !spec.polarity.accepts(batch.p[i]) || next == 0 {
                continue;
            }
            let Some(index) = pixel(geometry, batch.x[i], batch.y[i]) else {
                summary.off_sensor += 1;
                continue;
            };
            if t < now {
                // Time went backwards: the event may belong to a frame already finished.
                let first_open = active.front().map_or(next, |(k, _)| *k);
                let finished = &starts[..first_open];
                let from = finished.partition_point(|&s| s.saturating_add(spec.exposure_us) <= t);
                if finished.get(from).is_some_and(|&s| s <= t) {
                    summary.late_events += 1;
                }
            }
            for (_, acc) in active.iter_mut() {
                if t >= acc.start && t < acc.end {
                    acc.add(index, t, spec);
                }
            }
        }
    }
    // The recording ended (or every frame is complete): finish the rest, empty or partial.
    while next < starts.len() {
        active.push_back((
            next,
            Accumulator::new(geometry, starts[next], spec.exposure_us),
        ));
        next += 1;
        while active.len() > 1 {
            let (index, acc) = active.pop_front().expect("front exists");
            emit(index, acc)?;
        }
    }
    for (index, acc) in active {
        emit(index, acc)?;
    }
    Ok(summary)
}

/// The largest number of frames whose intervals overlap at one time.
fn max_in_flight(starts: &[i64], exposure_us: i64) -> usize {
    let mut most = 0;
    let mut first = 0;
    for (i, &s) in starts.iter().enumerate() {
        while starts[first].saturating_add(exposure_us) <= s {
            first += 1;
        }
        most = most.max(i + 1 - first);
    }
    most
}

/// All frames starting at `starts` (non-decreasing, µs), read once from `reader` in time
/// order, on the sensor geometry the file states (or the read options gave). `progress` is
/// called with the number of frames finished so far. For long series, [`stream_frames`]
/// hands frames out one by one instead of keeping them all.
pub fn frames_from_reader(
    reader: &mut EventReader,
    spec: &FrameSpec,
    starts: &[i64],
    mut progress: impl FnMut(usize),
) -> Result<Vec<Frame>> {
    let geometry = reader.metadata().geometry.ok_or_else(|| {
        Error::parameter(
            "geometry",
            "the recording does not state its sensor size; set it in the read options",
        )
    })?;
    let mut frames = Vec::with_capacity(starts.len().min(1 << 16));
    stream_frames(reader, geometry, spec, starts, |_, frame| {
        frames.push(frame);
        progress(frames.len());
        Ok(())
    })?;
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: Geometry = Geometry::new(8, 6);

    fn buffer(events: &[(i64, u16, u16, u8)]) -> EventBuffer {
        let mut b = EventBuffer::new();
        for &(t, x, y, p) in events {
            b.push(t, x, y, p);
        }
        b
    }

    fn spec(kind: FrameKind, exposure_us: i64) -> FrameSpec {
        FrameSpec {
            kind,
            exposure_us,
            ..FrameSpec::default()
        }
    }

    #[test]
    fn counts_and_polarity() {
        let b = buffer(&[
            (100, 1, 1, 1),
            (101, 1, 1, 1),
            (102, 1, 1, 0),
            (103, 7, 5, 0),
            (104, 8, 0, 1), // off the sensor
        ]);
        let s = spec(FrameKind::Count, 10);
        let (f, n) = build_frame_counted(&b, G, 100, &s);
        assert_eq!(n, 4);
        assert_eq!(f.get(1, 1), 3.0);
        assert_eq!(f.get(7, 5), 1.0);
        assert_eq!(f.data.iter().sum::<f32>(), 4.0);
        let pos = FrameSpec {
            polarity: PolaritySelection::Positive,
            ..s
        };
        let f = build_frame(&b, G, 100, &pos);
        assert_eq!((f.get(1, 1), f.get(7, 5)), (2.0, 0.0));
        let neg = FrameSpec {
            polarity: PolaritySelection::Negative,
            ..s
        };
        let f = build_frame(&b, G, 100, &neg);
        assert_eq!((f.get(1, 1), f.get(7, 5)), (1.0, 1.0));
        let f = build_frame(&b, G, 100, &spec(FrameKind::Binary, 10));
        assert_eq!((f.get(1, 1), f.get(7, 5), f.get(0, 0)), (1.0, 1.0, 0.0));
    }

    #[test]
    fn boundary_events_belong_to_one_frame() {
        let b = buffer(&[
            (99, 0, 0, 1),
            (100, 1, 0, 1),
            (109, 2, 0, 1),
            (110, 3, 0, 1),
        ]);
        let s = spec(FrameKind::Count, 10);
        let a = build_frame(&b, G, 100, &s);
        let next = build_frame(&b, G, 110, &s);
        assert_eq!(a.row(0)[..4], [0.0, 1.0, 1.0, 0.0]);
        assert_eq!(next.row(0)[..4], [0.0, 0.0, 0.0, 1.0]);
    }

    #[test]
    fn time_surface_is_zero_only_without_events() {
        let b = buffer(&[
            (100, 0, 0, 1), // at the start: 1/10, not "no event"
            (104, 1, 0, 1),
            (101, 1, 0, 1), // earlier, stored later: the last in time wins
            (109, 2, 0, 1), // last µs: 1
            (110, 3, 0, 1), // next frame
        ]);
        let f = build_frame(&b, G, 100, &spec(FrameKind::TimeSurface, 10));
        assert_eq!(f.row(0)[..5], [0.1, 0.5, 1.0, 0.0, 0.0]);
        assert!(f.data.iter().all(|&v| (0.0..=1.0).contains(&v)));
    }

    #[test]
    fn splat_weights_sum_to_the_event_count() {
        let b = buffer(&[(0, 0, 0, 1), (1, 4, 3, 1), (2, 4, 3, 1), (3, 7, 2, 1)]);
        for sigma in [0.3, 0.8, 1.5, 5.0] {
            let s = FrameSpec {
                splat_sigma: sigma,
                ..spec(FrameKind::Count, 10)
            };
            s.check().unwrap();
            let f = build_frame(&b, G, 0, &s);
            let sum: f64 = f.data.iter().map(|&v| v as f64).sum();
            assert!((sum - 4.0).abs() < 1e-5, "σ {sigma}: sum {sum}");
            assert!(f.data.iter().all(|&v| v >= 0.0));
        }
        // Away from the edges the blob is the normalised, symmetric Gaussian.
        let big = Geometry::new(21, 21);
        let s = FrameSpec {
            splat_sigma: 1.0,
            ..spec(FrameKind::Count, 10)
        };
        let f = build_frame(&buffer(&[(0, 10, 10, 1)]), big, 0, &s);
        let g: f64 = (-3..=3).map(|d: i32| (-0.5 * (d * d) as f64).exp()).sum();
        assert!((f.get(10, 10) as f64 - 1.0 / (g * g)).abs() < 1e-6);
        let e1 = (-0.5f64).exp() / (g * g);
        assert!((f.get(11, 10) as f64 - e1).abs() < 1e-6);
        assert_eq!(f.get(9, 10), f.get(11, 10));
        assert_eq!(f.get(10, 7), f.get(10, 13));
        assert!(f.get(10, 7) > 0.0 && f.get(10, 6) == 0.0 && f.get(14, 10) == 0.0);
    }

    #[test]
    fn spec_check_names_the_parameter() {
        assert!(FrameSpec::default().check().is_ok());
        let e = spec(FrameKind::Count, 0).check().unwrap_err();
        assert!(e.to_string().contains("exposure"), "{e}");
        for sigma in [-1.0, f64::NAN, 1e9] {
            let s = FrameSpec {
                splat_sigma: sigma,
                ..FrameSpec::default()
            };
            assert!(s.check().unwrap_err().to_string().contains("splat"));
            // build_frame does not panic on it either.
            build_frame(&buffer(&[(0, 1, 1, 1)]), G, 0, &s);
        }
        build_frame(
            &buffer(&[(0, 1, 1, 1)]),
            G,
            0,
            &spec(FrameKind::TimeSurface, -5),
        );
        build_frame(
            &buffer(&[(i64::MAX, 1, 1, 1)]),
            G,
            i64::MAX - 1,
            &FrameSpec::default(),
        );
    }

    #[test]
    fn kinds_parse_and_serialise() {
        for k in [FrameKind::Count, FrameKind::Binary, FrameKind::TimeSurface] {
            assert_eq!(FrameKind::parse(k.name()).unwrap(), k);
            let json = serde_json::to_string(&k).unwrap();
            assert_eq!(json, format!("\"{}\"", k.name()));
        }
        let e = FrameKind::parse("movie").unwrap_err().to_string();
        assert!(e.contains("movie") && e.contains("time-surface"), "{e}");
    }

    #[test]
    fn despeckle_clears_isolated_pixels() {
        let mut f = Frame::new(6, 5);
        let set = |f: &mut Frame, x: u32, y: u32| f.data[(y * 6 + x) as usize] = 1.0;
        set(&mut f, 0, 0); // isolated corner
        set(&mut f, 3, 2); // pair on a diagonal
        set(&mut f, 4, 3);
        set(&mut f, 5, 0); // isolated
        assert_eq!(despeckle(&mut f), 2);
        assert_eq!((f.get(0, 0), f.get(5, 0)), (0.0, 0.0));
        assert_eq!((f.get(3, 2), f.get(4, 3)), (1.0, 1.0));
    }

    #[test]
    fn frame_starts_cover_the_interval() {
        assert_eq!(frame_starts(10, 40, 10), vec![10, 20, 30]);
        assert_eq!(frame_starts(10, 41, 10), vec![10, 20, 30, 40]);
        assert!(frame_starts(10, 10, 5).is_empty());
        assert!(frame_starts(0, 100, 0).is_empty());
        assert_eq!(frame_starts(i64::MAX - 3, i64::MAX, 2).len(), 2);
        assert_eq!(max_in_flight(&[0, 5, 10, 15], 10), 2);
        assert_eq!(max_in_flight(&[0, 100, 200], 10), 1);
        assert_eq!(max_in_flight(&[], 10), 0);
    }

    /// A recording in memory, as an ebiv EVT file read back in batches of ~`batch_bytes`.
    fn reader_of(events: &EventBuffer, batch_bytes: usize) -> EventReader {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        let mut text = String::from("t,x,y,p\n");
        for e in events.iter() {
            text.push_str(&format!("{},{},{},{}\n", e.t, e.x, e.y, e.p));
        }
        std::fs::write(&path, text).unwrap();
        let options = crate::io::ReadOptions {
            geometry: Some(G),
            batch_bytes,
            ..Default::default()
        };
        let bytes: std::sync::Arc<[u8]> = std::fs::read(&path).unwrap().into();
        crate::io::open_memory(bytes, "r.csv", &options).unwrap()
    }

    /// Pseudo-random events over 0..2000 µs, time-ordered.
    fn random_events() -> EventBuffer {
        let mut b = EventBuffer::new();
        let mut s = 12345u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as u32
        };
        let mut t = 0i64;
        for _ in 0..3000 {
            t += (next() % 3) as i64;
            b.push(
                t,
                (next() % 9) as u16,
                (next() % 6) as u16,
                (next() % 2) as u8,
            );
        }
        b
    }

    #[test]
    fn streaming_equals_in_memory_building() {
        let events = random_events();
        let t_end = events.t[events.len() - 1];
        // Overlapping, abutting, gapped and beyond-the-end frames, and a repeated start.
        let starts = [
            -50,
            0,
            40,
            40,
            100,
            150,
            900,
            1000,
            2500,
            t_end - 20,
            t_end + 500,
        ];
        for kind in [FrameKind::Count, FrameKind::Binary, FrameKind::TimeSurface] {
            for (sigma, batch) in [(0.0, 64), (1.2, 1 << 20)] {
                let spec = FrameSpec {
                    kind,
                    exposure_us: 100,
                    polarity: PolaritySelection::Positive,
                    splat_sigma: sigma,
                };
                let mut reader = reader_of(&events, batch);
                let mut records = Vec::new();
                let mut frames = Vec::new();
                let summary = stream_frames(&mut reader, G, &spec, &starts, |r, f| {
                    records.push(r);
                    frames.push(f);
                    Ok(())
                })
                .unwrap();
                assert_eq!(summary, StreamSummary::default());
                assert_eq!(frames.len(), starts.len());
                for (i, (&s, f)) in starts.iter().zip(&frames).enumerate() {
                    let (expected, n) = build_frame_counted(&events, G, s, &spec);
                    assert_eq!(records[i].index, i);
                    assert_eq!(records[i].start_us, s);
                    assert_eq!(records[i].events, n, "{kind:?} frame {i}");
                    assert_eq!(f, &expected, "{kind:?} σ {sigma} frame {i} at {s}");
                }
                assert!(records[1].events > 0);
                assert_eq!(records[starts.len() - 1].events, 0);
            }
        }
        let mut progress = Vec::new();
        let spec = spec(FrameKind::Count, 300);
        let frames = frames_from_reader(&mut reader_of(&events, 64), &spec, &[0, 200, 400], |n| {
            progress.push(n)
        })
        .unwrap();
        assert_eq!(progress, [1, 2, 3]);
        assert_eq!(frames[1], build_frame(&events, G, 200, &spec));
    }

    #[test]
    fn streaming_rejects_bad_starts_and_unbounded_memory() {
        let events = random_events();
        let s = spec(FrameKind::Count, 100);
        let e = stream_frames(&mut reader_of(&events, 64), G, &s, &[10, 5], |_, _| Ok(()));
        assert!(e.unwrap_err().to_string().contains("must not decrease"));
        let huge = Geometry::new(60000, 60000);
        let e = stream_frames(
            &mut reader_of(&events, 64),
            huge,
            &s,
            &[0, 1],
            |_, _| Ok(()),
        );
        assert!(e.unwrap_err().to_string().contains("GB"));
        let e = stream_frames(
            &mut reader_of(&events, 64),
            G,
            &spec(FrameKind::Count, 0),
            &[0],
            |_, _| Ok(()),
        );
        assert!(e.unwrap_err().to_string().contains("exposure"));
        let mut n = 0;
        stream_frames(&mut reader_of(&events, 64), G, &s, &[], |_, _| {
            n += 1;
            Ok(())
        })
        .unwrap();
        assert_eq!(n, 0);
    }

    #[test]
    fn late_events_are_counted_not_lost_silently() {
        let b = buffer(&[(5, 1, 1, 1), (30, 1, 1, 1), (7, 2, 2, 1), (35, 3, 3, 1)]);
        let mut frames = Vec::new();
        let summary = stream_frames(
            &mut reader_of(&b, 1 << 20),
            G,
            &spec(FrameKind::Count, 10),
            &[0, 25],
            |r, _| {
                frames.push(r.events);
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(frames, [1, 1]);
        assert_eq!(summary.late_events, 1);
    }
}
