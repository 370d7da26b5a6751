//! Every real recording in the shared data decodes to exactly the values of `EXPECTED.json`.

mod common;

use common::{assert_matches_expected, data_dir, expected};
use ebiv::io::{self, Format, ReadOptions};

fn check(name: &str, format: Format) -> Option<io::Recording> {
    let dir = data_dir()?;
    let rec = io::read_all(dir.join(name), &ReadOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(rec.metadata.format, format);
    assert_matches_expected(&rec.events, &expected(&dir, name));
    assert_eq!(rec.report.events as usize, rec.events.len());
    Some(rec)
}

fn header_lines(rec: &io::Recording) -> Vec<String> {
    rec.metadata
        .header
        .iter()
        .map(|(k, v)| format!("% {k} {v}"))
        .collect()
}

#[test]
fn evt2_sample() {
    let Some(rec) = check("prophesee/evt2_sample.raw", Format::Evt2) else {
        return;
    };
    let exp = expected(&data_dir().unwrap(), "prophesee/evt2_sample.raw");
    let lines: Vec<String> = serde_json::from_value(exp["header_lines"].clone()).unwrap();
    assert_eq!(header_lines(&rec), lines);
    assert_eq!(rec.metadata.geometry, Some(ebiv::Geometry::new(640, 480)));
    assert_eq!(rec.events.triggers.len(), 0);
    assert!(!rec.report.has_problems(), "{:?}", rec.report);
}

#[test]
fn evt3_pedestrians_prefix() {
    let Some(rec) = check("prophesee/evt3_test_pedestrians.raw", Format::Evt3) else {
        return;
    };
    let exp = expected(&data_dir().unwrap(), "prophesee/evt3_test_pedestrians.raw");
    let lines: Vec<String> = serde_json::from_value(exp["header_lines"].clone()).unwrap();
    assert_eq!(header_lines(&rec), lines);
    assert_eq!(rec.metadata.geometry, Some(ebiv::Geometry::new(1280, 720)));
    assert_eq!(rec.events.triggers.len(), 0);
}

#[test]
fn evt3_metavision_time_shift() {
    let Some(dir) = data_dir() else { return };
    let options = ReadOptions {
        metavision_time_shift: true,
        ..Default::default()
    };
    let rec = io::read_all(dir.join("prophesee/evt3_test_pedestrians.raw"), &options).unwrap();
    // formats.md §14.1: the Metavision view of this file starts at 7 800 µs.
    assert_eq!(rec.events.t[0], 7800);
    assert_eq!(rec.metadata.time_shift_us, 5_840_504 - 7800);
}

#[test]
fn dat_ncars() {
    check("prophesee/sample_ncars.dat", Format::Dat);
}

#[test]
fn aedat4_sample() {
    check("inivation/sample.aedat4", Format::Aedat4);
}

#[test]
fn event_stream_dvs() {
    check("es/dvs.es", Format::EventStream);
}

#[test]
fn wallflow_npz_loads() {
    let Some(dir) = data_dir() else { return };
    let rec = io::read_all(
        dir.join("ebiv/wallflow_slice2.npz"),
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(rec.metadata.format, Format::Npz);
    assert_eq!(rec.events.len(), 89_239);
    assert_eq!(rec.events.count_on(), 89_239, "positive events only");
    let (t0, t1) = rec.events.time_range().unwrap();
    assert!(
        t0 >= 300_000 && t1 <= 320_000,
        "t = 300-320 ms, got {t0}..{t1}"
    );
    assert!(rec.events.x.iter().all(|&x| x < 512) && rec.events.y.iter().all(|&y| y < 512));
}

#[test]
fn metavision_hdf5_with_ecf_chunks() {
    let Some(rec) = check("hdf5/ecf_small.hdf5", Format::Hdf5) else {
        return;
    };
    let exp = expected(&data_dir().unwrap(), "hdf5/ecf_small.hdf5");
    let triggers: Vec<Vec<i64>> = rec
        .events
        .triggers
        .iter()
        .map(|tr| vec![tr.t, i64::from(tr.value), i64::from(tr.channel)])
        .collect();
    let want: Vec<Vec<i64>> = serde_json::from_value(exp["triggers_t_p_id"].clone()).unwrap();
    assert_eq!(triggers, want);
    let geometry = rec.metadata.geometry.unwrap();
    assert_eq!([geometry.width, geometry.height], [640, 480]);
    assert_eq!(rec.metadata.serial.as_deref(), Some("30384338"));
}

#[test]
fn dsec_style_hdf5_columns() {
    check("hdf5/generic_dsec.h5", Format::Hdf5);
}

/// Seeking by `/CD/indexes` lands on the same events as reading from the start.
#[test]
fn metavision_hdf5_seeks_by_its_index() {
    let Some(dir) = data_dir() else { return };
    let path = dir.join("hdf5/ecf_small.hdf5");
    let all = io::read_all(&path, &ReadOptions::default()).unwrap().events;
    for start in [
        1_317_888, 1_319_950, 1_320_000, 1_321_234, 1_322_418, 1_400_000,
    ] {
        let mut reader = io::open(&path, &ReadOptions::default()).unwrap();
        reader.skip_to(start).unwrap();
        let mut got = Vec::new();
        let mut batch = ebiv::EventBuffer::new();
        while reader.read_batch(&mut batch).unwrap() {
            got.extend(batch.t.iter().copied());
        }
        let want: Vec<i64> = all.t.iter().copied().filter(|&t| t >= start).collect();
        assert_eq!(got, want, "from {start}");
    }
}
