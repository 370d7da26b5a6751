//! Lone persistent pixels: pixels that fire through most of a slab while none of their 8
//! neighbours does. They are hot pixels (defects that fire at a high rate whatever the light
//! does; `docs/denoise.md`), not particle images, and are left out of the slab before the
//! estimators see it.
//!
//! Why the estimators need this: a hot pixel correlates with itself at zero lag in every
//! slice pair of sum of correlation, and piles its events up at zero velocity in motion
//! compensation. In a sparse window one or two of them outweigh the few particles, and the
//! window reports a confident vector at rest: passing every test of its own evidence,
//! because the evidence (a pixel active all through the slab) is real, only not flow. A
//! particle image, even a slow one, is never a single pixel: its edges span the 2–3 px of
//! its diameter, and a pixel fires only while the image moves across it, so pixels beside a
//! persistent one of a particle fire about as often. A hot pixel beside a passing particle
//! keeps its lone status, since the particle crosses the neighbours within a fraction of the
//! slab.
//!
//! The test scales with the slab: a hot pixel that fires too rarely to be persistent (fewer
//! than one event per sixteenth of the slab) also adds too few coincidences to make a peak.
//! Two hot pixels next to each other are not lone and stay (rare: one hot pixel in a
//! thousand makes 0.8 % of them have a hot neighbour).

use super::Slab;

/// Sub-intervals a slab is cut into to measure how persistently a pixel fires.
const SUB_INTERVALS: u32 = 16;

/// A pixel is persistent when it fires in at least this many sub-intervals (half of them).
const PERSISTENT: u32 = SUB_INTERVALS / 2;

/// A persistent pixel is lone when none of its 8 neighbours fires in more than this many
/// sub-intervals (a quarter of them): a particle crossing a neighbour in passing stays
/// below it, the neighbours of a slow particle's pixels do not.
const NEIGHBOUR_MAX: u32 = SUB_INTERVALS / 4;

impl Slab {
    /// Remove the events of lone persistent pixels (module documentation) and return how
    /// many were removed; the slab remembers the number ([`Slab::lone_pixel_events`]).
    /// O(events) plus one pass over a bitmap of the tiles' extent.
    pub fn drop_lone_pixels(&mut self) -> usize {
        let span = self.end_us - self.start_us;
        if self.t.is_empty() || span <= 0 {
            return 0;
        }
        let width = (self.tiles_x * self.tile) as usize;
        let height = (self.tiles_y * self.tile) as usize;
        // The sub-intervals each pixel fired in, a bit each; bit `LONE` marks lone pixels.
        const LONE: u32 = 1 << SUB_INTERVALS;
        let mut fired = vec![0u32; width * height];
        let sub_interval = |t: i64| {
            let k = (t - self.start_us).clamp(0, span - 1) as i128 * i128::from(SUB_INTERVALS)
                / i128::from(span);
            1u32 << k
        };
        for ((&x, &y), &t) in self.x.iter().zip(&self.y).zip(&self.t) {
            fired[y as usize * width + x as usize] |= sub_interval(t);
        }
        let count = |i: usize| fired[i].count_ones();
        let mut persistent: Vec<usize> = (self.x.iter().zip(&self.y))
            .map(|(&x, &y)| y as usize * width + x as usize)
            .filter(|&i| count(i) >= PERSISTENT)
            .collect();
        persistent.sort_unstable();
        persistent.dedup();
        let lone = |here: usize| {
            let (x, y) = (here % width, here / width);
            let rows = y.saturating_sub(1)..(y + 2).min(height);
            let cols = x.saturating_sub(1)..(x + 2).min(width);
            rows.flat_map(|r| cols.clone().map(move |c| r * width + c))
                .all(|i| i == here || count(i) <= NEIGHBOUR_MAX)
        };
        // Every lone pixel is found before any is marked, since marking changes the counts.
        let lone_pixels: Vec<usize> = persistent.into_iter().filter(|&i| lone(i)).collect();
        if lone_pixels.is_empty() {
            return 0;
        }
        for &i in &lone_pixels {
            fired[i] |= LONE;
        }
        let removed = self.retain(|x, y| fired[y as usize * width + x as usize] & LONE == 0);
        self.lone_pixel_events += removed;
        removed
    }

