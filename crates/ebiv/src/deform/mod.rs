//! Deformation by a predicted velocity field, the refinement step of multi-pass
//! interrogation (Scarano 2002, Meas. Sci. Technol. 13:R1): the events of an event window
//! ([`events`]), and the frames of PIV ([`frames`]).

pub mod events;
pub mod frames;
