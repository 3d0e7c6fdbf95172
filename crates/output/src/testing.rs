//! Fixtures shared by the tests of the views and the exports.
#![allow(clippy::unwrap_used)]

use evigrid::{Label, Window};

/// A 3 × 2 window at cells (10..13, -1..1), scrolled so storage and world order differ.
pub(crate) fn window() -> Window {
    let mut w = Window::new(3, 2, 0.5).unwrap();
    w.move_to(10, -1);
    w
}

/// Labels in storage order from a function of the global cell.
pub(crate) fn decisions(w: &Window, f: impl Fn(i64, i64) -> Label) -> Vec<Label> {
    (0..w.len())
        .map(|idx| {
            let c = w.cell_of_storage(idx).unwrap();
            f(c.col, c.row)
        })
        .collect()
}
