//! The library's errors as Python exceptions, with the command line's messages: a bad
//! setting is a `ValueError`, a file that cannot be opened or written an `OSError` (or
//! `FileNotFoundError`), anything else about the data an `ebiv.EbivError`.

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::PyErr;

create_exception!(
    ebiv,
    EbivError,
    PyException,
    "A recording, field or scenario ebiv cannot use: damaged, empty, or not what the call needs."
);

/// The Python exception of a library error.
pub fn to_py(e: ebiv::Error) -> PyErr {
    let message = e.to_string();
    match &e {
        ebiv::Error::Parameter { .. } => PyValueError::new_err(message),
        ebiv::Error::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(message)
        }
        ebiv::Error::Io { .. } | ebiv::Error::Stream(_) | ebiv::Error::Write { .. } => {
            PyOSError::new_err(message)
        }
        _ => EbivError::new_err(message),
    }
}

/// `Result` of the library into `PyResult`.
pub trait IntoPy<T> {
    fn py_err(self) -> pyo3::PyResult<T>;
}

impl<T> IntoPy<T> for ebiv::Result<T> {
    fn py_err(self) -> pyo3::PyResult<T> {
        self.map_err(to_py)
    }
}
