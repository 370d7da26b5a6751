//! Figures of particle tracks: the tracks drawn over the events they were fitted to,
//! coloured by speed, and histograms of track length and fit residual — the first look at
//! whether tracking followed the particles, and how closely the paths fit their events.

use super::axes::{format_value, Axes, ColourBar, ImageFigure, ImageFigureStyle};
use super::colormap::inferno;
use super::draw::{line, Colour};
use super::histogram::histogram;
use super::plot::{figure, Layer, Panel, BLUE};
use super::rate_map::EventRateMap;
use super::vector_map::auto_range;
use crate::error::{Error, Result};
use crate::event::Geometry;
use crate::export::TrackTable;
use image::RgbImage;
use std::ops::Range;

/// Indices into [`TrackTable::values`] (the columns of
/// [`crate::export::TRACK_COLUMNS`] from `x` on).
const X: usize = 0;
const Y: usize = 1;
const U: usize = 2;
const V: usize = 3;
const RESIDUAL: usize = 14;

/// Label of the colour bar of [`track_map`].
const SPEED_LABEL: &str = "speed (px/ms)";
/// Grey of the pixels with the most events in the background of [`track_map`]: dim, so the
/// coloured tracks stand out.
const EVENT_GREY: f64 = 110.0;
/// Colour of track segments without a finite speed.
const NO_SPEED: Colour = [170, 170, 170];

/// How a track map is drawn. `Default` chooses everything automatically.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackMapStyle {
    /// Title above the plot.
    pub title: Option<String>,
    /// Output pixels per sensor pixel, 1 to [`super::MAX_PIXEL_SCALE`]; `None`: so that the
    /// image is at least 640 px wide (at most 8), as the other figures of the sensor.
    pub pixel_scale: Option<u32>,
    /// Speeds at the ends of the colour map, px/ms; `None`: 0 to the 99th percentile of the
    /// sample speeds, rounded up to two significant digits.
    pub speed_range: Option<(f64, f64)>,
    /// Time subtracted from the times in the caption, µs (e.g. the first event's, so that
    /// times read as in the command line); 0 shows camera time.
    pub time_origin_us: i64,
}

impl TrackMapStyle {
    fn figure_style(&self) -> ImageFigureStyle {
        ImageFigureStyle {
            title: self.title.clone(),
            pixel_scale: self.pixel_scale,
            time_origin_us: self.time_origin_us,
        }
    }
}

/// The tracks as polylines through their samples over a dim grey image of the events, with
/// axes in sensor pixels, a colour bar of the speed |(u, v)| and a caption with the number
/// of tracks, their mean length and the interval they span. Each segment takes the colour of
/// the mean speed of its two samples, so accelerations show along a track; segments without
/// a finite speed are light grey, samples without a finite position break the line, and
/// tracks of a single sample are dots.
///
/// `events` holds the events per pixel, e.g. of the interval tracked; it must have been made
/// for `geometry` (`EventRateMap::new(geometry)`). `None` draws the tracks on black. An
/// empty table gives the figure with the caption "no tracks". An error for a sensor without
/// pixels, an enlargement out of range (see [`ImageFigureStyle::scale_for`]) or a speed range
/// that is not finite and increasing.
pub fn track_map(
    events: Option<&EventRateMap>,
    tracks: &TrackTable,
    geometry: Geometry,
    style: &TrackMapStyle,
) -> Result<RgbImage> {
    let (w, h) = (geometry.width, geometry.height);
    if w == 0 || h == 0 {
        return Err(Error::empty("track map", "the sensor has no pixels"));
    }
    let k = style.figure_style().scale_for(w, h)?;
    let range = speed_range(tracks, style)?;
    let ranges = track_ranges(tracks);
    let (figure, mut img) = ImageFigure::new(
        (w as f64, h as f64),
        ((w * k) as f64, (h * k) as f64),
        style.title.clone(),
        Some(ColourBar::linear(range, SPEED_LABEL, speed_colour)),
        map_caption(tracks, &ranges, style, events.is_some()),
    );
    let background = super::upscale(&event_background(events, geometry), k);
    let area = figure.axes.area;
    image::imageops::replace(&mut img, &background, area.x0 as i64, area.y0 as i64);
    let width = (1.0 + 0.25 * k as f64).min(3.0);
    draw_tracks(&mut img, &figure.axes, tracks, &ranges, range, width);
    figure.decorate(&mut img);
    Ok(img)
}

