//! Conversions between Python values and the library's: keyword arguments into settings and
//! reader options, event arrays into an [`EventBuffer`], and NetCDF datasets
//! ([`ebiv::export::Dataset`]) to and from plain Python structures that the pure-Python
//! part turns into `xarray.Dataset`s.

use crate::errors::IntoPy;
use ebiv::export::{Attribute, Dataset, Values, Variable};
use ebiv::io::{ReadOptions, READ_OPTIONS};
use ebiv::settings::ProcessSettings;
use ebiv::EventBuffer;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

/// A keyword's name as the command line and the configuration file spell it.
pub fn kebab(key: &str) -> String {
    key.replace('_', "-")
}

/// Split keyword arguments into settings (applied over `settings`) and reader options. A
/// value of `None` leaves the setting at its default.
pub fn apply_keywords(
    keywords: Option<&Bound<'_, PyDict>>,
    settings: &mut ProcessSettings,
    options: &mut ReadOptions,
) -> PyResult<()> {
    let Some(keywords) = keywords else {
        return Ok(());
    };
    for (key, value) in keywords.iter() {
        let key = kebab(&key.extract::<String>()?);
        if value.is_none() {
            continue;
        }
        if READ_OPTIONS.contains(&key.as_str()) {
            let text = reader_option_text(&key, &value)?;
            options.set(&key, &text).py_err()?;
        } else {
            settings.set(&key, &toml_value(&key, &value)?).py_err()?;
        }
    }
    Ok(())
}

/// The text of a reader option: `geometry=(1280, 720)` is `1280x720`, booleans are
/// `true`/`false`, anything else its `str()`.
pub fn reader_option_text(key: &str, value: &Bound<'_, PyAny>) -> PyResult<String> {
    if value.is_instance_of::<PyBool>() {
        return Ok(value.extract::<bool>()?.to_string());
    }
    if key == "geometry" && (value.is_instance_of::<PyTuple>() || value.is_instance_of::<PyList>())
    {
        let (w, h): (u32, u32) = value.extract().map_err(|_| {
            PyValueError::new_err("invalid parameter `geometry`: give (width, height) or \"WxH\"")
        })?;
        return Ok(format!("{w}x{h}"));
    }
    Ok(value.str()?.to_string())
}

/// Whether `value` names a file: a `str` or an `os.PathLike`.
pub fn is_path(value: &Bound<'_, PyAny>) -> PyResult<bool> {
    Ok(value.is_instance_of::<PyString>()
        || value.is_instance(&value.py().import("os")?.getattr("PathLike")?)?)
}

/// A Python value as the TOML value a configuration file would hold: bools, integers,
/// floats, strings (durations with units such as "10ms"), paths, and lists of them.
pub fn toml_value(key: &str, value: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    // bool before int: Python's True is an int.
    if value.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(value.extract()?));
    }
    if value.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(value.extract()?));
    }
    if value.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(value.extract()?));
    }
    if value.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(value.extract()?));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        let items: Vec<Bound<'_, PyAny>> = value.extract()?;
        return items
            .iter()
            .map(|item| toml_value(key, item))
            .collect::<PyResult<Vec<_>>>()
            .map(toml::Value::Array);
    }
    if is_path(value)? {
        let fspath = value.py().import("os")?.call_method1("fspath", (value,))?;
        return Ok(toml::Value::String(fspath.extract()?));
    }
    // NumPy scalars and other numbers.
    if let Ok(i) = value
        .call_method0("__index__")
        .and_then(|i| i.extract::<i64>())
    {
        return Ok(toml::Value::Integer(i));
    }
    if let Ok(f) = value
        .call_method0("__float__")
        .and_then(|f| f.extract::<f64>())
    {
        return Ok(toml::Value::Float(f));
    }
    Err(PyTypeError::new_err(format!(
        "invalid parameter `{key}`: a {} is not a setting value (use a bool, number, string or list)",
        value.get_type().name()?
    )))
}

