//! Flow statistics of a synthetic random series with known moments, invalid vectors left
//! out, and the files written.

use ebiv::export::{statistics_dataset, write_statistics, Values};
use ebiv::field::{FieldSeries, Status, VectorField};
use ebiv::statistics::{flow_statistics, StatsOptions};

/// Standard normal numbers (Box–Muller over a 64-bit LCG), reproducible.
struct Normal(u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn next(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// 4000 fields on a 3 × 2 grid: u = 2 + 0.5 n1, v = −1 + 0.3 (0.6 n1 + 0.8 n2), so that
/// u'u' = 0.25, v'v' = 0.09, u'v' = 0.09; every tenth field's vectors invalid, with wild
/// values.
fn random_series() -> FieldSeries {
    let (x, y) = (vec![8.0, 24.0, 40.0], vec![8.0, 24.0]);
    let mut series = FieldSeries::on_grid(x.clone(), y.clone());
    let mut normal = Normal(42);
    for t in 0..4000 {
        let mut f = VectorField::new(x.clone(), y.clone());
        for i in 0..6 {
            let (n1, n2) = (normal.next(), normal.next());
            if t % 10 == 0 {
                f.u[i] = 1e6;
                f.v[i] = -1e6;
                f.status[i] = Status::MEDIAN_TEST;
            } else {
                f.u[i] = (2.0 + 0.5 * n1) as f32;
                f.v[i] = (-1.0 + 0.3 * (0.6 * n1 + 0.8 * n2)) as f32;
                f.status[i] = Status::VALID;
            }
        }
        series.push(t * 1000, &f).unwrap();
    }
    series
}

#[test]
fn a_random_series_gives_its_known_moments() {
    let st = flow_statistics(&random_series(), &StatsOptions::default()).unwrap();
    for i in 0..6 {
        assert_eq!(st.count[i], 3600, "every tenth vector left out");
        // Tolerances of about four standard errors for 3600 samples.
        assert!((st.u_mean[i] - 2.0).abs() < 0.035, "{}", st.u_mean[i]);
        assert!((st.v_mean[i] + 1.0).abs() < 0.021, "{}", st.v_mean[i]);
        assert!((st.uu[i] - 0.25).abs() < 0.025, "{}", st.uu[i]);
        assert!((st.vv[i] - 0.09).abs() < 0.009, "{}", st.vv[i]);
        assert!((st.uv[i] - 0.09).abs() < 0.012, "{}", st.uv[i]);
        assert!((st.u_rms()[i] - 0.5).abs() < 0.025);
    }
}

#[test]
fn statistics_files_hold_the_values() {
    let series = random_series();
    let st = flow_statistics(&series, &StatsOptions::default()).unwrap();
    let dataset = statistics_dataset(&st, &[]);
    let var = |name: &str| {
        dataset
            .variables
            .iter()
            .find(|v| v.name == name)
            .unwrap_or_else(|| panic!("{name}"))
    };
    assert_eq!(var("uv").values, Values::F64(st.uv.clone()));
    assert_eq!(var("count").dims, vec!["y", "x"]);
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("stats.csv");
    write_statistics(&st, &[], &csv).unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "x_px,y_px,u_mean_px_ms,v_mean_px_ms,u_rms_px_ms,v_rms_px_ms,uu_px_ms_sq,vv_px_ms_sq,uv_px_ms_sq,count"
    );
    let first: Vec<f64> = lines
        .next()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(first[2], st.u_mean[0]);
    assert_eq!(first[9], 3600.0);
    write_statistics(&st, &[], &dir.path().join("stats.nc")).unwrap();
    assert!(write_statistics(&st, &[], &dir.path().join("stats.vtk")).is_err());
}