/// Two histograms side by side: the length of the tracks (ms, first to last sample, one
/// value per track) and the fit residual (px, RMS distance of the fit window's events from
/// the path, one value per sample), each with its count, median, and the values outside its
/// range or not finite. Long tracks and small residuals mean the tracker followed the
/// particles; a tail of large residuals shows paths that stray from their events.
/// An empty table gives empty panels with the caption "no tracks".
pub fn track_histograms(tracks: &TrackTable) -> Result<RgbImage> {
    let ranges = track_ranges(tracks);
    let lengths: Vec<f32> = track_lengths_ms(tracks, &ranges)
        .map(|l| l as f32)
        .collect();
    let residuals: Vec<f32> = tracks.values[RESIDUAL][..samples(tracks)]
        .iter()
        .map(|&r| r as f32)
        .collect();
    let panels = [
        histogram_panel(&lengths, "track length", ("length", "ms"), "tracks"),
        histogram_panel(&residuals, "fit residual", ("residual", "px"), "samples"),
    ];
    let caption = if ranges.is_empty() {
        vec!["no tracks".to_string()]
    } else {
        vec![
            format!("{} tracks, {} samples", ranges.len(), samples(tracks)),
            "length: first to last sample, one value per track".into(),
            "residual: RMS distance of the fit window's events from the path, one value per \
             sample"
                .into(),
        ]
    };
    Ok(figure(&panels, None, &caption))
}

/// The number of samples all columns hold, so that a table with columns of unequal length
/// is read as far as it is whole.
fn samples(tracks: &TrackTable) -> usize {
    tracks
        .values
        .iter()
        .map(Vec::len)
        .fold(tracks.track_id.len().min(tracks.t_us.len()), usize::min)
}

/// The samples of each track: runs of consecutive samples with one `track_id`.
fn track_ranges(tracks: &TrackTable) -> Vec<Range<usize>> {
    let ids = &tracks.track_id[..samples(tracks)];
    let mut ranges = Vec::new();
    let mut start = 0;
    for i in 1..=ids.len() {
        if i == ids.len() || ids[i] != ids[start] {
            ranges.push(start..i);
            start = i;
        }
    }
    ranges
}

/// Length of each track, ms: first to last sample.
fn track_lengths_ms<'a>(
    tracks: &'a TrackTable,
    ranges: &'a [Range<usize>],
) -> impl Iterator<Item = f64> + 'a {
    ranges
        .iter()
        .map(|r| tracks.t_us[r.end - 1].saturating_sub(tracks.t_us[r.start]) as f64 / 1000.0)
}

/// Speed |(u, v)| of sample `i`, px/ms.
fn speed(tracks: &TrackTable, i: usize) -> f64 {
    tracks.values[U][i].hypot(tracks.values[V][i])
}

/// The speeds at the ends of the colour map: `style.speed_range`, or 0 to the 99th
/// percentile of the finite sample speeds rounded up (as the vector maps).
fn speed_range(tracks: &TrackTable, style: &TrackMapStyle) -> Result<(f64, f64)> {
    if let Some((lo, hi)) = style.speed_range {
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(Error::parameter(
                "speed_range",
                format!("{lo} to {hi}: the speeds must be finite and increasing"),
            ));
        }
        return Ok((lo, hi));
    }
    let speeds: Vec<f32> = (0..samples(tracks))
        .map(|i| speed(tracks, i) as f32)
        .filter(|s| s.is_finite())
        .collect();
    let (lo, hi) = auto_range(&speeds);
    Ok((lo as f64, hi as f64))
}

/// The colour of a track at `s` ∈ [0, 1] of the speed range: the brighter part of inferno,
/// which stays visible on the dark event image.
fn speed_colour(s: f32) -> Colour {
    let s = if s.is_finite() {
        s.clamp(0.0, 1.0)
    } else {
        0.0
    };
    inferno(0.4 + 0.6 * s)
}

/// The colour of the segment from sample `a` to `b`: the mean of their finite speeds.
fn segment_colour(tracks: &TrackTable, a: usize, b: usize, range: (f64, f64)) -> Colour {
    let finite: Vec<f64> = [speed(tracks, a), speed(tracks, b)]
        .into_iter()
        .filter(|s| s.is_finite())
        .collect();
    if finite.is_empty() {
        return NO_SPEED;
    }
    let mean = finite.iter().sum::<f64>() / finite.len() as f64;
    speed_colour(((mean - range.0) / (range.1 - range.0)) as f32)
}

