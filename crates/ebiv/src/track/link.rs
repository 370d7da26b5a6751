//! Linking detections into tracks, slab by slab.
//!
//! First, every track with a known velocity claims the events of the new slab that lie
//! within `gate` of where it predicts its particle at each event's time (the nearest track
//! takes an event): particles passing close to each other keep their own events although
//! their images touch, as in the event-by-event assignment of Borer et al. (2017). A track's
//! claimed events form its detection. The events no track claims are clustered
//! ([`super::detect`]) and the clusters linked as follows.
//!
//! Each live track predicts where its particle is at the time of each new detection, by a
//! straight line fitted to its recent detections (constant velocity; the curvature over a
//! slab is far below a pixel at the flows measured). A detection within the track's gate is
//! a candidate; the pairs are then taken in order of their distance relative to the gate,
//! each track and each detection at most once — the nearest pair first, so that an
//! assignment is the best remaining choice for the track and for the detection alike (the
//! greedy form of the one-to-one assignment of Wang et al., ECCV 2020). A track that finds
//! no detection coasts on its prediction, its gate widening, until `max_gap` has passed;
//! then it ends. Detections no track takes start tracks; a new track's second detection is
//! searched within `max_speed` × slab of the first, or along the first's own velocity.

use super::detect::{detection_from_events, Detection, TrackEvent};
use super::params::TrackParams;

/// Least distance a kept track travels from its first to its last detection, px.
pub const MIN_TRAVEL_PX: f64 = 1.0;

/// How long a track may stay within [`MIN_TRAVEL_PX`] of its start before it ends, µs.
const STUCK_US: f64 = 50_000.0;

/// A track still being built: its detections and their events.
#[derive(Debug)]
pub struct LiveTrack {
    /// Identity, in order of creation.
    pub id: u64,
    /// (t µs, x, y) of each detection taken.
    pub detections: Vec<(f64, f64, f64)>,
    /// Velocity of the first detection, px/ms, if it had one.
    first_velocity: Option<(f64, f64)>,
    /// The events of its detections, in time order.
    pub events: Vec<TrackEvent>,
}

impl LiveTrack {
    fn last_time(&self) -> f64 {
        self.detections.last().map_or(f64::NEG_INFINITY, |d| d.0)
    }

    /// Predicted position at `t` and the gate there, px.
    fn predict(&self, t: f64, params: &TrackParams) -> (f64, f64, f64) {
        let &(t1, x1, y1) = self.detections.last().expect("a track has a detection");
        let dt_ms = (t - t1) / 1000.0;
        let slab_ms = params.slab_us as f64 / 1000.0;
        // Beyond one slab the gate widens with the time coasted (1 px per ms), to at most
        // three times the gate.
        let coast = (dt_ms - slab_ms).clamp(0.0, 2.0 * params.gate_px);
        if self.detections.len() >= 2 {
            let (u, v) = self.recent_velocity(params);
            (x1 + u * dt_ms, y1 + v * dt_ms, params.gate_px + coast)
        } else if let Some((u, v)) = self.first_velocity {
            // A single detection's velocity is rough: allow half of its travel over (at most)
            // one slab as error.
            let travel = (u * u + v * v).sqrt() * dt_ms.abs().min(slab_ms);
            (
                x1 + u * dt_ms,
                y1 + v * dt_ms,
                params.gate_px + 0.5 * travel + coast,
            )
        } else {
            (
                x1,
                y1,
                params.gate_px + params.max_speed * dt_ms.abs().min(slab_ms),
            )
        }
    }

    /// Whether the track has stayed within [`MIN_TRAVEL_PX`] of its start for [`STUCK_US`]: a
    /// hot or flickering pixel, not a particle (an event camera sees particles that move).
    /// It ends then, so that its events do not pile up for the whole recording.
    fn is_stuck(&self) -> bool {
        let (Some(first), Some(last)) = (self.detections.first(), self.detections.last()) else {
            return false;
        };
        last.0 - first.0 >= STUCK_US && (last.1 - first.1).hypot(last.2 - first.2) < MIN_TRAVEL_PX
    }

