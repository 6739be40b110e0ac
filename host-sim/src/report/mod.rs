//! What users look at: PNG images ([`png`]), plots ([`plot`]; a solver's residual against its
//! iterations: [`convergence`]; a sweep's error against its cost: [`pareto`]), progress bars
//! ([`progress`]) and the output files' plumbing ([`files`]).

pub mod convergence;
pub mod ff_figure;
pub mod files;
pub mod pareto;
pub mod plot;
pub mod png;
pub mod progress;
