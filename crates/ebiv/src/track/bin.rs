//! Lagrangian-to-Eulerian binning: the velocities of track samples averaged on a grid of
//! square bins into vector fields, one per time interval (or one over all the tracks).
//!
//! Tracks give velocities where particles are, at any distance from a wall; averaging them in
//! bins smaller than a correlation window gives mean fields of finer resolution than the
//! window estimators (Kähler, Scharnowski & Cierpka, Exp. Fluids, 2012). A bin's
//! uncertainty is the spread of its samples over the square root of the number of tracks in
//! it (the samples of one track are not independent); a bin crossed by fewer than
//! `min_tracks` tracks is left invalid ([`Status::FEW_EVENTS`], or [`Status::NO_EVENTS`]
//! when empty). `event_count` holds the samples of the bin, `slab_us` the interval.

use crate::event::Geometry;
use crate::export::TrackTable;
use crate::field::{FieldSeries, Status, TimeBasis};
use std::collections::HashSet;

/// How the samples are binned.
#[derive(Debug, Clone, PartialEq)]
pub struct BinParams {
    /// Bin size, px.
    pub bin_px: f64,
    /// Length of the time interval of each field, µs; `None` for one field over all tracks.
    pub interval_us: Option<i64>,
    /// Fewest tracks for a valid bin.
    pub min_tracks: u32,
}

impl Default for BinParams {
    fn default() -> Self {
        BinParams {
            bin_px: 16.0,
            interval_us: None,
            min_tracks: 3,
        }
    }
}

impl BinParams {
    /// Check the values, naming the offending setting.
    pub fn validate(&self) -> crate::Result<()> {
        if !(self.bin_px.is_finite() && self.bin_px >= 1.0 && self.bin_px <= 4096.0) {
            return Err(crate::Error::parameter(
                "bin",
                format!("{} px: must be 1 to 4096 px", self.bin_px),
            ));
        }
        if let Some(i) = self.interval_us {
            if !(1..=i64::from(u32::MAX)).contains(&i) {
                return Err(crate::Error::parameter(
                    "bin-interval",
                    format!("{i} µs: must be 1 µs to 71 min"),
                ));
            }
        }
        if self.min_tracks < 1 {
            return Err(crate::Error::parameter(
                "bin-min-tracks",
                "must be at least 1",
            ));
        }
        Ok(())
    }
}

/// Accumulated samples of one bin.
#[derive(Default, Clone)]
struct Bin {
    n: u32,
    su: f64,
    sv: f64,
    suu: f64,
    svv: f64,
    tracks: HashSet<u64>,
}

/// The binned fields of `tracks` on a sensor of `geometry`: bins of `bin_px` centred like
/// the truth grid of the simulator (first centre at `bin_px / 2 − 0.5`).
pub fn bin_tracks(
    tracks: &TrackTable,
    geometry: Geometry,
    params: &BinParams,
) -> crate::Result<FieldSeries> {
    params.validate()?;
    let step = params.bin_px;
    let x = FieldSeries::axis(step / 2.0 - 0.5, geometry.width as f64 - 1.0, step);
    let y = FieldSeries::axis(step / 2.0 - 0.5, geometry.height as f64 - 1.0, step);
    let (Some(&t0), Some(&t1)) = (tracks.t_us.iter().min(), tracks.t_us.iter().max()) else {
        return Err(crate::Error::empty("tracks", "no track samples to bin"));
    };
    let (origin, interval) = match params.interval_us {
        Some(i) => (t0.div_euclid(i) * i, i),
        None => (t0, t1.saturating_sub(t0).saturating_add(1).max(1)),
    };
    if interval > i64::from(u32::MAX) {
        return Err(crate::Error::parameter(
            "bin-interval",
            format!(
                "the tracks span {} µs: give an interval of at most 71 min",
                interval
            ),
        ));
    }
    let fields = (t1.saturating_sub(origin) / interval).saturating_add(1) as u128;
    if fields * x.len() as u128 * y.len() as u128
        > u128::from(crate::sim::scenario::MAX_TRUTH_VALUES)
    {
        return Err(crate::Error::parameter(
            "bin-interval",
            format!(
                "{fields} fields of {}×{} bins: too many; use a longer interval or larger bins",
                x.len(),
                y.len()
            ),
        ));
    }
    let centres: Vec<i64> = (0..fields as i64)
        .map(|k| origin + k * interval + interval / 2)
        .collect();
    let mut series = FieldSeries::new(x, y, centres);
    let (nx, ny) = (series.x.len(), series.y.len());
    let mut bins = vec![Bin::default(); series.u.len()];
    let [xs, ys, us, vs, ..] = &tracks.values;
    for k in 0..tracks.len() {
        let (x, y, u, v) = (xs[k], ys[k], us[k], vs[k]);
        let col = ((x + 0.5) / step).floor();
        let row = ((y + 0.5) / step).floor();
        let inside = col >= 0.0 && row >= 0.0 && (col as usize) < nx && (row as usize) < ny;
        if !(inside && u.is_finite() && v.is_finite()) {
            continue;
        }
        let ti = ((tracks.t_us[k] - origin) / interval) as usize;
        let b = &mut bins[series.index(ti, row as usize, col as usize)];
        b.n += 1;
        b.su += u;
        b.sv += v;
        b.suu += u * u;
        b.svv += v * v;
        b.tracks.insert(tracks.track_id[k]);
    }
    for (i, b) in bins.iter().enumerate() {
        series.event_count[i] = b.n;
        series.slab_us[i] = interval as u32;
        if b.n == 0 {
            continue;
        }
        if (b.tracks.len() as u32) < params.min_tracks {
            series.status[i] = Status::FEW_EVENTS;
            continue;
        }
        let n = b.n as f64;
        let (mu, mv) = (b.su / n, b.sv / n);
        let spread = |s2: f64, m: f64| ((s2 / n - m * m).max(0.0) * n / (n - 1.0).max(1.0)).sqrt();
        let k = (b.tracks.len() as f64).sqrt();
        series.u[i] = mu as f32;
        series.v[i] = mv as f32;
        series.u_unc[i] = (spread(b.suu, mu) / k) as f32;
        series.v_unc[i] = (spread(b.svv, mv) / k) as f32;
        series.status[i] = Status::VALID;
    }
    series.time_basis = TimeBasis::SlabCentre;
    series
        .attributes
        .push(("method".into(), "track binning".into()));
    series.attributes.push(("bin_px".into(), format!("{step}")));
    Ok(series)
}

/// Add the attributes of the tracks (source, settings) to a binned field, leaving out those
/// the field states itself (its `method`).
pub fn add_track_attributes(field: &mut FieldSeries, attributes: &[(String, String)]) {
    for (key, value) in attributes {
        if !field.attributes.iter().any(|(k, _)| k == key) {
            field.attributes.push((key.clone(), value.clone()));
        }
    }
}
