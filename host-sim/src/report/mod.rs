//! What users look at: PNG images ([`png`]), plots ([`plot`]), progress bars ([`progress`]) and
//! the output files' plumbing ([`files`]).

pub mod files;
pub mod plot;
pub mod png;
pub mod progress;
