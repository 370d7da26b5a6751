//! Statistics of a series of vector fields at every grid node: the mean velocity, its
//! fluctuations (RMS) and the Reynolds stresses `u'u'`, `v'v'`, `u'v'`, over the valid
//! vectors only, optionally per phase of a periodic flow (phase averaging).
//!
//! Phases come from a period (`period_us`: the phase of a field is its time since the phase
//! origin modulo the period) or from trigger edges of the recording ([`triggers`]: the phase
//! of a field at time t is (t − T_k) / (T_{k+1} − T_k) between the last trigger T_k at or
//! before t and the next one; fields outside the triggers' span are left out and counted).
//!
//! Invalid vectors are left out, never counted as zero; replaced ones too unless asked for
//! (an interpolated vector is no measurement). The moments are accumulated in one pass with
//! Welford's update (Welford, Technometrics 4:419, 1962; the covariance form of Chan, Golub &
//! LeVeque, 1983), in `f64`. The stresses are sample covariances (divided by N − 1), as in
//! Raffel et al., "Particle Image Velocimetry", 3rd ed., §9.1; the RMS is the square root of
//! the normal stress.

pub mod triggers;

use crate::error::{Error, Result};
use crate::field::{Calibration, FieldSeries, Quantity, Status};
pub use triggers::{
    read_trigger_times, triggers_for, TriggerPolarity, TriggerSummary, TriggerTimes,
};

/// How to average.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StatsOptions {
    /// Phase averaging: the period of the flow, µs; `None` averages over all fields.
    pub period_us: Option<i64>,
    /// Phase averaging by trigger: the trigger times, µs on the fields' clock (ascending);
    /// the phase of a field is its fraction of the interval between the triggers around it.
    /// Not with `period_us`.
    pub triggers_us: Option<Vec<i64>>,
    /// Phase bins per period or trigger interval (with `period_us` or `triggers_us`).
    pub phases: usize,
    /// The camera time, µs, at which phase 0 begins; `None`: the first field's time.
    pub phase_origin_us: Option<i64>,
    /// Count replaced vectors (interpolated by validation) as samples.
    pub include_replaced: bool,
}

/// Statistics at every node, per phase: arrays indexed `[phase][y][x]` (one phase without
/// phase averaging), in the series' image units (px/ms, or px for displacements).
#[derive(Debug, Clone, PartialEq)]
pub struct FlowStatistics {
    /// Column centres, px.
    pub x: Vec<f64>,
    /// Row centres, px.
    pub y: Vec<f64>,
    /// Number of phases.
    pub phases: usize,
    /// Centre of each phase bin: µs from the phase origin by period, a fraction of the
    /// trigger interval (0–1) by trigger; empty without phase averaging.
    pub phase_centres_us: Vec<f64>,
    /// Mean of u.
    pub u_mean: Vec<f64>,
    /// Mean of v.
    pub v_mean: Vec<f64>,
    /// Normal stress u'u' (variance of u).
    pub uu: Vec<f64>,
    /// Normal stress v'v'.
    pub vv: Vec<f64>,
    /// Shear stress u'v' (covariance of u and v).
    pub uv: Vec<f64>,
    /// Valid samples.
    pub count: Vec<u32>,
    /// Fields averaged.
    pub fields: usize,
    /// What u and v are (velocities or displacements), for their unit.
    pub quantity: Quantity,
    /// The series' calibration, for the writer.
    pub calibration: Option<Calibration>,
    /// The period of phase averaging, µs.
    pub period_us: Option<i64>,
    /// The camera time at which phase 0 begins, µs (with `period_us`).
    pub phase_origin_us: i64,
    /// Whether replaced vectors were counted.
    pub include_replaced: bool,
    /// Phase averaging by trigger: the triggers used and the fields left out.
    pub trigger: Option<TriggerSummary>,
}

impl FlowStatistics {
    /// RMS of u: the square root of u'u'.
    pub fn u_rms(&self) -> Vec<f64> {
        self.uu.iter().map(|v| v.sqrt()).collect()
    }

    /// Whether the statistics are per phase (by period or by trigger).
    pub fn phased(&self) -> bool {
        self.period_us.is_some() || self.trigger.is_some()
    }

