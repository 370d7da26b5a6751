//! The two threads of a live run: read and cut into slabs, then evaluate and deliver.

use super::input::{GrowingFile, PipeInput, StopCheck};
use super::queue::SlabQueue;
use super::{LiveField, LiveInput, LiveOptions, LiveSink, LiveStart, LiveStats, LiveSummary};
use crate::error::{Error, Result};
use crate::estimate::Estimator;
use crate::event::{EventBuffer, Geometry};
use crate::io::{open_source, EventReader};
use crate::process::{process_slab, BatchSource, Method, ProcessParams, SlidingEvents};
use crate::settings::{EstimatorTask, Resolved};
use crate::volume::Slab;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Run `run`'s event method (sum of correlation or motion compensation, any passes) live
/// on `options.input`, handing every field to `sink` as it is ready, until the input ends
/// or `stop` says so. Field times and slabs are those `ebiv process` evaluates on the
/// finished recording (`run.time` included).
pub fn run_live(
    run: &Resolved,
    options: &LiveOptions,
    stop: StopCheck,
    sink: &mut dyn LiveSink,
) -> Result<LiveSummary> {
    if matches!(run.method, Method::Piv | Method::Pulsed) {
        return Err(Error::parameter(
            "method",
            "live computes corrsum and motion fields; piv and pulsed are for ebiv process",
        ));
    }
    run.with_event_estimator(LiveTask {
        run,
        options,
        stop,
        sink,
    })?
}

struct LiveTask<'a> {
    run: &'a Resolved,
    options: &'a LiveOptions,
    stop: StopCheck,
    sink: &'a mut dyn LiveSink,
}

/// A slab cut from the stream, waiting for the estimator.
struct Job {
    t0: i64,
    slab: Slab,
    interval: (i64, i64),
    /// When the slab ended: the latency counts from here.
    ended: Instant,
    events: Option<EventBuffer>,
}

impl EstimatorTask for LiveTask<'_> {
    type Output = Result<LiveSummary>;

    fn run<E: Estimator>(self, estimator: &E) -> Result<LiveSummary> {
        let LiveTask {
            run,
            options,
            stop,
            sink,
        } = self;
        let name = options.input.name();
        if let Some(t) = run.time {
            if let (Some(a), Some(b)) = (t.start, t.end) {
                if b < a {
                    return Err(Error::parameter(
                        "time",
                        format!("END ({b} µs) is before START ({a} µs): no field"),
                    ));
                }
            }
        }
        // Checked before the input is opened (a pipe may take long to bring data).
        let step = match (options.every_us, run.time) {
            (Some(_), Some(_)) => {
                return Err(Error::parameter(
                    "every",
                    "give the time between fields once: --every, or the STEP of --time",
                ))
            }
            (Some(every), None) if every <= 0 => {
                return Err(Error::parameter(
                    "every",
                    format!("must be positive, got {every} µs"),
                ))
            }
            (Some(every), None) => every,
            (None, time) => time.map_or(run.slab_us(), |t| t.step),
        };
        if run.denoise.is_some_and(|d| d.filters.hot_pixels) {
            return Err(Error::parameter(
                "denoise",
                "a live run reads its input once, so it cannot learn the hot pixels from the recording's start; live denoises with refractory and correlation (remove hot pixels with ebiv process or ebiv filter)",
            ));
        }
        // The reader also stops when the evaluation fails.
        let failed = Arc::new(AtomicBool::new(false));
        let stop: StopCheck = {
            let (failed, requested) = (failed.clone(), stop.clone());
            Arc::new(move || failed.load(Ordering::Relaxed) || requested())
        };
        let mut reader = open_input(&options.input, options, stop.clone())?;
        let geometry = reader
            .metadata()
            .geometry
            .or(options.read.geometry)
            .ok_or_else(|| {
                Error::parameter(
                    "geometry",
                    format!("{name}: the file does not state its sensor size, which a live run needs before the first field; pass --geometry WIDTHxHEIGHT"),
                )
            })?;
        if let Some(d) = &run.denoise {
            reader.denoiser = Some(crate::denoise::Denoiser::new(d, geometry, None)?);
        }
        let mut params = run.process.clone();
        params.mask = run.mask_for(geometry)?;
        let grids = params.grids(geometry)?;
        let last = grids.last().expect("grids checked non-empty");
        let mut attributes = crate::process::run_attributes(estimator, &params);
        attributes.push(("source".into(), name.clone()));
        let mut start = LiveStart {
            source: name.clone(),
            geometry,
            x: last.x_centres(),
            y: last.y_centres(),
            attributes,
            time_origin_us: 0,
            calibration: run.calibration,
            derive: run.derive.clone(),
            step_us: step,
            description: String::new(),
        };
        let plan = Plan {
            geometry,
            planning: estimator.planning_extent_us(),
            slab: estimator.time_extent_us(),
            step,
            start: run.time.and_then(|t| t.start),
            end: run.time.and_then(|t| t.end),
            absolute_time: run.absolute_time,
            params: params.clone(),
            queue: options.queue.max(1),
            drops: options.input.drops_when_behind(),
            events_every: options.events_every,
            pace: match options.input {
                LiveInput::Replay { speed, .. } => Some(speed),
                _ => None,
            },
        };
        let counted = Arc::new(AtomicU64::new(0));
        let queue = SlabQueue::<Job>::new(plan.queue, plan.drops);
        let (origin_tx, origin_rx) = mpsc::channel::<(i64, Instant)>();
        std::thread::scope(|scope| {
            let reader_counted = counted.clone();
            let reader_stop = stop.clone();
            let plan = &plan;
            let queue = &queue;
            let cutting = scope.spawn(move || {
                let cut = cut_slabs(reader, plan, reader_stop, reader_counted, queue, origin_tx);
                queue.close();
                cut
            });
            let delivered = deliver(
                estimator, &grids, &params, queue, &origin_rx, &counted, &mut start, run, sink,
                &stop,
            );
            if delivered.is_err() {
                // The reader stops at its next push or read.
                failed.store(true, Ordering::Relaxed);
                queue.abandon();
            }
            let cut = cutting
                .join()
                .unwrap_or_else(|_| Err(Error::parameter("live", "the reading thread failed")));
            let (mut summary, report, stopped) = match (delivered, cut) {
                (Err(e), _) | (Ok(_), Err(e)) => return Err(e),
                (Ok(summary), Ok((report, stopped))) => (summary, report, stopped),
            };
            // Totals and rates over the whole run, from its first event to its end.
            let t = &mut summary.stats;
            t.events = counted.load(Ordering::Relaxed);
            if t.elapsed_s > 0.0 {
                t.event_rate = t.events as f64 / t.elapsed_s;
                t.field_rate = t.fields as f64 / t.elapsed_s;
            }
            summary.report = report;
            summary.stopped = stopped || stop();
            let t = &summary.stats;
            if t.fields == 0 && !summary.stopped {
                return Err(Error::empty(
                    name,
                    format!(
                        "no field: the input ended before the first field's slab was complete ({} after the first event, or --time's START){}",
                        crate::units::format_us(plan.planning.0 + plan.planning.1),
                        if t.events == 0 { "; it held no event" } else { "" }
                    ),
                ));
            }
            Ok(summary)
        })
    }
}

