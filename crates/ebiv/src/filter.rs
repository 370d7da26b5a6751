//! Selection of events by time interval, region of interest and polarity.

use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry, PolaritySelection};

/// A rectangular region of interest in sensor pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Roi {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Roi {
    /// Parse `x,y,width,height`.
    pub fn parse(text: &str) -> Result<Roi> {
        let parts: Vec<Option<u32>> = text.split(',').map(|p| p.trim().parse().ok()).collect();
        match parts.as_slice() {
            [Some(x), Some(y), Some(w), Some(h)] if *w > 0 && *h > 0 => Ok(Roi {
                x: *x,
                y: *y,
                width: *w,
                height: *h,
            }),
            _ => Err(Error::parameter(
                "roi",
                format!("`{text}` is not x,y,width,height with positive width and height"),
            )),
        }
    }

    /// Check that the region lies on a sensor of `geometry`.
    pub fn check_within(&self, geometry: Geometry) -> Result<()> {
        if self.x as u64 + self.width as u64 > geometry.width as u64
            || self.y as u64 + self.height as u64 > geometry.height as u64
        {
            return Err(Error::parameter(
                "roi",
                format!(
                    "region {},{} {}x{} extends beyond the {geometry} sensor",
                    self.x, self.y, self.width, self.height
                ),
            ));
        }
        Ok(())
    }

    /// The geometry of the cropped sensor.
    pub fn geometry(&self) -> Geometry {
        Geometry::new(self.width, self.height)
    }
}

/// Which events to keep. Times are absolute µs; the interval is `[t_start, t_end)`.
#[derive(Debug, Clone, Copy, Default)]
pub struct EventFilter {
    /// First time kept (inclusive).
    pub t_start: Option<i64>,
    /// End of the kept interval (exclusive).
    pub t_end: Option<i64>,
    /// Region to keep; kept events are shifted so that the region's corner becomes (0, 0).
    pub roi: Option<Roi>,
    /// Polarities kept.
    pub polarity: PolaritySelection,
}

impl EventFilter {
    /// Whether an event at time `t` lies in the interval.
    #[inline]
    pub fn in_time(&self, t: i64) -> bool {
        self.t_start.is_none_or(|s| t >= s) && self.t_end.is_none_or(|e| t < e)
    }

    /// Keep the selected events of `batch` (and the triggers within the interval).
    pub fn apply(&self, batch: &mut EventBuffer) {
        let roi = self.roi;
        batch.retain(|e| {
            let inside = roi.is_none_or(|r| {
                (e.x as u32).wrapping_sub(r.x) < r.width
                    && (e.y as u32).wrapping_sub(r.y) < r.height
            });
            inside && self.in_time(e.t) && self.polarity.accepts(e.p)
        });
        if let Some(r) = roi {
            batch.x.iter_mut().for_each(|x| *x -= r.x as u16);
            batch.y.iter_mut().for_each(|y| *y -= r.y as u16);
        }
        batch.triggers.retain(|tr| self.in_time(tr.t));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_crops_shifts_and_selects() {
        let mut b = EventBuffer::new();
        for i in 0..20u16 {
            b.push(i as i64 * 10, i, i, (i % 2) as u8);
        }
        let f = EventFilter {
            t_start: Some(50),
            t_end: Some(150),
            roi: Some(Roi::parse("4,4,10,10").unwrap()),
            polarity: PolaritySelection::Positive,
        };
        f.apply(&mut b);
        assert_eq!(b.t, vec![50, 70, 90, 110, 130]);
        assert_eq!(b.x, vec![1, 3, 5, 7, 9]);
    }

    #[test]
    fn roi_parsing_and_bounds() {
        assert!(Roi::parse("1,2,3").is_err());
        assert!(Roi::parse("1,2,0,3").is_err());
        let r = Roi::parse("600,400,100,100").unwrap();
        assert!(r.check_within(Geometry::new(640, 480)).is_err());
        assert!(r.check_within(Geometry::new(700, 500)).is_ok());
    }
}
