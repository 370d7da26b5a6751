//! Flows whose particle paths have a closed form (sensor-model.md §5 for the velocities, §6 for
//! the exact paths, after Mendes et al., SoftwareX 2020, and the PCM-SA test set).
//!
//! All are steady: `advect` depends only on the elapsed time. Rotations with a positive
//! angular velocity or circulation turn clockwise on screen (y points down).

use super::{distance_range, elapsed_ms, Flow};

/// Rotate `p` about `centre` by `angle` radians (clockwise on screen for a positive angle).
fn rotate_about(centre: (f64, f64), p: (f64, f64), angle: f64) -> (f64, f64) {
    let (s, c) = angle.sin_cos();
    let (dx, dy) = (p.0 - centre.0, p.1 - centre.1);
    (centre.0 + c * dx - s * dy, centre.1 + s * dx + c * dy)
}

/// Velocity of an axisymmetric vortex with angular velocity `omega` (1/ms) at `(x, y)`.
fn swirl(centre: (f64, f64), omega: f64, x: f64, y: f64) -> (f64, f64) {
    (-omega * (y - centre.1), omega * (x - centre.0))
}

/// Uniform translation `u = U cos α, v = U sin α` (PCM-SA sweeps, Mendes et al.).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Uniform {
    /// Velocity along x (right), px/ms.
    pub u: f64,
    /// Velocity along y (down), px/ms.
    pub v: f64,
}

impl Uniform {
    /// Speed `speed` (px/ms) in the direction `angle_rad` from +x; a positive angle points
    /// below the x axis on screen (clockwise, since y points down).
    pub fn from_speed_angle(speed: f64, angle_rad: f64) -> Self {
        let (s, c) = angle_rad.sin_cos();
        Uniform {
            u: speed * c,
            v: speed * s,
        }
    }
}

impl Flow for Uniform {
    fn velocity(&self, _x: f64, _y: f64, _t_us: f64) -> (f64, f64) {
        (self.u, self.v)
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        let t = elapsed_ms(t0_us, t1_us);
        (p.0 + self.u * t, p.1 + self.v * t)
    }

    fn max_speed(&self, _w: f64, _h: f64, _t_us: f64) -> f64 {
        self.u.hypot(self.v)
    }
}

/// Solid-body rotation `u = −Ω (y − y_c), v = Ω (x − x_c)` (PCM-SA; the turntable).
///
/// A positive `omega_per_ms` turns clockwise on screen: a particle to the right of the centre
/// moves down (+y). Exact path: rotation by Ω t about the centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolidBodyRotation {
    /// Centre of rotation (x, y), px.
    pub centre: (f64, f64),
    /// Angular velocity Ω, rad/ms (positive = clockwise on screen).
    pub omega_per_ms: f64,
}

impl Flow for SolidBodyRotation {
    fn velocity(&self, x: f64, y: f64, _t_us: f64) -> (f64, f64) {
        swirl(self.centre, self.omega_per_ms, x, y)
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        rotate_about(self.centre, p, self.omega_per_ms * elapsed_ms(t0_us, t1_us))
    }

    fn max_speed(&self, w: f64, h: f64, _t_us: f64) -> f64 {
        self.omega_per_ms.abs() * distance_range(self.centre, w, h).1
    }
}

/// Rankine vortex: solid-body core `u_θ = Ω r` for `r ≤ R`, irrotational outside,
/// `u_θ = Ω R² / r` (Mendes et al. with R = 100 px; the PIVlab generator).
///
/// A positive `omega_core_per_ms` turns clockwise on screen. Exact path: the radius is fixed
/// and the angle advances by ω(r) t with ω(r) = u_θ(r) / r (sensor-model.md §6).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RankineVortex {
    /// Vortex centre (x, y), px.
    pub centre: (f64, f64),
    /// Angular velocity of the core Ω, rad/ms (positive = clockwise on screen).
    pub omega_core_per_ms: f64,
    /// Core radius R, px.
    pub core_radius_px: f64,
}

impl RankineVortex {
    /// Angular velocity ω(r) = u_θ / r at radius `r`, rad/ms.
    pub fn angular_velocity(&self, r: f64) -> f64 {
        let radius = self.core_radius_px;
        if r <= radius {
            self.omega_core_per_ms
        } else {
            self.omega_core_per_ms * (radius / r).powi(2)
        }
    }

    /// Tangential velocity u_θ(r), px/ms.
    pub fn tangential_velocity(&self, r: f64) -> f64 {
        self.angular_velocity(r) * r
    }

