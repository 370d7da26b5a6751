//! Tracer particles: seeding, light-sheet position, motion and re-seeding
//! (sensor-model.md §1.2–§1.3).
//!
//! Particles fill the field of view and a margin around it, and a slab of ±`z_extent` across
//! the light sheet, so that they can enter and leave the view and the sheet. A particle that
//! leaves the seeded volume is replaced by a new one (new id) at a random place in the margin
//! or, for out-of-plane exits, at the opposite face of the slab, so the density stays uniform.

use super::flow::Flow;
use super::rng::{Rng, Stream};
use crate::error::{Error, Result};

/// How particles are seeded and lit.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SeedingParams {
    /// Particles per pixel (ppp) over the seeded slab of ±`sheet_thickness` across the sheet;
    /// half of them lie within the sheet's e⁻² thickness. EBIV works at 0.001–0.02.
    pub density: f64,
    /// Mean e⁻² particle-image diameter d_τ, px (Raffel et al. convention).
    pub diameter: f64,
    /// Standard deviation of the diameter, px.
    pub diameter_sigma: f64,
    /// Mean peak irradiance of an in-focus particle centred on a pixel, in units of the
    /// background irradiance (the contrast K of sensor-model.md §1.1).
    pub brightness: f64,
    /// Standard deviation of the brightness.
    pub brightness_sigma: f64,
    /// e⁻² full thickness of the Gaussian light sheet, px (image-scale units).
    pub sheet_thickness: f64,
    /// Standard deviation of the out-of-plane velocity w, px/ms (0 = particles stay at their z).
    pub out_of_plane_sigma: f64,
}

impl Default for SeedingParams {
    fn default() -> Self {
        SeedingParams {
            density: 0.005,
            diameter: 2.5,
            diameter_sigma: 0.2,
            brightness: 20.0,
            brightness_sigma: 2.0,
            sheet_thickness: 20.0,
            out_of_plane_sigma: 0.0,
        }
    }
}

impl SeedingParams {
    /// Check every value, naming the offending key.
    pub fn validate(&self) -> Result<()> {
        let checks = [
            (
                "particles.density",
                self.density,
                self.density >= 0.0 && self.density <= 1.0,
                "in [0, 1] particles per pixel",
            ),
            (
                "particles.diameter",
                self.diameter,
                self.diameter > 0.1 && self.diameter <= 50.0,
                "in (0.1, 50] px",
            ),
            (
                "particles.diameter_sigma",
                self.diameter_sigma,
                self.diameter_sigma >= 0.0,
                "at least 0 px",
            ),
            (
                "particles.brightness",
                self.brightness,
                self.brightness > 0.0,
                "above 0 (peak irradiance over the background)",
            ),
            (
                "particles.brightness_sigma",
                self.brightness_sigma,
                self.brightness_sigma >= 0.0,
                "at least 0",
            ),
            (
                "particles.sheet_thickness",
                self.sheet_thickness,
                self.sheet_thickness > 0.0,
                "above 0 px",
            ),
            (
                "particles.out_of_plane_sigma",
                self.out_of_plane_sigma,
                self.out_of_plane_sigma >= 0.0,
                "at least 0 px/ms",
            ),
        ];
        for (name, value, ok, allowed) in checks {
            if !ok || !value.is_finite() {
                return Err(Error::parameter(
                    name,
                    format!("{value} is out of range: must be finite and {allowed}"),
                ));
            }
        }
        Ok(())
    }

    /// Half-thickness of the seeded slab across the sheet: beyond it a particle is dimmer
    /// than e⁻⁸ of its in-sheet brightness.
    pub fn z_extent(&self) -> f64 {
        self.sheet_thickness
    }

    /// Relative sheet intensity at out-of-plane position `z`: exp(−8 z² / Δz0²)
    /// (sensor-model.md §1.2).
    #[inline]
    pub fn sheet_profile(&self, z: f64) -> f64 {
        (-8.0 * z * z / (self.sheet_thickness * self.sheet_thickness)).exp()
    }
}

