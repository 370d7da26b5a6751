//! Standard uncertainty of a PIV correlation peak (frames rebuilt from events, pulsed EBIV,
//! image pairs): the delete-a-block jackknife of [`crate::estimate::uncertainty`] on the
//! plane, after Wieneke's correlation statistics (Meas. Sci. Technol. 26:074002, 2015).
//!
//! Each pair's plane is `R(s) = Σₓ a(x)·b(x + s)` of the mean-free windows, normalised by
//! `√(Σa² Σb²)` and averaged over the pairs ([`super::correlate`]). Its values at the 3 × 3
//! lags around the peak are split into the contributions of the blocks of `x`, which add up
//! to them; the peak is fitted again as [`crate::peak::find_peak`] fits it with a tenth of
//! each block's contribution taken out (the infinitesimal jackknife).

use super::correlate::CorrelationKind;
use crate::estimate::uncertainty::{jackknife_sigma, Blocks};
use crate::peak::{fit_offsets, Peak, SubPixelFit};

/// Share of a block's contribution taken out.
const DELETED_SHARE: f64 = 0.1;

/// The mean-free windows `a`, `b` (`w × h`, row-major) of each frame pair.
pub(super) type WindowPair<'a> = (&'a [f32], &'a [f32]);

/// A function that hands every frame pair's windows to the function it is given.
pub(super) type EachPair<'a> = dyn FnMut(&mut dyn FnMut(WindowPair<'_>)) + 'a;

/// Standard uncertainty, px per axis, of the displacement at `peak` of the plane that
/// `pairs` give (shifted order: lag `(col − w/2, row − h/2)`), fitted with `fit`. NaN where
/// the peak lies on the plane's border. `each_pair` hands every pair's windows to the
/// closure it is given, so that they need not all be held at once.
pub(super) fn peak_sigma(
    [w, h]: [usize; 2],
    kind: CorrelationKind,
    peak: &Peak,
    fit: SubPixelFit,
    each_pair: &mut EachPair<'_>,
    contributions: &mut Vec<f64>,
) -> [f64; 2] {
    if peak.on_edge {
        return [f64::NAN; 2];
    }
    let blocks = Blocks::of(w, h);
    contributions.clear();
    contributions.resize(blocks.count() * 9, 0.0);
    let lags: [[i64; 2]; 9] = std::array::from_fn(|cell| {
        let (i, j) = ((cell / 3) as i64, (cell % 3) as i64);
        [
            peak.col as i64 - (w / 2) as i64 + j - 1,
            peak.row as i64 - (h / 2) as i64 + i - 1,
        ]
    });
    let (wi, hi) = (w as i64, h as i64);
    let mut pairs = 0usize;
    let mut add = |(a, b): WindowPair<'_>| {
        pairs += 1;
        let ea: f64 = a.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
        let eb: f64 = b.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
        if ea * eb <= 0.0 {
            return;
        }
        let norm = 1.0 / (ea * eb).sqrt();
        for y in 0..hi {
            for x in 0..wi {
                let va = f64::from(a[(y * wi + x) as usize]);
                if va == 0.0 {
                    continue;
                }
                let k = blocks.at(x as usize, y as usize);
                for (l, &[dx, dy]) in lags.iter().enumerate() {
                    let (mut qx, mut qy) = (x + dx, y + dy);
                    match kind {
                        CorrelationKind::Circular => {
                            qx = qx.rem_euclid(wi);
                            qy = qy.rem_euclid(hi);
                        }
                        CorrelationKind::Linear => {
                            if !(0..wi).contains(&qx) || !(0..hi).contains(&qy) {
                                continue;
                            }
                        }
                    }
                    let vb = f64::from(b[(qy * wi + qx) as usize]);
                    contributions[k * 9 + l] += norm * va * vb;
                }
            }
        }
    };
    each_pair(&mut add);
    if pairs == 0 {
        return [f64::NAN; 2];
    }
    let mut total = [0.0; 9];
    for k in 0..blocks.count() {
        for (t, c) in total.iter_mut().zip(&contributions[k * 9..(k + 1) * 9]) {
            *t += c;
        }
    }
    let grid = |v: &[f64; 9]| [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]];
    let estimates: Vec<[f64; 2]> = (0..blocks.count())
        .map(|k| {
            let part = &contributions[k * 9..(k + 1) * 9];
            let deleted: [f64; 9] = std::array::from_fn(|l| total[l] - DELETED_SHARE * part[l]);
            fit_offsets(grid(&deleted), fit).map(|d| d / DELETED_SHARE)
        })
        .collect();
    let weights: Vec<f64> = (0..blocks.count())
        .map(|k| contributions[k * 9 + 4])
        .collect();
    jackknife_sigma(&estimates, &weights)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two Gaussian particle images, each inside one block: moved by the same displacement
    /// they give next to no uncertainty; moved by displacements 0.4 px apart, one of the
    /// order of their disagreement.
    #[test]
    fn two_particles_that_disagree_give_an_uncertainty() {
        let (w, h) = (32usize, 32usize);
        let image = |shifts: &[([f64; 2], [f64; 2])], second: bool| {
            let mut v = vec![0f32; w * h];
            for &(p, d) in shifts {
                let c = if second {
                    [p[0] + d[0], p[1] + d[1]]
                } else {
                    p
                };
                for y in 0..h {
                    for x in 0..w {
                        let r2 = (x as f64 - c[0]).powi(2) + (y as f64 - c[1]).powi(2);
                        v[y * w + x] += (-r2 / 2.0).exp() as f32;
                    }
                }
            }
            let mean = v.iter().sum::<f32>() / v.len() as f32;
            v.iter().map(|x| x - mean).collect::<Vec<_>>()
        };
        let sigma = |shifts: &[([f64; 2], [f64; 2])]| {
            let (a, b) = (image(shifts, false), image(shifts, true));
            // The integer peak at the displacement (1, −1) from the centre (16, 16).
            let peak = Peak {
                col: 17,
                row: 15,
                x: 17.3,
                y: 15.4,
                value: 1.0,
                on_edge: false,
                second: f64::NAN,
            };
            let mut each = |f: &mut dyn FnMut(WindowPair<'_>)| f((&a, &b));
            let mut work = Vec::new();
            peak_sigma(
                [w, h],
                CorrelationKind::Circular,
                &peak,
                SubPixelFit::Gaussian3,
                &mut each,
                &mut work,
            )
        };
        let agree = sigma(&[([11.5, 11.5], [1.3, -0.6]), ([19.5, 27.5], [1.3, -0.6])]);
        let disagree = sigma(&[([11.5, 11.5], [1.1, -0.8]), ([19.5, 27.5], [1.5, -0.4])]);
        assert!(agree[0] < 0.02 && agree[1] < 0.02, "{agree:?}");
        for s in disagree {
            assert!(s > 0.05 && s < 0.6, "{disagree:?}");
        }
    }
}
