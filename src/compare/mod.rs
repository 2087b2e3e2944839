//! Equal-time comparison of the strategies against a converged reference (the thesis's
//! Figure 8): error metrics, the reference and its cache, a scheduler that gives every
//! strategy the same render time, and the files `portalview compare` writes.
//!
//! Quality is MSE against the reference over equal *time*. The reference is rendered with
//! antishadow sampling (the best strategy) from a different seed than the compared renders, so
//! its own noise is independent of theirs: it adds its per-pixel variance (the *noise floor*)
//! to every measured MSE. That floor is reported beside the results, and the reports give each
//! error and efficiency both as measured and with the floor subtracted.

mod equal_time;
mod metrics;
mod reference;
pub mod report;
mod time_to_error;
pub mod worker;

pub use equal_time::*;
pub use metrics::*;
pub use reference::*;
pub use report::{
    MeanSe, RunsRow, runs_csv, runs_markdown, runs_rows, write_figure8_outputs, write_runs_outputs,
    write_scene_outputs,
};
pub use report::{
    convergence_csv, convergence_svg, figure8_csv, figure8_markdown, summary_markdown,
};
pub use time_to_error::*;

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar with `template`'s style (the default style if the template is malformed).
pub fn progress_bar(len: u64, template: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style);
    }
    bar
}
