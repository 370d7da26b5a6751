//! The operating-envelope study (`ebiv::assess::envelope`, `ebiv bench envelope`) on a few
//! cells: a cell sum of correlation measures well, a setting the library rejects, the
//! pooling over seeds, the report and the CSV, and stopping on request.

use ebiv::assess::envelope::{run_study, EnvelopeSpec, PassSchedule, RunSetting, Step};

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