    /// RMS of v.
    pub fn v_rms(&self) -> Vec<f64> {
        self.vv.iter().map(|v| v.sqrt()).collect()
    }
}

/// The statistics of `series` (see the module documentation).
pub fn flow_statistics(series: &FieldSeries, options: &StatsOptions) -> Result<FlowStatistics> {
    let (nx, ny, nt) = (series.x.len(), series.y.len(), series.t_us.len());
    if nt == 0 {
        return Err(Error::parameter("field", "the series holds no field"));
    }
    if options.period_us.is_some() && options.triggers_us.is_some() {
        return Err(Error::parameter(
            "triggers",
            "phase averaging is by period or by trigger, not both",
        ));
    }
    let phase_option = if options.triggers_us.is_some() {
        "triggers"
    } else {
        "period"
    };
    let by_phase = options.period_us.is_some() || options.triggers_us.is_some();
    if by_phase && !series.time_basis.is_camera_time() {
        return Err(Error::parameter(
            phase_option,
            "the fields of image pairs carry no times; phase averaging needs a series in camera time",
        ));
    }
    let trigger_phases = options
        .triggers_us
        .as_deref()
        .map(|t| triggers::TriggerPhases::new(t, &series.t_us))
        .transpose()?;
    let phases = match options.period_us {
        None if trigger_phases.is_some() => check_phases(options.phases)?,
        None => 1,
        Some(p) if p <= 0 => {
            return Err(Error::parameter(
                "period",
                format!("must be positive, got {p} µs"),
            ))
        }
        Some(_) => check_phases(options.phases)?,
    };
    let nodes = nx * ny;
    let cells = phases
        .checked_mul(nodes)
        .filter(|&c| c <= 1 << 24)
        .ok_or_else(|| Error::parameter("phases", "too many phase bins for this grid"))?;
    let origin = options.phase_origin_us.unwrap_or(series.t_us[0]);
    let mut acc = vec![Moments::default(); cells];
    for (ti, &t) in series.t_us.iter().enumerate() {
        let phase = match (options.period_us, &trigger_phases) {
            (Some(period), _) => {
                let into = (t as i128 - origin as i128).rem_euclid(period as i128);
                ((into * phases as i128) / period as i128) as usize
            }
            (None, Some(tp)) => match tp.bin(t, phases) {
                Some(bin) => bin,
                None => continue,
            },
            (None, None) => 0,
        };
        for node in 0..nodes {
            let i = ti * nodes + node;
            let status = series.status[i];
            let counted = status.is_valid()
                || (options.include_replaced && status.contains(Status::REPLACED));
            let (u, v) = (series.u[i] as f64, series.v[i] as f64);
            if counted && u.is_finite() && v.is_finite() {
                acc[phase * nodes + node].add(u, v);
            }
        }
    }
    let phase_centres_us = match (options.period_us, &trigger_phases) {
        (Some(p), _) => (0..phases)
            .map(|k| (k as f64 + 0.5) * p as f64 / phases as f64)
            .collect(),
        (None, Some(_)) => (0..phases)
            .map(|k| (k as f64 + 0.5) / phases as f64)
            .collect(),
        (None, None) => Vec::new(),
    };
    Ok(FlowStatistics {
        x: series.x.clone(),
        y: series.y.clone(),
        phases,
        phase_centres_us,
        u_mean: acc.iter().map(|m| m.mean(m.mean_u)).collect(),
        v_mean: acc.iter().map(|m| m.mean(m.mean_v)).collect(),
        uu: acc.iter().map(|m| m.covariance(m.m_uu)).collect(),
        vv: acc.iter().map(|m| m.covariance(m.m_vv)).collect(),
        uv: acc.iter().map(|m| m.covariance(m.m_uv)).collect(),
        count: acc.iter().map(|m| m.n).collect(),
        fields: nt - trigger_phases.as_ref().map_or(0, |tp| tp.outside),
        quantity: series.quantity,
        calibration: series.calibration,
        period_us: options.period_us,
        phase_origin_us: origin,
        include_replaced: options.include_replaced,
        trigger: trigger_phases.map(|tp| tp.summary()),
    })
}

