//! Placeholder: this reader is being written.

use super::{FormatReader, ReadOptions, ReadSeek};
use crate::error::{Error, Result};

pub(crate) fn open(
    _source: Box<dyn ReadSeek>,
    context: String,
    _options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    Err(Error::unsupported(context, "this format is not read yet"))
}
