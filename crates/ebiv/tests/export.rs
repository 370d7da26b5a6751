//! Field writers: every format written and read back (NetCDF with the netcdf3 reader, CSV,
//! NPZ through zip and the .npy header, Tecplot and VTK by parsing), checking values,
//! shapes, NaN, status flags, the per-vector time slab `slab_us`, the per-vector standard
//! uncertainty `u_unc`, `v_unc` and the calibration's sign convention (y up flips y and v,
//! never an uncertainty).

use ebiv::export::{
    vtk_series_paths, write_field, write_field_csv, write_field_netcdf, write_field_npz,
    write_field_tecplot, write_field_vtk, TECPLOT_MISSING,
};
use ebiv::field::{Calibration, FieldSeries, Status};
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

const MM_PER_PX: f64 = 0.02;
const ORIGIN: [f64; 2] = [8.0, 24.0];

/// 2 times × 2 rows × 3 columns with NaN vectors, flags and an undefined peak ratio.
fn series(calibrated: bool) -> FieldSeries {
    let mut f = FieldSeries::new(vec![8.0, 24.0, 40.0], vec![8.0, 24.0], vec![1_000, 3_500]);
    for i in 0..f.u.len() {
        f.u[i] = 0.25 + 0.5 * i as f32;
        f.v[i] = 1.0 - 0.75 * i as f32;
        f.u_unc[i] = 0.01 + 0.002 * i as f32;
        f.v_unc[i] = 0.03 + 0.001 * i as f32;
        f.status[i] = Status::VALID;
        f.peak[i] = 10.0 + i as f32;
        f.peak_ratio[i] = 1.25 + i as f32 / 8.0;
        f.event_count[i] = 1000 + 7 * i as u32;
        // Distinct per vector, beyond 16 bits, as adaptive slabs would give.
        f.slab_us[i] = 70_000 + 1_000 * i as u32;
    }
    // t 0, row 1, col 2: no events. t 1, row 0, col 1: median test, replaced (has a value).
    let a = f.index(0, 1, 2);
    f.u[a] = f32::NAN;
    f.v[a] = f32::NAN;
    f.peak[a] = f32::NAN;
    f.peak_ratio[a] = f32::NAN;
    f.event_count[a] = 0;
    f.status[a] = Status::NO_EVENTS;
    let b = f.index(1, 0, 1);
    f.status[b] = Status::MEDIAN_TEST | Status::REPLACED;
    let c = f.index(1, 1, 0);
    f.u[c] = f32::NAN;
    f.v[c] = f32::NAN;
    // Invalid and replaced vectors have no uncertainty; (t 0, row 0, col 0) is valid with
    // an unknown one.
    for k in [a, b, c, f.index(0, 0, 0)] {
        f.u_unc[k] = f32::NAN;
        f.v_unc[k] = f32::NAN;
    }
    f.status[c] = Status::LOW_PEAK_RATIO | Status::MASKED;
    f.slab_us[c] = 0;
    f.attributes
        .push(("source file".into(), "recording \"A\".raw".into()));
    f.attributes.push(("tau_us".into(), "250".into()));
    if calibrated {
        f.calibration = Some(Calibration {
            mm_per_px: MM_PER_PX,
            origin_px: ORIGIN,
            y_up: true,
        });
    }
    f
}

/// Expected written position and velocity of vector `(t, row, col)`, computed here
/// independently of the library: mm and m/s with y and v flipped, or px and px/ms.
fn expected(f: &FieldSeries, t: usize, row: usize, col: usize) -> [f64; 4] {
    let i = f.index(t, row, col);
    let (x, y, u, v) = (f.x[col], f.y[row], f.u[i] as f64, f.v[i] as f64);
    if f.calibration.is_some() {
        [
            (x - ORIGIN[0]) * MM_PER_PX,
            -(y - ORIGIN[1]) * MM_PER_PX,
            u * MM_PER_PX,
            -v * MM_PER_PX,
        ]
    } else {
        [x, y, u, v]
    }
}

/// Expected written uncertainty `(u_unc, v_unc)` of vector `i`: scaled to m/s by the
/// calibration, never flipped.
fn expected_unc(f: &FieldSeries, i: usize) -> [f64; 2] {
    let scale = if f.calibration.is_some() {
        MM_PER_PX
    } else {
        1.0
    };
    [f.u_unc[i] as f64 * scale, f.v_unc[i] as f64 * scale]
}

