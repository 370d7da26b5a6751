//! The `[flow]` table of a scenario file: which flow, with which parameters.
//!
//! ```toml
//! [flow]
//! type = "lamb_oseen"
//! centre = [160.0, 120.0]
//! circulation = 2500.0
//! core_radius = 40.0
//! ```
//!
//! Units: positions and lengths px, velocities px/ms, rates and angular velocities 1/ms
//! (rad/ms), circulation px²/ms, angles degrees. Positive angular velocities and circulations
//! turn clockwise on screen (y points down). Formulas: sensor-model.md §5.

use super::{
    Cellular, Couette, Flow, GriddedFlow, LambOseenVortex, MixingLayer, Poiseuille, RandomVortices,
    RankineVortex, Sinusoidal, SolidBodyRotation, StagnationPoint, Superposition, Uniform,
};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A flow as written in a scenario file, internally tagged by `type`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum FlowSpec {
    /// Uniform translation, given either as `u`, `v` or as `speed`, `angle_deg`.
    Uniform {
        /// Velocity along x (right), px/ms.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        u: Option<f64>,
        /// Velocity along y (down), px/ms.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        v: Option<f64>,
        /// Speed, px/ms (instead of `u`, `v`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        speed: Option<f64>,
        /// Direction from +x, degrees, positive = clockwise on screen (default 0).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        angle_deg: Option<f64>,
    },
    /// Solid-body rotation ([`SolidBodyRotation`]).
    SolidBody {
        /// Centre of rotation [x, y], px.
        centre: [f64; 2],
        /// Angular velocity, rad/ms (positive = clockwise on screen).
        omega: f64,
    },
    /// Rankine vortex ([`RankineVortex`]).
    Rankine {
        /// Vortex centre [x, y], px.
        centre: [f64; 2],
        /// Angular velocity of the core, rad/ms (positive = clockwise on screen).
        omega: f64,
        /// Core radius, px.
        core_radius: f64,
    },
    /// Lamb–Oseen vortex ([`LambOseenVortex`]).
    LambOseen {
        /// Vortex centre [x, y], px.
        centre: [f64; 2],
        /// Circulation Γ, px²/ms (positive = clockwise on screen).
        circulation: f64,
        /// Core radius r_c, px (speed maximum at 1.1209 r_c).
        core_radius: f64,
    },
    /// Plane Couette shear, optionally rotated ([`Couette`]).
    Couette {
        /// Shear rate γ̇, 1/ms.
        gradient: f64,
        /// y of a point on the zero-velocity line, px.
        y0: f64,
        /// x of a point on the zero-velocity line, px (default 0; matters only when rotated).
        #[serde(default)]
        x0: f64,
        /// Rotation of the flow direction from +x, degrees, positive = counter-clockwise on
        /// screen (default 0).
        #[serde(default)]
        angle_deg: f64,
    },
    /// Hyperbolic-tangent mixing layer between two streams, optionally rotated
    /// ([`MixingLayer`]): `u = u1 + (u2 − u1) (1 + tanh((y − y0) / thickness)) / 2`, `v = 0`.
    MixingLayer {
        /// Velocity far above the centre line (smaller y, the top of the image), px/ms.
        u1: f64,
        /// Velocity far below the centre line (larger y), px/ms.
        u2: f64,
        /// y of a point on the centre line, px.
        y0: f64,
        /// Thickness δ of the tanh profile, px (the vorticity thickness is 2δ).
        thickness: f64,
        /// x of a point on the centre line, px (default 0; matters only when rotated).
        #[serde(default)]
        x0: f64,
        /// Rotation of the flow direction from +x, degrees, positive = counter-clockwise on
        /// screen (default 0; `u1` is on the left of the flow direction as seen on screen).
        #[serde(default)]
        angle_deg: f64,
    },
    /// Plane Poiseuille channel flow ([`Poiseuille`]).
    Poiseuille {
        /// Centre-line velocity, px/ms.
        u_max: f64,
        /// First wall, px.
        y_min: f64,
        /// Second wall, px (greater than `y_min`).
        y_max: f64,
    },
    /// Constant-speed sinusoidal stream ([`Sinusoidal`]).
    Sinusoidal {
        /// Amplitude of the streamlines, px.
        amplitude: f64,
        /// Wavelength along x, px.
        wavelength: f64,
        /// Speed along the streamlines, px/ms.
        speed: f64,
    },
    /// Cellular Taylor–Green-like flow ([`Cellular`]).
    Cellular {
        /// Velocity amplitude, px/ms.
        amplitude: f64,
        /// Period in x and y, px.
        period: f64,
    },
    /// Stagnation-point flow ([`StagnationPoint`]).
    Stagnation {
        /// Stagnation point [x, y], px.
        centre: [f64; 2],
        /// Strain rate k, 1/ms.
        k: f64,
    },
    /// A turbulence-like steady field: `count` Lamb–Oseen vortices of random position and
    /// sense over a uniform stream ([`RandomVortices`]).
    RandomVortices {
        /// Number of vortices.
        count: u32,
        /// Core radius r_c of every vortex, px.
        core_radius: f64,
        /// Peak tangential speed of every vortex (at 1.1209 r_c), px/ms.
        speed: f64,
        /// Region [width, height] px over which the centres are spread (from the origin).
        region: [f64; 2],
        /// Uniform stream [u, v] the vortices sit in, px/ms (default [0, 0]).
        #[serde(default)]
        mean: [f64; 2],
        /// Seed of the vortex positions and senses (default 1), independent of the
        /// scenario's seed so that every particle seed sees the same flow.
        #[serde(default = "default_flow_seed")]
        seed: u64,
    },
    /// The sum of several flows ([`Superposition`]).
    Superposition {
        /// The flows to add, each a table with its own `type`.
        flows: Vec<FlowSpec>,
    },
    /// A gridded field from a CSV or NetCDF classic file ([`GriddedFlow::open`]).
    Gridded {
        /// The file; relative paths are taken as given (see [`FlowSpec::with_base_dir`]).
        path: PathBuf,
    },
}

