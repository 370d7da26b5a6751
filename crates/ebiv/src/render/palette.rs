//! A 256-colour palette shared by all frames of an animation, by median cut (Heckbert,
//! "Color image quantization for frame buffer display", SIGGRAPH 1982) over a histogram of
//! colours quantised to 5 bits per channel.

use image::RgbImage;
use rayon::prelude::*;

/// Cells of the 5-bit-per-channel colour histogram.
const CELLS: usize = 32 * 32 * 32;

/// Histogram cell of an RGB colour.
#[inline]
pub fn cell(c: [u8; 3]) -> usize {
    ((c[0] as usize >> 3) << 10) | ((c[1] as usize >> 3) << 5) | (c[2] as usize >> 3)
}

/// Per-cell pixel counts and channel sums.
struct ColourHistogram {
    count: Vec<u64>,
    sum: Vec<[u64; 3]>,
}

impl ColourHistogram {
    fn new() -> Self {
        ColourHistogram {
            count: vec![0; CELLS],
            sum: vec![[0; 3]; CELLS],
        }
    }

    fn add(mut self, img: &RgbImage) -> Self {
        for p in img.pixels() {
            let i = cell(p.0);
            self.count[i] += 1;
            for k in 0..3 {
                self.sum[i][k] += p.0[k] as u64;
            }
        }
        self
    }

    fn merge(mut self, other: Self) -> Self {
        for i in 0..CELLS {
            self.count[i] += other.count[i];
            for k in 0..3 {
                self.sum[i][k] += other.sum[i][k];
            }
        }
        self
    }

    /// Mean 8-bit colour of the pixels in `cells`.
    fn mean(&self, cells: &[u16]) -> [u8; 3] {
        let n: u64 = cells.iter().map(|&c| self.count[c as usize]).sum();
        std::array::from_fn(|k| {
            let s: u64 = cells.iter().map(|&c| self.sum[c as usize][k]).sum();
            (s as f64 / n.max(1) as f64).round() as u8
        })
    }
}

/// Channel `k` (0 red, 1 green, 2 blue) of a cell, 0–31.
fn channel(c: u16, k: usize) -> u16 {
    (c >> (10 - 5 * k)) & 31
}

/// A palette of at most 256 colours for `frames` and the palette index of every histogram
/// cell (see [`cell`]). Colours that are few enough keep their exact values.
pub fn median_cut(frames: &[RgbImage]) -> (Vec<[u8; 3]>, Vec<u8>) {
    let hist = frames
        .par_iter()
        .fold(ColourHistogram::new, ColourHistogram::add)
        .reduce(ColourHistogram::new, ColourHistogram::merge);
    let occupied: Vec<u16> = (0..CELLS as u16)
        .filter(|&c| hist.count[c as usize] > 0)
        .collect();
    let mut boxes = vec![occupied];
    while boxes.len() < 256 {
        // Split the box with the largest population × longest side.
        let extent = |b: &[u16]| {
            (0..3)
                .map(|k| {
                    let (lo, hi) = b.iter().fold((31, 0), |(lo, hi), &c| {
                        (channel(c, k).min(lo), channel(c, k).max(hi))
                    });
                    (hi.saturating_sub(lo), k)
                })
                .max()
                .unwrap_or((0, 0))
        };
        let priority = |b: &Vec<u16>| {
            let n: u64 = b.iter().map(|&c| hist.count[c as usize]).sum();
            n * extent(b).0 as u64
        };
        let Some((i, _)) = boxes
            .iter()
            .enumerate()
            .filter(|(_, b)| b.len() > 1)
            .max_by_key(|(_, b)| priority(b))
        else {
            break;
        };
        let mut b = boxes.swap_remove(i);
        let axis = extent(&b).1;
        b.sort_unstable_by_key(|&c| channel(c, axis));
        let total: u64 = b.iter().map(|&c| hist.count[c as usize]).sum();
        let mut acc = 0;
        let mut split = b.len() - 1;
        for (j, &c) in b.iter().enumerate() {
            acc += hist.count[c as usize];
            if 2 * acc >= total {
                split = j + 1;
                break;
            }
        }
        let rest = b.split_off(split.clamp(1, b.len() - 1));
        boxes.push(b);
        boxes.push(rest);
    }
    let mut lut = vec![0u8; CELLS];
    let palette = boxes
        .iter()
        .enumerate()
        .map(|(j, b)| {
            for &c in b {
                lut[c as usize] = j as u8;
            }
            hist.mean(b)
        })
        .collect();
    (palette, lut)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn few_colours_are_kept_exactly_many_are_approximated() {
        let colours = [[0, 0, 0], [255, 255, 255], [235, 40, 40], [0, 225, 255]];
        let img = RgbImage::from_fn(8, 8, |x, _| colours[x as usize % 4].into());
        let (pal, lut) = median_cut(&[img]);
        assert_eq!(pal.len(), 4);
        for c in colours {
            assert_eq!(pal[lut[cell(c)] as usize], c);
        }
        let ramp = RgbImage::from_fn(256, 256, |x, y| [x as u8, y as u8, (x ^ y) as u8].into());
        let (pal, lut) = median_cut(std::slice::from_ref(&ramp));
        assert_eq!(pal.len(), 256);
        let worst = ramp
            .pixels()
            .map(|p| {
                let q = pal[lut[cell(p.0)] as usize];
                (0..3).map(|k| p.0[k].abs_diff(q[k])).max().unwrap()
            })
            .max()
            .unwrap();
        assert!(worst < 48, "worst channel error {worst}");
        let (pal, _) = median_cut(&[]);
        assert!(pal.len() <= 1);
    }
}
