//! Particle detection: the events of one time slab grouped into clusters of touching pixels
//! (8-connected, both polarities together), one cluster per particle image.
//!
//! A particle moving through the light sheet fires ON events where its image arrives and OFF
//! events where it leaves; over a slab short enough for it to move about its own diameter
//! these pixels form one connected patch, while background noise fires isolated pixels. The
//! detection's position is the mean of its ON and its OFF centroids, so that the lead of the
//! ON events and the trail of the OFF events cancel (to the extent they are symmetric; see
//! the `latency` setting), at the mean of their times.

/// One event as a track keeps it: time (µs), pixel and polarity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackEvent {
    /// Time, µs.
    pub t: i64,
    /// Column.
    pub x: u16,
    /// Row.
    pub y: u16,
    /// 1 = ON, 0 = OFF.
    pub p: u8,
}

/// A cluster of events in one slab.
#[derive(Debug, Clone)]
pub struct Detection {
    /// Time of the position, µs.
    pub t: f64,
    /// Position, px.
    pub x: f64,
    /// Position, px.
    pub y: f64,
    /// Velocity from the events' spread in time, px/ms, when they span enough time.
    pub velocity: Option<(f64, f64)>,
    /// The cluster's events, in time order.
    pub events: Vec<TrackEvent>,
}

/// Sums over the events of one polarity of a cluster.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    n: f64,
    t: f64,
    x: f64,
    y: f64,
    tt: f64,
    tx: f64,
    ty: f64,
}

impl Moments {
    fn add(&mut self, t: f64, x: f64, y: f64) {
        self.n += 1.0;
        self.t += t;
        self.x += x;
        self.y += y;
        self.tt += t * t;
        self.tx += t * x;
        self.ty += t * y;
    }

    /// Mean (t, x, y).
    fn mean(&self) -> (f64, f64, f64) {
        (self.t / self.n, self.x / self.n, self.y / self.n)
    }

    /// Least-squares slopes dx/dt, dy/dt (per µs) and the weight of that estimate (the
    /// events' time variance times their number), `None` below 4 events.
    fn slopes(&self) -> Option<(f64, f64, f64)> {
        if self.n < 4.0 {
            return None;
        }
        let (t, x, y) = self.mean();
        let var = self.tt / self.n - t * t;
        if var <= 1.0 {
            return None;
        }
        let cx = self.tx / self.n - t * x;
        let cy = self.ty / self.n - t * y;
        Some((cx / var, cy / var, var * self.n))
    }
}

/// Finds the clusters of one slab. Holds a per-pixel map reused across slabs, so that a slab
/// costs time in its events only.
pub struct Detector {
    width: usize,
    height: usize,
    /// The slab in which each pixel last fired (+1; 0 = never).
    stamp: Vec<u32>,
    /// The union-find node of each pixel in its stamped slab.
    node: Vec<u32>,
    parent: Vec<u32>,
    slab: u32,
    event_node: Vec<u32>,
}

impl Detector {
    /// A detector for a sensor of `width` × `height` pixels.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Detector {
            width: width as usize,
            height: height as usize,
            stamp: vec![0; n],
            node: vec![0; n],
            parent: Vec::new(),
            slab: 0,
            event_node: Vec::new(),
        }
    }

    fn find(&mut self, mut a: u32) -> u32 {
        while self.parent[a as usize] != a {
            let up = self.parent[self.parent[a as usize] as usize];
            self.parent[a as usize] = up;
            a = up;
        }
        a
    }

    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            // The older node becomes the root, so that roots follow first appearance.
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi as usize] = lo;
        }
    }

    /// The clusters of `events` (one slab, time order) with at least `min_events` events,
    /// in the order of their first event. Events outside the sensor are skipped.
    pub fn detect(&mut self, events: &[TrackEvent], min_events: u32) -> Vec<Detection> {
        self.slab = self.slab.wrapping_add(1);
        if self.slab == 0 {
            self.stamp.fill(0);
            self.slab = 1;
        }
        let stamp_now = self.slab;
        self.parent.clear();
        self.event_node.clear();
        let (w, h) = (self.width, self.height);
        for e in events {
            let (x, y) = (e.x as usize, e.y as usize);
            if x >= w || y >= h {
                self.event_node.push(u32::MAX);
                continue;
            }
            let pixel = y * w + x;
            if self.stamp[pixel] != stamp_now {
                let id = self.parent.len() as u32;
                self.parent.push(id);
                self.stamp[pixel] = stamp_now;
                self.node[pixel] = id;
                for (dx, dy) in [
                    (-1i32, -1i32),
                    (0, -1),
                    (1, -1),
                    (-1, 0),
                    (1, 0),
                    (-1, 1),
                    (0, 1),
                    (1, 1),
                ] {
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if nx < 0 || ny < 0 || nx as usize >= w || ny as usize >= h {
                        continue;
                    }
                    let neighbour = ny as usize * w + nx as usize;
                    if self.stamp[neighbour] == stamp_now {
                        let other = self.node[neighbour];
                        self.union(id, other);
                    }
                }
            }
            self.event_node.push(self.node[pixel]);
        }
        // Group events by root.
        let nodes = self.parent.len();
        let mut cluster_of_root = vec![u32::MAX; nodes];
        let mut clusters: Vec<(Moments, Moments, Vec<TrackEvent>)> = Vec::new();
        for (i, e) in events.iter().enumerate() {
            let node = self.event_node[i];
            if node == u32::MAX {
                continue;
            }
            let root = self.find(node) as usize;
            if cluster_of_root[root] == u32::MAX {
                cluster_of_root[root] = clusters.len() as u32;
                clusters.push((Moments::default(), Moments::default(), Vec::new()));
            }
            let c = &mut clusters[cluster_of_root[root] as usize];
            let m = if e.p != 0 { &mut c.0 } else { &mut c.1 };
            m.add(e.t as f64, e.x as f64, e.y as f64);
            c.2.push(*e);
        }
        clusters
            .into_iter()
            .filter(|c| c.2.len() as u32 >= min_events)
            .map(|(on, off, events)| detection_of(&on, &off, events))
            .collect()
    }
}