/// `a` equals `b` to single precision, NaN matching NaN.
fn same(a: f64, b: f64) -> bool {
    (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-6 * (1.0 + b.abs())
}

fn assert_same(what: &str, a: f64, b: f64) {
    assert!(same(a, b), "{what}: got {a}, expected {b}");
}

fn each_vector(f: &FieldSeries) -> impl Iterator<Item = (usize, usize, usize, usize)> + '_ {
    (0..f.t_us.len()).flat_map(move |t| {
        (0..f.y.len()).flat_map(move |r| (0..f.x.len()).map(move |c| (t, r, c, f.index(t, r, c))))
    })
}

// ---------------------------------------------------------------- NetCDF

#[test]
fn netcdf_round_trip() {
    for calibrated in [false, true] {
        let f = series(calibrated);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("field.nc");
        write_field_netcdf(&f, &path).unwrap();
        let (ds, _) = netcdf3::FileReader::open(&path).unwrap().close();
        assert_eq!(ds.dim_size("time"), Some(2));
        assert_eq!(ds.dim_size("y"), Some(2));
        assert_eq!(ds.dim_size("x"), Some(3));
        assert_eq!(
            ds.get_global_attr_as_string("source_file").as_deref(),
            Some("recording \"A\".raw")
        );
        assert_eq!(
            ds.get_global_attr_as_string("tau_us").as_deref(),
            Some("250")
        );
        // CF's `positive` is for vertical axes only; the direction is in the long name.
        assert_eq!(ds.get_var_attr_as_string("y", "positive"), None);
        let direction = if calibrated {
            "(up)"
        } else {
            "(down: image rows)"
        };
        assert!(ds
            .get_var_attr_as_string("y", "long_name")
            .unwrap()
            .ends_with(direction));
        let units = if calibrated {
            "m/s"
        } else {
            "pixel/millisecond"
        };
        for var in ["v", "u_unc", "v_unc"] {
            assert_eq!(
                ds.get_var_attr_as_string(var, "units").as_deref(),
                Some(units),
                "{var}"
            );
        }
        assert_eq!(
            ds.get_var_attr_as_string("u_unc", "long_name").as_deref(),
            Some("standard uncertainty of u (one standard deviation)")
        );
        let mut r = netcdf3::FileReader::open(&path).unwrap();
        assert_eq!(r.read_var_f64("time").unwrap(), vec![1_000.0, 3_500.0]);
        let (x, y) = (r.read_var_f64("x").unwrap(), r.read_var_f64("y").unwrap());
        let (u, v) = (r.read_var_f32("u").unwrap(), r.read_var_f32("v").unwrap());
        let u_unc = r.read_var_f32("u_unc").unwrap();
        let v_unc = r.read_var_f32("v_unc").unwrap();
        let status = r.read_var_i16("status").unwrap();
        let peak = r.read_var_f32("peak").unwrap();
        let ratio = r.read_var_f32("peak_ratio").unwrap();
        let count = r.read_var_i32("event_count").unwrap();
        let slab = r.read_var_i32("slab_us").unwrap();
        for (t, row, col, i) in each_vector(&f) {
            let e = expected(&f, t, row, col);
            assert_same("x", x[col], e[0]);
            assert_same("y", y[row], e[1]);
            assert_same("u", u[i] as f64, e[2]);
            assert_same("v", v[i] as f64, e[3]);
            let e_unc = expected_unc(&f, i);
            assert_same("u_unc", u_unc[i] as f64, e_unc[0]);
            assert_same("v_unc", v_unc[i] as f64, e_unc[1]);
            assert_eq!(status[i], f.status[i].0 as i16);
            assert_same("peak", peak[i] as f64, f.peak[i] as f64);
            assert_same("peak_ratio", ratio[i] as f64, f.peak_ratio[i] as f64);
            assert_eq!(count[i], f.event_count[i] as i32);
            assert_eq!(slab[i], f.slab_us[i] as i32);
        }
        assert_eq!(
            ds.get_var_attr_as_string("slab_us", "units").as_deref(),
            Some("us")
        );
        assert!(ds.get_var_attr_as_string("slab_us", "long_name").is_some());
        if calibrated {
            assert_eq!(r.read_var_f64("x_px").unwrap(), f.x);
            assert_eq!(r.read_var_f64("y_px").unwrap(), f.y);
        } else {
            assert!(r.read_var_f64("x_px").is_err());
        }
    }
}

