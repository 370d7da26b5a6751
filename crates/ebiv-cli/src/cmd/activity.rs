//! `ebiv info --activity`: the options and the printout of the pixel-activity statistics.

use clap::Args;
use ebiv::activity::{Activity, ActivityReport, ActivitySettings};
use ebiv::filter::{EventFilter, Roi};
use ebiv::io::ReadOptions;
use ebiv::units::format_us;
use ebiv::{EventBuffer, Geometry, PolaritySelection};
use std::path::Path;

/// What `--activity` measures, and on which events.
#[derive(Debug, Args)]
pub struct ActivityArgs {
    /// Also measure pixel activity: events per active pixel, time between a pixel's events,
    /// share of pixels with any event, events per window and slab, particle trail width
    /// (definitions: docs/calibration.md).
    #[arg(long)]
    pub activity: bool,
    /// Activity: polarities counted (pos, neg or both).
    #[arg(long, default_value = "both", value_parser = super::convert::parse_polarity, requires = "activity")]
    pub polarity: PolaritySelection,
    /// Activity: only the region x,y,width,height.
    #[arg(long, value_name = "X,Y,W,H", value_parser = parse_roi, requires = "activity")]
    pub roi: Option<Roi>,
    /// Activity: only START:END (e.g. `0ms:20ms`), from the first event of the recording (or
    /// in camera time with --absolute-time); slabs start at START.
    #[arg(long, visible_alias = "time", value_name = "START:END", value_parser = ebiv::units::parse_range, requires = "activity")]
    pub time_range: Option<(Option<i64>, Option<i64>)>,
    /// Read --time-range as camera time stamps in µs rather than from the first event.
    #[arg(long, requires = "activity")]
    pub absolute_time: bool,
    /// Activity: side of the square windows whose events are counted, px [default: 40].
    #[arg(long, value_name = "PX", requires = "activity")]
    pub window: Option<u32>,
    /// Activity: length of the time slabs of the window counts and trail widths (e.g. `10ms`)
    /// [default: 10ms].
    #[arg(long, value_parser = ebiv::units::parse_us, requires = "activity")]
    pub slab: Option<i64>,
}

fn parse_roi(s: &str) -> Result<Roi, String> {
    Roi::parse(s).map_err(|e| e.to_string())
}

/// The accumulator and its event selection, set up once the file's geometry is known.
pub struct ActivityRun {
    filter: EventFilter,
    activity: Activity,
    scratch: EventBuffer,
}

impl ActivityArgs {
    /// The selection and the accumulator for `path`, whose sensor is `geometry` (if stated).
    pub fn start(
        &self,
        path: &Path,
        options: &ReadOptions,
        geometry: Option<Geometry>,
    ) -> Result<ActivityRun, ebiv::Error> {
        let first = ebiv::process::first_event_time(path, options)?;
        let origin = if self.absolute_time {
            0
        } else {
            first.unwrap_or(0)
        };
        let (start, end) = self.time_range.unwrap_or((None, None));
        let filter = EventFilter {
            t_start: start.map(|s| s + origin),
            t_end: end.map(|e| e + origin),
            roi: self.roi,
            polarity: self.polarity,
        };
        let geometry = match (self.roi, geometry) {
            (Some(roi), Some(g)) => {
                roi.check_within(g)?;
                roi.geometry()
            }
            (Some(roi), None) => roi.geometry(),
            (None, Some(g)) => g,
            (None, None) => {
                return Err(ebiv::Error::parameter(
                    "geometry",
                    "the file does not state its sensor size, which the share of active pixels needs; pass --geometry WxH or --roi X,Y,W,H",
                ))
            }
        };
        let defaults = ActivitySettings::default();
        let settings = ActivitySettings {
            window_px: self.window.unwrap_or(defaults.window_px),
            slab_us: self.slab.unwrap_or(defaults.slab_us),
        };
        let slab_origin = filter.t_start.or(first).unwrap_or(0);
        Ok(ActivityRun {
            activity: Activity::new(geometry, slab_origin, filter.t_end, settings)?,
            filter,
            scratch: EventBuffer::new(),
        })
    }
}

impl ActivityRun {
    /// Add the selected events of a batch.
    pub fn add(&mut self, batch: &EventBuffer) -> Result<(), ebiv::Error> {
        self.scratch.clear();
        self.scratch.extend_from(batch);
        self.filter.apply(&mut self.scratch);
        self.activity.add(&self.scratch)
    }

    /// The statistics, and a line describing the selection.
    pub fn finish(self) -> (ActivityReport, String) {
        let f = &self.filter;
        let mut what = format!("polarity {}", f.polarity.name());
        if let Some(r) = f.roi {
            what += &format!(", region {},{} {}x{}", r.x, r.y, r.width, r.height);
        }
        match (f.t_start, f.t_end) {
            (None, None) => what += ", whole recording",
            (a, b) => {
                let side = |t: Option<i64>| t.map_or(String::new(), |t| format!("{t}"));
                what += &format!(", t {} .. {} µs", side(a), side(b));
            }
        }
        (self.activity.finish(), what)
    }
}

/// Print the statistics as text.
pub fn print(report: &ActivityReport, selection: &str) {
    let ms = |us: f64| us * 1e-3;
    println!("activity    {selection}");
    println!("  events                            {}", report.events);
    match report.events_per_active_pixel {
        Some([m, p90]) => {
            println!("  events per active pixel           median {m:.1}, 90th percentile {p90:.1}")
        }
        None => println!("  events per active pixel           none (no events)"),
    }
    match report.gap_us {
        Some([a, b, c]) => println!(
            "  time between a pixel's events     10/50/90 %: {:.2} / {:.2} / {:.2} ms ({} gaps)",
            ms(a),
            ms(b),
            ms(c),
            report.gaps
        ),
        None => println!("  time between a pixel's events     none (no pixel fired twice)"),
    }
    println!(
        "  pixels with any event             {:.1} % ({} of {})",
        100.0 * report.active_share,
        report.active_pixels,
        report.pixels
    );
    let s = report.settings;
    let cell = format!("{0}x{0} px in {1}", s.window_px, format_us(s.slab_us));
    match report.window_events {
        Some([a, b, c]) => println!(
            "  events per {cell:<22} 5/50/95 %: {a:.0} / {b:.0} / {c:.0} ({} windows in {} slabs)",
            report.window_cells, report.slabs
        ),
        None => println!(
            "  events per {cell:<22} none (no whole window and slab; see --window, --slab)"
        ),
    }
    match report.trail_width_px {
        Some([a, b, c]) => println!(
            "  trail width                       25/50/75 %: {a:.2} / {b:.2} / {c:.2} px ({} trails)",
            report.trails
        ),
        None => println!("  trail width                       none (no elongated trail in a whole slab)"),
    }
    if report.late_events > 0 {
        println!(
            "  warning: {} events more than a slab out of time order were left out of the window counts and trails",
            report.late_events
        );
    }
}
