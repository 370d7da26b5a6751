//! Vector fields as NumPy `.npz`: a ZIP archive of `.npy` arrays (NumPy Enhancement
//! Proposal 1, "A simple file format for NumPy arrays", format version 1.0: magic, header
//! dict with `descr`, `fortran_order`, `shape`, padded to a multiple of 64 bytes;
//! little-endian, C order), deflate-compressed like `numpy.savez_compressed`.
//!
//! Arrays: `x`, `y` (`<f8`, px), `t_us` (`<i8`), and with shape `(nt, ny, nx)`: `u`, `v`
//! (`<f4`, px/ms, NaN = invalid), `u_unc`, `v_unc` (`<f4`, px/ms: the standard uncertainty of
//! `u`, `v`, one standard deviation, NaN where unknown), `status` (`|u1`, bits of
//! [`Status`]), `peak`, `peak_ratio` (`<f4`), `event_count`, `slab_us` (`<u4`; the time slab
//! each vector was measured over, µs, 0 where there is none). With a calibration also `x_mm`,
//! `y_mm` (`<f8`) and `u_m_s`, `v_m_s`, `u_unc_m_s`, `v_unc_m_s` (`<f4`; y and v positive up
//! when `y_up`, the uncertainties scaled but never negated). Derived quantities
//! ([`crate::derived`]) under their names (`vorticity`, `<f4`, image coordinates and units:
//! 1/ms, `1` for displacements) and, where a calibration writes other values, as it writes
//! them (`vorticity_1_s` for velocities, `vorticity_y_up` for displacements with y up; see
//! [`crate::derived::DerivedQuantity::physical_name`]). `attributes` is a 1-D unicode array
//! (`<U…`) of `key=value` strings: axis convention, units, status legend, what `slab_us`
//! holds, calibration, software, the series' attributes and, last, one per derived array
//! (its definition, sign convention and unit). Everything loads
//! with `numpy.load(path)` without pickles.
//!
//! [`Status`]: crate::field::Status

use super::{check, metadata, write_atomic, Physical};
use crate::derived::DerivedQuantity;
use crate::error::Result;
use crate::field::FieldSeries;
use std::io::Write;
use std::path::Path;

/// An element type that has a `.npy` type descriptor.
pub(crate) trait NpyElement: Copy {
    /// The NumPy `descr` string, e.g. `<f4`.
    const DESCR: &'static str;
    /// Append the little-endian bytes of `self`.
    fn put(self, out: &mut Vec<u8>);
}

