//! Unwrapping of 32-bit microsecond clocks (DAT, AEDAT 2.0), which wrap every 2^32 µs ≈ 71.6
//! min: a drop by more than 2^31 µs is taken as one wrap (faery's rule, formats.md §5).

/// Turns a stream of 32-bit time stamps into a monotonic-by-wraps `i64` clock.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Unwrap32 {
    last: Option<u32>,
    offset: i64,
}

impl Unwrap32 {
    /// The unwrapped time of the next raw stamp.
    #[inline]
    pub fn unwrap(&mut self, raw: u32) -> i64 {
        if let Some(last) = self.last {
            if last > raw && last - raw > 1 << 31 {
                self.offset += 1 << 32;
            }
        }
        self.last = Some(raw);
        raw as i64 + self.offset
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wraps_only_on_large_drops() {
        let mut u = Unwrap32::default();
        assert_eq!(u.unwrap(10), 10);
        assert_eq!(
            u.unwrap(5),
            5,
            "a small step back is a regression, not a wrap"
        );
        assert_eq!(u.unwrap(u32::MAX - 3), (u32::MAX - 3) as i64);
        assert_eq!(u.unwrap(2), (1i64 << 32) + 2);
    }
}
