//! Placeholder: the NPY writer is being written.

use super::EventWriter;
use crate::error::{Error, Result};
use crate::event::EventBuffer;
use std::path::Path;

pub(crate) struct NpyWriter;

impl NpyWriter {
    pub fn create(_path: &Path) -> Result<Self> {
        Err(Error::parameter(
            "output",
            "NPY output is not available yet",
        ))
    }
}

impl EventWriter for NpyWriter {
    fn write(&mut self, _events: &EventBuffer) -> Result<()> {
        Ok(())
    }
    fn finish(self: Box<Self>) -> Result<()> {
        Ok(())
    }
}

pub(crate) struct NpzWriter;

impl NpzWriter {
    pub fn create(_path: &Path) -> Result<Self> {
        Err(Error::parameter(
            "output",
            "NPZ output is not available yet",
        ))
    }
}

impl EventWriter for NpzWriter {
    fn write(&mut self, _events: &EventBuffer) -> Result<()> {
        Ok(())
    }
    fn finish(self: Box<Self>) -> Result<()> {
        Ok(())
    }
}
