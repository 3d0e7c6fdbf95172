//! Free space along a ray: the cells it crosses in the world-fixed window.

use crate::window::Window;

/// Walks the cells a ray crosses (Amanatides & Woo 1987), in cell units, from `origin` along
/// the unit direction `(sin, cos)` of its angle, calling `visit` with the storage index of each
/// window cell it marks free: with `whole_cells`, cells left at or before `limit` (the ray
/// leaves them before reaching the obstacle range); otherwise cells entered before `limit`.
pub(super) fn walk_ray(
    window: &Window,
    origin: (f64, f64),
    (sin, cos): (f64, f64),
    limit: f64,
    whole_cells: bool,
    mut visit: impl FnMut(usize),
) {
    let (ox, oy) = origin;
    let mut col = ox.floor() as i64;
    let mut row = oy.floor() as i64;
    let step_col: i64 = if cos >= 0.0 { 1 } else { -1 };
    let step_row: i64 = if sin >= 0.0 { 1 } else { -1 };
    // Ray parameter t (cell units of distance) at which the next column / row boundary is met.
    let next_boundary = |o: f64, cell: i64, step: i64| (cell + i64::from(step > 0)) as f64 - o;
    let mut t_col = if cos != 0.0 {
        next_boundary(ox, col, step_col) / cos
    } else {
        f64::INFINITY
    };
    let mut t_row = if sin != 0.0 {
        next_boundary(oy, row, step_row) / sin
    } else {
        f64::INFINITY
    };
    let dt_col = if cos != 0.0 {
        1.0 / cos.abs()
    } else {
        f64::INFINITY
    };
    let dt_row = if sin != 0.0 {
        1.0 / sin.abs()
    } else {
        f64::INFINITY
    };
    let mut t_enter = 0.0;
    let (w, h) = (window.width() as i64, window.height() as i64);
    let (c0, r0) = (window.first_col(), window.first_row());
    // Storage column and row, stepped with the global ones: no division per cell.
    let mut storage_col = col.rem_euclid(w);
    let mut storage_row = row.rem_euclid(h);
    let wrap = |v: i64, n: i64| {
        if v == n {
            0
        } else if v < 0 {
            n - 1
        } else {
            v
        }
    };
    loop {
        let t_exit = t_col.min(t_row);
        let marked = if whole_cells {
            t_exit <= limit
        } else {
            t_enter < limit
        };
        if !marked {
            return;
        }
        let (dc, dr) = (col - c0, row - r0);
        if (0..w).contains(&dc) && (0..h).contains(&dr) {
            visit((storage_row * w + storage_col) as usize);
        } else if (dc < 0 && step_col < 0)
            || (dc >= w && step_col > 0)
            || (dr < 0 && step_row < 0)
            || (dr >= h && step_row > 0)
        {
            // Outside the window and moving away from it: the ray cannot come back.
            return;
        }
        t_enter = t_exit;
        if t_col < t_row {
            col += step_col;
            storage_col = wrap(storage_col + step_col, w);
            t_col += dt_col;
        } else {
            row += step_row;
            storage_row = wrap(storage_row + step_row, h);
            t_row += dt_row;
        }
    }
}