    /// Keep only the events whose pixel passes `keep`, tile by tile in their time order;
    /// return how many were removed.
    fn retain(&mut self, keep: impl Fn(u16, u16) -> bool) -> usize {
        let mut kept = 0;
        for k in 0..self.tile_start.len() - 1 {
            let (from, to) = (self.tile_start[k], self.tile_start[k + 1]);
            self.tile_start[k] = kept;
            for i in from..to {
                if keep(self.x[i], self.y[i]) {
                    self.x[kept] = self.x[i];
                    self.y[kept] = self.y[i];
                    self.t[kept] = self.t[i];
                    kept += 1;
                }
            }
        }
        let removed = self.t.len() - kept;
        *self.tile_start.last_mut().expect("a slab has tiles") = kept;
        self.x.truncate(kept);
        self.y.truncate(kept);
        self.t.truncate(kept);
        removed
    }
}

#[cfg(test)]
mod tests {
    use crate::event::{Geometry, PolaritySelection};
    use crate::volume::Slab;

    /// A slab of 10 ms over a 32 × 32 sensor from `(t, x, y)` events.
    fn slab(events: &[(i64, u16, u16)]) -> Slab {
        let mut sorted = events.to_vec();
        sorted.sort();
        let t: Vec<i64> = sorted.iter().map(|e| e.0).collect();
        let x: Vec<u16> = sorted.iter().map(|e| e.1).collect();
        let y: Vec<u16> = sorted.iter().map(|e| e.2).collect();
        let p = vec![1u8; t.len()];
        let geometry = Geometry::new(32, 32);
        Slab::build(
            &t,
            &x,
            &y,
            &p,
            geometry,
            0,
            10_000,
            PolaritySelection::Both,
            8,
        )
    }

    /// A pixel firing every `period` µs through the slab.
    fn firing(x: u16, y: u16, period: i64) -> Vec<(i64, u16, u16)> {
        (0..10_000 / period).map(|k| (k * period, x, y)).collect()
    }

    /// A particle image of 3 × 3 px crossing the sensor along row 20 at `speed` px/ms: each
    /// pixel of the image's rows fires every 100 µs while the image covers it.
    fn particle(speed: f64) -> Vec<(i64, u16, u16)> {
        let mut events = Vec::new();
        for t in (0..10_000).step_by(100) {
            let centre = 4.0 + speed * t as f64 / 1000.0;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    let x = (centre.round() as i64 + dx) as u16;
                    events.push((t, x, (20 + dy) as u16));
                }
            }
        }
        events
    }

    #[test]
    fn a_lone_hot_pixel_is_removed_and_counted() {
        let mut events = firing(5, 5, 400);
        events.extend(particle(2.0));
        let particle_events = events.len() - 25;
        let mut slab = slab(&events);
        assert_eq!(slab.drop_lone_pixels(), 25);
        assert_eq!(slab.len(), particle_events);
        assert_eq!(slab.lone_pixel_events(), 25);
        let mut left = Vec::new();
        let window = crate::grid::Window {
            x0: 0,
            y0: 0,
            width: 32,
            height: 32,
        };
        slab.visit(&window, 0, 10_000, 0, |x, y, _| left.push((x, y)));
        assert!(!left.contains(&(5, 5)));
        assert_eq!(left.len(), particle_events);
    }

    #[test]
    fn the_pixels_of_a_slow_particle_stay() {
        // 0.1 px/ms: the image stays on its pixels through the slab, every one persistent
        // but none lone.
        let events = particle(0.1);
        let mut slab = slab(&events);
        assert_eq!(slab.drop_lone_pixels(), 0);
        assert_eq!(slab.len(), events.len());
    }

    #[test]
    fn a_hot_pixel_beside_a_passing_particle_is_still_lone() {
        let mut events = firing(12, 21, 300);
        let hot = events.len();
        events.extend(particle(3.0).into_iter().filter(|e| (e.1, e.2) != (12, 21)));
        let mut slab = slab(&events);
        assert_eq!(slab.drop_lone_pixels(), hot);
    }

    #[test]
    fn a_rare_pixel_and_two_hot_neighbours_stay() {
        // Fires in 4 of 16 sub-intervals: not persistent.
        let mut events = firing(3, 3, 2_500);
        // Two adjacent hot pixels: neither is lone.
        events.extend(firing(20, 5, 300));
        events.extend(firing(21, 5, 300));
        let mut slab = slab(&events);
        assert_eq!(slab.drop_lone_pixels(), 0);
        assert_eq!(slab.len(), events.len());
    }

    #[test]
    fn pixels_on_the_sensor_edge_and_empty_slabs_are_handled() {
        let mut slab = slab(&firing(0, 31, 300));
        assert!(slab.drop_lone_pixels() > 0);
        assert!(slab.is_empty());
        assert_eq!(self::slab(&[]).drop_lone_pixels(), 0);
    }
}
