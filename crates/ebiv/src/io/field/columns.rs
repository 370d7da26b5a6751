//! Column names of vector-field tables: what each column holds and in which unit.
//!
//! A name is a base and an optional unit, written in brackets (`u [px/frame]`, PIVlab;
//! `x (mm)`) or, as ebiv writes them, as a suffix with `/` spelled `_` (`u_px_ms`, `x_mm`,
//! `t_us`). Case and surrounding quotes are ignored.

use crate::derived::DerivedQuantity;

/// What a column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// x position.
    X,
    /// y position.
    Y,
    /// x velocity or displacement.
    U,
    /// y velocity or displacement.
    V,
    /// Time of the field (`t`, `time`, `t_us`).
    Time,
    /// Index of the field (`field`, `frame`).
    FieldIndex,
    /// ebiv's status bits.
    Status,
    /// Non-zero for an invalid (possibly replaced) vector (OpenPIV `flags`).
    Flags,
    /// Non-zero for a masked vector (OpenPIV `mask`).
    Mask,
    /// Zero for an invalid vector (`valid`).
    Valid,
    /// Correlation peak.
    Peak,
    /// Peak ratio (`peak_ratio`, OpenPIV `s2n`, `sig2noise`).
    PeakRatio,
    /// Events per window.
    EventCount,
    /// Time slab of the vector, µs.
    SlabUs,
    /// Standard uncertainty of u.
    UUnc,
    /// Standard uncertainty of v.
    VUnc,
    /// A quantity derived from the velocity gradient, as ebiv names its columns
    /// (`vorticity_1_ms`, `vorticity_1_s`, `vorticity_y_up`; [`crate::derived`]).
    Derived(DerivedQuantity),
    /// Anything else (ignored).
    Other,
}

/// One column of a table header.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// What it holds.
    pub role: Role,
    /// Unit as written, lower case, `/` form (`px/ms`, `m/s`, `mm`), empty when not given.
    pub unit: String,
    /// The name as written.
    pub name: String,
}

/// Bases that take a unit suffix, longest first so that `u_unc` is not read as `u` in `unc`.
const SUFFIXED: [(&str, Role); 7] = [
    ("u_unc", Role::UUnc),
    ("v_unc", Role::VUnc),
    ("x", Role::X),
    ("y", Role::Y),
    ("u", Role::U),
    ("v", Role::V),
    ("t", Role::Time),
];

fn role_of(base: &str) -> Role {
    match base {
        "x" => Role::X,
        "y" => Role::Y,
        "u" | "vx" | "dx" => Role::U,
        "v" | "vy" | "dy" => Role::V,
        "t" | "time" => Role::Time,
        "field" | "frame" | "index" => Role::FieldIndex,
        "status" => Role::Status,
        "flags" | "flag" => Role::Flags,
        "mask" | "masked" => Role::Mask,
        "valid" => Role::Valid,
        "peak" => Role::Peak,
        "peak_ratio" | "s2n" | "sig2noise" | "snr" => Role::PeakRatio,
        "event_count" | "events" => Role::EventCount,
        "slab_us" | "slab" => Role::SlabUs,
        "u_unc" | "sigma_u" | "u_uncertainty" => Role::UUnc,
        "v_unc" | "sigma_v" | "v_uncertainty" => Role::VUnc,
        _ => Role::Other,
    }
}

impl Column {
    /// Parse a header cell.
    pub fn parse(raw: &str) -> Column {
        let name = raw.trim().trim_matches(|c| c == '"' || c == '\'').trim();
        let s = name.to_lowercase();
        if let Some(open) = s.find(['[', '(']) {
            let base = s[..open].trim().replace(' ', "_");
            let unit = s[open + 1..]
                .trim_end()
                .trim_end_matches([']', ')'])
                .trim()
                .to_string();
            let unit = if unit == "-" || unit == "1" {
                String::new()
            } else {
                unit
            };
            return Column {
                role: role_of(&base),
                unit,
                name: name.to_string(),
            };
        }
        let role = role_of(&s);
        if role != Role::Other {
            let unit = if role == Role::SlabUs { "us" } else { "" };
            return Column {
                role,
                unit: unit.into(),
                name: name.to_string(),
            };
        }
        for q in DerivedQuantity::ALL {
            if let Some(rest) = s.strip_prefix(q.name()).and_then(|r| r.strip_prefix('_')) {
                if matches!(rest, "1" | "1_ms" | "1_s" | "y_up") {
                    return Column {
                        role: Role::Derived(q),
                        unit: rest.replace('_', "/"),
                        name: name.to_string(),
                    };
                }
            }
        }
        for (base, role) in SUFFIXED {
            if let Some(rest) = s.strip_prefix(base).and_then(|r| r.strip_prefix('_')) {
                if !rest.is_empty() {
                    return Column {
                        role,
                        unit: rest.replace('_', "/"),
                        name: name.to_string(),
                    };
                }
            }
        }
        Column {
            role: Role::Other,
            unit: String::new(),
            name: name.to_string(),
        }
    }

    /// Whether the unit is an image unit (px, px/ms, px/frame, or none).
    pub fn in_image_units(&self) -> bool {
        self.unit.is_empty() || self.unit.starts_with("px") || self.unit.starts_with("pix")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_of_ebiv_openpiv_and_pivlab() {
        let c = Column::parse("u_px_ms");
        assert_eq!((c.role, c.unit.as_str()), (Role::U, "px/ms"));
        let c = Column::parse("u_unc_m_s");
        assert_eq!((c.role, c.unit.as_str()), (Role::UUnc, "m/s"));
        let c = Column::parse("t_us");
        assert_eq!((c.role, c.unit.as_str()), (Role::Time, "us"));
        let c = Column::parse("\"v [px/frame]\"");
        assert_eq!((c.role, c.unit.as_str()), (Role::V, "px/frame"));
        let c = Column::parse("x [m]");
        assert_eq!((c.role, c.unit.as_str()), (Role::X, "m"));
        assert!(!c.in_image_units());
        assert_eq!(Column::parse("flags").role, Role::Flags);
        assert_eq!(Column::parse("s2n").role, Role::PeakRatio);
        assert_eq!(Column::parse("peak_ratio").role, Role::PeakRatio);
        assert_eq!(Column::parse("slab_us").role, Role::SlabUs);
        assert_eq!(Column::parse("vorticity [1/frame]").role, Role::Other);
        assert_eq!(Column::parse("vorticity").role, Role::Other);
        let c = Column::parse("vorticity_1_ms");
        let vorticity = Role::Derived(DerivedQuantity::Vorticity);
        assert_eq!((c.role, c.unit.as_str()), (vorticity, "1/ms"));
        let c = Column::parse("e_xy_1");
        let e_xy = Role::Derived(DerivedQuantity::StrainXy);
        assert_eq!((c.role, c.unit.as_str()), (e_xy, "1"));
        let c = Column::parse("swirling_strength_y_up");
        let swirl = Role::Derived(DerivedQuantity::SwirlingStrength);
        assert_eq!((c.role, c.unit.as_str()), (swirl, "y/up"));
        assert_eq!(Column::parse("Y").role, Role::Y);
        assert!(Column::parse("x_px").in_image_units());
    }
}