    fn radius(&self, p: (f64, f64)) -> f64 {
        (p.0 - self.centre.0).hypot(p.1 - self.centre.1)
    }
}

impl Flow for RankineVortex {
    fn velocity(&self, x: f64, y: f64, _t_us: f64) -> (f64, f64) {
        let omega = self.angular_velocity(self.radius((x, y)));
        swirl(self.centre, omega, x, y)
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        let omega = self.angular_velocity(self.radius(p));
        rotate_about(self.centre, p, omega * elapsed_ms(t0_us, t1_us))
    }

    fn max_speed(&self, w: f64, h: f64, _t_us: f64) -> f64 {
        // u_θ rises to r = R and falls beyond: its maximum over the distances the rectangle
        // spans is at R clamped into that span.
        let (near, far) = distance_range(self.centre, w, h);
        let r = self.core_radius_px.max(near).min(far);
        self.tangential_velocity(r).abs()
    }
}

/// Lamb–Oseen vortex `u_θ = Γ / (2π r) · (1 − exp(−r² / r_c²))` (PCM-SA: Γ = 5000 px²/ms,
/// r_c = 40 px; Mendes et al.). The speed peaks at r = 1.1209 r_c (r² / r_c² = 1.25643).
///
/// A positive circulation turns clockwise on screen. Exact path: the radius is fixed and the
/// angle advances by ω(r) t, ω(r) = u_θ(r) / r, which tends to Γ / (2π r_c²) at the centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LambOseenVortex {
    /// Vortex centre (x, y), px.
    pub centre: (f64, f64),
    /// Circulation Γ, px²/ms (positive = clockwise on screen).
    pub circulation_px2_per_ms: f64,
    /// Core radius r_c, px.
    pub core_radius_px: f64,
}

/// r² / r_c² at the speed maximum of the Lamb–Oseen vortex (root of 1 + 2q = e^q).
pub const LAMB_OSEEN_PEAK_Q: f64 = 1.256_431_208_626_17;

impl LambOseenVortex {
    /// Angular velocity ω(r) = u_θ / r at radius `r`, rad/ms; finite at r = 0.
    pub fn angular_velocity(&self, r: f64) -> f64 {
        let rc2 = self.core_radius_px * self.core_radius_px;
        let q = r * r / rc2;
        // (1 − e^{−q}) / q, accurate for small q and exactly 1 at the centre.
        let shape = if q < 1e-8 {
            1.0 - 0.5 * q
        } else {
            -(-q).exp_m1() / q
        };
        self.circulation_px2_per_ms / (2.0 * std::f64::consts::PI * rc2) * shape
    }

    /// Tangential velocity u_θ(r), px/ms.
    pub fn tangential_velocity(&self, r: f64) -> f64 {
        self.angular_velocity(r) * r
    }

    /// Radius of the speed maximum, 1.1209 r_c.
    pub fn peak_radius(&self) -> f64 {
        LAMB_OSEEN_PEAK_Q.sqrt() * self.core_radius_px
    }

    fn radius(&self, p: (f64, f64)) -> f64 {
        (p.0 - self.centre.0).hypot(p.1 - self.centre.1)
    }
}

impl Flow for LambOseenVortex {
    fn velocity(&self, x: f64, y: f64, _t_us: f64) -> (f64, f64) {
        let omega = self.angular_velocity(self.radius((x, y)));
        swirl(self.centre, omega, x, y)
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        let omega = self.angular_velocity(self.radius(p));
        rotate_about(self.centre, p, omega * elapsed_ms(t0_us, t1_us))
    }

    fn max_speed(&self, w: f64, h: f64, _t_us: f64) -> f64 {
        let (near, far) = distance_range(self.centre, w, h);
        let r = self.peak_radius().max(near).min(far);
        self.tangential_velocity(r).abs()
    }
}

/// Plane Couette (simple shear) flow, optionally rotated (Mendes et al. use 0°, 22.3° and
/// 45°): with `s = (y − y0) cos α + (x − x0) sin α`, `u = γ̇ s cos α`, `v = −γ̇ s sin α`
/// (sensor-model.md §5).
///
/// At α = 0 this is `u = γ̇ (y − y0), v = 0`: the zero-velocity line is `y = y0` and the flow
/// runs to the right below it (larger y). A positive α turns the flow direction
/// `(cos α, −sin α)` counter-clockwise on screen; the zero-velocity line passes through
/// `(x0, y0)`. Exact path: s is conserved and the particle advances by γ̇ s t along the flow
/// direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Couette {
    /// Shear rate γ̇ = U_max / height, 1/ms.
    pub gradient_per_ms: f64,
    /// x of a point on the zero-velocity line, px (irrelevant at α = 0).
    pub x0: f64,
    /// y of a point on the zero-velocity line, px.
    pub y0: f64,
    /// Rotation α of the flow direction from +x, rad (positive = counter-clockwise on screen).
    pub angle_rad: f64,
}

