//! Tracks scored against the simulator's particle paths (`ebiv simulate --tracks`).
//!
//! Each measured sample is matched to the true particle nearest to it at its time (within
//! `match_px`); a track belongs to the particle most of its samples match, and is *spurious*
//! when fewer than `min_purity` of its samples match that particle. Errors (position,
//! velocity, acceleration) are taken over the samples that match their track's particle.
//! The true acceleration is the central difference of the true velocity along the path.
//!
//! Yield counts the particles *in view*: inside the image (more than `border_px` from its
//! edges), within the light sheet's e⁻² half-thickness, not behind a wall, and moving at
//! least `min_speed` (an event camera does not see a particle that does not move: below
//! about 0.1 px/ms its image changes too slowly to fire events). A particle in view for
//! `min_visible_us` without a break counts; it is *tracked* when one track follows it over
//! at least `min_coverage` of that stretch.

use super::fit::Track;
use crate::sim::simulation::TrackPoint;
use std::collections::HashMap;

/// Where a particle counts as in view, and what counts as a match.
#[derive(Debug, Clone, PartialEq)]
pub struct ScoreOptions {
    /// Largest distance between a sample and its particle, px.
    pub match_px: f64,
    /// Share of a track's samples that must match its particle.
    pub min_purity: f64,
    /// Half of the light sheet's e⁻² thickness, px: particles further out are not in view.
    pub sheet_half_px: f64,
    /// Rectangles (x, y, width, height) hidden behind walls.
    pub hidden: Vec<[f64; 4]>,
    /// Margin at the image edges, px.
    pub border_px: f64,
    /// Slowest particle counted in view, px/ms.
    pub min_speed: f64,
    /// Shortest time in view for a particle to count in the yield, µs.
    pub min_visible_us: i64,
    /// Share of its time in view that one track must follow for a particle to be tracked.
    pub min_coverage: f64,
    /// Image size, px.
    pub width: f64,
    /// Image size, px.
    pub height: f64,
}

impl ScoreOptions {
    /// The defaults for an image of `width` × `height` px and a light sheet of e⁻²
    /// thickness `sheet_px`.
    pub fn new(width: u32, height: u32, sheet_px: f64) -> Self {
        ScoreOptions {
            match_px: 1.5,
            min_purity: 0.8,
            sheet_half_px: sheet_px / 2.0,
            hidden: Vec::new(),
            border_px: 2.0,
            min_speed: 0.1,
            min_visible_us: 10_000,
            min_coverage: 0.8,
            width: width as f64,
            height: height as f64,
        }
    }

    /// The options when only the true paths are known: the image as far as the paths reach,
    /// the simulator's default light sheet, no walls.
    pub fn from_truth(truth: &[TrackPoint]) -> Self {
        let (w, h) = truth.iter().fold((1.0f64, 1.0f64), |a, p| {
            (a.0.max(p.x + 1.0), a.1.max(p.y + 1.0))
        });
        let sheet = crate::sim::particles::SeedingParams::default().sheet_thickness;
        ScoreOptions::new(w.ceil() as u32, h.ceil() as u32, sheet)
    }

    /// The options for a simulated scenario: its image, light sheet and walls.
    pub fn for_scenario(s: &crate::sim::scenario::Scenario) -> Self {
        let mut o = ScoreOptions::new(s.sensor.width, s.sensor.height, s.particles.sheet_thickness);
        o.hidden = s
            .illumination
            .walls
            .iter()
            .map(|w| [w.x, w.y, w.width, w.height])
            .collect();
        o
    }

    fn in_view(&self, p: &TrackPoint) -> bool {
        let b = self.border_px;
        p.x >= b - 0.5
            && p.y >= b - 0.5
            && p.x < self.width - 0.5 - b
            && p.y < self.height - 0.5 - b
            && p.z.abs() <= self.sheet_half_px
            && (p.u * p.u + p.v * p.v).sqrt() >= self.min_speed
            && !self
                .hidden
                .iter()
                .any(|r| p.x >= r[0] && p.x < r[0] + r[2] && p.y >= r[1] && p.y < r[1] + r[3])
    }
}