/// Events from four equally long arrays `t` (µs), `x`, `y` (px) and `p` (0/1), converted
/// to the library's types with their ranges checked.
pub fn events_from_arrays<'py>(
    t: &Bound<'py, PyAny>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    p: &Bound<'py, PyAny>,
) -> PyResult<EventBuffer> {
    let np = t.py().import("numpy")?;
    // Integers only: a float time (seconds?) or coordinate would be truncated silently, and
    // NaN passes any range check.
    let column = |name: &str, a: &Bound<'_, PyAny>, what: &str, range: (i128, i128)| {
        let a = np.call_method1("asarray", (a,))?;
        if a.getattr("ndim")?.extract::<usize>()? != 1 {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `{name}`: events are 1-D arrays"
            )));
        }
        let kind: String = a.getattr("dtype")?.getattr("kind")?.extract()?;
        if !matches!(kind.as_str(), "i" | "u" | "b") {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `{name}`: {what} as integers, not {}",
                a.getattr("dtype")?.str()?
            )));
        }
        if a.getattr("size")?.extract::<usize>()? > 0 {
            // Python integers: exact for every integer type, unlike floats.
            let int = |v: Bound<'_, PyAny>| v.call_method0("__index__")?.extract::<i128>();
            let lo = int(a.call_method0("min")?)?;
            let hi = int(a.call_method0("max")?)?;
            if lo < range.0 || hi > range.1 {
                return Err(PyValueError::new_err(format!(
                    "invalid parameter `{name}`: values {lo}..{hi} outside the range of {what}"
                )));
            }
        }
        Ok::<(), PyErr>(())
    };
    column("t", t, "µs (int64)", (i64::MIN as i128, i64::MAX as i128))?;
    column("x", x, "pixels (0..=65535)", (0, u16::MAX as i128))?;
    column("y", y, "pixels (0..=65535)", (0, u16::MAX as i128))?;
    column("p", p, "polarities (0 or 1)", (0, 1))?;
    let as_type = |a: &Bound<'py, PyAny>, dtype: &str| -> PyResult<Bound<'py, PyAny>> {
        np.call_method1("ascontiguousarray", (a, dtype))
    };
    let t = as_type(t, "int64")?;
    let x = as_type(x, "uint16")?;
    let y = as_type(y, "uint16")?;
    let p = as_type(p, "uint8")?;
    let t: PyReadonlyArray1<'_, i64> = t.extract()?;
    let x: PyReadonlyArray1<'_, u16> = x.extract()?;
    let y: PyReadonlyArray1<'_, u16> = y.extract()?;
    let p: PyReadonlyArray1<'_, u8> = p.extract()?;
    let n = t.len();
    if x.len() != n || y.len() != n || p.len() != n {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `source`: t, x, y and p differ in length ({n}, {}, {}, {})",
            x.len(),
            y.len(),
            p.len()
        )));
    }
    Ok(EventBuffer {
        t: t.as_slice()?.to_vec(),
        x: x.as_slice()?.to_vec(),
        y: y.as_slice()?.to_vec(),
        p: p.as_slice()?.to_vec(),
        triggers: Vec::new(),
    })
}

/// Events as four NumPy arrays `(t, x, y, p)`, handing over the buffers without copies.
pub fn events_to_py<'py>(py: Python<'py>, events: EventBuffer) -> Bound<'py, PyTuple> {
    let EventBuffer { t, x, y, p, .. } = events;
    PyTuple::new(
        py,
        [
            PyArray1::from_vec(py, t).into_any(),
            PyArray1::from_vec(py, x).into_any(),
            PyArray1::from_vec(py, y).into_any(),
            PyArray1::from_vec(py, p).into_any(),
        ],
    )
    .expect("a tuple of four arrays")
}