// ---------------------------------------------------------------- CSV

#[test]
fn csv_round_trip() {
    for calibrated in [false, true] {
        let f = series(calibrated);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("field.csv");
        write_field_csv(&f, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(
            &header[..12],
            [
                "t_us",
                "x_px",
                "y_px",
                "u_px_ms",
                "v_px_ms",
                "u_unc_px_ms",
                "v_unc_px_ms",
                "status",
                "peak",
                "peak_ratio",
                "event_count",
                "slab_us"
            ]
        );
        if calibrated {
            assert_eq!(
                &header[12..],
                ["x_mm", "y_mm", "u_m_s", "v_m_s", "u_unc_m_s", "v_unc_m_s"]
            );
        } else {
            assert_eq!(header.len(), 12);
        }
        let rows: Vec<Vec<f64>> = lines
            .map(|l| l.split(',').map(|s| s.parse::<f64>().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 12);
        for ((t, row, col, i), r) in each_vector(&f).zip(&rows) {
            assert_eq!(r.len(), header.len());
            assert_eq!(r[0], f.t_us[t] as f64);
            // The first columns stay in image units whatever the calibration.
            assert_eq!([r[1], r[2]], [f.x[col], f.y[row]]);
            assert_same("u", r[3], f.u[i] as f64);
            assert_same("v", r[4], f.v[i] as f64);
            assert_same("u_unc", r[5], f.u_unc[i] as f64);
            assert_same("v_unc", r[6], f.v_unc[i] as f64);
            assert_eq!(r[7], f.status[i].0 as f64);
            assert_same("peak", r[8], f.peak[i] as f64);
            assert_same("peak_ratio", r[9], f.peak_ratio[i] as f64);
            assert_eq!(r[10], f.event_count[i] as f64);
            assert_eq!(r[11], f.slab_us[i] as f64);
            if calibrated {
                let e = expected(&f, t, row, col);
                let e_unc = expected_unc(&f, i);
                for (k, want) in e.into_iter().chain(e_unc).enumerate() {
                    assert_same(header[12 + k], r[12 + k], want);
                }
            }
        }
        assert!(text.contains(",NaN,NaN,NaN,NaN,1,NaN,NaN,0,75000"));
    }
}

// ---------------------------------------------------------------- NPZ

/// A parsed .npy member: descriptor, shape and raw little-endian data.
struct Npy {
    descr: String,
    shape: Vec<usize>,
    data: Vec<u8>,
}

fn parse_npy(bytes: &[u8]) -> Npy {
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!((10 + len) % 64, 0, "header not aligned");
    let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
    assert!(header.ends_with('\n'));
    assert!(header.contains("'fortran_order': False"));
    let descr = header.split("'descr': '").nth(1).unwrap();
    let descr = descr[..descr.find('\'').unwrap()].to_string();
    let shape = header.split("'shape': (").nth(1).unwrap();
    let shape: Vec<usize> = shape[..shape.find(')').unwrap()]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    Npy {
        descr,
        shape,
        data: bytes[10 + len..].to_vec(),
    }
}

impl Npy {
    fn len(&self) -> usize {
        self.shape.iter().product()
    }
    fn f64s(&self) -> Vec<f64> {
        assert_eq!(self.descr, "<f8");
        assert_eq!(self.data.len(), 8 * self.len());
        self.data
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }
    fn f32s(&self) -> Vec<f32> {
        assert_eq!(self.descr, "<f4");
        assert_eq!(self.data.len(), 4 * self.len());
        self.data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }
    fn i64s(&self) -> Vec<i64> {
        assert_eq!(self.descr, "<i8");
        self.data
            .chunks_exact(8)
            .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }
    fn u32s(&self) -> Vec<u32> {
        assert_eq!(self.descr, "<u4");
        self.data
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }
    fn strings(&self) -> Vec<String> {
        let width: usize = self.descr.strip_prefix("<U").unwrap().parse().unwrap();
        assert_eq!(self.data.len(), 4 * width * self.len());
        self.data
            .chunks_exact(4 * width)
            .map(|s| {
                s.chunks_exact(4)
                    .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
                    .take_while(|&c| c != 0)
                    .map(|c| char::from_u32(c).unwrap())
                    .collect()
            })
            .collect()
    }
}

fn read_npz(path: &Path) -> HashMap<String, Npy> {
    let mut zip = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
    let mut out = HashMap::new();
    for k in 0..zip.len() {
        let mut member = zip.by_index(k).unwrap();
        let name = member.name().strip_suffix(".npy").unwrap().to_string();
        let mut bytes = Vec::new();
        member.read_to_end(&mut bytes).unwrap();
        out.insert(name, parse_npy(&bytes));
    }
    out
}

#[test]
fn npz_round_trip() {
    for calibrated in [false, true] {
        let f = series(calibrated);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("field.npz");
        write_field_npz(&f, &path).unwrap();
        let a = read_npz(&path);
        let grid = vec![2, 2, 3];
        assert_eq!(a["x"].f64s(), f.x);
        assert_eq!(a["y"].f64s(), f.y);
        assert_eq!(a["t_us"].i64s(), f.t_us);
        for name in [
            "u",
            "v",
            "u_unc",
            "v_unc",
            "status",
            "peak",
            "peak_ratio",
            "event_count",
            "slab_us",
        ] {
            assert_eq!(a[name].shape, grid, "{name}");
        }
        let (u, v) = (a["u"].f32s(), a["v"].f32s());
        let (u_unc, v_unc) = (a["u_unc"].f32s(), a["v_unc"].f32s());
        let (peak, ratio) = (a["peak"].f32s(), a["peak_ratio"].f32s());
        assert_eq!(a["status"].descr, "|u1");
        let status = &a["status"].data;
        let count = a["event_count"].u32s();
        let slab = a["slab_us"].u32s();
        for (_, _, _, i) in each_vector(&f) {
            assert_same("u", u[i] as f64, f.u[i] as f64);
            assert_same("v", v[i] as f64, f.v[i] as f64);
            assert_same("u_unc", u_unc[i] as f64, f.u_unc[i] as f64);
            assert_same("v_unc", v_unc[i] as f64, f.v_unc[i] as f64);
            assert_same("peak", peak[i] as f64, f.peak[i] as f64);
            assert_same("peak_ratio", ratio[i] as f64, f.peak_ratio[i] as f64);
            assert_eq!(status[i], f.status[i].0);
            assert_eq!(count[i], f.event_count[i]);
            assert_eq!(slab[i], f.slab_us[i]);
        }
        let attributes = a["attributes"].strings();
        assert!(attributes.iter().any(|s| s.starts_with("slab_us=")));
        assert!(attributes.contains(&"source_file=recording \"A\".raw".to_string()));
        assert!(attributes.iter().any(|s| s.starts_with("axis_convention=")));
        if calibrated {
            assert!(attributes.contains(&"y_positive=up".to_string()));
            let (x, y) = (a["x_mm"].f64s(), a["y_mm"].f64s());
            let (um, vm) = (a["u_m_s"].f32s(), a["v_m_s"].f32s());
            let (uu, vu) = (a["u_unc_m_s"].f32s(), a["v_unc_m_s"].f32s());
            for name in ["u_m_s", "v_m_s", "u_unc_m_s", "v_unc_m_s"] {
                assert_eq!(a[name].shape, grid, "{name}");
            }
            for (t, row, col, i) in each_vector(&f) {
                let e = expected(&f, t, row, col);
                let e_unc = expected_unc(&f, i);
                assert_same("x_mm", x[col], e[0]);
                assert_same("y_mm", y[row], e[1]);
                assert_same("u_m_s", um[i] as f64, e[2]);
                assert_same("v_m_s", vm[i] as f64, e[3]);
                assert_same("u_unc_m_s", uu[i] as f64, e_unc[0]);
                assert_same("v_unc_m_s", vu[i] as f64, e_unc[1]);
            }
        } else {
            for name in ["x_mm", "u_m_s", "u_unc_m_s", "v_unc_m_s"] {
                assert!(!a.contains_key(name), "{name}");
            }
        }
    }
}

// ---------------------------------------------------------------- Tecplot

#[test]
fn tecplot_round_trip() {
    for calibrated in [false, true] {
        let f = series(calibrated);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("field.dat");
        write_field_tecplot(&f, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(!text.to_ascii_lowercase().contains("nan"));
        let unit = if calibrated { "mm" } else { "px" };
        let vunit = if calibrated { "m/s" } else { "px/ms" };
        let variables = format!(
            "VARIABLES = \"x [{unit}]\" \"y [{unit}]\" \"u [{vunit}]\" \"v [{vunit}]\" \
             \"u_unc [{vunit}]\" \"v_unc [{vunit}]\" \"status\" \"peak\" \"peak_ratio\" \
             \"event_count\" \"slab_us\""
        );
        assert!(text.lines().any(|l| l == variables), "{text}");
        assert!(text.contains("DATASETAUXDATA source_file=\"recording \\\"A\\\".raw\""));
        // Zones: header line, optional AUXDATA lines, then nx*ny points.
        let mut zones: Vec<(String, Vec<Vec<f64>>)> = Vec::new();
        for line in text.lines() {
            if line.starts_with("ZONE") {
                zones.push((line.to_string(), Vec::new()));
            } else if let Some((_, points)) = zones.last_mut() {
                if line.starts_with("AUXDATA") {
                    continue;
                }
                points.push(line.split(' ').map(|s| s.parse().unwrap()).collect());
            }
        }
        assert_eq!(zones.len(), 2);
        for (t, (zone, points)) in zones.iter().enumerate() {
            let time = f.t_us[t];
            assert!(zone.contains(&format!("T=\"t = {time} us\"")), "{zone}");
            assert!(zone.contains(&format!("SOLUTIONTIME={time}")));
            assert!(zone.contains("I=3, J=2") && zone.contains("DATAPACKING=POINT"));
            assert!(zone.contains("STRANDID=1"));
            assert_eq!(points.len(), 6);
            for (k, p) in points.iter().enumerate() {
                let (row, col) = (k / 3, k % 3);
                let i = f.index(t, row, col);
                let e = expected(&f, t, row, col);
                let missing = |want: f64| if want.is_nan() { TECPLOT_MISSING } else { want };
                assert_eq!(p.len(), 11);
                let e_unc = expected_unc(&f, i);
                let values = e.into_iter().chain(e_unc);
                for (j, (name, want)) in ["x", "y", "u", "v", "u_unc", "v_unc"]
                    .iter()
                    .zip(values)
                    .enumerate()
                {
                    assert_same(name, p[j], missing(want));
                }
                assert_eq!(p[6], f.status[i].0 as f64);
                assert_same("peak", p[7], missing(f.peak[i] as f64));
                assert_same("peak_ratio", p[8], missing(f.peak_ratio[i] as f64));
                assert_eq!(p[9], f.event_count[i] as f64);
                assert_eq!(p[10], f.slab_us[i] as f64);
            }
        }
    }
}

// ---------------------------------------------------------------- VTK

/// A parsed legacy binary VTK rectilinear grid.
#[derive(Debug)]
struct Vtk {
    title: String,
    dims: [usize; 3],
    x: Vec<f64>,
    y: Vec<f64>,
    velocity: Vec<[f32; 3]>,
    status: Vec<u8>,
    u_unc: Vec<f32>,
    v_unc: Vec<f32>,
    peak: Vec<f32>,
    peak_ratio: Vec<f32>,
    event_count: Vec<u32>,
    slab_us: Vec<u32>,
}

fn parse_vtk(bytes: &[u8]) -> Vtk {
    let mut pos = 0;
    let mut line = || {
        let end = pos + bytes[pos..].iter().position(|&b| b == b'\n').unwrap();
        let text = std::str::from_utf8(&bytes[pos..end]).unwrap().to_string();
        pos = end + 1;
        text
    };
    assert_eq!(line(), "# vtk DataFile Version 3.0");
    let title = line();
    assert_eq!(line(), "BINARY");
    assert_eq!(line(), "DATASET RECTILINEAR_GRID");
    let dims: Vec<usize> = line()
        .strip_prefix("DIMENSIONS ")
        .unwrap()
        .split(' ')
        .map(|s| s.parse().unwrap())
        .collect();
    let n = dims[0] * dims[1] * dims[2];
    let mut out = Vtk {
        title,
        dims: [dims[0], dims[1], dims[2]],
        x: vec![],
        y: vec![],
        velocity: vec![],
        status: vec![],
        u_unc: vec![],
        v_unc: vec![],
        peak: vec![],
        peak_ratio: vec![],
        event_count: vec![],
        slab_us: vec![],
    };
    let take = |pos: &mut usize, len: usize| -> Vec<u8> {
        let b = bytes[*pos..*pos + len].to_vec();
        *pos += len;
        assert_eq!(bytes[*pos], b'\n', "binary block not followed by a newline");
        *pos += 1;
        b
    };
    let be64 = |b: Vec<u8>| -> Vec<f64> {
        b.chunks_exact(8)
            .map(|c| f64::from_be_bytes(c.try_into().unwrap()))
            .collect()
    };
    let be32 =
        |b: Vec<u8>| -> Vec<[u8; 4]> { b.chunks_exact(4).map(|c| c.try_into().unwrap()).collect() };
    while pos < bytes.len() {
        let end = pos + bytes[pos..].iter().position(|&b| b == b'\n').unwrap();
        let header = std::str::from_utf8(&bytes[pos..end]).unwrap().to_string();
        pos = end + 1;
        let words: Vec<&str> = header.split(' ').collect();
        match words[0] {
            "X_COORDINATES" | "Y_COORDINATES" | "Z_COORDINATES" => {
                assert_eq!(words[2], "double");
                let count: usize = words[1].parse().unwrap();
                let values = be64(take(&mut pos, 8 * count));
                match words[0] {
                    "X_COORDINATES" => out.x = values,
                    "Y_COORDINATES" => out.y = values,
                    _ => assert_eq!(values, vec![0.0]),
                }
            }
            "POINT_DATA" => assert_eq!(words[1].parse::<usize>().unwrap(), n),
            "VECTORS" => {
                assert_eq!(header, "VECTORS velocity float");
                out.velocity = be32(take(&mut pos, 12 * n))
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]].map(f32::from_be_bytes))
                    .collect();
            }
            "SCALARS" => {
                assert_eq!(header, "SCALARS status unsigned_char 1");
                let end = pos + bytes[pos..].iter().position(|&b| b == b'\n').unwrap();
                assert_eq!(&bytes[pos..end], b"LOOKUP_TABLE default");
                pos = end + 1;
                out.status = take(&mut pos, n);
            }
            "FIELD" => assert_eq!(header, "FIELD FieldData 6"),
            "u_unc" | "v_unc" | "peak" | "peak_ratio" => {
                assert_eq!(&words[1..], ["1", &n.to_string(), "float"]);
                let v: Vec<f32> = be32(take(&mut pos, 4 * n))
                    .into_iter()
                    .map(f32::from_be_bytes)
                    .collect();
                match words[0] {
                    "u_unc" => out.u_unc = v,
                    "v_unc" => out.v_unc = v,
                    "peak" => out.peak = v,
                    _ => out.peak_ratio = v,
                }
            }
            "event_count" | "slab_us" => {
                assert_eq!(&words[1..], ["1", &n.to_string(), "unsigned_int"]);
                let v: Vec<u32> = be32(take(&mut pos, 4 * n))
                    .into_iter()
                    .map(u32::from_be_bytes)
                    .collect();
                if words[0] == "event_count" {
                    out.event_count = v;
                } else {
                    out.slab_us = v;
                }
            }
            "" => {}
            other => panic!("unexpected VTK keyword {other}"),
        }
    }
    for len in [
        out.velocity.len(),
        out.status.len(),
        out.u_unc.len(),
        out.v_unc.len(),
        out.peak.len(),
        out.peak_ratio.len(),
        out.event_count.len(),
        out.slab_us.len(),
    ] {
        assert_eq!(len, n, "an array is missing");
    }
    out
}

