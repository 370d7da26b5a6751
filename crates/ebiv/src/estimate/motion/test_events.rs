//! Synthetic window events for the motion-compensation unit tests.

use super::iwe::Events;
use crate::test_rng::xorshift;

/// At least 300 events of particles (trails of ring-shaped images, integer pixels) moving
/// with `vel` px/ms over ±5 ms, inside a 40 × 40 px window.
pub(super) fn trails(vel: [f64; 2], seed: u64) -> Events {
    let mut rng = xorshift(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let mut next = || (rng() >> 11) as f64 / (1u64 << 53) as f64;
    let mut ev = Events::default();
    while ev.t.len() < 300 {
        let (px, py) = (next() * 60.0 - 10.0, next() * 60.0 - 10.0);
        for k in 0..40 {
            let t = -5.0 + 10.0 * next();
            let a = next() * std::f64::consts::TAU;
            let x = (px + vel[0] * t + 1.2 * a.cos()).round();
            let y = (py + vel[1] * t + 1.2 * a.sin()).round();
            if (0.0..40.0).contains(&x) && (0.0..40.0).contains(&y) && k % 2 == 0 {
                ev.x.push(x as f32);
                ev.y.push(y as f32);
                ev.t.push(t as f32);
            }
        }
    }
    ev
}