/// Open the input as an event reader.
fn open_input(input: &LiveInput, options: &LiveOptions, stop: StopCheck) -> Result<EventReader> {
    let extension = |path: &std::path::Path| {
        path.extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
    };
    let name = input.name();
    let opened = match input {
        LiveInput::File(path) | LiveInput::Replay { path, .. } => {
            return crate::io::open(path, &options.read)
        }
        LiveInput::Follow { path, idle } => {
            let file = GrowingFile::open(path, *idle, stop)?;
            open_source(
                Box::new(file),
                &name,
                extension(path).as_deref(),
                &options.read,
            )
        }
        LiveInput::Stdin => open_source(
            Box::new(PipeInput::new(std::io::stdin(), stop)),
            &name,
            None,
            &options.read,
        ),
    };
    opened.map_err(|e| match e {
        Error::Stream(source) => Error::parameter("input", format!("{name}: {source}")),
        other => other,
    })
}

/// What the reading thread needs to cut slabs.
struct Plan {
    geometry: Geometry,
    /// Events before and after a field's time that field times are planned with, µs.
    planning: (i64, i64),
    /// Events before and after a field's time that its slab holds, µs.
    slab: (i64, i64),
    step: i64,
    /// `time`'s start and end, relative to the first event unless `absolute_time`.
    start: Option<i64>,
    end: Option<i64>,
    absolute_time: bool,
    params: ProcessParams,
    queue: usize,
    drops: bool,
    events_every: Option<Duration>,
    /// Replay speed.
    pace: Option<f64>,
}

/// The reader as a source of batches: counts events, stops on request, and paces a replay.
struct LiveBatches {
    reader: EventReader,
    stop: StopCheck,
    counted: Arc<AtomicU64>,
    /// A batch read ahead (to find the first event).
    pending: Option<EventBuffer>,
    /// Replay: speed, and the wall-clock instant and camera time of the first event.
    clock: Option<(f64, Instant, i64)>,
    /// Latest event time read.
    last_us: Option<i64>,
    stopped: bool,
}

