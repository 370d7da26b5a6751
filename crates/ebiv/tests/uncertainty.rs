//! Coverage of the per-vector standard uncertainty (`u_unc`, `v_unc`) against simulator
//! ground truth: the share of true errors within ±1σ and ±2σ, and the rank correlation
//! between |error| and σ, per estimator, pooled over uniform flows, seeding densities,
//! windows and seeds. Single pass, no predictor, the estimators' default settings.
//!
//! `coverage_sweep` (ignored: 15 s in release, minutes in debug) prints the table of `docs/uncertainty.md`:
//! `cargo test --release -p ebiv --test uncertainty -- --ignored --nocapture`.

use ebiv::estimate::corrsum::{CorrSumParams, SumOfCorrelation};
use ebiv::estimate::motion::{ContrastMaximization, MotionParams};
use ebiv::estimate::Estimator;
use ebiv::grid::{Grid, GridSpec};
use ebiv::process::{process_slab, ProcessParams};
use ebiv::volume::Slab;
use ebiv::PolaritySelection;

/// Pooled (error, σ) pairs of one estimator, both components, and the count of valid
/// components without a σ.
#[derive(Default)]
struct Pairs(Vec<(f64, f64)>, usize);

impl Pairs {
    fn coverage(&self, k: f64) -> f64 {
        let inside = self.0.iter().filter(|(e, s)| e.abs() <= k * s).count();
        inside as f64 / self.0.len().max(1) as f64
    }

    /// Spearman's rank correlation of |error| and σ (average ranks for ties).
    fn rank_correlation(&self) -> f64 {
        let ranks = |values: Vec<f64>| {
            let mut order: Vec<usize> = (0..values.len()).collect();
            order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
            let mut r = vec![0.0; values.len()];
            let mut i = 0;
            while i < order.len() {
                let mut j = i;
                while j + 1 < order.len() && values[order[j + 1]] == values[order[i]] {
                    j += 1;
                }
                for &k in &order[i..=j] {
                    r[k] = (i + j) as f64 / 2.0;
                }
                i = j + 1;
            }
            r
        };
        let a = ranks(self.0.iter().map(|p| p.0.abs()).collect());
        let b = ranks(self.0.iter().map(|p| p.1).collect());
        let n = a.len() as f64;
        let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
        let cov: f64 = a.iter().zip(&b).map(|(x, y)| (x - ma) * (y - mb)).sum();
        let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
        let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
        cov / (va * vb).sqrt()
    }

    /// How many times too large σ is, robustly: 0.674 (the median |e/σ| of normal errors
    /// with the right σ) over the median |e/σ|.
    fn scale(&self) -> f64 {
        let mut z: Vec<f64> = self.0.iter().map(|(e, s)| (e / s).abs()).collect();
        z.sort_by(f64::total_cmp);
        0.674 / z.get(z.len() / 2).copied().unwrap_or(f64::NAN)
    }

    fn describe(&self, name: &str) -> String {
        format!(
            "{name}: {} components ({} more without σ), within ±1σ {:.1} %, within ±2σ {:.1} %, rank correlation |e|–σ {:.2}, σ too large by {:.2}×",
            self.0.len(),
            self.1,
            100.0 * self.coverage(1.0),
            100.0 * self.coverage(2.0),
            self.rank_correlation(),
            self.scale()
        )
    }
}

/// A `size`² gen4 scene of a uniform flow `(u, v)` px/ms over 30 ms: the slab of the
/// positive events `t0 − before .. t0 + after` µs, and the simulation (for its truth).
fn simulated_slab(
    (u, v): (f64, f64),
    density: f64,
    size: u32,
    seed: u64,
    (t0, before, after): (i64, i64, i64),
) -> (Slab, ebiv::sim::simulation::Simulation) {
    let text = format!(
        "seed = {seed}\nduration = \"30ms\"\n[sensor]\nwidth = {size}\nheight = {size}\n\
         preset = \"gen4\"\n[flow]\ntype = \"uniform\"\nu = {u}\nv = {v}\n[particles]\n\
         density = {density}\ndiameter = 2.5\nbrightness = 20.0\n"
    );
    let scenario: ebiv::sim::scenario::Scenario = toml::from_str(&text).unwrap();
    let sim = scenario.simulation().unwrap();
    let events = sim.run(None, &|_| {}).unwrap().events;
    let mut columns = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for e in events.iter() {
        columns.0.push(e.t);
        columns.1.push(e.x);
        columns.2.push(e.y);
        columns.3.push(e.p);
    }
    let (t, x, y, p) = columns;
    let slab = Slab::build(
        &t,
        &x,
        &y,
        &p,
        sim.geometry,
        t0 - before,
        t0 + after,
        PolaritySelection::Positive,
        16,
    );
    (slab, sim)
}

/// Simulate a `size`² gen4 scene of a uniform flow and add the (error, σ) of every valid
/// vector of a single-pass field at 15 ms to `pairs`.
fn measure<E: Estimator>(
    est: &E,
    flow: (f64, f64),
    density: f64,
    (size, window): (u32, u32),
    seed: u64,
    pairs: &mut Pairs,
) {
    let t0 = 15_000;
    let (before, after) = est.time_extent_us();
    let (slab, sim) = simulated_slab(flow, density, size, seed, (t0, before, after));
    let grid = Grid::new(&GridSpec::square(window, window), sim.geometry).unwrap();
    let mut scratch = est.scratch([window, window]);
    for i in 0..grid.len() {
        let w = grid.window(i);
        let e = est.estimate(&slab, &w, t0, None, &mut scratch);
        if !e.status.is_valid() {
            assert!(
                e.u_unc.is_nan() && e.v_unc.is_nan(),
                "invalid vector with σ"
            );
            continue;
        }
        let [cx, cy] = w.centre();
        let truth = sim.flow.velocity(cx, cy, t0 as f64);
        for (error, sigma) in [(e.u - truth.0, e.u_unc), (e.v - truth.1, e.v_unc)] {
            if sigma.is_finite() && sigma >= 0.0 {
                pairs.0.push((error, f64::from(sigma)));
            } else {
                pairs.1 += 1;
            }
        }
    }
}