fn default_flow_seed() -> u64 {
    1
}

/// Checks the parameters of one spec, naming keys with a prefix (`flows[1].`).
struct Check<'a> {
    prefix: &'a str,
}

impl Check<'_> {
    fn key(&self, name: &str) -> String {
        format!("{}{name}", self.prefix)
    }

    fn finite(&self, name: &str, value: f64) -> Result<f64> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(Error::parameter(
                self.key(name),
                format!("must be a finite number, not {value}"),
            ))
        }
    }

    fn positive(&self, name: &str, value: f64) -> Result<f64> {
        if self.finite(name, value)? > 0.0 {
            Ok(value)
        } else {
            Err(Error::parameter(
                self.key(name),
                format!("must be greater than 0, not {value}"),
            ))
        }
    }

    fn point(&self, name: &str, p: [f64; 2]) -> Result<(f64, f64)> {
        if p.iter().all(|v| v.is_finite()) {
            Ok((p[0], p[1]))
        } else {
            Err(Error::parameter(
                self.key(name),
                format!("must be two finite numbers [x, y], not {p:?}"),
            ))
        }
    }
}

impl FlowSpec {
    /// Uniform translation by (`u`, `v`) px/ms, x right and y down (`type = "uniform"`).
    pub fn uniform(u: f64, v: f64) -> FlowSpec {
        FlowSpec::Uniform {
            u: Some(u),
            v: Some(v),
            speed: None,
            angle_deg: None,
        }
    }

    /// The flow as a one-line TOML inline table, as in a scenario file
    /// (`{ type = "uniform", u = 2.0 }`), for file metadata.
    pub fn describe(&self) -> String {
        toml::Value::try_from(self)
            .map(|v| v.to_string())
            .unwrap_or_else(|e| format!("(not describable: {e})"))
    }

    /// Validate the parameters and build the flow. Errors name the offending key; a gridded
    /// flow's file errors name the file.
    pub fn build(&self) -> Result<Box<dyn Flow>> {
        self.build_at("")
    }