#[test]
fn vtk_round_trip() {
    for calibrated in [false, true] {
        let f = series(calibrated);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("field.vtk");
        write_field_vtk(&f, &path).unwrap();
        assert!(!path.exists(), "a series goes to numbered files");
        let files = vtk_series_paths(&path, 2);
        assert_eq!(files[0], dir.path().join("field_0000.vtk"));
        let series: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("field.vtk.series")).unwrap(),
        )
        .unwrap();
        assert_eq!(series["file-series-version"], "1.0");
        assert_eq!(series["files"][1]["name"], "field_0001.vtk");
        assert_eq!(series["files"][1]["time"], 3_500);
        for (t, file) in files.iter().enumerate() {
            let vtk = parse_vtk(&std::fs::read(file).unwrap());
            assert_eq!(vtk.dims, [3, 2, 1]);
            assert!(vtk.title.contains(&format!("t = {} us", f.t_us[t])));
            // Coordinates ascend, and y points up in every VTK file (uncalibrated: y = −row,
            // v positive up), so the image rows come bottom first.
            assert!(vtk.y[0] < vtk.y[1] && vtk.x[0] < vtk.x[1]);
            let rows: [usize; 2] = [1, 0];
            let up = if calibrated { 1.0 } else { -1.0 };
            for (j, &row) in rows.iter().enumerate() {
                for col in 0..3 {
                    let k = j * 3 + col;
                    let i = f.index(t, row, col);
                    let e = expected(&f, t, row, col);
                    assert_same("x", vtk.x[col], e[0]);
                    assert_same("y", vtk.y[j], up * e[1]);
                    assert_same("u", vtk.velocity[k][0] as f64, e[2]);
                    assert_same("v", vtk.velocity[k][1] as f64, up * e[3]);
                    assert_eq!(vtk.velocity[k][2], 0.0);
                    assert_eq!(vtk.status[k], f.status[i].0);
                    // Scaled with the calibration, never negated with v.
                    let e_unc = expected_unc(&f, i);
                    assert_same("u_unc", vtk.u_unc[k] as f64, e_unc[0]);
                    assert_same("v_unc", vtk.v_unc[k] as f64, e_unc[1]);
                    assert_same("peak", vtk.peak[k] as f64, f.peak[i] as f64);
                    assert_same("ratio", vtk.peak_ratio[k] as f64, f.peak_ratio[i] as f64);
                    assert_eq!(vtk.event_count[k], f.event_count[i]);
                    assert_eq!(vtk.slab_us[k], f.slab_us[i]);
                }
            }
        }
    }
}

