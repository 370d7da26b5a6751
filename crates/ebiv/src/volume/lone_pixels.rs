//! Lone persistent pixels: pixels that fire through most of a slab while none of their 8
//! neighbours fires, in either polarity. They are hot pixels (defects that fire at a high
//! rate whatever the light does; `docs/denoise.md`), not particle images, and are left out
//! of the slab before the estimators see it.
//!
//! Why the estimators need this: a hot pixel correlates with itself at zero lag in every
//! slice pair of sum of correlation, and piles its events up at zero velocity in motion
//! compensation. In a sparse window one or two of them outweigh the few particles, and the
//! window reports a confident vector at rest: passing every test of its own evidence,
//! because the evidence (a pixel active all through the slab) is real, only not flow.
//!
//! Why a particle image never looks like one: a pixel fires only while the light on it
//! changes, and a moving image takes from one pixel the light it brings to the next, so a
//! pixel that keeps firing as an image moves over it has a neighbour that keeps firing in
//! the opposite polarity: the pixel the image leaves, even for an image smaller than a
//! pixel creeping along a row (whose ON events, with the default positive polarity, are
//! one pixel wide). The neighbours are therefore judged on the events of both polarities,
//! whatever polarity the slab keeps. The light moves on slowly at the edge of a slow image,
//! and the ON events of the pixel it enters come early in the crossing while the OFF events
//! of the pixel it leaves come late, so a neighbour firing in as few as three sub-intervals
//! makes a pixel not lone. A neighbour firing in one or two (noise events, a particle
//! passing) leaves it lone.
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
/// sub-intervals. The limit trades signal for hot pixels: a quarter of the sub-intervals
/// took about 5 % of the events of images of 1 px creeping at 0.05 px/ms for hot pixels,
/// two about 1 %, one about 0.2 %; but with one, a particle crossing a hot pixel's
/// neighbours in the 2.5 ms sub-intervals of a 40 ms adaptive slab keeps the hot pixel for
/// the whole slab. The tests `small_slow_particle_images_are_not_taken_for_hot_pixels` and
/// `lone_hot_pixels_make_no_valid_vectors_at_rest` (tests/denoise.rs) print both sides.
const NEIGHBOUR_MAX: u32 = 2;

/// Largest bounding box of a slab's events, in pixels, that [`Slab::drop_lone_pixels`] maps
/// (128 MB at 2 bytes per pixel; the largest event sensors have under 4 Mpx).
pub const MAX_MAP_PIXELS: usize = 1 << 26;

/// Pixel indices within the bounding box of a slab's events.
#[derive(Debug, Clone, Copy)]
struct PixelMap {
    x0: u16,
    y0: u16,
    width: usize,
    height: usize,
}

impl PixelMap {
    /// The bounding box of the pixels `xy`; `None` without any or when it holds more than
    /// [`MAX_MAP_PIXELS`].
    fn around(xy: impl Iterator<Item = (u16, u16)>) -> Option<PixelMap> {
        let (mut lo, mut hi) = ([u16::MAX; 2], [0u16; 2]);
        let mut any = false;
        for (x, y) in xy {
            any = true;
            lo = [lo[0].min(x), lo[1].min(y)];
            hi = [hi[0].max(x), hi[1].max(y)];
        }
        let width = usize::from(hi[0].checked_sub(lo[0])?) + 1;
        let height = usize::from(hi[1].checked_sub(lo[1])?) + 1;
        (any && width * height <= MAX_MAP_PIXELS).then_some(PixelMap {
            x0: lo[0],
            y0: lo[1],
            width,
            height,
        })
    }

    #[inline]
    fn index(&self, x: u16, y: u16) -> usize {
        usize::from(y - self.y0) * self.width + usize::from(x - self.x0)
    }
}

