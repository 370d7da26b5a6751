//! How one setting's value is read from a command-line flag or a TOML value, and written
//! back: the types a [`super::ProcessSettings`] field may have.
//!
//! TOML values are the common currency: a flag's text, a configuration file's value and
//! (later) a Python keyword argument all become one, so every front end accepts the same
//! spellings (`slab = "10ms"` and `--slab 10ms`; `window = [64, 40]` and `--window 64,40`).

use crate::derived::DerivedList;
use crate::estimate::corrsum::{CorrKernel, Weighting};
use crate::estimate::motion::{Objective, SearchMethod};
use crate::event::PolaritySelection;
use crate::filter::Roi;
use crate::frame::events::FrameKind;
use crate::peak::SubPixelFit;
use crate::piv::{CorrelationKind, DeformationMode, Interpolation};
use crate::process::{FieldTimes, Method, TimeSteps};
use std::path::PathBuf;
use toml::Value;

/// How a setting appears on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A switch without a value: `--replace` (default off) or `--no-deform` (default on).
    Switch,
    /// One value: `--slab 10ms`.
    Value,
    /// One or more values: `--images a.png b.png`.
    Values,
}

/// A type a setting may have.
pub trait SettingValue: Sized {
    /// How the flag takes its value.
    const KIND: Kind = Kind::Value;

    /// Read the value from a flag's text.
    fn from_text(text: &str) -> Result<Self, String>;

    /// Read the value from a TOML value (a configuration file, or a converted flag).
    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::String(s) => Self::from_text(s),
            Value::Integer(_) | Value::Float(_) | Value::Boolean(_) => {
                Self::from_text(&value.to_string())
            }
            other => Err(format!("expected one value, got `{other}`")),
        }
    }

    /// Read the value from several flag texts (`Kind::Values`); one text otherwise.
    fn from_texts(texts: &[String]) -> Result<Self, String> {
        match texts {
            [one] => Self::from_text(one),
            _ => Err(format!("expected one value, got {}", texts.len())),
        }
    }

    /// The value as TOML, for templates and output attributes; `None` when unset.
    fn to_toml(&self) -> Option<Value>;
}

impl SettingValue for bool {
    const KIND: Kind = Kind::Switch;

    fn from_text(text: &str) -> Result<Self, String> {
        match text.trim() {
            "true" | "yes" | "on" => Ok(true),
            "false" | "no" | "off" => Ok(false),
            _ => Err(format!("`{text}` is not true or false")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::Boolean(*self))
    }
}

impl SettingValue for u32 {
    fn from_text(text: &str) -> Result<Self, String> {
        text.trim()
            .parse()
            .map_err(|_| format!("`{text}` is not a whole number ≥ 0"))
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::Integer(i64::from(*self)))
    }
}

impl SettingValue for f64 {
    fn from_text(text: &str) -> Result<Self, String> {
        match text.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("`{text}` is not a finite number")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::Float(*self))
    }
}

impl SettingValue for PathBuf {
    fn from_text(text: &str) -> Result<Self, String> {
        if text.is_empty() {
            return Err("the path is empty".into());
        }
        Ok(PathBuf::from(text))
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::String(self.display().to_string()))
    }
}

impl<T: SettingValue> SettingValue for Option<T> {
    const KIND: Kind = T::KIND;

    fn from_text(text: &str) -> Result<Self, String> {
        T::from_text(text).map(Some)
    }

    fn from_toml(value: &Value) -> Result<Self, String> {
        T::from_toml(value).map(Some)
    }

    fn from_texts(texts: &[String]) -> Result<Self, String> {
        T::from_texts(texts).map(Some)
    }

    fn to_toml(&self) -> Option<Value> {
        self.as_ref().and_then(T::to_toml)
    }
}

/// A duration in whole µs, written with units: `"10ms"`, `"250us"`, `"1.5s"`, or a number of
/// µs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Duration(pub i64);

impl Duration {
    /// Whole milliseconds.
    pub const fn ms(ms: i64) -> Self {
        Duration(ms * 1000)
    }

