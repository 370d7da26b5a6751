//! Where the true velocity comes from: a simulation scenario's flow, evaluated exactly, or a
//! truth field file (`ebiv simulate --truth`), interpolated bilinearly in space and linearly
//! in time ([`GriddedFlow`]).

use crate::error::Result;
use crate::sim::flow::{Flow, GriddedFlow};
use crate::sim::scenario::Scenario;
use std::path::Path;

/// The true velocity `(x_px, y_px, t_us) → (u, v)` px/ms, image coordinates.
#[derive(Debug)]
pub struct Truth {
    flow: Box<dyn Flow>,
    description: String,
}

impl Truth {
    /// The exact flow of a simulation scenario.
    pub fn from_scenario(scenario: &Scenario, origin: &str) -> Result<Truth> {
        Ok(Truth {
            flow: scenario.flow.build()?,
            description: format!("flow of scenario {origin}: {}", scenario.flow.describe()),
        })
    }

    /// The truth in the file at `path`: a scenario (`.toml`), whose flow is evaluated
    /// exactly, or else a truth field ([`Truth::from_file`]).
    pub fn from_path(path: &Path) -> Result<Truth> {
        let is_toml = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
        if is_toml {
            let scenario = Scenario::from_file(path)?;
            Truth::from_scenario(&scenario, &path.display().to_string())
        } else {
            Truth::from_file(path)
        }
    }

    /// The flow of the ready scenario `name` (as `ebiv simulate --example NAME` runs it).
    pub fn from_example(name: &str) -> Result<Truth> {
        Truth::from_scenario(&Scenario::from_example(name)?, &format!("example `{name}`"))
    }

    /// A truth field file as `ebiv simulate --truth` writes it (NetCDF or CSV; see
    /// [`GriddedFlow::open`]). Outside the file's grid and times the velocity is that of the
    /// nearest edge node or field.
    pub fn from_file(path: &Path) -> Result<Truth> {
        Ok(Truth {
            flow: Box::new(GriddedFlow::open(path)?),
            description: format!("truth field {}", path.display()),
        })
    }

    /// Any flow, e.g. one built in a program.
    pub fn from_flow(flow: Box<dyn Flow>, description: impl Into<String>) -> Truth {
        Truth {
            flow,
            description: description.into(),
        }
    }

    /// The true velocity at image point (x, y) px and time `t_us`, px/ms.
    pub fn velocity(&self, x: f64, y: f64, t_us: f64) -> (f64, f64) {
        self.flow.velocity(x, y, t_us)
    }

    /// Where the truth comes from, for reports.
    pub fn describe(&self) -> &str {
        &self.description
    }
}