/// How measured tracks compare with the true paths.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct TrackScore {
    /// Particles in view long enough to count.
    pub particles: usize,
    /// Of those, the particles one track follows over `min_coverage` of their time in view.
    pub particles_tracked: usize,
    /// particles_tracked / particles.
    pub yield_fraction: f64,
    /// Tracks measured.
    pub tracks: usize,
    /// Tracks that follow no single particle (fewer than `min_purity` of their samples on it).
    pub spurious: usize,
    /// spurious / tracks.
    pub spurious_fraction: f64,
    /// Mean duration of the tracks (first to last sample), ms.
    pub mean_length_ms: f64,
    /// Samples compared (those on their track's particle).
    pub samples: usize,
    /// RMS position error, px.
    pub position_rms: f64,
    /// Mean position error along the direction of motion, px (negative = behind).
    pub position_bias_along: f64,
    /// RMS velocity error (vector magnitude), px/ms.
    pub velocity_rms: f64,
    /// RMS acceleration error (vector magnitude), px/ms².
    pub acceleration_rms: f64,
    /// Largest true speed of the compared samples, px/ms.
    pub peak_speed: f64,
    /// Largest true acceleration of the compared samples, px/ms².
    pub peak_acceleration: f64,
    /// Share of velocity components within two stated standard uncertainties of the truth.
    pub velocity_coverage_2sigma: f64,
    /// Share of position components within two stated standard uncertainties.
    pub position_coverage_2sigma: f64,
    /// Shortest time in view counted in the yield, ms.
    pub min_visible_ms: f64,
    /// Regression of the along-track position error on the speed: the error grows by this
    /// time lag, µs (an estimate of the `latency` to set).
    pub lag_us: f64,
}

impl TrackScore {
    /// The scores as lines of text.
    pub fn summary(&self) -> String {
        format!(
            "yield: {} of {} particles in view ≥ {} ms tracked over ≥ 80 % of it ({:.1} %)\n\
             tracks: {}, spurious {} ({:.2} %), mean length {:.2} ms\n\
             position RMS {:.3} px (bias along the motion {:+.3} px; lag {:.0} µs)\n\
             velocity RMS {:.4} px/ms ({:.2} % of the peak speed {:.2} px/ms)\n\
             acceleration RMS {:.4} px/ms² ({})\n\
             uncertainty coverage (2σ): position {:.1} %, velocity {:.1} % ({} samples)\n",
            self.particles_tracked,
            self.particles,
            self.min_visible_ms,
            100.0 * self.yield_fraction,
            self.tracks,
            self.spurious,
            100.0 * self.spurious_fraction,
            self.mean_length_ms,
            self.position_rms,
            self.position_bias_along,
            self.lag_us,
            self.velocity_rms,
            100.0 * self.velocity_rms / self.peak_speed.max(1e-12),
            self.peak_speed,
            self.acceleration_rms,
            if self.peak_acceleration > 1e-6 {
                format!(
                    "{:.1} % of the peak {:.3} px/ms²",
                    100.0 * self.acceleration_rms / self.peak_acceleration,
                    self.peak_acceleration
                )
            } else {
                "the true paths do not accelerate".to_string()
            },
            100.0 * self.position_coverage_2sigma,
            100.0 * self.velocity_coverage_2sigma,
            self.samples,
        )
    }
}

/// One particle's path, time order.
struct Path {
    points: Vec<TrackPoint>,
}

impl Path {
    /// Position, velocity and acceleration at `t` (µs), linear between samples; `None`
    /// outside the path.
    fn at(&self, t: f64) -> Option<([f64; 2], [f64; 2], [f64; 2])> {
        let p = &self.points;
        let i = p.partition_point(|q| q.t_us < t);
        let (a, b) = if i < p.len() && p[i].t_us == t {
            (i, i)
        } else if i == 0 || i >= p.len() {
            return None;
        } else {
            (i - 1, i)
        };
        let f = if a == b {
            0.0
        } else {
            (t - p[a].t_us) / (p[b].t_us - p[a].t_us)
        };
        let lerp = |x: f64, y: f64| x + (y - x) * f;
        let acc = |k: usize| -> [f64; 2] {
            let (lo, hi) = (k.saturating_sub(1), (k + 1).min(p.len() - 1));
            let dt = (p[hi].t_us - p[lo].t_us) / 1000.0;
            if dt <= 0.0 {
                return [f64::NAN; 2];
            }
            [(p[hi].u - p[lo].u) / dt, (p[hi].v - p[lo].v) / dt]
        };
        let (aa, ab) = (acc(a), acc(b));
        Some((
            [lerp(p[a].x, p[b].x), lerp(p[a].y, p[b].y)],
            [lerp(p[a].u, p[b].u), lerp(p[a].v, p[b].v)],
            [lerp(aa[0], ab[0]), lerp(aa[1], ab[1])],
        ))
    }
}

