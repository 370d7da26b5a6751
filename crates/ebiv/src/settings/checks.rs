//! Range checks of single settings, run wherever a value is set; the caller adds the key to
//! the message. Checks of one setting against another are in [`super::resolve`].

use super::value::{Duration, PixelList, SlabLength};

type Check = Result<(), String>;

/// A setting's value, or the value inside a setting that may be unset.
pub trait Each<T> {
    fn each(&self) -> Option<&T>;
}

impl<T> Each<T> for T {
    fn each(&self) -> Option<&T> {
        Some(self)
    }
}

impl<T> Each<T> for Option<T> {
    fn each(&self) -> Option<&T> {
        self.as_ref()
    }
}

pub fn positive(v: &impl Each<f64>) -> Check {
    match v.each() {
        Some(&x) if !(x.is_finite() && x > 0.0) => {
            Err(format!("must be a positive number, got {x}"))
        }
        _ => Ok(()),
    }
}

pub fn above_one(v: &impl Each<f64>) -> Check {
    match v.each() {
        Some(&x) if !(x.is_finite() && x > 1.0) => {
            Err(format!("must be a number above 1, got {x}"))
        }
        _ => Ok(()),
    }
}

pub fn non_negative(v: &impl Each<f64>) -> Check {
    match v.each() {
        Some(&x) if !(x.is_finite() && x >= 0.0) => {
            Err(format!("must be zero or positive, got {x}"))
        }
        _ => Ok(()),
    }
}

pub fn positive_duration(v: &impl Each<Duration>) -> Check {
    match v.each() {
        Some(d) if d.0 <= 0 => Err(format!("{} µs: must be longer than 0", d.0)),
        Some(d) if d.0 > 3_600_000_000 => Err(format!("{} µs: must be at most an hour", d.0)),
        _ => Ok(()),
    }
}

pub fn positive_slab(v: &SlabLength) -> Check {
    match v {
        SlabLength::Fixed(d) => positive_duration(d),
        SlabLength::Auto => Ok(()),
    }
}

pub fn positive_pixels(v: &Option<PixelList>) -> Check {
    match v {
        Some(list) if list.0.contains(&0) => {
            let text = list.0.iter().map(u32::to_string).collect::<Vec<_>>();
            Err(format!(
                "`{}`: 0 px is not a size; every value must be at least 1 px",
                text.join(",")
            ))
        }
        _ => Ok(()),
    }
}

pub fn overlap_fraction(v: &f64) -> Check {
    if (0.0..1.0).contains(v) {
        Ok(())
    } else {
        Err(format!("must lie in [0, 1), got {v}"))
    }
}

pub fn at_least_one(v: &u32) -> Check {
    if *v >= 1 {
        Ok(())
    } else {
        Err("must be at least 1".into())
    }
}

pub fn at_least_one_if_given(v: &Option<u32>) -> Check {
    match v {
        Some(0) => Err("must be at least 1".into()),
        _ => Ok(()),
    }
}

pub fn at_least_one_px(v: &Option<u32>) -> Check {
    match v {
        Some(0) => Err("must be at least 1 px".into()),
        _ => Ok(()),
    }
}

pub fn at_most_twenty(v: &u32) -> Check {
    let most = crate::piv::MAX_FINAL_ITERATIONS;
    if *v <= most {
        Ok(())
    } else {
        Err(format!("{v}: at most {most} repetitions"))
    }
}

pub fn splat_sigma(v: &f64) -> Check {
    let most = crate::frame::events::MAX_SPLAT_SIGMA;
    if (0.0..=most).contains(v) {
        Ok(())
    } else {
        Err(format!(
            "σ = {v} px is out of range 0..={most} (0 = no splatting)"
        ))
    }
}

pub fn frame_pairs(v: &u32) -> Check {
    let most = crate::piv::events::MAX_PAIRS;
    if (1..=most).contains(v) {
        Ok(())
    } else {
        Err(format!("{v}: give 1 to {most} frame pairs per field"))
    }
}