impl Couette {
    /// Horizontal shear `u = γ̇ (y − y0)`.
    pub fn horizontal(gradient_per_ms: f64, y0: f64) -> Self {
        Couette {
            gradient_per_ms,
            x0: 0.0,
            y0,
            angle_rad: 0.0,
        }
    }

    /// The wall-normal coordinate s of `(x, y)`, px.
    fn s(&self, x: f64, y: f64) -> f64 {
        let (sin, cos) = self.angle_rad.sin_cos();
        (y - self.y0) * cos + (x - self.x0) * sin
    }
}

impl Flow for Couette {
    fn velocity(&self, x: f64, y: f64, _t_us: f64) -> (f64, f64) {
        let speed = self.gradient_per_ms * self.s(x, y);
        let (sin, cos) = self.angle_rad.sin_cos();
        // `0.0 −` keeps v at +0 rather than −0 when unrotated (as files print it).
        (speed * cos, 0.0 - speed * sin)
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        let (u, v) = self.velocity(p.0, p.1, t0_us);
        let t = elapsed_ms(t0_us, t1_us);
        (p.0 + u * t, p.1 + v * t)
    }

    fn max_speed(&self, w: f64, h: f64, _t_us: f64) -> f64 {
        // |s| is convex: its maximum over the rectangle is at a corner.
        let corners = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)];
        let s_max = corners
            .iter()
            .map(|&(x, y)| self.s(x, y).abs())
            .fold(0.0, f64::max);
        self.gradient_per_ms.abs() * s_max
    }
}

/// Hyperbolic-tangent mixing layer between two streams, optionally rotated like [`Couette`]:
/// with `s = (y − y0) cos α + (x − x0) sin α`,
///
/// `U(s) = u1 + (u2 − u1) · (1 + tanh(s / δ)) / 2`,  `u = U(s) cos α`, `v = −U(s) sin α`.
///
/// The profile is the classical model of a plane free shear layer: Michalke, "On the inviscid
/// instability of the hyperbolic-tangent velocity profile", J. Fluid Mech. 19:543–556 (1964),
/// whose length scale is δ here; Pope, *Turbulent Flows* (2000), §5.4 (the plane mixing
/// layer). It gives an estimator a velocity gradient of known width between two uniform
/// streams of chosen speeds. The largest shear, `(u2 − u1) / (2δ)`, is on the centre line
/// `s = 0`, where `U = (u1 + u2) / 2`; the vorticity thickness `(u2 − u1) / max |dU/ds|` is
/// 2δ and the momentum thickness `∫ (U − u1)(u2 − U) / (u2 − u1)² ds` is δ / 2. From
/// s = −2δ to 2δ the velocity covers tanh 2 = 96 % of the difference.
///
/// At α = 0 this is `u = U(y − y0), v = 0`: `u1` far above the centre line `y = y0` (the top
/// of the image, y points down) and `u2` far below it. A positive α turns the flow direction
/// `(cos α, −sin α)` counter-clockwise on screen; the centre line passes through `(x0, y0)`.
/// Exact path: s is conserved and the particle advances by U(s) t along the flow direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MixingLayer {
    /// Velocity far on the side s → −∞ (above the centre line at α = 0), px/ms.
    pub u1: f64,
    /// Velocity far on the side s → +∞ (below the centre line at α = 0), px/ms.
    pub u2: f64,
    /// x of a point on the centre line, px (irrelevant at α = 0).
    pub x0: f64,
    /// y of a point on the centre line, px.
    pub y0: f64,
    /// Thickness δ, px: the length scale of the tanh (half the vorticity thickness).
    pub thickness_px: f64,
    /// Rotation α of the flow direction from +x, rad (positive = counter-clockwise on screen).
    pub angle_rad: f64,
}

impl MixingLayer {
    /// Horizontal layer `u = U(y − y0)`: `u1` above the centre line `y = y0`, `u2` below it.
    pub fn horizontal(u1: f64, u2: f64, y0: f64, thickness_px: f64) -> Self {
        MixingLayer {
            u1,
            u2,
            x0: 0.0,
            y0,
            thickness_px,
            angle_rad: 0.0,
        }
    }