/// One tracer particle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Particle {
    /// Identity; a re-seeded particle gets a new one.
    pub id: u64,
    /// Position, px.
    pub x: f64,
    /// Position, px (down).
    pub y: f64,
    /// Out-of-plane position, px (0 = sheet centre).
    pub z: f64,
    /// Out-of-plane velocity, px/ms.
    pub w: f64,
    /// e⁻² image diameter, px.
    pub diameter: f64,
    /// Peak irradiance at the sheet centre, in background units.
    pub brightness: f64,
}

/// The particles of one simulation and the volume they live in.
#[derive(Debug, Clone)]
pub struct ParticleCloud {
    /// The particles.
    pub particles: Vec<Particle>,
    params: SeedingParams,
    /// Seeded region: `[-margin, width + margin] × [-margin, height + margin]`.
    width: f64,
    height: f64,
    margin: f64,
    next_id: u64,
    rng: Rng,
}

impl ParticleCloud {
    /// Seed particles for a `width` × `height` view with a `margin` around it.
    pub fn seed(params: &SeedingParams, width: f64, height: f64, margin: f64, seed: u64) -> Self {
        let mut rng = Rng::new(seed, Stream::Seeding, 0);
        let area = (width + 2.0 * margin) * (height + 2.0 * margin);
        let n = (params.density * area).round() as usize;
        let mut cloud = ParticleCloud {
            particles: Vec::with_capacity(n),
            params: params.clone(),
            width,
            height,
            margin,
            next_id: 0,
            rng: Rng::new(seed, Stream::Reseeding, 0),
        };
        for _ in 0..n {
            let x = rng.range(-margin, width + margin);
            let y = rng.range(-margin, height + margin);
            let p = cloud.new_particle(&mut rng, x, y, None);
            cloud.particles.push(p);
        }
        cloud
    }

    fn new_particle(&mut self, rng: &mut Rng, x: f64, y: f64, z: Option<f64>) -> Particle {
        let p = &self.params;
        let ze = p.z_extent();
        let id = self.next_id;
        self.next_id += 1;
        Particle {
            id,
            x,
            y,
            z: z.unwrap_or_else(|| rng.range(-ze, ze)),
            w: p.out_of_plane_sigma * rng.normal(),
            diameter: (p.diameter + p.diameter_sigma * rng.normal()).max(0.3),
            brightness: (p.brightness + p.brightness_sigma * rng.normal()).max(0.0),
        }
    }

    /// Move every particle from `t0_us` to `t1_us` with `flow` (exact paths where the flow has
    /// them) and replace those that left the seeded volume.
    pub fn advance(&mut self, flow: &dyn Flow, t0_us: f64, t1_us: f64) {
        use rayon::prelude::*;
        let dt_ms = (t1_us - t0_us) * 1e-3;
        self.particles.par_iter_mut().for_each(|p| {
            let (x, y) = flow.advect((p.x, p.y), t0_us, t1_us);
            p.x = x;
            p.y = y;
            p.z += p.w * dt_ms;
        });
        let (w, h, m, ze) = (self.width, self.height, self.margin, self.params.z_extent());
        let mut rng = self.rng.clone();
        for i in 0..self.particles.len() {
            let p = self.particles[i];
            let inside = p.x >= -m && p.x <= w + m && p.y >= -m && p.y <= h + m;
            if !inside || !p.x.is_finite() || !p.y.is_finite() {
                let (x, y) = self.inflow_position(&mut rng, flow, t1_us, dt_ms);
                self.particles[i] = self.new_particle(&mut rng, x, y, None);
            } else if p.z.abs() > ze {
                // Leaves the slab: a new particle enters through the opposite face.
                let z = -p.z.signum() * ze;
                self.particles[i] = self.new_particle(&mut rng, p.x, p.y, Some(z));
            }
        }
        self.rng = rng;
    }

