//! The operating-envelope study (`ebiv::assess::envelope`, `ebiv bench envelope`) on a few
//! cells: a cell sum of correlation measures well, a setting the library rejects, the
//! pooling over seeds, the report and the CSV, and stopping on request.

use ebiv::assess::envelope::{
    run_study, run_study_with_vectors, EnvelopeSpec, PassSchedule, RunSetting, Step, ValidVector,
};

/// Sum of correlation, 1 px/ms, 0.01 particles/px, 32 px windows, T = 10 ms, one pass, on
/// two seeds; and the same with a zero slab, which the settings layer rejects.
fn small_study() -> EnvelopeSpec {
    EnvelopeSpec {
        methods: vec!["corrsum".into()],
        speeds: vec![1.0],
        densities: vec![0.01],
        windows: vec![32],
        slabs: vec!["10ms".into(), "0ms".into()],
        passes: vec![PassSchedule::Single],
        seeds: vec![1, 2],
        size: 192,
    }
}

#[test]
fn a_small_study_measures_its_cells_and_reports_rejected_settings() {
    let spec = small_study();
    let mut steps = Vec::new();
    let results = run_study(&spec, &mut |step| {
        steps.push(step);
        Ok(())
    })
    .unwrap();
    // Two recordings, each processed by the one setting the library accepts.
    let simulated = steps
        .iter()
        .filter(|s| matches!(s, Step::Simulated { .. }))
        .count();
    assert_eq!(simulated, 2);
    assert_eq!(steps.last(), Some(&Step::Processed { done: 2, total: 2 }));
    assert_eq!(results.cells.len(), 2);

    let easy = RunSetting {
        method: "corrsum".into(),
        passes: PassSchedule::Single,
        window: 32,
        slab: "10ms".into(),
    };
    let cell = results
        .cell(1.0, 0.01, &easy)
        .expect("the cell is reported");
    let stats = cell.outcome.as_ref().expect("the setting runs");
    println!("corrsum, 1 px/ms, 0.01/px, W 32, T 10 ms, single pass: {stats:?}");
    // 192 px frame, 32 px windows on a 16 px step: 11 × 11 vectors per field, three fields
    // per recording, two recordings pooled.
    assert_eq!((stats.recordings, stats.fields), (2, 6));
    assert_eq!(stats.vectors, 6 * 11 * 11);
    assert!(stats.valid_share() >= 0.9, "{stats:?}");
    assert!(stats.rms < 0.05, "{stats:?}");
    assert!(stats.gross_share() < 0.01 && !cell.fails(), "{stats:?}");

    let rejected = RunSetting {
        slab: "0ms".into(),
        ..easy
    };
    let cell = results.cell(1.0, 0.01, &rejected).unwrap();
    let reason = cell.outcome.as_ref().expect_err("a zero slab is rejected");
    assert!(reason.contains("slab"), "{reason}");

    let report = results.markdown();
    println!("{report}");
    assert!(report.contains("| v px/ms | particles/px | W 32, T 10ms | W 32, T 0ms |"));
    assert!(report.contains("| 1 | 0.01 | "), "{report}");
    assert!(report.contains(" | n/a |"), "{report}");
    assert!(report.contains("n/a (W 32, T 0ms): "), "{report}");
    assert!(
        report.contains("cells failing: 0 of 1 measured (corrsum single 0), 1 n/a"),
        "{report}"
    );

    let csv = results.csv();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3, "{csv}");
    let header: Vec<&str> = lines[0].split(',').collect();
    let measured: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(measured.len(), header.len(), "{}", lines[1]);
    assert!(lines[1].starts_with("corrsum,single,32,10ms,1,0.01,2,6,726,"));
    let fails = header.iter().position(|&c| c == "fails").unwrap();
    assert_eq!(measured[fails], "false");
    assert!(lines[2].starts_with("corrsum,single,32,0ms,"));
    assert!(
        lines[2].ends_with('"') && lines[2].contains("slab"),
        "{}",
        lines[2]
    );
}

#[test]
fn an_error_from_the_progress_callback_stops_the_study() {
    let spec = EnvelopeSpec {
        slabs: vec!["10ms".into()],
        seeds: vec![1],
        densities: vec![0.002],
        size: 64,
        ..small_study()
    };
    let mut steps = 0;
    let result = run_study(&spec, &mut |_| {
        steps += 1;
        Err(ebiv::Error::parameter("study", "stopped"))
    });
    assert!(result.is_err());
    assert_eq!(steps, 1, "nothing runs after the callback's error");
}