/// Draw each track as a polyline `width` output px wide, clipped to the plot area.
fn draw_tracks(
    img: &mut RgbImage,
    axes: &Axes,
    tracks: &TrackTable,
    ranges: &[Range<usize>],
    range: (f64, f64),
    width: f64,
) {
    let at = |i: usize| (axes.px(tracks.values[X][i]), axes.py(tracks.values[Y][i]));
    for r in ranges {
        let last = r.end - 1;
        for a in r.start..last.max(r.start + 1) {
            let b = (a + 1).min(last);
            let colour = segment_colour(tracks, a, b, range);
            line(img, at(a), at(b), width, colour, &axes.area);
        }
    }
}

/// Events per pixel as a dim grey image, on a square-root scale saturating at the 99.9th
/// percentile of the pixels with events (as the rate maps); black without events.
fn event_background(events: Option<&EventRateMap>, geometry: Geometry) -> RgbImage {
    let (w, h) = (geometry.width, geometry.height);
    let Some(map) = events else {
        return RgbImage::new(w, h);
    };
    let mut active: Vec<u32> = (0..h)
        .flat_map(|y| (0..w).map(move |x| map.count(x, y)))
        .filter(|&c| c > 0)
        .collect();
    let top = if active.is_empty() {
        1.0
    } else {
        let i = ((active.len() as f64 * 0.999) as usize).min(active.len() - 1);
        *active.select_nth_unstable(i).1 as f64
    };
    RgbImage::from_fn(w, h, |x, y| {
        let g = EVENT_GREY * (map.count(x, y) as f64 / top).min(1.0).sqrt();
        image::Rgb([g.round() as u8; 3])
    })
}

/// The caption of [`track_map`]: how many tracks, their mean length, the interval they span
/// and what the colours mean.
fn map_caption(
    tracks: &TrackTable,
    ranges: &[Range<usize>],
    style: &TrackMapStyle,
    events: bool,
) -> Vec<String> {
    let colours = if events {
        "colour: speed along each track, grey: events per pixel (square-root scale)"
    } else {
        "colour: speed along each track"
    };
    if ranges.is_empty() {
        return vec!["no tracks".into(), colours.into()];
    }
    let mean = track_lengths_ms(tracks, ranges).sum::<f64>() / ranges.len() as f64;
    let times = &tracks.t_us[..samples(tracks)];
    let first = times.iter().copied().min().unwrap_or(0);
    let last = times.iter().copied().max().unwrap_or(0);
    let figure = style.figure_style();
    vec![
        format!(
            "{} tracks, mean length {} ms, from {} to {}",
            ranges.len(),
            format_value(mean, mean.abs().max(1e-3) / 100.0),
            figure.time(first),
            figure.time(last)
        ),
        colours.into(),
    ]
}