    /// The shortest exact text with units: `10ms`, `2s`, `250us`.
    pub fn text(self) -> String {
        match self.0 {
            0 => "0us".into(),
            us if us % 1_000_000 == 0 => format!("{}s", us / 1_000_000),
            us if us % 1000 == 0 => format!("{}ms", us / 1000),
            us => format!("{us}us"),
        }
    }
}

impl SettingValue for Duration {
    fn from_text(text: &str) -> Result<Self, String> {
        crate::units::parse_us(text).map(Duration)
    }

    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::Integer(us) => Ok(Duration(*us)),
            Value::Float(us) if us.is_finite() && us.abs() < 9.0e18 => {
                Ok(Duration(us.round() as i64))
            }
            Value::String(s) => Self::from_text(s),
            other => Err(format!(
                "`{other}` is not a duration; write e.g. \"10ms\", \"250us\" or \"1.5s\""
            )),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::String(self.text()))
    }
}

/// The time slab of the event methods: one duration for every window, or `auto`, a slab
/// per window chosen from its velocity ([`crate::estimate::adaptive`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlabLength {
    /// The same slab everywhere.
    Fixed(Duration),
    /// A slab per window.
    Auto,
}

impl SlabLength {
    /// The fixed slab, or `auto_first` (the first pass's slab of `auto`), µs.
    pub fn first_pass_us(self, auto_first: Duration) -> i64 {
        match self {
            SlabLength::Fixed(d) => d.0,
            SlabLength::Auto => auto_first.0,
        }
    }
}

impl SettingValue for SlabLength {
    fn from_text(text: &str) -> Result<Self, String> {
        if text.trim() == "auto" {
            return Ok(SlabLength::Auto);
        }
        Duration::from_text(text)
            .map(SlabLength::Fixed)
            .map_err(|e| format!("{e}; or `auto` for a slab per window"))
    }

    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::String(s) => Self::from_text(s),
            other => Duration::from_toml(other)
                .map(SlabLength::Fixed)
                .map_err(|e| format!("{e}, or \"auto\"")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        match self {
            SlabLength::Fixed(d) => d.to_toml(),
            SlabLength::Auto => Some(Value::String("auto".into())),
        }
    }
}

/// Window sizes or steps in px, one per pass: `40`, `64,40` or `[64, 40]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PixelList(pub Vec<u32>);

impl SettingValue for PixelList {
    fn from_text(text: &str) -> Result<Self, String> {
        let values: Result<Vec<u32>, _> = text.split(',').map(|s| s.trim().parse()).collect();
        let negative = text
            .split(',')
            .any(|s| s.trim().parse::<i64>().is_ok_and(|v| v < 0));
        match values {
            Ok(v) if !v.is_empty() => Ok(PixelList(v)),
            _ if negative => Err(format!(
                "`{text}`: sizes in px cannot be negative; give positive pixel counts (e.g. 64,40)"
            )),
            _ => Err(format!(
                "`{text}` is not a pixel count or a comma-separated list of them (e.g. 64,40)"
            )),
        }
    }

    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::Array(items) if !items.is_empty() => items
                .iter()
                .map(|v| match v {
                    Value::Integer(i) if *i < 0 => Err(format!("{i} (negative)")),
                    Value::Integer(i) => u32::try_from(*i).map_err(|_| format!("{i} px")),
                    other => Err(format!("`{other}`")),
                })
                .collect::<Result<Vec<u32>, String>>()
                .map(PixelList)
                .map_err(|e| format!("{e} is not a pixel count")),
            Value::Array(_) => Err("the list is empty".into()),
            Value::Integer(i) if *i < 0 => Err(format!(
                "{i}: sizes in px cannot be negative; give a positive pixel count"
            )),
            Value::Integer(i) => u32::try_from(*i)
                .map(|v| PixelList(vec![v]))
                .map_err(|_| format!("{i} is not a pixel count")),
            Value::String(s) => Self::from_text(s),
            other => Err(format!("`{other}` is not a pixel count or a list of them")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::Array(
            self.0.iter().map(|&v| Value::Integer(v.into())).collect(),
        ))
    }
}