impl LiveBatches {
    /// Read up to the first event; its time, or `None` for an input without events.
    fn first_event(&mut self, pace: Option<f64>) -> Result<Option<i64>> {
        let mut batch = EventBuffer::new();
        while self.read(&mut batch)? {
            if let Some(&t) = batch.t.first() {
                self.clock = pace.map(|speed| (speed, Instant::now(), t));
                self.pending = Some(batch);
                return Ok(Some(t));
            }
        }
        Ok(None)
    }

    fn read(&mut self, out: &mut EventBuffer) -> Result<bool> {
        if (self.stop)() {
            self.stopped = true;
            return Ok(false);
        }
        if !self.reader.read_batch(out)? {
            return Ok(false);
        }
        self.counted.fetch_add(out.len() as u64, Ordering::Relaxed);
        if let Some(&t) = out.t.iter().max() {
            self.last_us = Some(self.last_us.map_or(t, |l| l.max(t)));
        }
        Ok(true)
    }

    /// The wall-clock instant a replay reaches camera time `t` (`None` without a replay).
    fn instant_of(&self, t: i64) -> Option<Instant> {
        let (speed, wall, first) = self.clock?;
        let seconds = (t - first).max(0) as f64 / 1e6 / speed;
        Some(wall + Duration::from_secs_f64(seconds.min(1e9)))
    }

    /// Wait until a replay reaches camera time `t`, checking for a stop request.
    fn wait_until(&mut self, t: i64) {
        let Some(due) = self.instant_of(t) else {
            return;
        };
        loop {
            let now = Instant::now();
            if now >= due || (self.stop)() {
                return;
            }
            std::thread::sleep((due - now).min(Duration::from_millis(20)));
        }
    }
}

impl BatchSource for LiveBatches {
    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        if let Some(pending) = self.pending.take() {
            *out = pending;
        } else if !self.read(out)? {
            return Ok(false);
        }
        if let (Some((speed, ..)), Some(&first)) = (self.clock, out.t.first()) {
            // A replay hands events over as they are "recorded": in pieces of at most
            // REPLAY_PIECE of wall-clock time, each when its last event is due.
            let span = (REPLAY_PIECE.as_secs_f64() * 1e6 * speed).max(1.0) as i64;
            let cut = out.t.partition_point(|&t| t <= first.saturating_add(span));
            if cut < out.len() {
                self.pending = Some(out.split_off(cut));
            }
            if let Some(&t) = out.t.last() {
                self.wait_until(t);
            }
        }
        Ok(true)
    }
}

/// Wall-clock time of events a replay hands over at once.
const REPLAY_PIECE: Duration = Duration::from_millis(1);

/// The reading thread: cut the stream into the slabs of the field times and queue them.
/// Returns the reader's report and whether a stop request ended it.
fn cut_slabs(
    reader: EventReader,
    plan: &Plan,
    stop: StopCheck,
    counted: Arc<AtomicU64>,
    queue: &SlabQueue<Job>,
    origin: mpsc::Sender<(i64, Instant)>,
) -> Result<(crate::io::DecodeReport, bool)> {
    let mut batches = LiveBatches {
        reader,
        stop,
        counted,
        pending: None,
        clock: None,
        last_us: None,
        stopped: false,
    };
    let Some(first) = batches.first_event(plan.pace)? else {
        return Ok((batches.reader.report(), batches.stopped));
    };
    let _ = origin.send((first, Instant::now()));
    let time_origin = if plan.absolute_time { 0 } else { first };
    let offset = |t: i64| {
        time_origin.checked_add(t).ok_or_else(|| {
            Error::parameter("time", format!("{t} µs is beyond the range of time stamps"))
        })
    };
    let first_field = match plan.start {
        Some(start) => offset(start)?,
        None => first.saturating_add(plan.planning.0),
    };
    let last_field = plan.end.map(offset).transpose()?;
    let (before, after) = plan.slab;
    let mut sliding = SlidingEvents::default();
    let mut events_due = Instant::now();
    for k in 0i64.. {
        let Some(t0) = k
            .checked_mul(plan.step)
            .and_then(|d| first_field.checked_add(d))
        else {
            break;
        };
        if last_field.is_some_and(|end| t0 > end) {
            break;
        }
        let (start, end) = (t0 - before, t0 + after);
        sliding.advance(&mut batches, start, end)?;
        let events = sliding.events();
        let complete = events.t.last().is_some_and(|&t| t >= end);
        if !complete {
            // The input ended: a field fits when its planned interval lies within the events
            // read, as in `ebiv process`.
            let fits = batches
                .last_us
                .is_some_and(|last| t0 + plan.planning.1 <= last + 1);
            if batches.stopped || !fits {
                break;
            }
        }
        let ended = batches.instant_of(end).unwrap_or_else(Instant::now);
        let slab = plan.params.field_slab(events, plan.geometry, start, end);
        let shown = plan
            .events_every
            .filter(|_| Instant::now() >= events_due)
            .map(|every| {
                events_due = Instant::now() + every;
                interval_events(events, start, end)
            });
        let job = Job {
            t0,
            slab,
            interval: (start, end),
            ended,
            events: shown,
        };
        if !queue.push(job) {
            break;
        }
    }
    Ok((batches.reader.report(), batches.stopped))
}