    /// The cross-stream coordinate s of `(x, y)`, px (0 on the centre line).
    pub fn s(&self, x: f64, y: f64) -> f64 {
        let (sin, cos) = self.angle_rad.sin_cos();
        (y - self.y0) * cos + (x - self.x0) * sin
    }

    /// The streamwise velocity U(s), px/ms.
    pub fn profile(&self, s: f64) -> f64 {
        self.u1 + (self.u2 - self.u1) * 0.5 * (1.0 + (s / self.thickness_px).tanh())
    }

    /// The shear dU/ds, 1/ms: `(u2 − u1) / (2δ) · sech²(s / δ)`.
    pub fn shear_rate(&self, s: f64) -> f64 {
        let sech = 1.0 / (s / self.thickness_px).cosh();
        (self.u2 - self.u1) / (2.0 * self.thickness_px) * sech * sech
    }
}

impl Flow for MixingLayer {
    fn velocity(&self, x: f64, y: f64, _t_us: f64) -> (f64, f64) {
        let speed = self.profile(self.s(x, y));
        let (sin, cos) = self.angle_rad.sin_cos();
        (speed * cos, 0.0 - speed * sin)
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        let (u, v) = self.velocity(p.0, p.1, t0_us);
        let t = elapsed_ms(t0_us, t1_us);
        (p.0 + u * t, p.1 + v * t)
    }

    fn max_speed(&self, w: f64, h: f64, _t_us: f64) -> f64 {
        // U is monotonic in s, and s is linear: |U| is largest at a corner.
        let corners = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)];
        corners
            .iter()
            .map(|&(x, y)| self.profile(self.s(x, y)).abs())
            .fold(0.0, f64::max)
    }
}

/// Plane Poiseuille (channel) flow `u = −U_max (y − y_min)(y − y_max) / ((y_max − y_min)/2)²`,
/// `v = 0` between the walls `y_min < y_max`, and at rest outside the channel (Mendes et al.).
/// Exact path: y is fixed and x advances by u(y) t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Poiseuille {
    /// Centre-line velocity U_max, px/ms (positive = to the right).
    pub u_max: f64,
    /// First wall, px.
    pub y_min: f64,
    /// Second wall, px (greater than `y_min`).
    pub y_max: f64,
}

impl Poiseuille {
    /// Streamwise velocity at height `y`, px/ms (0 outside the channel).
    pub fn profile(&self, y: f64) -> f64 {
        if !(y > self.y_min && y < self.y_max) {
            return 0.0;
        }
        let half = 0.5 * (self.y_max - self.y_min);
        -self.u_max * (y - self.y_min) * (y - self.y_max) / (half * half)
    }
}

impl Flow for Poiseuille {
    fn velocity(&self, _x: f64, y: f64, _t_us: f64) -> (f64, f64) {
        (self.profile(y), 0.0)
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        (p.0 + self.profile(p.1) * elapsed_ms(t0_us, t1_us), p.1)
    }

    fn max_speed(&self, _w: f64, h: f64, _t_us: f64) -> f64 {
        // The profile is unimodal about the centre line.
        let mid = 0.5 * (self.y_min + self.y_max);
        self.profile(mid.max(0.0).min(h)).abs()
    }
}

/// Plane stagnation-point flow `u = k (x − x_c), v = −k (y − y_c)` (Mendes et al., with
/// k = U_max / M, M the distance to the far corner). Mendes et al. keep one half-plane (a
/// wall through the centre); here the field is defined everywhere — put the centre on an image
/// edge for the wall flow. With k > 0 the flow arrives along y and leaves along x. Exact path:
/// `x − x_c = e^{k t} (x0 − x_c)`, `y − y_c = e^{−k t} (y0 − y_c)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StagnationPoint {
    /// Stagnation point (x, y), px.
    pub centre: (f64, f64),
    /// Strain rate k, 1/ms.
    pub k_per_ms: f64,
}

impl Flow for StagnationPoint {
    fn velocity(&self, x: f64, y: f64, _t_us: f64) -> (f64, f64) {
        (
            self.k_per_ms * (x - self.centre.0),
            -self.k_per_ms * (y - self.centre.1),
        )
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        let kt = self.k_per_ms * elapsed_ms(t0_us, t1_us);
        (
            self.centre.0 + kt.exp() * (p.0 - self.centre.0),
            self.centre.1 + (-kt).exp() * (p.1 - self.centre.1),
        )
    }

    fn max_speed(&self, w: f64, h: f64, _t_us: f64) -> f64 {
        self.k_per_ms.abs() * distance_range(self.centre, w, h).1
    }
}