    /// Distance from the first to the last detection, px.
    pub fn travel(&self) -> f64 {
        match (self.detections.first(), self.detections.last()) {
            (Some(a), Some(b)) => (b.1 - a.1).hypot(b.2 - a.2),
            _ => 0.0,
        }
    }

    /// The recent velocity, or the first detection's, or none (zero).
    fn velocity_or_zero(&self, params: &TrackParams) -> (f64, f64) {
        if self.detections.len() >= 2 {
            self.recent_velocity(params)
        } else {
            self.first_velocity.unwrap_or((0.0, 0.0))
        }
    }

    /// Least-squares velocity (px/ms) over the detections of the last 2 ms (at least two).
    fn recent_velocity(&self, params: &TrackParams) -> (f64, f64) {
        let last = self.last_time();
        let span = (2000.0f64).max(2.0 * params.slab_us as f64);
        let n = self.detections.len();
        let first = self
            .detections
            .iter()
            .rposition(|d| last - d.0 > span)
            .map_or(0, |i| i + 1)
            .min(n - 2);
        let recent = &self.detections[first..];
        let k = recent.len() as f64;
        let (mt, mx, my) = recent.iter().fold((0.0, 0.0, 0.0), |a, d| {
            (a.0 + d.0 / k, a.1 + d.1 / k, a.2 + d.2 / k)
        });
        let (mut tt, mut tx, mut ty) = (0.0, 0.0, 0.0);
        for d in recent {
            let dt = (d.0 - mt) / 1000.0;
            tt += dt * dt;
            tx += dt * (d.1 - mx);
            ty += dt * (d.2 - my);
        }
        if tt <= 0.0 {
            return (0.0, 0.0);
        }
        (tx / tt, ty / tt)
    }
}

/// A track that claims events: its index, last detection (t µs, x, y) and velocity (px/ms).
type Mover = (usize, (f64, f64, f64), (f64, f64));

/// Grid cells (column, row) to the indices of what lies in them.
type CellMap =
    std::collections::HashMap<(i64, i64), Vec<usize>, std::hash::BuildHasherDefault<CellHasher>>;