    /// Where a replacement particle enters: a point on the boundary of the seeded region
    /// drawn with probability proportional to the inflow velocity there (the particle flux),
    /// moved inwards by a random part of one step's travel, so a steady flow keeps a uniform
    /// density.
    fn inflow_position(&self, rng: &mut Rng, flow: &dyn Flow, t_us: f64, dt_ms: f64) -> (f64, f64) {
        let (w, h, m) = (
            self.width + 2.0 * self.margin,
            self.height + 2.0 * self.margin,
            self.margin,
        );
        let vmax = flow.max_speed(self.width, self.height, t_us).max(1e-9) * 1.5;
        for _ in 0..1000 {
            let s = rng.range(0.0, 2.0 * (w + h));
            // Point on the perimeter and the inward normal.
            let (x, y, nx, ny) = if s < w {
                (s - m, -m, 0.0, 1.0)
            } else if s < 2.0 * w {
                (s - w - m, h - m, 0.0, -1.0)
            } else if s < 2.0 * w + h {
                (-m, s - 2.0 * w - m, 1.0, 0.0)
            } else {
                (w - m, s - 2.0 * w - h - m, -1.0, 0.0)
            };
            let (u, v) = flow.velocity(x, y, t_us);
            let inflow = u * nx + v * ny;
            if inflow > 0.0 && rng.uniform() * vmax < inflow {
                let depth = rng.uniform() * inflow * dt_ms;
                return (x + nx * depth, y + ny * depth);
            }
        }
        random_in_margin(rng, self.width, self.height, m)
    }

    /// The seeding parameters.
    pub fn params(&self) -> &SeedingParams {
        &self.params
    }
}

/// A uniformly random point of the margin band around the view (not inside the view).
fn random_in_margin(rng: &mut Rng, w: f64, h: f64, m: f64) -> (f64, f64) {
    if m <= 0.0 {
        return (rng.range(0.0, w), rng.range(0.0, h));
    }
    // Four strips: top and bottom (full width with corners), left and right.
    let top = (w + 2.0 * m) * m;
    let side = h * m;
    let pick = rng.range(0.0, 2.0 * top + 2.0 * side);
    if pick < top {
        (rng.range(-m, w + m), rng.range(-m, 0.0))
    } else if pick < 2.0 * top {
        (rng.range(-m, w + m), rng.range(h, h + m))
    } else if pick < 2.0 * top + side {
        (rng.range(-m, 0.0), rng.range(0.0, h))
    } else {
        (rng.range(w, w + m), rng.range(0.0, h))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::flow::Flow;

    #[derive(Debug)]
    struct Shift(f64);
    impl Flow for Shift {
        fn velocity(&self, _: f64, _: f64, _: f64) -> (f64, f64) {
            (self.0, 0.0)
        }
        fn advect(&self, p: (f64, f64), t0: f64, t1: f64) -> (f64, f64) {
            (p.0 + self.0 * (t1 - t0) * 1e-3, p.1)
        }
        fn max_speed(&self, _: f64, _: f64, _: f64) -> f64 {
            self.0.abs()
        }
    }

    #[test]
    fn density_stays_uniform_while_particles_stream_through() {
        let params = SeedingParams {
            density: 0.01,
            ..Default::default()
        };
        let mut cloud = ParticleCloud::seed(&params, 200.0, 100.0, 10.0, 3);
        let n0 = cloud.particles.len();
        assert_eq!(n0, (0.01f64 * 220.0 * 120.0).round() as usize);
        let in_view = |c: &ParticleCloud| {
            c.particles
                .iter()
                .filter(|p| p.x >= 0.0 && p.x < 200.0 && p.y >= 0.0 && p.y < 100.0)
                .count()
        };
        let before = in_view(&cloud);
        // 5 px/ms for 100 ms: every particle crosses the view about twice.
        let mut t = 0.0;
        for _ in 0..1000 {
            cloud.advance(&Shift(5.0), t, t + 100.0);
            t += 100.0;
        }
        let after = in_view(&cloud);
        assert_eq!(cloud.particles.len(), n0);
        let expected = 0.01 * 200.0 * 100.0;
        for n in [before, after] {
            assert!(
                (n as f64 - expected).abs() < 4.0 * expected.sqrt(),
                "{n} vs {expected}"
            );
        }
    }

    #[test]
    fn same_seed_same_particles() {
        let p = SeedingParams::default();
        let a = ParticleCloud::seed(&p, 64.0, 64.0, 8.0, 9);
        let b = ParticleCloud::seed(&p, 64.0, 64.0, 8.0, 9);
        assert_eq!(a.particles, b.particles);
    }
}