/// Score `tracks` against the true `paths` (the simulator's track points, any order).
pub fn score_tracks(tracks: &[Track], truth: &[TrackPoint], options: &ScoreOptions) -> TrackScore {
    let mut by_id: HashMap<u64, Path> = HashMap::new();
    for p in truth {
        by_id
            .entry(p.id)
            .or_insert_with(|| Path { points: Vec::new() })
            .points
            .push(*p);
    }
    for path in by_id.values_mut() {
        path.points.sort_by(|a, b| a.t_us.total_cmp(&b.t_us));
    }
    // Truth positions per truth time, bucketed for the nearest search.
    let cell = 8.0;
    let mut frames: HashMap<i64, HashMap<(i64, i64), Vec<u64>>> = HashMap::new();
    for p in truth {
        frames
            .entry(p.t_us.round() as i64)
            .or_default()
            .entry(((p.x / cell).floor() as i64, (p.y / cell).floor() as i64))
            .or_default()
            .push(p.id);
    }
    let mut frame_times: Vec<i64> = frames.keys().copied().collect();
    frame_times.sort_unstable();
    let nearest_frame = |t: f64| -> Option<i64> {
        let i = frame_times.partition_point(|&f| (f as f64) < t);
        [i.checked_sub(1), Some(i)]
            .into_iter()
            .flatten()
            .filter_map(|k| frame_times.get(k).copied())
            .min_by(|a, b| (*a as f64 - t).abs().total_cmp(&(*b as f64 - t).abs()))
    };
    let mut score = TrackScore {
        tracks: tracks.len(),
        min_visible_ms: options.min_visible_us as f64 / 1000.0,
        ..TrackScore::default()
    };
    // Per particle: the longest time followed by one track, µs.
    let mut followed: HashMap<u64, Vec<(f64, f64)>> = HashMap::new();
    let (mut se_pos, mut se_vel, mut se_acc, mut n_acc) = (0.0, 0.0, 0.0, 0usize);
    let (mut along_sum, mut cover_v, mut cover_p) = (0.0, 0usize, 0usize);
    let (mut sxx, mut sxy, mut sx, mut sy, mut moving) = (0.0, 0.0, 0.0, 0.0, 0.0f64);
    let mut length_sum = 0.0;
    for track in tracks {
        let s = &track.samples;
        if let (Some(a), Some(b)) = (s.first(), s.last()) {
            length_sum += (b.t_us - a.t_us) as f64 / 1000.0;
        }
        // Nearest particle of each sample.
        let matches: Vec<Option<u64>> = s
            .iter()
            .map(|q| {
                let t = q.t_us as f64;
                let frame = frames.get(&nearest_frame(t)?)?;
                let (cx, cy) = ((q.x / cell).floor() as i64, (q.y / cell).floor() as i64);
                let mut best: Option<(f64, u64)> = None;
                for bx in cx - 1..=cx + 1 {
                    for by in cy - 1..=cy + 1 {
                        for id in frame.get(&(bx, by)).into_iter().flatten() {
                            let Some((pos, _, _)) = by_id[id].at(t) else {
                                continue;
                            };
                            let d = ((pos[0] - q.x).powi(2) + (pos[1] - q.y).powi(2)).sqrt();
                            if d <= options.match_px && best.is_none_or(|b| d < b.0) {
                                best = Some((d, *id));
                            }
                        }
                    }
                }
                best.map(|b| b.1)
            })
            .collect();
        let mut counts: HashMap<u64, usize> = HashMap::new();
        for id in matches.iter().flatten() {
            *counts.entry(*id).or_default() += 1;
        }
        let Some((&id, &count)) = counts
            .iter()
            .max_by_key(|(id, c)| (**c, std::cmp::Reverse(**id)))
        else {
            score.spurious += 1;
            continue;
        };
        if (count as f64) < options.min_purity * s.len() as f64 {
            score.spurious += 1;
            continue;
        }
        let path = &by_id[&id];
        let mut first_last: Option<(f64, f64)> = None;
        for (q, m) in s.iter().zip(&matches) {
            if *m != Some(id) {
                continue;
            }
            let t = q.t_us as f64;
            let Some((pos, vel, acc)) = path.at(t) else {
                continue;
            };
            first_last = Some(first_last.map_or((t, t), |(a, _)| (a, t)));
            let (ex, ey) = (q.x - pos[0], q.y - pos[1]);
            se_pos += ex * ex + ey * ey;
            let (eu, ev) = (q.u - vel[0], q.v - vel[1]);
            se_vel += eu * eu + ev * ev;
            if q.ax.is_finite() && acc[0].is_finite() {
                se_acc += (q.ax - acc[0]).powi(2) + (q.ay - acc[1]).powi(2);
                n_acc += 1;
                score.peak_acceleration = score.peak_acceleration.max(acc[0].hypot(acc[1]));
            }
            let speed = vel[0].hypot(vel[1]);
            score.peak_speed = score.peak_speed.max(speed);
            if speed > 0.0 {
                let along = (ex * vel[0] + ey * vel[1]) / speed;
                along_sum += along;
                sxx += speed * speed;
                sxy += speed * along;
                sx += speed;
                sy += along;
                moving += 1.0;
            }
            cover_v +=
                (eu.abs() <= 2.0 * q.unc[2]) as usize + (ev.abs() <= 2.0 * q.unc[3]) as usize;
            cover_p +=
                (ex.abs() <= 2.0 * q.unc[0]) as usize + (ey.abs() <= 2.0 * q.unc[1]) as usize;
            score.samples += 1;
        }
        if let Some(span) = first_last {
            followed.entry(id).or_default().push(span);
        }
    }
    let n = score.samples.max(1) as f64;
    score.position_rms = (se_pos / n).sqrt();
    score.velocity_rms = (se_vel / n).sqrt();
    score.acceleration_rms = (se_acc / n_acc.max(1) as f64).sqrt();
    score.position_bias_along = along_sum / moving.max(1.0);
    score.velocity_coverage_2sigma = cover_v as f64 / (2.0 * n);
    score.position_coverage_2sigma = cover_p as f64 / (2.0 * n);
    let denominator = moving * sxx - sx * sx;
    score.lag_us = if denominator > 0.0 {
        -(moving * sxy - sx * sy) / denominator * 1000.0
    } else {
        0.0
    };
    score.spurious_fraction = score.spurious as f64 / score.tracks.max(1) as f64;
    score.mean_length_ms = length_sum / score.tracks.max(1) as f64;
    // Yield over the particles in view long enough.
    for (id, path) in &by_id {
        for (start, end) in visible_stretches(&path.points, options) {
            if end - start < options.min_visible_us as f64 {
                continue;
            }
            score.particles += 1;
            let best = followed
                .get(id)
                .into_iter()
                .flatten()
                .map(|&(a, b)| (b.min(end) - a.max(start)).max(0.0))
                .fold(0.0, f64::max);
            if best >= options.min_coverage * (end - start) {
                score.particles_tracked += 1;
            }
        }
    }
    score.yield_fraction = score.particles_tracked as f64 / score.particles.max(1) as f64;
    score
}

/// The unbroken stretches (start, end µs) of a path in view: consecutive samples in view
/// less than 1 ms apart.
fn visible_stretches(points: &[TrackPoint], options: &ScoreOptions) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut current: Option<(f64, f64)> = None;
    for p in points {
        if !options.in_view(p) {
            out.extend(current.take());
            continue;
        }
        current = match current {
            Some((a, b)) if p.t_us - b <= 1000.0 => Some((a, p.t_us)),
            other => {
                out.extend(other);
                Some((p.t_us, p.t_us))
            }
        };
    }
    out.extend(current);
    out
}
