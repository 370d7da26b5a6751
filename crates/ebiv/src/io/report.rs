//! Counters of what a reader dropped, skipped or found odd, so that no loss is silent.

/// What a reader could not turn into events, and why. Reported by `ebiv info`.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct DecodeReport {
    /// Events delivered.
    pub events: u64,
    /// Trigger edges delivered.
    pub triggers: u64,
    /// Events dropped because their pixel lies outside the sensor geometry.
    pub out_of_range: u64,
    /// Events dropped because they came before the first time base of the stream.
    pub before_time_base: u64,
    /// Places where a time stamp is smaller than the one before it (kept, not clamped).
    pub time_regressions: u64,
    /// Words or records of an unknown or unused type, skipped.
    pub unknown_words: u64,
    /// Malformed records (vectors without base, invalid flags, bad packets), skipped.
    pub malformed: u64,
    /// Records that are valid but not events (IMU, monitoring, frames), skipped.
    pub skipped_other: u64,
    /// Bytes at the end of the file that did not form a complete record.
    pub truncated_bytes: u64,
    /// Human-readable warnings, each naming the byte offset or record concerned.
    pub warnings: Vec<String>,
    /// What the denoising filters removed, when the reader denoises (`events` counts the
    /// events before them).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub denoise: Option<crate::denoise::DenoiseReport>,
}

/// At most this many warnings are kept; later ones are only counted.
const MAX_WARNINGS: usize = 50;

impl DecodeReport {
    /// Record a warning, keeping the list bounded.
    pub fn warn(&mut self, message: impl Into<String>) {
        if self.warnings.len() < MAX_WARNINGS {
            self.warnings.push(message.into());
        } else if self.warnings.len() == MAX_WARNINGS {
            self.warnings
                .push("further warnings suppressed; counters stay exact".into());
        }
    }

    /// Whether anything was dropped, skipped as invalid, or found out of order.
    pub fn has_problems(&self) -> bool {
        self.out_of_range
            + self.before_time_base
            + self.time_regressions
            + self.unknown_words
            + self.malformed
            + self.truncated_bytes
            > 0
            || !self.warnings.is_empty()
    }

    /// Add the format decoder's counters to the generic ones kept by the reader.
    pub(crate) fn merged_with(&self, inner: &DecodeReport) -> DecodeReport {
        let mut warnings = inner.warnings.clone();
        warnings.extend(self.warnings.iter().cloned());
        DecodeReport {
            events: self.events,
            triggers: self.triggers,
            out_of_range: inner.out_of_range + self.out_of_range,
            before_time_base: inner.before_time_base + self.before_time_base,
            time_regressions: inner.time_regressions + self.time_regressions,
            unknown_words: inner.unknown_words + self.unknown_words,
            malformed: inner.malformed + self.malformed,
            skipped_other: inner.skipped_other + self.skipped_other,
            truncated_bytes: inner.truncated_bytes + self.truncated_bytes,
            warnings,
            denoise: self.denoise.clone(),
        }
    }
}
