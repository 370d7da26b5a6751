//! Live runs: a recording followed while another thread writes it in pieces, a replay that
//! cannot keep up, and the files written as fields arrive, each against `ebiv process` on
//! the finished recording.

mod common;

use ebiv::export::{write_field_netcdf, LiveWriter};
use ebiv::field::FieldSeries;
use ebiv::io::field::{read_field, FieldReadOptions};
use ebiv::live::{run_live, LiveField, LiveInput, LiveOptions, LiveSink, LiveStart, StopCheck};
use ebiv::settings::{ProcessSettings, Resolved};
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

/// A 256 × 256 recording of a uniform flow, 60 ms, written as EVT 3.0 RAW into `dir`.
fn recording(dir: &Path) -> std::path::PathBuf {
    let (_, events) =
        common::simulate_scene("type = \"uniform\"\nu = 2.0\nv = -0.5", "60ms", "", 21);
    let path = dir.join("rec.raw");
    let mut writer = ebiv::io::write::create(
        &path,
        ebiv::io::Format::Evt3,
        Some(ebiv::Geometry::new(256, 256)),
    )
    .unwrap();
    writer.write(&events).unwrap();
    writer.finish().unwrap();
    path
}

/// Sum of correlation, two passes, a field every 5 ms of 10 ms slabs.
fn settings(input: &Path, extra: &[(&str, &str)]) -> Resolved {
    let mut s = ProcessSettings::default();
    s.set_flag("input", &[input.display().to_string()]).unwrap();
    for (key, value) in [("slab", "10ms"), ("time", "::5ms"), ("window", "48,32")]
        .iter()
        .chain(extra)
    {
        s.set_flag(key, &[value.to_string()]).unwrap();
    }
    s.resolve().unwrap()
}

/// What `ebiv process` measures on the finished recording.
fn processed(run: &Resolved) -> FieldSeries {
    let source = run.event_source(&ebiv::io::ReadOptions::default());
    run.measure(&source, &mut ()).unwrap().series
}

/// Keeps the fields as a series, and the count of dropped ones.
#[derive(Default)]
struct Collect {
    start: Option<LiveStart>,
    series: Option<FieldSeries>,
    dropped: u64,
}

impl LiveSink for Collect {
    fn started(&mut self, start: &LiveStart) -> ebiv::Result<()> {
        self.start = Some(start.clone());
        Ok(())
    }
    fn field(&mut self, f: &LiveField) -> ebiv::Result<()> {
        let start = self.start.as_ref().unwrap();
        match &mut self.series {
            Some(s) => s.push(f.t0_us, f.field)?,
            None => self.series = Some(start.series_of(f.t0_us, f.field)?),
        }
        self.dropped += f.dropped_before;
        assert_eq!(f.stats.dropped, self.dropped);
        Ok(())
    }
}

fn never() -> StopCheck {
    Arc::new(|| false)
}

/// The fields of `live` equal those of `expected` at the same times.
fn assert_same_fields(live: &FieldSeries, expected: &FieldSeries) {
    let (nx, ny) = (expected.x.len(), expected.y.len());
    assert!(!live.t_us.is_empty());
    for (k, t) in live.t_us.iter().enumerate() {
        let j = expected
            .t_us
            .iter()
            .position(|e| e == t)
            .unwrap_or_else(|| panic!("field {t} µs is not one of process's"));
        let (a, b) = (k * nx * ny, j * nx * ny);
        let same = |x: &[f32], y: &[f32]| {
            x[a..a + nx * ny]
                .iter()
                .zip(&y[b..b + nx * ny])
                .all(|(p, q)| p.to_bits() == q.to_bits())
        };
        assert!(
            same(&live.u, &expected.u) && same(&live.v, &expected.v),
            "field {t}"
        );
        assert_eq!(live.status[a..a + nx * ny], expected.status[b..b + nx * ny]);
    }
}

#[test]
fn following_a_file_written_in_pieces_gives_the_fields_of_process() {
    let dir = tempfile::tempdir().unwrap();
    let finished = recording(dir.path());
    let bytes = std::fs::read(&finished).unwrap();
    let growing = dir.path().join("growing.raw");
    std::fs::write(&growing, b"").unwrap();
    // Another thread appends the recording in pieces that split words and the header.
    let writer = {
        let growing = growing.clone();
        std::thread::spawn(move || {
            use std::io::Write;
            let mut file = std::fs::OpenOptions::new()
                .append(true)
                .open(growing)
                .unwrap();
            for piece in bytes.chunks(7919) {
                file.write_all(piece).unwrap();
                file.flush().unwrap();
                std::thread::sleep(Duration::from_millis(3));
            }
        })
    };
    let run = settings(&growing, &[]);
    let mut options = LiveOptions::new(LiveInput::Follow {
        path: growing.clone(),
        idle: Duration::from_millis(1500),
    });
    options.queue = 1000;
    let mut sink = Collect::default();
    let summary = run_live(&run, &options, never(), &mut sink).unwrap();
    writer.join().unwrap();
    let expected = processed(&settings(&finished, &[]));
    let live = sink.series.unwrap();
    assert_eq!(summary.stats.dropped, 0);
    assert_eq!(live.t_us, expected.t_us, "the same field times");
    assert_same_fields(&live, &expected);
    assert!(
        summary.report.warnings.is_empty(),
        "{:?}",
        summary.report.warnings
    );
}