#[test]
fn vtk_single_field_goes_to_the_given_path() {
    let mut f = series(false);
    let n = f.field_len();
    f.t_us.truncate(1);
    for a in [
        &mut f.u,
        &mut f.v,
        &mut f.u_unc,
        &mut f.v_unc,
        &mut f.peak,
        &mut f.peak_ratio,
    ] {
        a.truncate(n);
    }
    f.status.truncate(n);
    f.event_count.truncate(n);
    f.slab_us.truncate(n);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("one.vtk");
    write_field_vtk(&f, &path).unwrap();
    let vtk = parse_vtk(&std::fs::read(&path).unwrap());
    // Row 1 (the lower one) comes first in the y-up file: (row 1, column 2) is point 2.
    assert!(vtk.velocity[2][0].is_nan() && vtk.velocity[2][1].is_nan());
    assert_eq!(vtk.status[2], Status::NO_EVENTS.0);
    assert!(!dir.path().join("one.vtk.series").exists());
}

// ---------------------------------------------------------------- dispatch

#[test]
fn write_field_picks_the_format_from_the_extension() {
    let f = series(true);
    let dir = tempfile::tempdir().unwrap();
    let magic: [(&str, &[u8]); 6] = [
        ("a.nc", b"CDF\x02"),
        ("a.NPZ", b"PK\x03\x04"),
        (
            "a.csv",
            b"t_us,x_px,y_px,u_px_ms,v_px_ms,u_unc_px_ms,v_unc_px_ms,status",
        ),
        ("a.dat", b"# ebiv"),
        ("a.tec", b"# ebiv"),
        ("a_0000.vtk", b"# vtk DataFile"),
    ];
    for (name, start) in magic {
        let target = dir.path().join(name.replace("_0000", ""));
        write_field(&f, &target).unwrap();
        let bytes = std::fs::read(dir.path().join(name)).unwrap();
        assert!(bytes.starts_with(start), "{name}");
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    let err = write_field(&f, &dir.path().join("a.plt")).unwrap_err();
    assert!(err.to_string().contains(".dat"), "{err}");
}
