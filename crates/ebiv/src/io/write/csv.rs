//! Placeholder: the CSV writer is being written.

use super::EventWriter;
use crate::error::{Error, Result};
use crate::event::EventBuffer;
use std::path::Path;

pub(crate) struct CsvWriter;

impl CsvWriter {
    pub fn create(_path: &Path) -> Result<Self> {
        Err(Error::parameter(
            "output",
            "CSV output is not available yet",
        ))
    }
}

impl EventWriter for CsvWriter {
    fn write(&mut self, _events: &EventBuffer) -> Result<()> {
        Ok(())
    }
    fn finish(self: Box<Self>) -> Result<()> {
        Ok(())
    }
}