/// `phases` if it is 1 to 10000.
fn check_phases(phases: usize) -> Result<usize> {
    if phases == 0 || phases > 10_000 {
        return Err(Error::parameter(
            "phases",
            format!("must be 1 to 10000, got {phases}"),
        ));
    }
    Ok(phases)
}

/// Running moments of (u, v) at one node (Welford's update).
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    n: u32,
    mean_u: f64,
    mean_v: f64,
    /// Sums of products of deviations.
    m_uu: f64,
    m_vv: f64,
    m_uv: f64,
}

impl Moments {
    fn add(&mut self, u: f64, v: f64) {
        self.n += 1;
        let n = self.n as f64;
        let (du, dv) = (u - self.mean_u, v - self.mean_v);
        self.mean_u += du / n;
        self.mean_v += dv / n;
        // Deviation before the update times deviation after it.
        self.m_uu += du * (u - self.mean_u);
        self.m_vv += dv * (v - self.mean_v);
        self.m_uv += du * (v - self.mean_v);
    }

    /// A mean, NaN without samples.
    fn mean(&self, value: f64) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            value
        }
    }

    /// A sample covariance from its sum of products, NaN with fewer than two samples.
    fn covariance(&self, sum: f64) -> f64 {
        if self.n < 2 {
            f64::NAN
        } else {
            sum / (self.n - 1) as f64
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::VectorField;

    /// A 2 × 1 grid series of the given (u, v) per field, the second node invalid.
    fn series(values: &[(f32, f32)], times: &[i64]) -> FieldSeries {
        let mut s = FieldSeries::on_grid(vec![0.0, 16.0], vec![0.0]);
        for (&(u, v), &t) in values.iter().zip(times) {
            let mut f = VectorField::new(vec![0.0, 16.0], vec![0.0]);
            f.u = vec![u, 99.0];
            f.v = vec![v, 99.0];
            f.status = vec![Status::VALID, Status::MEDIAN_TEST];
            s.push(t, &f).unwrap();
        }
        s
    }

    #[test]
    fn moments_of_a_known_sample_and_invalid_vectors_left_out() {
        let values = [(1.0, 2.0), (3.0, 0.0), (5.0, 4.0), (7.0, 2.0)];
        let s = series(&values, &[0, 10, 20, 30]);
        let st = flow_statistics(&s, &StatsOptions::default()).unwrap();
        assert_eq!(st.count, vec![4, 0]);
        assert!((st.u_mean[0] - 4.0).abs() < 1e-12 && (st.v_mean[0] - 2.0).abs() < 1e-12);
        // Sample variances: u 20/3, v 8/3; covariance (−3·0 + −1·−2 + 1·2 + 3·0)/3 = 4/3.
        assert!((st.uu[0] - 20.0 / 3.0).abs() < 1e-12);
        assert!((st.vv[0] - 8.0 / 3.0).abs() < 1e-12);
        assert!((st.uv[0] - 4.0 / 3.0).abs() < 1e-12);
        assert!(
            st.u_mean[1].is_nan() && st.uu[1].is_nan(),
            "no sample: NaN, not zero"
        );
    }

    #[test]
    fn phase_averaging_sorts_fields_by_their_phase() {
        // Period 40 µs, 2 phases: times 0, 40, 80 in phase 0 (u = 1), 20, 60 in phase 1 (u = 5).
        let values = [(1.0, 0.0), (5.0, 0.0), (1.0, 0.0), (5.0, 0.0), (1.0, 0.0)];
        let s = series(&values, &[0, 20, 40, 60, 80]);
        let options = StatsOptions {
            period_us: Some(40),
            phases: 2,
            ..StatsOptions::default()
        };
        let st = flow_statistics(&s, &options).unwrap();
        assert_eq!(st.phases, 2);
        assert_eq!((st.count[0], st.count[2]), (3, 2));
        assert_eq!((st.u_mean[0], st.u_mean[2]), (1.0, 5.0));
        assert_eq!(st.uu[0], 0.0);
        assert_eq!(st.phase_centres_us, vec![10.0, 30.0]);
        let bad = StatsOptions {
            period_us: Some(0),
            phases: 2,
            ..StatsOptions::default()
        };
        assert!(flow_statistics(&s, &bad).is_err());
    }
}
