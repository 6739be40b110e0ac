//! What users look at: PNG images ([`png`]) and plots ([`plot`]).

pub mod plot;
pub mod png;