/// Text values given one or more times: `--images a.png b.png`, `images = ["a.png"]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TextList(pub Vec<String>);

impl SettingValue for TextList {
    const KIND: Kind = Kind::Values;

    fn from_text(text: &str) -> Result<Self, String> {
        Ok(TextList(vec![text.to_string()]))
    }

    fn from_texts(texts: &[String]) -> Result<Self, String> {
        if texts.is_empty() {
            return Err("give at least one value".into());
        }
        Ok(TextList(texts.to_vec()))
    }

    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::String(s) => Ok(TextList(vec![s.clone()])),
            Value::Array(items) => items
                .iter()
                .map(|v| match v {
                    Value::String(s) => Ok(s.clone()),
                    other => Err(format!("`{other}` is not a text")),
                })
                .collect::<Result<Vec<_>, _>>()
                .and_then(|v| Self::from_texts(&v)),
            other => Err(format!("`{other}` is not a text or a list of texts")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::Array(
            self.0.iter().map(|s| Value::String(s.clone())).collect(),
        ))
    }
}

impl SettingValue for DerivedList {
    fn from_text(text: &str) -> Result<Self, String> {
        crate::derived::parse_quantities(text).map(DerivedList)
    }

    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::String(s) => Self::from_text(s),
            Value::Array(items) => {
                let names = items
                    .iter()
                    .map(|v| match v {
                        Value::String(s) => Ok(s.clone()),
                        other => Err(format!("`{other}` is not a quantity name")),
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Self::from_text(&names.join(","))
            }
            other => Err(format!("`{other}` is not a list of quantity names")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::Array(
            self.0
                .iter()
                .map(|q| Value::String(q.name().to_string()))
                .collect(),
        ))
    }
}

/// An image point `X,Y` in px (`[x, y]` in TOML).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point(pub [f64; 2]);

impl SettingValue for Point {
    fn from_text(text: &str) -> Result<Self, String> {
        let v: Vec<Option<f64>> = text.split(',').map(|s| s.trim().parse().ok()).collect();
        match v.as_slice() {
            [Some(x), Some(y)] if x.is_finite() && y.is_finite() => Ok(Point([*x, *y])),
            _ => Err(format!("`{text}` is not X,Y")),
        }
    }

    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::Array(items) if items.len() == 2 => {
                let coordinate = |v: &Value| match v {
                    Value::Integer(i) => Some(*i as f64),
                    Value::Float(f) if f.is_finite() => Some(*f),
                    _ => None,
                };
                match (coordinate(&items[0]), coordinate(&items[1])) {
                    (Some(x), Some(y)) => Ok(Point([x, y])),
                    _ => Err(format!("`{value}` is not [x, y]")),
                }
            }
            Value::String(s) => Self::from_text(s),
            other => Err(format!("`{other}` is not [x, y]")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::Array(vec![
            Value::Float(self.0[0]),
            Value::Float(self.0[1]),
        ]))
    }
}

impl SettingValue for FieldTimes {
    fn from_text(text: &str) -> Result<Self, String> {
        let (start, end, step) = TimeSteps::parse(text).map_err(|e| match e {
            crate::Error::Parameter { message, .. } => message,
            other => other.to_string(),
        })?;
        Ok(FieldTimes { start, end, step })
    }

    fn to_toml(&self) -> Option<Value> {
        let side = |t: Option<i64>| t.map(|us| Duration(us).text()).unwrap_or_default();
        Some(Value::String(format!(
            "{}:{}:{}",
            side(self.start),
            side(self.end),
            Duration(self.step).text()
        )))
    }
}

impl SettingValue for Roi {
    fn from_text(text: &str) -> Result<Self, String> {
        Roi::parse(text).map_err(|e| match e {
            crate::Error::Parameter { message, .. } => message,
            other => other.to_string(),
        })
    }

