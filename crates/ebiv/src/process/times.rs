//! Which field times to evaluate: `START:END:STEP` with END inclusive, or every field that
//! fits in the recording.

use crate::error::{Error, Result};

/// Field centre times `START:END:STEP`, END inclusive; START or END may be left out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FieldTimes {
    /// First field time, µs (relative to the first event unless `absolute-time`).
    pub start: Option<i64>,
    /// Last field time (inclusive), µs.
    pub end: Option<i64>,
    /// Interval between fields, µs.
    pub step: i64,
}

/// Field centre times `start, start + step, …, ≤ end` (µs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TimeSteps {
    /// First field's centre time, µs.
    pub start: i64,
    /// Last field's centre time (inclusive), µs.
    pub end: i64,
    /// Interval between fields, µs.
    pub step: i64,
}

impl TimeSteps {
    /// Parse `START:END:STEP` with units (`60ms:80ms:1ms`; bare numbers are µs). `START`
    /// and `END` may be empty (`:100ms:5ms`), to be filled from the recording.
    pub fn parse(text: &str) -> Result<(Option<i64>, Option<i64>, i64)> {
        let bad = |m: String| Error::parameter("time", m);
        let parts: Vec<&str> = text.split(':').collect();
        if parts.len() != 3 {
            return Err(bad(format!(
                "expected START:END:STEP (e.g. 10ms:90ms:5ms), got `{text}`"
            )));
        }
        let value = |s: &str| -> Result<Option<i64>> {
            let s = s.trim();
            if s.is_empty() {
                return Ok(None);
            }
            crate::units::parse_us(s).map(Some).map_err(bad)
        };
        let step = value(parts[2])?.ok_or_else(|| bad("STEP is required".into()))?;
        if step <= 0 {
            return Err(bad(format!("STEP must be positive, got `{}`", parts[2])));
        }
        Ok((value(parts[0])?, value(parts[1])?, step))
    }

    /// Every field of interval `step` whose events `[t0 − before, t0 + after)` lie within
    /// the recording `[first_us, last_us]`, the first as early as possible.
    pub fn fitting(
        first_us: i64,
        last_us: i64,
        before: i64,
        after: i64,
        step: i64,
    ) -> Option<Self> {
        let start = first_us.checked_add(before)?;
        let end = last_us.checked_add(1)?.checked_sub(after)?;
        (end >= start && step > 0).then_some(TimeSteps { start, end, step })
    }

    /// The times themselves, at most `limit` of them (an error beyond, naming the count).
    pub fn times(&self, limit: usize) -> Result<Vec<i64>> {
        if self.step <= 0 || self.end < self.start {
            return Err(Error::parameter(
                "time",
                format!(
                    "no field time in {}..{} µs with step {} µs",
                    self.start, self.end, self.step
                ),
            ));
        }
        // (In i128: the span of two extreme times overflows i64.)
        let count = (self.end as i128 - self.start as i128) / self.step as i128 + 1;
        if count > limit as i128 {
            return Err(Error::parameter(
                "time",
                format!("{count} field times requested, more than the limit of {limit}"),
            ));
        }
        // (Within start..=end, so within i64.)
        Ok((0..count as i64)
            .map(|i| self.start + i * self.step)
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn end_is_inclusive() {
        let (s, e, step) = TimeSteps::parse("60ms:60ms:1ms").unwrap();
        let t = TimeSteps {
            start: s.unwrap(),
            end: e.unwrap(),
            step,
        };
        assert_eq!(t.times(10).unwrap(), vec![60_000]);
        let t = TimeSteps {
            start: 0,
            end: 10,
            step: 5,
        };
        assert_eq!(t.times(10).unwrap(), vec![0, 5, 10]);
        assert!(t.times(2).is_err());
        let extreme = TimeSteps {
            start: i64::MIN + 5,
            end: i64::MAX - 5,
            step: 1_000_000_000_000,
        };
        let err = extreme.times(MAX_TEST_FIELDS).unwrap_err().to_string();
        assert!(err.contains("more than the limit"), "{err}");
    }

    const MAX_TEST_FIELDS: usize = 1000;

    #[test]
    fn parse_rejects_nonsense() {
        assert!(TimeSteps::parse("1ms:2ms").is_err());
        assert!(TimeSteps::parse("1ms:2ms:0").is_err());
        assert!(TimeSteps::parse("1ms:2ms:-1ms").is_err());
        assert!(TimeSteps::parse("a:2ms:1ms").is_err());
        assert_eq!(
            TimeSteps::parse(":5ms:1ms").unwrap(),
            (None, Some(5000), 1000)
        );
    }

    #[test]
    fn fitting_fields_lie_inside_the_recording() {
        let t = TimeSteps::fitting(1000, 30_999, 5000, 5000, 10_000).unwrap();
        assert_eq!(t.times(100).unwrap(), vec![6000, 16_000, 26_000]);
        assert!(TimeSteps::fitting(0, 5000, 5000, 5000, 1000).is_none());
    }
}
