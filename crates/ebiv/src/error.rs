//! The library's error type. Every variant says what was wrong and where.

use std::path::PathBuf;

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in `ebiv`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An operating-system I/O error on a file.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// An I/O error on a stream with no file name.
    #[error("I/O error: {0}")]
    Stream(#[from] std::io::Error),

    /// The file's content is not what its format requires.
    #[error("{context}: {message} (at byte {offset})")]
    Corrupt {
        /// File name or format name.
        context: String,
        /// Byte offset of the problem in the file.
        offset: u64,
        /// What is wrong.
        message: String,
    },

    /// The file is valid but uses something ebiv does not read.
    #[error("{context}: {message}")]
    Unsupported {
        /// File name or format name.
        context: String,
        /// What is not supported, and what to do instead.
        message: String,
    },

    /// The format of a file could not be determined.
    #[error("{path}: unrecognised file format ({hint})")]
    UnknownFormat {
        /// The file.
        path: PathBuf,
        /// What was seen and which formats are known.
        hint: String,
    },

    /// A parameter value is out of range or inconsistent.
    #[error("invalid parameter `{name}`: {message}")]
    Parameter {
        /// The parameter's name as the user knows it.
        name: String,
        /// Why the value is rejected.
        message: String,
    },

    /// A line of a text file could not be parsed.
    #[error("{context}, line {line}: {message}")]
    Parse {
        /// File name.
        context: String,
        /// 1-based line number.
        line: u64,
        /// What is wrong.
        message: String,
    },

    /// The input holds nothing for the request: no events in the selected time or polarity.
    /// Reported instead of writing an empty result.
    #[error("{context}: {message}")]
    Empty {
        /// The input concerned.
        context: String,
        /// What was empty, and what to check.
        message: String,
    },

    /// Writing an output failed for a reason other than I/O.
    #[error("cannot write {what}: {message}")]
    Write {
        /// The output concerned.
        what: String,
        /// Why.
        message: String,
    },
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// A corrupt-content error at `offset` in `context`.
    pub fn corrupt(context: impl Into<String>, offset: u64, message: impl Into<String>) -> Self {
        Error::Corrupt {
            context: context.into(),
            offset,
            message: message.into(),
        }
    }

    /// An unsupported-content error.
    pub fn unsupported(context: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Unsupported {
            context: context.into(),
            message: message.into(),
        }
    }

    /// An empty-result error: `context` holds nothing for the request.
    pub fn empty(context: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Empty {
            context: context.into(),
            message: message.into(),
        }
    }

    /// An invalid-parameter error.
    pub fn parameter(name: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Parameter {
            name: name.into(),
            message: message.into(),
        }
    }
}
