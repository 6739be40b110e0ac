//! Progress bars on stderr (indicatif): one per phase, hidden with `--quiet`.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar labelled `what`, or a hidden one when `quiet`.
pub fn bar(quiet: bool, what: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(1);
    pb.set_style(
        ProgressStyle::with_template("{msg:>8} [{bar:40}] {pos}/{len} ({elapsed})")
            .expect("static template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// Progress of the lighting phase on `pb`: source and cycle.
pub fn light(pb: &ProgressBar) -> impl FnMut(usize, u64) + '_ {
    |s, c| {
        pb.set_message(format!("light {}", s + 1));
        pb.set_length(c.max(1));
        pb.set_position(c);
    }
}
