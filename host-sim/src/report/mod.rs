//! What users look at: PNG images ([`png`]), plots ([`plot`]; a solver's residual against its
//! iterations: [`convergence`]), progress bars ([`progress`]) and the output files' plumbing
//! ([`files`]).

pub mod convergence;
pub mod files;
pub mod plot;
pub mod png;
pub mod progress;