/// The events of `[start, end)`.
fn interval_events(events: &EventBuffer, start: i64, end: i64) -> EventBuffer {
    let mut out = EventBuffer::new();
    for i in 0..events.len() {
        if (start..end).contains(&events.t[i]) {
            out.push(events.t[i], events.x[i], events.y[i], events.p[i]);
        }
    }
    out
}

/// The evaluating thread: evaluate each queued slab, deliver its field, keep the statistics.
#[allow(clippy::too_many_arguments)]
fn deliver<E: Estimator>(
    estimator: &E,
    grids: &[crate::grid::Grid],
    params: &ProcessParams,
    queue: &SlabQueue<Job>,
    origin: &Receiver<(i64, Instant)>,
    counted: &AtomicU64,
    start: &mut LiveStart,
    run: &Resolved,
    sink: &mut dyn LiveSink,
    stop: &StopCheck,
) -> Result<LiveSummary> {
    let mut summary = LiveSummary::default();
    let mut latencies: Vec<f64> = Vec::new();
    let mut recent: VecDeque<(Instant, u64, u64)> = VecDeque::new();
    let mut begun: Option<Instant> = None;
    let mut stats = LiveStats::default();
    while let Some((job, dropped_before)) = queue.pop() {
        // A stop request ends the run after the field being evaluated: the slabs still
        // queued are not evaluated.
        if stop() {
            break;
        }
        if begun.is_none() {
            let (first, at) = origin.recv().map_err(|_| {
                Error::parameter("live", "the reading thread ended before the first event")
            })?;
            begun = Some(at);
            start.time_origin_us = if run.absolute_time { 0 } else { first };
            start.description = describe(start, estimator, params);
            sink.started(start)?;
        }
        let result = process_slab(estimator, &job.slab, job.t0, grids, params);
        let latency = job.ended.elapsed().as_secs_f64() * 1e3;
        latencies.push(latency);
        summary.empty_fields += u64::from(job.slab.is_empty());
        summary.lone_pixel_events += job.slab.lone_pixel_events() as u64;
        let now = Instant::now();
        stats.fields += 1;
        stats.dropped += dropped_before;
        stats.events = counted.load(Ordering::Relaxed);
        stats.latency_ms = latency;
        stats.latency_p99_ms = percentile(&latencies[latencies.len().saturating_sub(1000)..], 0.99);
        stats.elapsed_s = begun.map_or(0.0, |b| (now - b).as_secs_f64());
        recent.push_back((now, stats.events, stats.fields));
        while recent.len() > 2 && now - recent[1].0 >= Duration::from_secs(1) {
            recent.pop_front();
        }
        if let (Some(a), Some(b)) = (recent.front(), recent.back()) {
            let span = (b.0 - a.0).as_secs_f64();
            if span > 0.0 {
                stats.event_rate = (b.1 - a.1) as f64 / span;
                stats.field_rate = (b.2 - a.2) as f64 / span;
            }
        }
        sink.field(&LiveField {
            t0_us: job.t0,
            field: &result.field,
            dropped_before,
            events: job.events.as_ref(),
            interval_us: job.interval,
            stats,
        })?;
    }
    // The run's wall-clock time, from its first event to its end.
    let begun = begun.or_else(|| origin.try_recv().ok().map(|(_, at)| at));
    stats.elapsed_s = begun.map_or(0.0, |b| b.elapsed().as_secs_f64());
    summary.stats = stats;
    summary.latency_p50_ms = percentile(&latencies, 0.5);
    summary.latency_p99_ms = percentile(&latencies, 0.99);
    summary.latency_max_ms = latencies.iter().copied().fold(0.0, f64::max);
    Ok(summary)
}

/// The `q` quantile of `values` (nearest rank), 0 without values.
fn percentile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// "rec.raw: fields every 10 ms from 10 ms after the first event, corrsum on 1280x720, passes …".
fn describe<E: Estimator>(start: &LiveStart, estimator: &E, params: &ProcessParams) -> String {
    format!(
        "{}: a field every {}, {} on {}, passes {}",
        start.source,
        crate::units::format_us(start.step_us),
        estimator.name(),
        start.geometry,
        crate::grid::describe_passes(&params.passes)
    )
}