impl Slab {
    /// Remove the events of lone persistent pixels (module documentation) and return how
    /// many were removed; the slab remembers the number ([`Slab::lone_pixel_events`]).
    /// `(t, x, y)` are the events the slab was built from, of both polarities (the slab's
    /// time interval and the sensor are selected here).
    ///
    /// The sub-intervals cut the part of the slab the events cover: at a recording's ends,
    /// in a gap, and with the long slabs of adaptive runs a slab reaches past its events, and
    /// a hot pixel must not escape by firing through only the covered part. O(events), plus a
    /// map of 2 bytes per pixel of the events' bounding box; events spread over more than
    /// [`MAX_MAP_PIXELS`] (no sensor has so many pixels) are left as they are.
    pub fn drop_lone_pixels(&mut self, (t, x, y): (&[i64], &[u16], &[u16])) -> usize {
        if self.is_empty() {
            return 0;
        }
        let n = t.len().min(x.len()).min(y.len());
        let (range, _) = super::candidate_range(&t[..n], self.start_us, self.end_us);
        let inside = |&i: &usize| (self.start_us..self.end_us).contains(&t[i]);
        let events = || range.clone().filter(inside);
        let (Some(first), Some(last)) =
            (events().map(|i| t[i]).min(), events().map(|i| t[i]).max())
        else {
            return 0;
        };
        let span = last - first + 1;
        let Some(map) = PixelMap::around(events().map(|i| (x[i], y[i]))) else {
            return 0;
        };
        // The sub-intervals each pixel fired in, a bit each.
        let mut fired = vec![0u16; map.width * map.height];
        let sub_interval = |t: i64| {
            let k = (t - first) as i128 * i128::from(SUB_INTERVALS) / i128::from(span);
            1u16 << k
        };
        for i in events() {
            fired[map.index(x[i], y[i])] |= sub_interval(t[i]);
        }
        let count = |i: usize| fired[i].count_ones();
        let mut persistent: Vec<usize> = (self.x.iter().zip(&self.y))
            .map(|(&x, &y)| map.index(x, y))
            .filter(|&i| count(i) >= PERSISTENT)
            .collect();
        persistent.sort_unstable();
        persistent.dedup();
        // (Pixels beyond the bounding box hold no event: the neighbourhood is clipped to it.)
        let lone = |here: usize| {
            let (x, y) = (here % map.width, here / map.width);
            let rows = y.saturating_sub(1)..(y + 2).min(map.height);
            let cols = x.saturating_sub(1)..(x + 2).min(map.width);
            rows.flat_map(|r| cols.clone().map(move |c| r * map.width + c))
                .all(|i| i == here || count(i) <= NEIGHBOUR_MAX)
        };
        // Every lone pixel is found before any is marked, since marking changes the counts.
        let lone_pixels: Vec<usize> = persistent.into_iter().filter(|&i| lone(i)).collect();
        if lone_pixels.is_empty() {
            return 0;
        }
        // The map again, as marks: 1 for a lone pixel, 0 for every other of the slab.
        for (&x, &y) in self.x.iter().zip(&self.y) {
            fired[map.index(x, y)] = 0;
        }
        for &i in &lone_pixels {
            fired[i] = 1;
        }
        let removed = self.retain(|x, y| fired[map.index(x, y)] == 0);
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

    /// Events `(t, x, y, polarity)` as the columns a slab is built from.
    struct Source {
        t: Vec<i64>,
        x: Vec<u16>,
        y: Vec<u16>,
        p: Vec<u8>,
    }

    impl Source {
        fn new(events: &[(i64, u16, u16, u8)]) -> Source {
            let mut sorted = events.to_vec();
            sorted.sort();
            Source {
                t: sorted.iter().map(|e| e.0).collect(),
                x: sorted.iter().map(|e| e.1).collect(),
                y: sorted.iter().map(|e| e.2).collect(),
                p: sorted.iter().map(|e| e.3).collect(),
            }
        }

        /// The slab of `[start, end)` on a `size`² sensor with `polarity`, and what
        /// [`Slab::drop_lone_pixels`] removed from it.
        fn dropped(
            &self,
            size: u32,
            (start, end): (i64, i64),
            polarity: PolaritySelection,
        ) -> (Slab, usize) {
            let geometry = Geometry::new(size, size);
            let tile = if size > 1000 { 64 } else { 8 };
            let (t, x, y, p) = (&self.t, &self.x, &self.y, &self.p);
            let mut slab = Slab::build(t, x, y, p, geometry, start, end, polarity, tile);
            let removed = slab.drop_lone_pixels((t, x, y));
            (slab, removed)
        }
    }

    /// What is removed from a 10 ms slab of both polarities on a 32 × 32 sensor.
    fn dropped(events: &[(i64, u16, u16, u8)]) -> (Slab, usize) {
        Source::new(events).dropped(32, (0, 10_000), PolaritySelection::Both)
    }

    /// A pixel firing ON every `period` µs through the 10 ms.
    fn firing(x: u16, y: u16, period: i64) -> Vec<(i64, u16, u16, u8)> {
        (0..10_000 / period)
            .map(|k| (k * period, x, y, 1))
            .collect()
    }

    /// A particle image of 3 × 3 px crossing the sensor along row 20 at `speed` px/ms: each
    /// pixel of the image's rows fires every 100 µs while the image covers it.
    fn particle(speed: f64) -> Vec<(i64, u16, u16, u8)> {
        let mut events = Vec::new();
        for t in (0..10_000).step_by(100) {
            let centre = 4.0 + speed * t as f64 / 1000.0;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    let x = (centre.round() as i64 + dx) as u16;
                    events.push((t, x, (20 + dy) as u16, 1));
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
        let (slab, removed) = dropped(&events);
        assert_eq!(removed, 25);
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
        let (slab, removed) = dropped(&events);
        assert_eq!(removed, 0);
        assert_eq!(slab.len(), events.len());
    }

    #[test]
    fn a_small_slow_image_stays_with_positive_events_only() {
        // An image smaller than a pixel creeping along row 9: the pixel it enters fires ON,
        // the one it leaves fires OFF, both all through the slab. The slab keeps the ON
        // events, one pixel wide; the OFF neighbour shows they are not a hot pixel's.
        let mut events = Vec::new();
        for k in 0..40 {
            events.push((k * 250, 10, 9, 1));
            events.push((k * 250 + 100, 9, 9, 0));
        }
        let source = Source::new(&events);
        let (slab, removed) = source.dropped(32, (0, 10_000), PolaritySelection::Positive);
        assert_eq!(removed, 0);
        assert_eq!(slab.len(), 40);
        // Without the OFF events, the ON pixel is lone.
        let on: Vec<_> = events.into_iter().filter(|e| e.3 == 1).collect();
        let (_, removed) = Source::new(&on).dropped(32, (0, 10_000), PolaritySelection::Positive);
        assert_eq!(removed, 40);
    }

    #[test]
    fn a_hot_pixel_beside_a_fast_particle_is_still_lone() {
        // At 20 px/ms the image covers the hot pixel's neighbours from 300 to 500 µs, within
        // the first sub-interval of 625 µs.
        let mut events = firing(12, 21, 300);
        let hot = events.len();
        events.extend(
            particle(20.0)
                .into_iter()
                .filter(|e| (e.1, e.2) != (12, 21)),
        );
        assert_eq!(dropped(&events).1, hot);
        // At 1 px/ms it covers them for three milliseconds: in that slab the pixel is kept.
        let mut events = firing(12, 21, 300);
        events.extend(particle(1.0).into_iter().filter(|e| (e.1, e.2) != (12, 21)));
        assert_eq!(dropped(&events).1, 0);
    }

    #[test]
    fn a_rare_pixel_and_two_hot_neighbours_stay() {
        // Fires in 4 of 16 sub-intervals: not persistent.
        let mut events = firing(3, 3, 2_500);
        // Two adjacent hot pixels: neither is lone.
        events.extend(firing(20, 5, 300));
        events.extend(firing(21, 5, 300));
        let (slab, removed) = dropped(&events);
        assert_eq!(removed, 0);
        assert_eq!(slab.len(), events.len());
    }

    #[test]
    fn a_slab_reaching_past_its_events_is_cut_over_the_events() {
        // The hot pixel fires through the 10 ms of events of a slab of 200 ms (an adaptive
        // run's longest slab around a field near the recording's start).
        let mut events = firing(5, 5, 400);
        events.extend(particle(2.0));
        let source = Source::new(&events);
        let (_, removed) = source.dropped(32, (-100_000, 100_000), PolaritySelection::Both);
        assert_eq!(removed, 25);
    }

    #[test]
    fn events_spread_over_a_huge_sensor_are_left_alone() {
        // Two pixels 65 534 px apart: a bounding box of 4.3 G pixels is not mapped.
        let far: Vec<_> = (0..50)
            .map(|k| {
                (
                    k / 2 * 400,
                    (k % 2) as u16 * 65_534,
                    (k % 2) as u16 * 65_534,
                    1,
                )
            })
            .collect();
        let (slab, removed) =
            Source::new(&far).dropped(65_535, (0, 10_000), PolaritySelection::Both);
        assert_eq!(removed, 0);
        assert_eq!(slab.len(), 50);
        // The same two pixels closer together are both lone hot pixels.
        let near: Vec<_> = far
            .iter()
            .map(|e| (e.0, e.1.min(100), e.2.min(100), 1))
            .collect();
        let (_, removed) = Source::new(&near).dropped(65_535, (0, 10_000), PolaritySelection::Both);
        assert_eq!(removed, 50);
    }

    #[test]
    fn pixels_on_the_sensor_edge_and_empty_slabs_are_handled() {
        let (slab, removed) = dropped(&firing(0, 31, 300));
        assert!(removed > 0);
        assert!(slab.is_empty());
        assert_eq!(dropped(&[]).1, 0);
    }
}