#[test]
fn a_replay_that_cannot_keep_up_drops_whole_fields() {
    let dir = tempfile::tempdir().unwrap();
    let path = recording(dir.path());
    // Motion compensation on three passes, a field every millisecond, replayed 50 times faster
    // than recorded: far more fields than the machine computes in time.
    let extra = [
        ("method", "motion"),
        ("time", "::1ms"),
        ("window", "64,48,32"),
    ];
    let run = settings(&path, &extra);
    let mut options = LiveOptions::new(LiveInput::Replay {
        path: path.clone(),
        speed: 50.0,
    });
    options.queue = 1;
    let mut sink = Collect::default();
    let summary = run_live(&run, &options, never(), &mut sink).unwrap();
    let expected = processed(&run);
    let live = sink.series.unwrap();
    assert!(summary.stats.dropped > 0, "{summary:?}");
    assert_eq!(
        summary.stats.fields + summary.stats.dropped,
        expected.t_us.len() as u64,
        "every field is computed or dropped"
    );
    // The fields computed are whole: exactly those of process.
    assert_same_fields(&live, &expected);
    assert!(summary.latency_p99_ms >= summary.latency_p50_ms);
}

#[test]
fn a_stop_request_ends_the_run_with_the_fields_so_far() {
    let dir = tempfile::tempdir().unwrap();
    let path = recording(dir.path());
    let run = settings(&path, &[]);
    let options = LiveOptions::new(LiveInput::Follow {
        path,
        idle: Duration::from_secs(3600),
    });
    // Stop once the file has been read (the follower would otherwise wait an hour).
    let begun = std::time::Instant::now();
    let stop: StopCheck = Arc::new(move || begun.elapsed() > Duration::from_millis(700));
    let mut sink = Collect::default();
    let summary = run_live(&run, &options, stop, &mut sink).unwrap();
    assert!(summary.stopped);
    assert!(summary.stats.fields > 0);
    assert!(begun.elapsed() < Duration::from_secs(60));
}

#[test]
fn live_files_hold_the_fields_of_process_and_are_valid_after_every_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = recording(dir.path());
    let run = settings(&path, &[]);
    let mut sink = Collect::default();
    run_live(
        &run,
        &LiveOptions::new(LiveInput::File(path)),
        never(),
        &mut sink,
    )
    .unwrap();
    let (start, series) = (sink.start.unwrap(), sink.series.unwrap());
    let nt = series.t_us.len();
    assert!(nt >= 3);
    let reference = dir.path().join("reference.nc");
    write_field_netcdf(&series, &reference).unwrap();
    let expected = read_field(&reference, &FieldReadOptions::default()).unwrap();
    for ext in ["nc", "csv", "npz"] {
        let out = dir.path().join(format!("live.{ext}"));
        let mut writer = LiveWriter::create(&out).unwrap();
        for k in 0..nt {
            let field = series.field(k);
            writer
                .append(&start, series.t_us[k], &field, k as u64)
                .unwrap();
            if ext != "npz" {
                // Readable, with every field so far, while the run goes on.
                let so_far = read_field(&out, &FieldReadOptions::default()).unwrap();
                assert_eq!(so_far.t_us, series.t_us[..=k], "{ext} after field {k}");
            }
        }
        writer.finish().unwrap();
        if ext == "npz" {
            // Written at the end: the series with the dropped counts as an attribute.
            let mut with_counts = series.clone();
            let counts: Vec<String> = (0..nt).map(|k| k.to_string()).collect();
            with_counts
                .attributes
                .push(("fields_dropped".into(), counts.join(" ")));
            let reference = dir.path().join("reference.npz");
            ebiv::export::write_field_npz(&with_counts, &reference).unwrap();
            assert_eq!(
                std::fs::read(&out).unwrap(),
                std::fs::read(&reference).unwrap()
            );
            continue;
        }
        let back = read_field(&out, &FieldReadOptions::default()).unwrap();
        assert_eq!(back.t_us, expected.t_us, "{ext}");
        assert_same_fields(&back, &expected);
    }
    let bad = LiveWriter::create(&dir.path().join("live.vtk"))
        .err()
        .unwrap()
        .to_string();
    assert!(bad.contains(".csv, .nc or .npz"), "{bad}");
}