/// The detection made of `events` (one particle's, in time order).
pub fn detection_from_events(events: Vec<TrackEvent>) -> Detection {
    let (mut on, mut off) = (Moments::default(), Moments::default());
    for e in &events {
        let m = if e.p != 0 { &mut on } else { &mut off };
        m.add(e.t as f64, e.x as f64, e.y as f64);
    }
    detection_of(&on, &off, events)
}

/// A detection at the mean of the ON and the OFF centroids (or of the one polarity present).
fn detection_of(on: &Moments, off: &Moments, events: Vec<TrackEvent>) -> Detection {
    let (t, x, y) = match (on.n > 0.0, off.n > 0.0) {
        (true, true) => {
            let (a, b) = (on.mean(), off.mean());
            ((a.0 + b.0) / 2.0, (a.1 + b.1) / 2.0, (a.2 + b.2) / 2.0)
        }
        (true, false) => on.mean(),
        _ => off.mean(),
    };
    Detection {
        t,
        x,
        y,
        velocity: cluster_velocity(on, off),
        events,
    }
}

/// The velocity of a cluster, px/ms: the time-weighted mean of its polarities' slopes.
fn cluster_velocity(on: &Moments, off: &Moments) -> Option<(f64, f64)> {
    let (mut u, mut v, mut weight) = (0.0, 0.0, 0.0);
    for (du, dv, w) in [on.slopes(), off.slopes()].into_iter().flatten() {
        u += du * w;
        v += dv * w;
        weight += w;
    }
    (weight > 0.0).then(|| (u / weight * 1000.0, v / weight * 1000.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(t: i64, x: u16, y: u16, p: u8) -> TrackEvent {
        TrackEvent { t, x, y, p }
    }

    #[test]
    fn touching_pixels_form_one_cluster_and_isolated_ones_are_noise() {
        let mut d = Detector::new(20, 20);
        let events = vec![
            ev(0, 5, 5, 1),
            ev(1, 6, 6, 1),
            ev(2, 7, 6, 0),
            ev(3, 7, 7, 0),
            ev(4, 15, 15, 1),
            ev(5, 5, 5, 0),
        ];
        let found = d.detect(&events, 2);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].events.len(), 5);
        // ON centroid (5.5, 5.5), OFF centroid (19/3, 6): midpoint.
        assert!((found[0].x - (5.5 + 19.0 / 3.0) / 2.0).abs() < 1e-12);
        // A later slab does not see the earlier one's pixels.
        let found = d.detect(&[ev(10, 6, 5, 1), ev(11, 20, 20, 1)], 1);
        assert_eq!(found.len(), 1, "the off-sensor event is skipped");
    }

    #[test]
    fn two_chains_joined_late_are_one_cluster() {
        let mut d = Detector::new(10, 3);
        // Two separate runs joined by a last pixel between them.
        let events = vec![
            ev(0, 1, 1, 1),
            ev(1, 2, 1, 1),
            ev(2, 5, 1, 1),
            ev(3, 6, 1, 1),
            ev(4, 3, 1, 1),
            ev(5, 4, 1, 0),
        ];
        let found = d.detect(&events, 1);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].events.len(), 6);
    }
}