/// A fast hash of grid cells (a multiplicative hash of the two coordinates): the cell keys
/// come from the program, not from an adversary.
#[derive(Default)]
pub struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(5) ^ u64::from(b)).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
        }
    }

    fn write_i64(&mut self, value: i64) {
        self.0 = (self.0.rotate_left(5) ^ value as u64).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// Items (by index) on a grid of square cells over the sensor, for the search of what lies
/// near a point; emptied in constant time by a stamp, so that a slab costs time in its
/// items only.
struct CellGrid {
    cell: f64,
    cols: i64,
    rows: i64,
    width: f64,
    height: f64,
    stamp: Vec<u32>,
    head: Vec<u32>,
    next: Vec<u32>,
    now: u32,
}

const NONE: u32 = u32::MAX;

impl CellGrid {
    fn new(width: u32, height: u32) -> Self {
        CellGrid {
            cell: 0.0,
            cols: 0,
            rows: 0,
            width: width as f64,
            height: height as f64,
            stamp: Vec::new(),
            head: Vec::new(),
            next: Vec::new(),
            now: 0,
        }
    }

    /// Empty the grid for `items` items on cells of `cell` px.
    fn reset(&mut self, cell: f64, items: usize) {
        if cell != self.cell {
            self.cell = cell;
            self.cols = (self.width / cell).ceil() as i64 + 1;
            self.rows = (self.height / cell).ceil() as i64 + 1;
            let n = (self.cols * self.rows) as usize;
            self.stamp = vec![0; n];
            self.head = vec![NONE; n];
            self.now = 0;
        }
        self.now = self.now.wrapping_add(1);
        if self.now == 0 {
            self.stamp.fill(0);
            self.now = 1;
        }
        self.next.clear();
        self.next.resize(items, NONE);
    }

    /// The cell of a point, clamped to the grid (points off the sensor join its edge cells).
    fn cell_of(&self, x: f64, y: f64) -> (i64, i64) {
        let c = ((x / self.cell).floor() as i64).clamp(0, self.cols - 1);
        let r = ((y / self.cell).floor() as i64).clamp(0, self.rows - 1);
        (c, r)
    }

    fn insert(&mut self, item: usize, x: f64, y: f64) {
        let (c, r) = self.cell_of(x, y);
        let i = (r * self.cols + c) as usize;
        if self.stamp[i] != self.now {
            self.stamp[i] = self.now;
            self.head[i] = NONE;
        }
        self.next[item] = self.head[i];
        self.head[i] = item as u32;
    }

    /// Call `f` with every item in the cell of (x, y) and its eight neighbours.
    fn for_near(&self, x: f64, y: f64, mut f: impl FnMut(usize)) {
        let (c, r) = self.cell_of(x, y);
        for row in (r - 1).max(0)..=(r + 1).min(self.rows - 1) {
            for col in (c - 1).max(0)..=(c + 1).min(self.cols - 1) {
                let i = (row * self.cols + col) as usize;
                if self.stamp[i] != self.now {
                    continue;
                }
                let mut k = self.head[i];
                while k != NONE {
                    f(k as usize);
                    k = self.next[k as usize];
                }
            }
        }
    }
}

/// Links detections slab by slab and hands over the tracks that have ended.
pub struct Linker {
    params: TrackParams,
    live: Vec<LiveTrack>,
    next_id: u64,
    grid: CellGrid,
}

impl Linker {
    /// A linker with no tracks, for a sensor of `geometry`.
    pub fn new(params: TrackParams, geometry: crate::event::Geometry) -> Self {
        Linker {
            params,
            live: Vec::new(),
            next_id: 0,
            grid: CellGrid::new(geometry.width, geometry.height),
        }
    }

    /// Set the detection slab (once an automatic one is chosen).
    pub fn set_slab(&mut self, slab_us: i64) {
        self.params.slab_us = slab_us;
    }

    /// Number of tracks alive.
    pub fn live_count(&self) -> usize {
        self.live.len()
    }

    /// Let the tracks of known velocity claim the events of a slab (time order): each event
    /// within `gate` of a track's predicted position at its time goes to the nearest such
    /// track. Returns the detections of the tracks that claimed at least `min_events` (by
    /// track index) and the events left for clustering, in time order.
    pub fn claim(&mut self, events: &[TrackEvent]) -> (Vec<(usize, Detection)>, Vec<TrackEvent>) {
        let Some(first) = events.first() else {
            return (Vec::new(), Vec::new());
        };
        let t_mid = first.t as f64 / 2.0 + events[events.len() - 1].t as f64 / 2.0;
        let gate = self.params.gate_px;
        // Movers sit at their position of mid-slab; an event may lie `gate` from where the
        // mover is at its own time, up to half a slab of motion (at most `max_speed`) away.
        let slab_ms = self.params.slab_us as f64 / 1000.0;
        // The tracks that can claim: (track, last detection, velocity).
        let movers: Vec<Mover> = self
            .live
            .iter()
            .enumerate()
            .filter(|(_, t)| t.detections.len() >= 2)
            .map(|(i, t)| {
                (
                    i,
                    *t.detections.last().expect("two detections"),
                    t.recent_velocity(&self.params),
                )
            })
            .collect();
        if movers.is_empty() {
            return (Vec::new(), events.to_vec());
        }
        let fastest = movers
            .iter()
            .map(|m| m.2 .0.hypot(m.2 .1))
            .fold(0.0f64, f64::max)
            .min(self.params.max_speed);
        let cell = (2.0 * gate)
            .max(8.0)
            .max(gate + fastest * slab_ms / 2.0 + 1.0);
        let grid = &mut self.grid;
        grid.reset(cell, movers.len());
        for (k, (_, d, vel)) in movers.iter().enumerate() {
            let dt = (t_mid - d.0) / 1000.0;
            grid.insert(k, d.1 + vel.0 * dt, d.2 + vel.1 * dt);
        }
        let mut claimed: Vec<Vec<TrackEvent>> = vec![Vec::new(); movers.len()];
        let mut owner: Vec<Option<usize>> = Vec::with_capacity(events.len());
        for e in events {
            let (ex, ey) = (e.x as f64, e.y as f64);
            let mut best: Option<(f64, usize)> = None;
            grid.for_near(ex, ey, |k| {
                let (_, d, vel) = movers[k];
                let dt = (e.t as f64 - d.0) / 1000.0;
                let dist2 = (ex - d.1 - vel.0 * dt).powi(2) + (ey - d.2 - vel.1 * dt).powi(2);
                if dist2 <= gate * gate && best.is_none_or(|b| dist2 < b.0) {
                    best = Some((dist2, k));
                }
            });
            owner.push(best.map(|b| b.1));
        }
        for (e, o) in events.iter().zip(&owner) {
            if let Some(k) = o {
                claimed[*k].push(*e);
            }
        }
        let min = self.params.min_events as usize;
        let mut rest = Vec::new();
        for (e, o) in events.iter().zip(&owner) {
            if o.is_none_or(|k| claimed[k].len() < min) {
                rest.push(*e);
            }
        }
        let detections = claimed
            .into_iter()
            .enumerate()
            .filter(|(_, c)| c.len() >= min)
            .map(|(k, c)| (movers[k].0, detection_from_events(c)))
            .collect();
        (detections, rest)
    }

    /// Take a slab ending at `slab_end` (µs): the detections of tracks that claimed events
    /// ([`Linker::claim`]) and the clusters of the other events. Returns the tracks that
    /// ended (no detection for `max_gap` before `slab_end`).
    pub fn step(
        &mut self,
        claimed: Vec<(usize, Detection)>,
        detections: Vec<Detection>,
        slab_end: f64,
    ) -> Vec<LiveTrack> {
        let mut busy = vec![false; self.live.len()];
        for (track, d) in claimed {
            busy[track] = true;
            let live = &mut self.live[track];
            live.detections.push((d.t, d.x, d.y));
            live.events.extend_from_slice(&d.events);
        }
        let assigned = self.assign(&detections, &busy);
        let mut detections: Vec<Option<Detection>> = detections.into_iter().map(Some).collect();
        for (track, det) in assigned {
            let d = detections[det]
                .take()
                .expect("each detection is assigned once");
            let live = &mut self.live[track];
            live.detections.push((d.t, d.x, d.y));
            live.events.extend_from_slice(&d.events);
        }
        self.merge_duplicates(slab_end - self.params.slab_us as f64);
        // Ended tracks leave before the new ones start.
        let max_gap = self.params.max_gap_us as f64;
        let (ended, live): (Vec<_>, Vec<_>) = std::mem::take(&mut self.live)
            .into_iter()
            .partition(|t| slab_end - t.last_time() > max_gap || t.is_stuck());
        self.live = live;
        for d in detections.into_iter().flatten() {
            self.live.push(LiveTrack {
                id: self.next_id,
                detections: vec![(d.t, d.x, d.y)],
                first_velocity: d.velocity,
                events: d.events,
            });
            self.next_id += 1;
        }
        ended
    }

    /// Merge tracks that follow one particle: two tracks whose detections of this slab (after
    /// `slab_start`) lie within half the gate of each other, moving alike (within 1 px/ms),
    /// become the older one. A particle whose events were split between a track and a
    /// fragment would otherwise feed two tracks that compete for its events, and the loser
    /// drifts to a neighbour.
    fn merge_duplicates(&mut self, slab_start: f64) {
        let close = self.params.gate_px / 2.0;
        let current: Vec<usize> = (0..self.live.len())
            .filter(|&i| self.live[i].last_time() >= slab_start)
            .collect();
        let mut grid = CellMap::default();
        let cell = 8.0;
        for &i in &current {
            let &(_, x, y) = self.live[i].detections.last().expect("a detection");
            grid.entry(((x / cell).floor() as i64, (y / cell).floor() as i64))
                .or_default()
                .push(i);
        }
        let mut into: Vec<Option<usize>> = vec![None; self.live.len()];
        for &i in &current {
            if into[i].is_some() {
                continue;
            }
            let &(_, x, y) = self.live[i].detections.last().expect("a detection");
            let (cx, cy) = ((x / cell).floor() as i64, (y / cell).floor() as i64);
            for bx in cx - 1..=cx + 1 {
                for by in cy - 1..=cy + 1 {
                    for &j in grid.get(&(bx, by)).into_iter().flatten() {
                        if j <= i || into[j].is_some() {
                            continue;
                        }
                        let &(_, xj, yj) = self.live[j].detections.last().expect("a detection");
                        if (xj - x).hypot(yj - y) > close {
                            continue;
                        }
                        let (vi, vj) = (
                            self.live[i].velocity_or_zero(&self.params),
                            self.live[j].velocity_or_zero(&self.params),
                        );
                        if (vi.0 - vj.0).hypot(vi.1 - vj.1) <= 1.0 {
                            // The younger joins the older (lower id, created first).
                            into[j] = Some(i);
                        }
                    }
                }
            }
        }
        if into.iter().all(Option::is_none) {
            return;
        }
        let mut moved: Vec<(usize, LiveTrack)> = Vec::new();
        let mut kept = Vec::with_capacity(self.live.len());
        let mut new_index = vec![0usize; self.live.len()];
        for (i, track) in std::mem::take(&mut self.live).into_iter().enumerate() {
            match into[i] {
                Some(target) => moved.push((target, track)),
                None => {
                    new_index[i] = kept.len();
                    kept.push(track);
                }
            }
        }
        for (target, track) in moved {
            let t = &mut kept[new_index[target]];
            t.events.extend(track.events);
            t.detections.extend(track.detections);
            t.detections.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        self.live = kept;
    }

    /// Every remaining track, ended by the end of the events.
    pub fn finish(&mut self) -> Vec<LiveTrack> {
        std::mem::take(&mut self.live)
    }

    /// One-to-one pairs (track index, detection index) of the tracks not `busy`, nearest
    /// relative distance first.
    fn assign(&self, detections: &[Detection], busy: &[bool]) -> Vec<(usize, usize)> {
        if detections.is_empty() || self.live.is_empty() {
            return Vec::new();
        }
        // Detections bucketed on a coarse grid for the candidate search.
        let cell = 16.0;
        let mut buckets = CellMap::default();
        for (i, d) in detections.iter().enumerate() {
            let key = ((d.x / cell).floor() as i64, (d.y / cell).floor() as i64);
            buckets.entry(key).or_default().push(i);
        }
        let t_ref = detections.iter().map(|d| d.t).sum::<f64>() / detections.len() as f64;
        let key_range = |f: fn(&(i64, i64)) -> i64| {
            let keys = buckets.keys().map(f);
            (keys.clone().min().unwrap_or(0), keys.max().unwrap_or(0))
        };
        let ((x_lo, x_hi), (y_lo, y_hi)) = (key_range(|k| k.0), key_range(|k| k.1));
        // Detections lie up to half a slab from t_ref, where the prediction may move by up
        // to `max_speed` per ms.
        let drift = self.params.max_speed * self.params.slab_us as f64 / 2000.0;
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (ti, track) in self.live.iter().enumerate() {
            if busy[ti] {
                continue;
            }
            let (px, py, gate) = track.predict(t_ref, &self.params);
            let reach = (((gate + drift) / cell).ceil() as i64).max(1);
            let (cx, cy) = ((px / cell).floor() as i64, (py / cell).floor() as i64);
            // Only the buckets that hold detections.
            for bx in (cx - reach).max(x_lo)..=(cx + reach).min(x_hi) {
                for by in (cy - reach).max(y_lo)..=(cy + reach).min(y_hi) {
                    let Some(list) = buckets.get(&(bx, by)) else {
                        continue;
                    };
                    for &di in list {
                        let d = &detections[di];
                        let (qx, qy, gate) = track.predict(d.t, &self.params);
                        let dist = ((d.x - qx).powi(2) + (d.y - qy).powi(2)).sqrt();
                        if dist <= gate {
                            pairs.push((dist / gate, ti, di));
                        }
                    }
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut track_taken = vec![false; self.live.len()];
        let mut det_taken = vec![false; detections.len()];
        let mut out = Vec::new();
        for (_, ti, di) in pairs {
            if !track_taken[ti] && !det_taken[di] {
                track_taken[ti] = true;
                det_taken[di] = true;
                out.push((ti, di));
            }
        }
        out
    }
}