    fn build_at(&self, prefix: &str) -> Result<Box<dyn Flow>> {
        let c = Check { prefix };
        Ok(match *self {
            FlowSpec::Uniform {
                u,
                v,
                speed,
                angle_deg,
            } => match (u, v, speed) {
                (None, None, Some(speed)) => Box::new(Uniform::from_speed_angle(
                    c.finite("speed", speed)?,
                    c.finite("angle_deg", angle_deg.unwrap_or(0.0))?
                        .to_radians(),
                )),
                (_, _, Some(_)) => {
                    return Err(Error::parameter(
                        c.key("speed"),
                        "give either `u` and `v`, or `speed` and `angle_deg`, not both",
                    ))
                }
                (Some(u), Some(v), None) => {
                    if angle_deg.is_some() {
                        return Err(Error::parameter(
                            c.key("angle_deg"),
                            "goes with `speed`; with `u` and `v` leave it out",
                        ));
                    }
                    Box::new(Uniform {
                        u: c.finite("u", u)?,
                        v: c.finite("v", v)?,
                    })
                }
                (u, _, None) => {
                    let missing = if u.is_none() { "u" } else { "v" };
                    return Err(Error::parameter(
                        c.key(missing),
                        "is missing: give `u` and `v` (px/ms), or `speed` (px/ms) and `angle_deg`",
                    ));
                }
            },
            FlowSpec::SolidBody { centre, omega } => Box::new(SolidBodyRotation {
                centre: c.point("centre", centre)?,
                omega_per_ms: c.finite("omega", omega)?,
            }),
            FlowSpec::Rankine {
                centre,
                omega,
                core_radius,
            } => Box::new(RankineVortex {
                centre: c.point("centre", centre)?,
                omega_core_per_ms: c.finite("omega", omega)?,
                core_radius_px: c.positive("core_radius", core_radius)?,
            }),
            FlowSpec::LambOseen {
                centre,
                circulation,
                core_radius,
            } => Box::new(LambOseenVortex {
                centre: c.point("centre", centre)?,
                circulation_px2_per_ms: c.finite("circulation", circulation)?,
                core_radius_px: c.positive("core_radius", core_radius)?,
            }),
            FlowSpec::Couette {
                gradient,
                y0,
                x0,
                angle_deg,
            } => Box::new(Couette {
                gradient_per_ms: c.finite("gradient", gradient)?,
                x0: c.finite("x0", x0)?,
                y0: c.finite("y0", y0)?,
                angle_rad: c.finite("angle_deg", angle_deg)?.to_radians(),
            }),
            FlowSpec::MixingLayer {
                u1,
                u2,
                y0,
                thickness,
                x0,
                angle_deg,
            } => Box::new(MixingLayer {
                u1: c.finite("u1", u1)?,
                u2: c.finite("u2", u2)?,
                x0: c.finite("x0", x0)?,
                y0: c.finite("y0", y0)?,
                thickness_px: c.positive("thickness", thickness)?,
                angle_rad: c.finite("angle_deg", angle_deg)?.to_radians(),
            }),
            FlowSpec::Poiseuille {
                u_max,
                y_min,
                y_max,
            } => {
                let (y_min, y_max) = (c.finite("y_min", y_min)?, c.finite("y_max", y_max)?);
                if y_max <= y_min {
                    return Err(Error::parameter(
                        c.key("y_max"),
                        format!("must be greater than y_min = {y_min}, not {y_max}"),
                    ));
                }
                Box::new(Poiseuille {
                    u_max: c.finite("u_max", u_max)?,
                    y_min,
                    y_max,
                })
            }
            FlowSpec::Sinusoidal {
                amplitude,
                wavelength,
                speed,
            } => Box::new(Sinusoidal {
                amplitude_px: c.finite("amplitude", amplitude)?,
                wavelength_px: c.positive("wavelength", wavelength)?,
                speed: c.finite("speed", speed)?,
            }),
            FlowSpec::Cellular { amplitude, period } => Box::new(Cellular {
                amplitude: c.finite("amplitude", amplitude)?,
                period_px: c.positive("period", period)?,
            }),
            FlowSpec::Stagnation { centre, k } => Box::new(StagnationPoint {
                centre: c.point("centre", centre)?,
                k_per_ms: c.finite("k", k)?,
            }),
            FlowSpec::RandomVortices {
                count,
                core_radius,
                speed,
                region,
                mean,
                seed,
            } => {
                if count == 0 || count > 10_000 {
                    return Err(Error::parameter(
                        c.key("count"),
                        format!("must be 1 to 10000 vortices, not {count}"),
                    ));
                }
                let region = c.point("region", region)?;
                c.positive("region", region.0.min(region.1))?;
                Box::new(RandomVortices::new(
                    count,
                    c.positive("core_radius", core_radius)?,
                    c.finite("speed", speed)?,
                    region,
                    c.point("mean", mean)?,
                    seed,
                ))
            }
            FlowSpec::Superposition { ref flows } => {
                if flows.is_empty() {
                    return Err(Error::parameter(
                        c.key("flows"),
                        "must list at least one flow",
                    ));
                }
                let parts = flows
                    .iter()
                    .enumerate()
                    .map(|(i, f)| f.build_at(&format!("{prefix}flows[{i}].")))
                    .collect::<Result<Vec<_>>>()?;
                Box::new(Superposition(parts))
            }
            FlowSpec::Gridded { ref path } => {
                if path.as_os_str().is_empty() {
                    return Err(Error::parameter(
                        c.key("path"),
                        "must name a CSV or NetCDF file",
                    ));
                }
                Box::new(GriddedFlow::open(path)?)
            }
        })
    }

    /// The same spec with relative gridded-flow paths taken relative to `dir` (the directory
    /// of the scenario file), including inside superpositions.
    pub fn with_base_dir(&self, dir: &Path) -> FlowSpec {
        match self {
            FlowSpec::Gridded { path } if path.is_relative() => FlowSpec::Gridded {
                path: dir.join(path),
            },
            FlowSpec::Superposition { flows } => FlowSpec::Superposition {
                flows: flows.iter().map(|f| f.with_base_dir(dir)).collect(),
            },
            other => other.clone(),
        }
    }
}

#[cfg(test)]
mod tests;
