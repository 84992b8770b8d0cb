//! Progress bars of long phases (photon pass, cache prefill, render, cells).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A progress bar on stderr, hidden when stderr is not a terminal or when `quiet`.
pub fn progress_bar(len: u64, quiet: bool, what: &str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(Some(len), if quiet { ProgressDrawTarget::hidden() } else { ProgressDrawTarget::stderr() });
    pb.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// Set by [`cancel`]: long phases (render tiles, progressive passes, photon batches)
/// stop early and the pipeline returns [`Interrupted`]. One flag for the process: a
/// front end (the Python module on Ctrl-C) cancels every render in progress.
static CANCEL: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Asks every running render to stop as soon as it can.
pub fn cancel() {
    CANCEL.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// Whether [`cancel`] was called since the last [`clear_cancel`].
#[inline]
pub fn cancelled() -> bool {
    CANCEL.load(std::sync::atomic::Ordering::Relaxed)
}

/// Lets renders run again (after the cancelled ones have returned).
pub fn clear_cancel() {
    CANCEL.store(false, std::sync::atomic::Ordering::Relaxed);
}

/// The error of a render stopped by [`cancel`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Interrupted;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("interrupted")
    }
}

impl std::error::Error for Interrupted {}

/// `Err(Interrupted)` once [`cancel`] was called.
pub fn check_cancel() -> anyhow::Result<()> {
    if cancelled() { Err(Interrupted.into()) } else { Ok(()) }
}
