//! `ebiv bench piv`: multi-pass PIV of a synthetic image pair, timed.

use clap::Args;
use ebiv::piv::{piv_pair, PivParams};
use ebiv::sim::piv_images::{particle_image_pair, ParticleImageParams};
use std::time::Instant;

/// Settings of the PIV benchmark (defaults: the 1024×1024, 64/32/16 px, 50 % overlap case
/// the OpenPIV benchmarks time).
#[derive(Debug, Args)]
pub struct PivBenchArgs {
    /// Image width and height, px.
    #[arg(long, default_value_t = 1024)]
    pub size: u32,
    /// Window sizes of the passes, largest first.
    #[arg(long, value_delimiter = ',', default_value = "64,32,16")]
    pub passes: Vec<u32>,
    /// Overlap of neighbouring windows (0 ≤ overlap < 1).
    #[arg(long, default_value_t = 0.5)]
    pub overlap: f64,
    /// Repetitions of the last pass at most (default of `ebiv process --method piv`).
    #[arg(long)]
    pub iterations: Option<u32>,
    /// How many runs; the best is reported.
    #[arg(long, default_value_t = 5)]
    pub repeat: u32,
}

pub fn run(args: &PivBenchArgs) -> Result<(), ebiv::Error> {
    let image = ParticleImageParams {
        width: args.size,
        height: args.size,
        density: 0.05,
        diameter: 3.0,
        noise: 2.0,
        bits: 8,
        ..Default::default()
    };
    let shift = |x: f64, y: f64| {
        let s = args.size as f64;
        [3.0 + 2.0 * (y / s - 0.5), -1.5 + 1.5 * (x / s - 0.5)]
    };
    let (a, b) = particle_image_pair(&image, shift, 1);
    let mut params = PivParams {
        passes: PivParams::passes_with_overlap(&args.passes, args.overlap)?,
        ..PivParams::default()
    };
    if let Some(n) = args.iterations {
        params.last_pass_repeats = n;
    }
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..args.repeat.max(1) {
        let started = Instant::now();
        let out = piv_pair(&a, &b, &params)?;
        best = best.min(started.elapsed().as_secs_f64());
        last = Some(out);
    }
    let out = last.expect("at least one run");
    let evaluations: Vec<String> = out
        .passes
        .iter()
        .map(|p| format!("{}px x{}", p.window[0], p.iterations))
        .collect();
    println!(
        "piv {0}x{0} px, passes {1:?} overlap {2}: {3} vectors ({4:.1} % valid), best of {5}: {6:.3} s on {7} (pass evaluations: {8})",
        args.size,
        args.passes,
        args.overlap,
        out.field.len(),
        100.0 * out.field.valid_share(),
        args.repeat.max(1),
        best,
        super::worker_threads(),
        evaluations.join(", ")
    );
    Ok(())
}