/// A dataset as `{"dims": [(name, length)], "variables": [(name, dims, array, attrs)],
/// "attrs": {…}}`, arrays shaped by their dimensions. One-value numeric attributes become
/// numbers, as xarray reads them from the file.
pub fn dataset_to_py<'py>(py: Python<'py>, dataset: Dataset) -> PyResult<Bound<'py, PyDict>> {
    let lengths = dataset.dims.clone();
    let shape = |dims: &[String]| -> Vec<usize> {
        dims.iter()
            .map(|d| lengths.iter().find(|(n, _)| n == d).map_or(0, |(_, l)| *l))
            .collect()
    };
    let variables = PyList::empty(py);
    for var in dataset.variables {
        let shape = shape(&var.dims);
        let array = match var.values {
            Values::F64(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
            Values::F32(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
            Values::I16(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
            Values::I32(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
        };
        let dims = PyTuple::new(py, &var.dims)?;
        let attrs = attributes_to_py(py, var.attributes)?;
        variables.append((var.name, dims, array, attrs))?;
    }
    let out = PyDict::new(py);
    out.set_item("dims", dataset.dims)?;
    out.set_item("variables", variables)?;
    out.set_item("attrs", attributes_to_py(py, dataset.attributes)?)?;
    Ok(out)
}

fn attributes_to_py<'py>(
    py: Python<'py>,
    attributes: Vec<(String, Attribute)>,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for (key, value) in attributes {
        match value {
            Attribute::Text(text) => out.set_item(key, text)?,
            Attribute::F64(v) if v.len() == 1 => out.set_item(key, v[0])?,
            Attribute::F64(v) => out.set_item(key, PyArray1::from_vec(py, v))?,
            Attribute::I16(v) => out.set_item(key, PyArray1::from_vec(py, v))?,
        }
    }
    Ok(out)
}

/// The inverse of [`dataset_to_py`]: a dataset from the same structure (arrays of float64,
/// float32, int16 or int32; attributes of text, numbers or numeric arrays).
pub fn dataset_from_py(value: &Bound<'_, PyAny>) -> PyResult<Dataset> {
    let np = value.py().import("numpy")?;
    let dims: Vec<(String, usize)> = value.get_item("dims")?.extract()?;
    let mut variables = Vec::new();
    for item in value.get_item("variables")?.try_iter()? {
        let (name, var_dims, array, attrs): (
            String,
            Vec<String>,
            Bound<'_, PyAny>,
            Bound<'_, PyDict>,
        ) = item?.extract()?;
        let array = np.call_method1("ravel", (np.call_method1("asarray", (array,))?,))?;
        let array = np.call_method1("ascontiguousarray", (array,))?;
        let dtype: String = array.getattr("dtype")?.getattr("name")?.extract()?;
        let values = match dtype.as_str() {
            "float64" => Values::F64(contiguous(&array)?),
            "float32" => Values::F32(contiguous(&array)?),
            "int16" => Values::I16(contiguous(&array)?),
            "int32" => Values::I32(contiguous(&array)?),
            other => {
                return Err(PyTypeError::new_err(format!(
                    "variable `{name}`: a NetCDF field holds float64, float32, int16 or int32 values, not {other}"
                )))
            }
        };
        variables.push(Variable {
            name,
            dims: var_dims,
            values,
            attributes: attributes_from_py(&attrs)?,
        });
    }
    let attrs: Bound<'_, PyDict> = value.get_item("attrs")?.extract()?;
    Ok(Dataset {
        dims,
        variables,
        attributes: attributes_from_py(&attrs)?,
    })
}

/// The values of a contiguous 1-D NumPy array.
fn contiguous<T: numpy::Element + Copy>(array: &Bound<'_, PyAny>) -> PyResult<Vec<T>> {
    let array: PyReadonlyArray1<'_, T> = array.extract()?;
    Ok(array.as_slice()?.to_vec())
}

fn attributes_from_py(attrs: &Bound<'_, PyDict>) -> PyResult<Vec<(String, Attribute)>> {
    let np = attrs.py().import("numpy")?;
    let mut out = Vec::new();
    for (key, value) in attrs.iter() {
        let key: String = key.extract()?;
        let attribute = if value.is_instance_of::<PyString>() {
            Attribute::Text(value.extract()?)
        } else {
            let array = np.call_method1("atleast_1d", (np.call_method1("asarray", (&value,))?,))?;
            let kind: String = array.getattr("dtype")?.getattr("kind")?.extract()?;
            match kind.as_str() {
                "i" | "u" if key == "flag_masks" || key == "valid_range" => {
                    Attribute::I16(np.call_method1("asarray", (array, "int16"))?.extract()?)
                }
                "i" | "u" | "f" => {
                    Attribute::F64(np.call_method1("asarray", (array, "float64"))?.extract()?)
                }
                _ => Attribute::Text(value.str()?.to_string()),
            }
        };
        out.push((key, attribute));
    }
    Ok(out)
}