    /// `"X,Y,W,H"`, or the array `[x, y, w, h]`.
    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::String(s) => Self::from_text(s),
            Value::Array(items) if items.iter().all(Value::is_integer) => Self::from_text(
                &items
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(","),
            ),
            other => Err(format!("`{other}` is not \"X,Y,W,H\" or [x, y, w, h]")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::String(format!(
            "{},{},{},{}",
            self.x, self.y, self.width, self.height
        )))
    }
}

/// Denoising filters: `hot-pixels,correlation`, `["refractory", "correlation"]`, `all`,
/// `none`.
impl SettingValue for crate::denoise::DenoiseFilters {
    fn from_text(text: &str) -> Result<Self, String> {
        Self::parse(text)
    }

    fn from_toml(value: &Value) -> Result<Self, String> {
        match value {
            Value::String(s) => Self::parse(s),
            Value::Array(items) => {
                let names = items
                    .iter()
                    .map(|v| match v {
                        Value::String(s) => Ok(s.as_str()),
                        other => Err(format!("`{other}` is not a filter name")),
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Self::parse_names(names)
            }
            other => Err(format!("`{other}` is not a list of denoising filters")),
        }
    }

    fn to_toml(&self) -> Option<Value> {
        Some(Value::String(self.text()))
    }
}

/// Named choices: the first name of each variant is the one written back; the type's own
/// parser may accept more spellings.
macro_rules! choice {
    ($ty:ty, $parse:expr, { $($variant:path => $name:literal),+ $(,)? }) => {
        impl SettingValue for $ty {
            fn from_text(text: &str) -> Result<Self, String> {
                let parse: fn(&str) -> Option<$ty> = $parse;
                parse(text.trim()).ok_or_else(|| {
                    let names = [$($name),+];
                    format!("`{text}` is not {}", one_of(&names))
                })
            }

            fn to_toml(&self) -> Option<Value> {
                Some(Value::String(match self { $($variant => $name,)+ }.to_string()))
            }
        }
    };
    // A type that names its own values (`name()`), listed by variant.
    ($ty:ty, $parse:expr, named [ $($variant:path),+ $(,)? ]) => {
        impl SettingValue for $ty {
            fn from_text(text: &str) -> Result<Self, String> {
                let parse: fn(&str) -> Option<$ty> = $parse;
                parse(text.trim()).ok_or_else(|| {
                    let names = [$($variant.name()),+];
                    format!("`{text}` is not {}", one_of(&names))
                })
            }

            fn to_toml(&self) -> Option<Value> {
                Some(Value::String(self.name().to_string()))
            }
        }
    };
}

/// "a, b or c".
pub(crate) fn one_of(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => (*one).to_string(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}

choice!(Method, Method::parse, {
    Method::CorrSum => "corrsum",
    Method::Motion => "motion",
    Method::Piv => "piv",
    Method::Pulsed => "pulsed",
});
choice!(PolaritySelection, PolaritySelection::parse, named [
    PolaritySelection::Positive,
    PolaritySelection::Negative,
    PolaritySelection::Both,
]);
choice!(SubPixelFit, SubPixelFit::parse, named [
    SubPixelFit::Gaussian3,
    SubPixelFit::Parabolic3,
    SubPixelFit::Gaussian2d,
]);
choice!(Weighting, |t| match t {
    "binary" => Some(Weighting::Binary),
    "count" => Some(Weighting::Count),
    _ => None,
}, {
    Weighting::Binary => "binary",
    Weighting::Count => "count",
});
choice!(CorrKernel, |t| match t {
    "auto" => Some(CorrKernel::Auto),
    "fft" => Some(CorrKernel::Fft),
    "direct" => Some(CorrKernel::Direct),
    _ => None,
}, {
    CorrKernel::Auto => "auto",
    CorrKernel::Fft => "fft",
    CorrKernel::Direct => "direct",
});
choice!(SearchMethod, |t| match t {
    "newton" => Some(SearchMethod::Newton),
    "grid" => Some(SearchMethod::Grid),
    _ => None,
}, named [
    SearchMethod::Newton,
    SearchMethod::Grid,
]);
choice!(Objective, |t| match t {
    "variance" | "var" => Some(Objective::Variance),
    "sum-of-squares" | "sumsq" => Some(Objective::SumOfSquares),
    "sum-exp" | "sumexp" => Some(Objective::SumExp),
    "r1" => Some(Objective::R1),
    "isoa" => Some(Objective::Isoa),
    "max-accumulation" | "moa" => Some(Objective::MaxAccumulation),
    _ => None,
}, named [
    Objective::Variance,
    Objective::SumOfSquares,
    Objective::SumExp,
    Objective::R1,
    Objective::Isoa,
    Objective::MaxAccumulation,
]);
choice!(CorrelationKind, CorrelationKind::parse, {
    CorrelationKind::Circular => "circular",
    CorrelationKind::Linear => "linear",
});
choice!(DeformationMode, DeformationMode::parse, named [
    DeformationMode::Symmetric,
    DeformationMode::Second,
]);
choice!(Interpolation, Interpolation::parse, {
    Interpolation::Quintic => "quintic",
    Interpolation::Cubic => "cubic",
    Interpolation::Linear => "linear",
});
choice!(FrameKind, |t| FrameKind::parse(t).ok(), named [
    FrameKind::Count,
    FrameKind::Binary,
    FrameKind::TimeSurface,
]);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_round_trip_with_units() {
        for us in [0, 1, 250, 1000, 1500, 10_000, 2_000_000, 2_500_000] {
            let d = Duration(us);
            assert_eq!(Duration::from_toml(&d.to_toml().unwrap()), Ok(d), "{us}");
        }
        assert_eq!(
            Duration::from_toml(&Value::Integer(3000)),
            Ok(Duration(3000))
        );
        assert!(Duration::from_toml(&Value::Boolean(true)).is_err());
    }

    #[test]
    fn regions_are_text_or_an_array() {
        let text = Roi::from_toml(&Value::String("10,20,300,200".into())).unwrap();
        let ints = |v: &[i64]| Value::Array(v.iter().map(|&i| Value::Integer(i)).collect());
        assert_eq!(Roi::from_toml(&ints(&[10, 20, 300, 200])), Ok(text));
        assert!(Roi::from_toml(&ints(&[10, 20, 300])).is_err());
        assert!(Roi::from_toml(&Value::Array(vec![Value::Float(1.5)])).is_err());
    }

    #[test]
    fn pixel_lists_accept_a_number_a_list_or_text() {
        let both = PixelList(vec![64, 40]);
        assert_eq!(PixelList::from_text("64, 40"), Ok(both.clone()));
        assert_eq!(PixelList::from_toml(&both.to_toml().unwrap()), Ok(both));
        assert_eq!(
            PixelList::from_toml(&Value::Integer(32)),
            Ok(PixelList(vec![32]))
        );
        assert!(PixelList::from_toml(&Value::Integer(-1)).is_err());
        assert!(PixelList::from_text("").is_err());
        assert!(PixelList::from_toml(&Value::Array(vec![])).is_err());
    }

    #[test]
    fn choices_name_their_alternatives() {
        assert_eq!(
            SubPixelFit::from_text("gauss2d"),
            Ok(SubPixelFit::Gaussian2d)
        );
        let e = Weighting::from_text("counts").unwrap_err();
        assert!(e.contains("binary or count"), "{e}");
        let fit = SubPixelFit::Parabolic3;
        assert_eq!(SubPixelFit::from_toml(&fit.to_toml().unwrap()), Ok(fit));
    }

    #[test]
    fn field_times_and_points_round_trip() {
        let t = FieldTimes::from_text(":90ms:5ms").unwrap();
        assert_eq!((t.start, t.end, t.step), (None, Some(90_000), 5000));
        assert_eq!(FieldTimes::from_toml(&t.to_toml().unwrap()), Ok(t));
        assert!(FieldTimes::from_text("1ms:2ms").is_err());
        let p = Point::from_toml(&toml::Value::Array(vec![
            Value::Integer(0),
            Value::Float(720.0),
        ]))
        .unwrap();
        assert_eq!(p, Point([0.0, 720.0]));
        assert!(Point::from_text("1,nan").is_err());
    }
}