macro_rules! npy_element {
    ($t:ty, $descr:literal) => {
        impl NpyElement for $t {
            const DESCR: &'static str = $descr;
            fn put(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
        }
    };
}

npy_element!(f64, "<f8");
npy_element!(f32, "<f4");
npy_element!(i64, "<i8");
npy_element!(u64, "<u8");
npy_element!(u32, "<u4");
npy_element!(u8, "|u1");

/// A version 1.0 `.npy` header for a C-order array of type `descr` and `shape`, padded
/// with spaces and a final newline to a multiple of 64 bytes.
fn npy_header(descr: &str, shape: &[usize]) -> Vec<u8> {
    let shape = match shape {
        [n] => format!("({n},)"),
        dims => format!(
            "({})",
            dims.iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    let total = (10 + dict.len() + 1).div_ceil(64) * 64;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&((total - 10) as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.resize(total - 1, b' ');
    out.push(b'\n');
    out
}

/// A complete `.npy` file of `data` with `shape`.
pub(crate) fn npy<T: NpyElement>(data: &[T], shape: &[usize]) -> Vec<u8> {
    let mut out = npy_header(T::DESCR, shape);
    out.reserve(std::mem::size_of_val(data));
    for &v in data {
        v.put(&mut out);
    }
    out
}

/// A `.npy` file of a 1-D unicode array (`<U{n}`: UCS-4 little-endian, each string padded
/// with NUL code points to the longest one).
pub(crate) fn npy_strings(strings: &[String]) -> Vec<u8> {
    let width = strings
        .iter()
        .map(|s| s.chars().count())
        .max()
        .unwrap_or(0)
        .max(1);
    let mut out = npy_header(&format!("<U{width}"), &[strings.len()]);
    for s in strings {
        let mut n = 0;
        for c in s.chars() {
            out.extend_from_slice(&(c as u32).to_le_bytes());
            n += 1;
        }
        out.resize(out.len() + 4 * (width - n), 0);
    }
    out
}

/// Write `field` as a NumPy `.npz` archive, through a temporary file.
pub fn write_field_npz(field: &FieldSeries, path: &Path) -> Result<()> {
    check(field)?;
    let shape = [field.t_us.len(), field.y.len(), field.x.len()];
    let status: Vec<u8> = field.status.iter().map(|s| s.0).collect();
    let mut members: Vec<(&str, Vec<u8>)> = vec![
        ("x", npy(&field.x, &[field.x.len()])),
        ("y", npy(&field.y, &[field.y.len()])),
        ("t_us", npy(&field.t_us, &[field.t_us.len()])),
        ("u", npy(&field.u, &shape)),
        ("v", npy(&field.v, &shape)),
        ("u_unc", npy(&field.u_unc, &shape)),
        ("v_unc", npy(&field.v_unc, &shape)),
        ("status", npy(&status, &shape)),
        ("peak", npy(&field.peak, &shape)),
        ("peak_ratio", npy(&field.peak_ratio, &shape)),
        ("event_count", npy(&field.event_count, &shape)),
        ("slab_us", npy(&field.slab_us, &shape)),
    ];
    if let Some(c) = &field.calibration {
        let p = Physical::new(field, c);
        members.push(("x_mm", npy(&p.x_mm, &[p.x_mm.len()])));
        members.push(("y_mm", npy(&p.y_mm, &[p.y_mm.len()])));
        members.push(("u_m_s", npy(&p.u, &shape)));
        members.push(("v_m_s", npy(&p.v, &shape)));
        members.push(("u_unc_m_s", npy(&p.u_unc, &shape)));
        members.push(("v_unc_m_s", npy(&p.v_unc, &shape)));
    }
    let calibration = field.calibration.as_ref();
    let mut derived_attributes = Vec::new();
    let physical_names: Vec<Option<String>> = field
        .derived
        .iter()
        .map(|d| d.quantity.physical_name(field.quantity, calibration))
        .collect();
    for (d, physical) in field.derived.iter().zip(&physical_names) {
        let q = d.quantity;
        members.push((q.name(), npy(&d.values, &shape)));
        derived_attributes.push(format!(
            "{}={}, {}",
            q.name(),
            q.long_name(false),
            DerivedQuantity::unit(field.quantity, None)
        ));
        if let (Some(name), Some(c)) = (physical, calibration) {
            members.push((name, npy(&DerivedQuantity::written(d, field), &shape)));
            derived_attributes.push(format!(
                "{name}={}, {}",
                q.long_name(c.y_up),
                DerivedQuantity::unit(field.quantity, calibration)
            ));
        }
    }
    let attributes: Vec<String> = metadata(field)
        .into_iter()
        .map(|(k, v)| format!("{k}={v}"))
        .chain(derived_attributes)
        .collect();
    members.push(("attributes", npy_strings(&attributes)));

    write_npz(path, &members)
}

/// Write `members` (name, `.npy` bytes) as a NumPy `.npz` archive (deflated), through a
/// temporary file.
pub(crate) fn write_npz(path: &Path, members: &[(&str, Vec<u8>)]) -> Result<()> {
    write_atomic(path, |w| {
        use zip::write::SimpleFileOptions;
        let mut zip = zip::ZipWriter::new(w);
        for (name, bytes) in members {
            let options = SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Deflated)
                .large_file(bytes.len() as u64 >= u32::MAX as u64);
            zip.start_file(format!("{name}.npy"), options)
                .map_err(zip_io)?;
            zip.write_all(bytes)?;
        }
        zip.finish().map_err(zip_io)?;
        Ok(())
    })
}

/// A ZIP error as an I/O error (the caller adds the path).
fn zip_io(e: zip::result::ZipError) -> std::io::Error {
    match e {
        zip::result::ZipError::Io(io) => io,
        other => std::io::Error::other(other.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_padded_to_64_bytes_with_the_shape() {
        let h = npy_header("<f4", &[2, 3, 4]);
        assert_eq!(h.len() % 64, 0);
        assert_eq!(&h[..8], b"\x93NUMPY\x01\x00");
        assert_eq!(u16::from_le_bytes([h[8], h[9]]) as usize, h.len() - 10);
        let text = std::str::from_utf8(&h[10..]).unwrap();
        assert!(text.starts_with("{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4), }"));
        assert!(text.ends_with(" \n"));
        let one = npy_header("<i8", &[5]);
        assert!(std::str::from_utf8(&one[10..])
            .unwrap()
            .contains("'shape': (5,)"));
    }

    #[test]
    fn strings_are_ucs4_padded_to_the_longest() {
        let data = npy_strings(&["ab".into(), "µ".into()]);
        let header = npy_header("<U2", &[2]);
        assert_eq!(&data[..header.len()], &header[..]);
        let body = &data[header.len()..];
        assert_eq!(body.len(), 16);
        assert_eq!(&body[..8], &[b'a', 0, 0, 0, b'b', 0, 0, 0]);
        assert_eq!(&body[8..], &[0xB5, 0, 0, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn archive_holds_every_array() {
        let f = FieldSeries::new(vec![0.0, 1.0], vec![0.0], vec![3]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.npz");
        write_field_npz(&f, &path).unwrap();
        let zip = zip::ZipArchive::new(std::fs::File::open(&path).unwrap()).unwrap();
        let mut names: Vec<&str> = zip.file_names().collect();
        names.sort_unstable();
        assert_eq!(
            names,
            [
                "attributes.npy",
                "event_count.npy",
                "peak.npy",
                "peak_ratio.npy",
                "slab_us.npy",
                "status.npy",
                "t_us.npy",
                "u.npy",
                "u_unc.npy",
                "v.npy",
                "v_unc.npy",
                "x.npy",
                "y.npy"
            ]
        );
        assert!(!dir.path().join("f.npz.partial").exists());
    }

    /// The `<f4` data of member `name` of the archive at `path`, after checking its header.
    fn read_f4(path: &Path, name: &str, shape: &str) -> Vec<f32> {
        use std::io::Read;
        let mut zip = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
        let mut bytes = Vec::new();
        zip.by_name(&format!("{name}.npy"))
            .unwrap()
            .read_to_end(&mut bytes)
            .unwrap();
        let start = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let header = std::str::from_utf8(&bytes[10..start]).unwrap();
        assert!(header.contains("'descr': '<f4'"), "{name}: {header}");
        assert!(
            header.contains(&format!("'shape': {shape}")),
            "{name}: {header}"
        );
        bytes[start..]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect()
    }

    #[test]
    fn uncertainties_round_trip_and_calibration_scales_without_flipping() {
        let mut f = FieldSeries::new(vec![0.0, 1.0], vec![0.0], vec![3]);
        f.u = vec![2.0, f32::NAN];
        f.v = vec![4.0, f32::NAN];
        f.u_unc = vec![0.25, f32::NAN];
        f.v_unc = vec![0.5, f32::NAN];
        f.status[0] = crate::field::Status::VALID;
        f.calibration = Some(crate::field::Calibration {
            mm_per_px: 0.5,
            origin_px: [0.0, 0.0],
            y_up: true,
        });
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.npz");
        write_field_npz(&f, &path).unwrap();
        let shape = "(1, 1, 2)";
        let u_unc = read_f4(&path, "u_unc", shape);
        let v_unc = read_f4(&path, "v_unc", shape);
        assert_eq!((u_unc[0], v_unc[0]), (0.25, 0.5));
        assert!(u_unc[1].is_nan() && v_unc[1].is_nan());
        // y up flips v (4 px/ms → -2 m/s) but not its uncertainty (0.5 px/ms → 0.25 m/s).
        assert_eq!(read_f4(&path, "v_m_s", shape)[0], -2.0);
        let u_unc = read_f4(&path, "u_unc_m_s", shape);
        let v_unc = read_f4(&path, "v_unc_m_s", shape);
        assert_eq!((u_unc[0], v_unc[0]), (0.125, 0.25));
        assert!(u_unc[1].is_nan() && v_unc[1].is_nan());
    }
}