/// One cell of sum of correlation, single pass, 32 px windows on a 128 px frame, seed 1,
/// with every valid vector handed to the test as well.
fn corrsum_cell(
    speed: f64,
    density: f64,
    slab: &str,
) -> (ebiv::assess::envelope::CellStats, Vec<ValidVector>) {
    let spec = EnvelopeSpec {
        methods: vec!["corrsum".into()],
        speeds: vec![speed],
        densities: vec![density],
        windows: vec![32],
        slabs: vec![slab.into()],
        passes: vec![PassSchedule::Single],
        seeds: vec![1],
        size: 128,
    };
    let mut vectors = Vec::new();
    let results =
        run_study_with_vectors(&spec, &mut |_| Ok(()), &mut |v| vectors.push(v.clone())).unwrap();
    let stats = *results.cells[0].outcome.as_ref().unwrap();
    println!("corrsum {speed} px/ms, {density}/px, W 32, T {slab}: {stats:?}");
    (stats, vectors)
}

/// A vector whose own evidence is weak is not valid: particles that move a small fraction of
/// a pixel over a 2 ms slab (0.02 and 0.05 px/ms, τ = 0.6 ms) leave a plane of chance
/// coincidences, whose peak was valid and wrong in every such window before sum of
/// correlation tested the evidence behind it (41 and 45 valid vectors, all gross, at
/// 0.05 particles/px).
#[test]
fn slow_flow_in_short_slabs_has_no_grossly_wrong_valid_vector() {
    for speed in [0.02, 0.05] {
        let (stats, _) = corrsum_cell(speed, 0.05, "2ms");
        assert_eq!(stats.gross, 0, "{speed} px/ms: {stats:?}");
    }
}

/// A displacement beyond the search radius (5 and 10 px/ms over τ = 3 ms: 15 and 30 px,
/// the radius of 32 px windows is 10 px) leaves only unrelated streaks in the plane; their
/// highest peak was valid and wrong in a third of the windows before.
#[test]
fn displacement_beyond_the_search_radius_gives_no_grossly_wrong_valid_vector() {
    for speed in [5.0, 10.0] {
        let (stats, _) = corrsum_cell(speed, 0.05, "10ms");
        assert_eq!(stats.gross, 0, "{speed} px/ms: {stats:?}");
    }
}

/// The evidence tests leave well-measured flows alone: at 1 and 2.5 px/ms, 0.01 and 0.05
/// particles/px, T = 10 ms, at least 98 % of the vectors are valid (all of them were before
/// the tests), none of them grossly wrong, and every valid vector rests on at least as many
/// events as the peak's evidence requires.
#[test]
fn well_measured_flows_keep_their_valid_vectors() {
    for speed in [1.0, 2.5] {
        for density in [0.01, 0.05] {
            let (stats, vectors) = corrsum_cell(speed, density, "10ms");
            assert!(stats.valid_share() >= 0.98, "{speed}, {density}: {stats:?}");
            assert_eq!(stats.gross, 0, "{speed}, {density}: {stats:?}");
            assert_eq!(vectors.len(), stats.valid);
            assert!(vectors.iter().all(|v| !v.gross && v.event_count >= 10));
        }
    }
}

#[test]
fn valid_vectors_are_written_as_csv_rows_with_their_cell_and_error() {
    let (stats, vectors) = corrsum_cell(1.0, 0.01, "10ms");
    assert_eq!(vectors.len(), stats.valid);
    let header: Vec<&str> = ValidVector::CSV_HEADER.trim_end().split(',').collect();
    let row = vectors[0].csv_row();
    let fields: Vec<&str> = row.trim_end().split(',').collect();
    assert_eq!(fields.len(), header.len(), "{row}");
    assert!(row.starts_with("corrsum,single,32,10ms,1,0.01,1,"), "{row}");
    let column = |name: &str| fields[header.iter().position(|&c| c == name).unwrap()];
    // The claimed displacement is |v|·τ, τ = 3 ms.
    let displacement: f64 = column("displacement_px").parse().unwrap();
    assert!((displacement - 3.0).abs() < 0.2, "{row}");
    assert_eq!(column("gross"), "false");
    let error: f64 = column("error_px_per_ms").parse().unwrap();
    assert!(error < 0.2, "{row}");
}
