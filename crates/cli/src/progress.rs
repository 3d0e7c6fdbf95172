//! Progress bars on standard error, hidden when standard error is not a terminal.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};

/// Set by `-q`: no progress bars either.
static QUIET: AtomicBool = AtomicBool::new(false);

/// Hides every progress bar from now on (`-q`).
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// How a bar is drawn: its label (the prefix) once on the left, then what the command says as it
/// goes (the message: `bench`'s round), dimmed. The label was the message, drawn twice.
const TEMPLATE: &str = "{prefix:>12} [{bar:40}] {pos}/{len} {wide_msg:.dim} ({eta})";

/// A bar of `len` steps labelled `label`; draws nothing when stderr is a pipe or a file, so logs
/// and CI output stay clean.
pub fn bar(len: u64, label: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if std::io::stderr().is_terminal() && !QUIET.load(Ordering::Relaxed) {
        if let Ok(style) = ProgressStyle::with_template(TEMPLATE) {
            bar.set_style(style.progress_chars("=> "));
        }
    } else {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar.set_prefix(label.to_string());
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_label_is_drawn_once() {
        let b = bar(3, "run");
        assert_eq!(b.prefix(), "run");
        assert_eq!(b.message(), "");
        // The label as prefix, the message once: no placeholder repeats the label.
        assert_eq!(TEMPLATE.matches("prefix").count(), 1);
        assert_eq!(TEMPLATE.matches("msg").count(), 1);
    }
}
