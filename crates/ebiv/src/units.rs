//! Durations and times as users type them in options and configuration files: `10ms`,
//! `250us`, `1.5s`, `42` (a bare number is µs).

/// Parse a duration or time into whole microseconds. A bare number is microseconds; the
/// suffixes `us`/`µs`, `ms`, `s`, `min` are accepted, with an optional sign and decimals.
pub fn parse_us(text: &str) -> Result<i64, String> {
    let s = text.trim();
    let (number, scale) = if let Some(n) = s.strip_suffix("min") {
        (n, 60_000_000.0)
    } else if let Some(n) = s.strip_suffix("ms") {
        (n, 1_000.0)
    } else if let Some(n) = s.strip_suffix("us").or_else(|| s.strip_suffix("µs")) {
        (n, 1.0)
    } else if let Some(n) = s.strip_suffix('s') {
        (n, 1_000_000.0)
    } else {
        (s, 1.0)
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a time; write e.g. 10ms, 250us, 1.5s or 42 (µs)"))?;
    let us = value * scale;
    if !us.is_finite() || us.abs() > 9.0e18 {
        return Err(format!("`{text}` is out of range"));
    }
    Ok(us.round() as i64)
}

/// Parse `START:END` (either side may be empty: open-ended) into microseconds.
pub fn parse_range(text: &str) -> Result<(Option<i64>, Option<i64>), String> {
    let (a, b) = text
        .split_once(':')
        .ok_or_else(|| format!("`{text}` is not a range; write START:END, e.g. 10ms:20ms"))?;
    let side = |s: &str| -> Result<Option<i64>, String> {
        if s.trim().is_empty() {
            Ok(None)
        } else {
            parse_us(s).map(Some)
        }
    };
    let (start, end) = (side(a)?, side(b)?);
    if let (Some(s), Some(e)) = (start, end) {
        if e <= s {
            return Err(format!("in `{text}` the end is not after the start"));
        }
    }
    Ok((start, end))
}

/// Format microseconds for people: `12.345 ms`, `1.234567 s`.
pub fn format_us(us: i64) -> String {
    let a = us.unsigned_abs();
    if a >= 1_000_000 {
        format!("{:.6} s", us as f64 * 1e-6)
    } else if a >= 1_000 {
        format!("{:.3} ms", us as f64 * 1e-3)
    } else {
        format!("{us} µs")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units() {
        assert_eq!(parse_us("10ms"), Ok(10_000));
        assert_eq!(parse_us("250us"), Ok(250));
        assert_eq!(parse_us("250µs"), Ok(250));
        assert_eq!(parse_us("1.5s"), Ok(1_500_000));
        assert_eq!(parse_us("42"), Ok(42));
        assert_eq!(parse_us("-3ms"), Ok(-3000));
        assert!(parse_us("ten").is_err());
        assert!(parse_us("1e30s").is_err());
        assert_eq!(parse_range("10ms:20ms"), Ok((Some(10_000), Some(20_000))));
        assert_eq!(parse_range(":5ms"), Ok((None, Some(5000))));
        assert!(parse_range("5ms:1ms").is_err());
        assert!(parse_range("5ms").is_err());
    }
}

/// Serde helper: a duration field that accepts `"10ms"`-style strings or a number of µs.
pub mod serde_us {
    use serde::{Deserialize, Deserializer};

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Raw {
        Text(String),
        Number(f64),
    }

    /// Deserialize µs from `"10ms"`, `"1.5s"`, `250` (µs).
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<i64, D::Error> {
        match Raw::deserialize(d)? {
            Raw::Text(s) => super::parse_us(&s).map_err(serde::de::Error::custom),
            Raw::Number(n) if n.is_finite() && n.abs() < 9.0e18 => Ok(n.round() as i64),
            Raw::Number(n) => Err(serde::de::Error::custom(format!("{n} µs is out of range"))),
        }
    }
}