/// Default passes (64 then 40 px) with and without the uncertainty give the same vectors
/// bit for bit; with it, the valid vectors of the last pass carry a σ, without it none does.
#[test]
fn turning_the_uncertainty_off_changes_nothing_else() {
    let (corrsum, motion) = estimators();
    fn check<E: Estimator>(est: &E, slab: &Slab, geometry: ebiv::Geometry) {
        let with = ProcessParams {
            passes: vec![GridSpec::square(64, 32), GridSpec::square(40, 20)],
            ..ProcessParams::default()
        };
        let without = ProcessParams {
            uncertainty: false,
            ..with.clone()
        };
        let grids = with.grids(geometry).unwrap();
        let a = process_slab(est, slab, 15_000, &grids, &with).field;
        let b = process_slab(est, slab, 15_000, &grids, &without).field;
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.u), bits(&b.u), "{}", est.name());
        assert_eq!(bits(&a.v), bits(&b.v), "{}", est.name());
        assert_eq!(a.status, b.status, "{}", est.name());
        assert!(b.u_unc.iter().chain(&b.v_unc).all(|s| s.is_nan()));
        let valid = (0..a.len()).filter(|&i| a.status[i].is_valid()).count();
        let with_sigma = (0..a.len())
            .filter(|&i| a.status[i].is_valid() && a.u_unc[i].is_finite())
            .count();
        assert!(
            valid > 20 && with_sigma * 50 >= valid * 49,
            "{}: {with_sigma} of {valid}",
            est.name()
        );
    }
    let extent = corrsum.time_extent_us().0.max(motion.time_extent_us().0);
    let (slab, sim) = simulated_slab((1.5, 0.4), 0.008, 192, 3, (15_000, extent, extent));
    check(&corrsum, &slab, sim.geometry);
    check(&motion, &slab, sim.geometry);
}

fn estimators() -> (SumOfCorrelation, ContrastMaximization) {
    (
        SumOfCorrelation::new(CorrSumParams::default()).unwrap(),
        ContrastMaximization::new(MotionParams::default()).unwrap(),
    )
}

/// A small sweep (two flows, two densities, one seed): at most 2 % of the valid vectors
/// lack a σ, invalid ones carry none; σ follows the error (positive rank correlation); sum of
/// correlation's σ covers at least the nominal shares (it is conservative), motion
/// compensation's at least 80 % at ±2σ (measured shares printed; the targets 68 %/95 % are
/// not met by motion compensation, see `docs/uncertainty.md`).
#[test]
fn uncertainty_covers_the_true_errors_of_uniform_flows() {
    let (corrsum, motion) = estimators();
    let (mut c, mut m) = (Pairs::default(), Pairs::default());
    for flow in [(1.5, 0.2), (2.1666667, 0.8333333)] {
        for density in [0.003, 0.01] {
            measure(&corrsum, flow, density, (128, 32), 1, &mut c);
            measure(&motion, flow, density, (128, 32), 1, &mut m);
        }
    }
    println!("{}", c.describe("corrsum"));
    println!("{}", m.describe("motion"));
    assert!(c.0.len() > 100 && m.0.len() > 100);
    assert!(
        c.1 * 50 <= c.0.len() && m.1 * 50 <= m.0.len(),
        "σ missing on over 2 %"
    );
    assert!(c.coverage(1.0) >= 0.68 && c.coverage(2.0) >= 0.95);
    assert!(m.coverage(2.0) >= 0.8);
    assert!(c.rank_correlation() > 0.1 && m.rank_correlation() > 0.1);
}

/// The coverage table of `docs/uncertainty.md`: four uniform flows (0.7–4.1 px/ms), three
/// densities (0.002–0.015 particles/px), 32 and 48 px windows, two seeds, 256 × 256 px;
/// pooled, then per density.
#[test]
#[ignore = "validation sweep printing the docs table (15 s in release, minutes in debug): run with --release -- --ignored --nocapture"]
fn coverage_sweep() {
    let (corrsum, motion) = estimators();
    let (mut c, mut m) = (Pairs::default(), Pairs::default());
    let mut lines = Vec::new();
    for density in [0.002, 0.006, 0.015] {
        let (mut cd, mut md) = (Pairs::default(), Pairs::default());
        for flow in [(1.5, 0.2), (2.1666667, 0.8333333), (0.6, -0.3), (4.0, 1.0)] {
            for window in [32, 48] {
                for seed in [1, 2] {
                    measure(&corrsum, flow, density, (256, window), seed, &mut cd);
                    measure(&motion, flow, density, (256, window), seed, &mut md);
                }
            }
        }
        lines.push(cd.describe(&format!("corrsum at {density} particles/px")));
        lines.push(md.describe(&format!("motion at {density} particles/px")));
        c.0.extend(cd.0);
        c.1 += cd.1;
        m.0.extend(md.0);
        m.1 += md.1;
    }
    println!("{}", c.describe("corrsum"));
    println!("{}", m.describe("motion"));
    for line in lines {
        println!("{line}");
    }
}