/// A panel of the histogram of the finite `values` of `quantity` = (name, unit), counted in
/// `unit_count`s, with the count, the median and the values outside the range or not finite
/// as notes.
fn histogram_panel(
    values: &[f32],
    heading: &str,
    (name, unit): (&str, &str),
    unit_count: &str,
) -> Panel {
    let h = histogram(values, 0, None);
    let bins = h.counts.len();
    let edges = (0..=bins)
        .map(|i| h.lo + (h.hi - h.lo) * i as f64 / bins as f64)
        .collect();
    let heights = h.counts.iter().map(|&c| c as f64).collect();
    let tallest = h.counts.iter().copied().max().unwrap_or(0).max(1) as f64;
    let mut notes = vec![format!("n = {} {unit_count}", h.total())];
    let mut finite: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if !finite.is_empty() {
        let mid = finite.len() / 2;
        let median = *finite.select_nth_unstable_by(mid, f32::total_cmp).1 as f64;
        notes.push(format!(
            "median {} {unit}",
            format_value(median, (h.hi - h.lo) / 100.0)
        ));
    }
    if h.below + h.above > 0 {
        notes.push(format!("{} outside", h.below + h.above));
    }
    let not_finite = values.len() - finite.len();
    if not_finite > 0 {
        notes.push(format!("{not_finite} not finite"));
    }
    Panel {
        heading: heading.into(),
        x_label: format!("{name} [{unit}]"),
        y_label: unit_count.into(),
        x_range: (h.lo, h.hi),
        y_range: (0.0, tallest * 1.35),
        layers: vec![Layer::Bars {
            edges,
            heights,
            colour: BLUE,
        }],
        notes: notes.into_iter().map(|n| (None, n)).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::event::{EventBuffer, PolaritySelection};
    use crate::export::TRACK_COLUMNS;
    use crate::render::axes::probe::{colour_bar_column, near, plot_frame};

    /// A sample: t µs, x, y, u, v.
    type Sample = (i64, f64, f64, f64, f64);

    /// A table of tracks, each given as its samples, with residual 0.2 px.
    fn table(tracks: &[Vec<Sample>]) -> TrackTable {
        let mut t = TrackTable::default();
        for (id, samples) in tracks.iter().enumerate() {
            for &(time, x, y, u, v) in samples {
                t.track_id.push(id as u64);
                t.t_us.push(time);
                let mut row = [0.0; 15];
                row[X] = x;
                row[Y] = y;
                row[U] = u;
                row[V] = v;
                row[RESIDUAL] = 0.2;
                for (column, value) in t.values.iter_mut().zip(row) {
                    column.push(value);
                }
            }
        }
        t
    }

    /// Two straight tracks at 0.5 and 1 px/ms and a circle of radius 10 px at 0.75 px/ms,
    /// sampled every 0.5 ms.
    fn synthetic() -> TrackTable {
        let straight = |y: f64, speed: f64| -> Vec<_> {
            (0..=80)
                .map(|i| {
                    let ms = i as f64 * 0.5;
                    (i * 500, 5.0 + speed * ms, y, speed, 0.0)
                })
                .collect()
        };
        let omega = 0.075;
        let circle = (0..=84)
            .map(|i| {
                let ms = i as f64 * 0.5;
                let a = omega * ms;
                let (x, y) = (40.0 + 10.0 * a.cos(), 30.0 + 10.0 * a.sin());
                (i * 500, x, y, -0.75 * a.sin(), 0.75 * a.cos())
            })
            .collect();
        table(&[straight(6.0, 0.5), straight(14.0, 1.0), circle])
    }

    fn fixed_range() -> TrackMapStyle {
        TrackMapStyle {
            speed_range: Some((0.0, 1.0)),
            ..Default::default()
        }
    }

    #[test]
    fn column_indices_name_the_columns() {
        for (i, name) in [
            (X, "x"),
            (Y, "y"),
            (U, "u"),
            (V, "v"),
            (RESIDUAL, "residual"),
        ] {
            assert_eq!(TRACK_COLUMNS[i + 2].0, name);
        }
    }

    #[test]
    fn tracks_are_drawn_in_the_colour_of_their_speed() {
        let tracks = synthetic();
        assert_eq!(track_ranges(&tracks), [0..81, 81..162, 162..247]);
        let img = track_map(None, &tracks, Geometry::new(64, 48), &fixed_range()).unwrap();
        let (l, t, r, b) = plot_frame(&img);
        // A small sensor is enlarged 8 times, as the other figures of the sensor.
        assert_eq!((r - l - 1, b - t - 1), (512, 384));
        let at = |x: f64, y: f64| {
            let p = (
                l as f64 + 1.0 + 8.0 * (x + 0.5),
                t as f64 + 1.0 + 8.0 * (y + 0.5),
            );
            img.get_pixel(p.0 as u32, p.1 as u32).0
        };
        assert!(
            near(at(15.0, 6.0), speed_colour(0.5)),
            "{:?}",
            at(15.0, 6.0)
        );
        assert!(near(at(30.0, 14.0), speed_colour(1.0)));
        assert!(
            near(at(50.0, 30.0), speed_colour(0.75)),
            "circle at angle 0"
        );
        assert!(
            near(at(40.0, 40.0), speed_colour(0.75)),
            "circle at angle 90°"
        );
        assert_eq!(at(40.0, 30.0), [0, 0, 0], "inside the circle");
        assert_eq!(at(5.0, 40.0), [0, 0, 0], "away from the tracks");
        let coloured = (l + 1..r)
            .flat_map(|x| (t + 1..b).map(move |y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0 != [0, 0, 0])
            .count();
        assert!(coloured > 2_000, "{coloured} track pixels");
        assert!(colour_bar_column(&img, speed_colour(1.0), speed_colour(0.0)).is_some());
    }

    #[test]
    fn events_are_a_dim_grey_background() {
        let mut events = EventBuffer::new();
        for t in 0..10 {
            events.push(t * 100, 60, 2, 1);
        }
        events.push(0, 60, 40, 1);
        let g = Geometry::new(64, 48);
        let mut map = EventRateMap::new(g);
        map.add(&events, 0, 1_000, PolaritySelection::Both);
        let bg = event_background(Some(&map), g);
        assert_eq!(bg.get_pixel(60, 2).0, [110; 3]);
        assert_eq!(bg.get_pixel(60, 40).0, [35; 3], "sqrt(1/10) of the top");
        assert_eq!(bg.get_pixel(0, 0).0, [0; 3]);
        let style = TrackMapStyle {
            pixel_scale: Some(8),
            ..fixed_range()
        };
        let img = track_map(Some(&map), &synthetic(), g, &style).unwrap();
        let (l, t, ..) = plot_frame(&img);
        assert_eq!(img.get_pixel(l + 1 + 484, t + 1 + 20).0, [110; 3]);
    }

    #[test]
    fn caption_counts_tracks_and_their_mean_length() {
        let tracks = synthetic();
        let style = TrackMapStyle {
            time_origin_us: 1_000,
            ..Default::default()
        };
        let caption = map_caption(&tracks, &track_ranges(&tracks), &style, true);
        assert_eq!(
            caption[0],
            "3 tracks, mean length 40.7 ms, from -1.000 ms to 41.000 ms"
        );
        assert!(caption[1].contains("grey: events"));
    }

    #[test]
    fn a_full_size_sensor_is_drawn_one_to_one() {
        let img = track_map(
            None,
            &synthetic(),
            Geometry::new(1280, 720),
            &Default::default(),
        )
        .unwrap();
        let (l, t, r, b) = plot_frame(&img);
        assert_eq!((r - l - 1, b - t - 1), (1280, 720));
        assert!(img.width() < 1600 && img.height() < 900);
    }

    #[test]
    fn histograms_show_lengths_and_residuals() {
        use crate::render::histogram::tests::bar_heights;
        let img = track_histograms(&synthetic()).unwrap();
        let middle = img.width() / 2;
        assert!(!bar_heights(&img, 0).is_empty());
        assert!(!bar_heights(&img, middle).is_empty(), "residual bars");
        assert!(img.width() > 800);
    }

    #[test]
    fn empty_and_broken_tables_do_not_panic() {
        let empty = TrackTable::default();
        let g = Geometry::new(64, 48);
        let img = track_map(None, &empty, g, &Default::default()).unwrap();
        assert!(img.width() > 512);
        assert_eq!(
            map_caption(&empty, &[], &Default::default(), false),
            ["no tracks", "colour: speed along each track"]
        );
        assert!(track_histograms(&empty).unwrap().width() > 800);

        let mut odd = synthetic();
        odd.values[X][3] = f64::NAN;
        odd.values[U][90] = f64::NAN;
        odd.values[U][100] = f64::INFINITY;
        odd.values[RESIDUAL][5] = f64::NAN;
        odd.values[Y][200] = 1e300;
        track_map(None, &odd, g, &Default::default()).unwrap();
        track_histograms(&odd).unwrap();
        odd.values[RESIDUAL].truncate(10);
        let ranges = track_ranges(&odd);
        assert_eq!((ranges.len(), ranges[0].clone()), (1, 0..10));
        track_map(None, &odd, g, &Default::default()).unwrap();
        track_histograms(&odd).unwrap();
        let mut nan = table(&[vec![(0, 1.0, 1.0, f64::NAN, f64::NAN)]]);
        nan.values[RESIDUAL][0] = f64::NAN;
        track_map(None, &nan, g, &Default::default()).unwrap();
        track_histograms(&nan).unwrap();
    }

    #[test]
    fn bad_parameters_are_errors() {
        let tracks = synthetic();
        let g = Geometry::new(64, 48);
        for range in [(1.0, 1.0), (0.0, f64::NAN), (2.0, 1.0)] {
            let style = TrackMapStyle {
                speed_range: Some(range),
                ..Default::default()
            };
            let e = track_map(None, &tracks, g, &style).unwrap_err();
            assert!(e.to_string().contains("speed_range"), "{e}");
        }
        let style = TrackMapStyle {
            pixel_scale: Some(0),
            ..Default::default()
        };
        assert!(track_map(None, &tracks, g, &style).is_err());
        assert!(track_map(None, &tracks, Geometry::new(0, 10), &Default::default()).is_err());
    }
}
