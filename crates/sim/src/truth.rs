//! Ground truth per cell of a window at one instant, in the perception grid's classes.
//!
//! # The rule: a cell is what covers its centre
//! [`label_window_centre`], the truth every score is computed on (issue 30): one rule for every
//! object, building or road user. A cell whose centre a building covers is I (U if the building
//! is missing from the map handed to the pipeline: the map prior's own cell-centre rule, SPEC §4);
//! a cell whose centre an actor covers takes the actor's class (U street furniture, S a road
//! user slower than [`STOPPED_BELOW_MPS`], M one at or above it). A cell an object covers in part
//! without its centre is F: calling it M is a false M, missing the object there is no miss. Such
//! cells form the *band* ([`CentreTruth::band`]), reported beside the scores as information.
//! Nothing in view is left out: the only cells outside the classes are [`IGNORED`] ones, under
//! the ego or an object holding the sensor, which the sensor cannot see.
//!
//! A road user never seen moving (standing since it came into view, on ground never seen free)
//! is S, and flagged ([`CentreTruth::never_seen_moving`]): no evidence tells it from a pole, so
//! the evaluation scores S and U both correct there. Which actors these are depends on what the
//! sensor saw; the caller names them ([`ActorRoles`]).
//!
//! # The previous rule, kept one release for comparison
//! [`label_window`] and [`label_window_with_outline`] label by the rule before issue 30, which
//! the evaluation still scores beside the headline so that the change can be read. Each cell is sampled at `n × n` points (the centres of an `n × n` subdivision; n odd, by
//! default [`DEFAULT_SAMPLES_PER_AXIS`] = 3, so the cell centre is one of them).
//!
//! - **Buildings: the map prior's rule, plus a boundary band.** A cell whose *centre* is inside a
//!   building is I (U if the building is missing from the map): the cell-centre rule by which the
//!   map prior gives a cell the building context (SPEC §4), so a mapped building's cells are the
//!   same cells in truth and in the prior (up to rounding on an edge through a centre). A cell a
//!   building overlaps but not at its centre is [`Label::Edge`], the boundary band (by exact
//!   overlap: the cells the footprint's outline passes through, so a façade 5 cm into a cell,
//!   between its edge and its outer samples, counts as the scanner's returns there do):
//!   part wall, part open space, it is crossed by rays from one side and hit from another, and
//!   free or infrastructure are both defensible there. The evaluation scores the band as static
//!   (predicting M there is wrong, see `eval::metrics`) and no other class.
//! - **Road users and street furniture: any overlap.** A cell takes the class of an actor that
//!   covers at least one of its samples, and an actor always claims the cell holding its centre,
//!   so an object thinner than a sample spacing (a 0.2 m bollard in 0.5 m cells) is never lost.
//!   Why not the centre rule here: a scanner return lands in whichever cell the object's outline
//!   crosses, and the outline cells of a car are the only ones a scanner sees, so a cell a moving
//!   car covers in part is M.
//! - **The object outline band.** A cell an actor overlaps (exactly, by any area) at none of its
//!   samples holds a sliver of the object, under half a sample spacing deep (8 cm in 0.5 m
//!   cells): the scanner may return from it or cross the cell beside it. Such a cell is F here
//!   and flagged in the outline mask of [`label_window_with_outline`]; the evaluation scores
//!   it as no class, as PASCAL VOC leaves its "void" band along object boundaries unscored.
//!
//! When several objects claim a cell the highest class wins in the order
//! F < edge < I < U < S < M: a pedestrian standing against a wall is S, not I, and a car beside
//! a building is the car.
//!
//! Classes: F where nothing is; I for buildings present in the map handed to the pipeline; U for
//! street furniture and for buildings missing from that map; S for a road user slower than
//! [`STOPPED_BELOW_MPS`]; M for one at or above it. Cells under the ego vehicle are
//! [`IGNORED`]: its own sensor cannot see them, so scoring them would only measure the blind spot.
//! So are the cells of any object that holds the sensor (a sensor inside an object sees nothing
//! of it); the simulator keeps that from happening, and the rule keeps a collision it missed
//! from being scored as the method's error.

use crate::actors::Actor;
use crate::geometry::Vec2;
use crate::label::Label;
use crate::world::World;
use geodata::CellWindow;
use std::ops::RangeInclusive;

/// Truth of a cell excluded from scoring (under the ego, or under an object holding the sensor):
/// it outranks every class.
pub const IGNORED: Label = Label::Unknown;
/// Speed below which a road user is stopped (S), m/s.
pub const STOPPED_BELOW_MPS: f64 = 0.5;
/// Default number of samples per cell side.
pub const DEFAULT_SAMPLES_PER_AXIS: usize = 3;

/// The class of an actor at this instant.
pub fn actor_class(actor: &Actor) -> Label {
    if actor.kind.is_infrastructure() {
        Label::U
    } else if actor.speed_mps < STOPPED_BELOW_MPS {
        Label::S
    } else {
        Label::M
    }
}

/// Rank of a truth label when several objects claim a cell:
/// F < edge < I < U < S < M < [`IGNORED`] (O is never truth), indexed by code.
const RANK: [u8; 8] = [7, 0, 2, 3, 4, 5, 6, 1];

fn priority(label: Label) -> u8 {
    RANK[label as usize]
}

/// Gives `cell` to `claim` if it ranks higher than what the cell holds.
fn claim(cell: &mut Label, claim: Label) {
    if priority(claim) > priority(*cell) {
        *cell = claim;
    }
}

/// Labels every cell of `window` into `out` (row-major, `out[row * width + col]`, rows from the
/// south): one of F, I, U, S, M, or [`IGNORED`] under the actors in `unseen`: the ego, and any
/// object that holds the sensor (a sensor inside an object sees nothing of it).
///
/// `out` is resized to the window. `samples_per_axis` is clamped to 1..=7 and rounded up to an
/// odd number, so that the cell centre is a sample.
pub fn label_window(
    world: &World,
    actors: &[Actor],
    unseen: &[u32],
    window: &CellWindow,
    samples_per_axis: usize,
    out: &mut Vec<Label>,
) {
    let mut outline = Vec::new();
    label_window_with_outline(
        world,
        actors,
        unseen,
        window,
        samples_per_axis,
        out,
        &mut outline,
    );
}

/// [`label_window`], and in `outline` (same layout) the object outline band: cells an actor
/// not in `unseen` overlaps, by any area, but at none of their samples, and that nothing
/// else claims (they are F in `out`). There the object covers a sliver of the cell, less than
/// half a sample spacing deep: a ray may end on it or cross the cell beside it, so free and the
/// object's class are both defensible, and the evaluation scores neither (`eval::metrics`).
pub fn label_window_with_outline(
    world: &World,
    actors: &[Actor],
    unseen: &[u32],
    window: &CellWindow,
    samples_per_axis: usize,
    out: &mut Vec<Label>,
    outline: &mut Vec<bool>,
) {
    let (w, h) = (window.width, window.height);
    out.clear();
    out.resize(w * h, Label::F);
    outline.clear();
    outline.resize(w * h, false);
    if w == 0 || h == 0 || window.cell_size_m.is_nan() || window.cell_size_m <= 0.0 {
        return;
    }
    let n = samples_per_axis.clamp(1, 7) | 1;
    let s = window.cell_size_m;
    let sub = s / n as f64;
    let x0 = window.first_col as f64 * s;
    let y0 = window.first_row as f64 * s;

    label_buildings(world, window, n, out);

    // Actors: test the samples of the cells under each footprint's bounding box.
    for a in actors {
        let code = actor_code(a, unseen);
        let Some((cols, rows)) = cells_under(a, window) else {
            continue;
        };
        for row in rows {
            for col in cols.clone() {
                let cx = x0 + col as f64 * s;
                let cy = y0 + row as f64 * s;
                let covered = (0..n * n).any(|q| {
                    let sample = Vec2::new(
                        cx + ((q % n) as f64 + 0.5) * sub,
                        cy + ((q / n) as f64 + 0.5) * sub,
                    );
                    a.footprint.contains(&a.pose, sample)
                });
                if covered {
                    claim(&mut out[row * w + col], code);
                } else if code != IGNORED {
                    let min = Vec2::new(cx, cy);
                    let max = Vec2::new(cx + s, cy + s);
                    if a.footprint.overlaps_rect(&a.pose, min, max) {
                        outline[row * w + col] = true;
                    }
                }
            }
        }
        // The cell holding the centre, for objects thinner than the sample spacing.
        let p = a.pose.position_m;
        let (cc, rc) = (((p.x - x0) / s).floor(), ((p.y - y0) / s).floor());
        if cc >= 0.0 && rc >= 0.0 && (cc as usize) < w && (rc as usize) < h {
            claim(&mut out[rc as usize * w + cc as usize], code);
        }
    }
    // A sliver of one object in a cell another object or a building claims is that claim's.
    for (band, &label) in outline.iter_mut().zip(out.iter()) {
        *band &= label == Label::F;
    }
}

/// The truth of one instant by the centre rule (see the module docs), row-major over the
/// window like [`label_window`]'s output.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CentreTruth {
    /// Per cell: the class of what covers its centre, F where nothing does, or [`IGNORED`].
    pub labels: Vec<Label>,
    /// Per cell: the band, truth F and covered in part (by any area, not at the centre) by a
    /// building or an actor that is not unseen. Reported, scored as F.
    pub band: Vec<bool>,
    /// Per cell: truth S from a road user never seen moving (one of
    /// [`ActorRoles::never_seen_moving`]), for which S and U are both correct.
    pub never_seen_moving: Vec<bool>,
}

/// The actors the truth treats apart from their class.
#[derive(Clone, Copy, Debug, Default)]
pub struct ActorRoles<'a> {
    /// Actors the sensor cannot see (the ego, an object holding the sensor): [`IGNORED`].
    pub unseen: &'a [u32],
    /// Road users never seen moving: standing since they came into view, on ground never seen
    /// free. Their S cells are flagged in [`CentreTruth::never_seen_moving`]. Who they are
    /// depends on what the sensor saw, so the caller (the evaluation) decides.
    pub never_seen_moving: &'a [u32],
}

/// Labels every cell of `window` into `truth` by the centre rule: a cell is what covers its
/// centre, building or actor, with [`IGNORED`] under the actors in `roles.unseen`; a cell
/// covered only in part is F and in the band. When several objects cover a centre the highest
/// class wins (F < I < U < S < M < [`IGNORED`]).
pub fn label_window_centre(
    world: &World,
    actors: &[Actor],
    roles: ActorRoles<'_>,
    window: &CellWindow,
    truth: &mut CentreTruth,
) {
    let (w, h) = (window.width, window.height);
    let CentreTruth {
        labels,
        band,
        never_seen_moving,
    } = truth;
    for plane in [&mut *band, &mut *never_seen_moving] {
        plane.clear();
        plane.resize(w * h, false);
    }
    labels.clear();
    labels.resize(w * h, Label::F);
    if w == 0 || h == 0 || window.cell_size_m.is_nan() || window.cell_size_m <= 0.0 {
        return;
    }
    // Buildings: one sample, the centre; every other cell they cover in part is band.
    label_buildings(world, window, 1, labels);
    for (label, in_band) in labels.iter_mut().zip(band.iter_mut()) {
        if *label == Label::Edge {
            *label = Label::F;
            *in_band = true;
        }
    }
    let s = window.cell_size_m;
    let x0 = window.first_col as f64 * s;
    let y0 = window.first_row as f64 * s;
    for a in actors {
        let code = actor_code(a, roles.unseen);
        let parked = code == Label::S && roles.never_seen_moving.contains(&a.id);
        let Some((cols, rows)) = cells_under(a, window) else {
            continue;
        };
        for row in rows {
            for col in cols.clone() {
                let k = row * w + col;
                let min = Vec2::new(x0 + col as f64 * s, y0 + row as f64 * s);
                let centre = Vec2::new(min.x + 0.5 * s, min.y + 0.5 * s);
                if a.footprint.contains(&a.pose, centre) {
                    claim(&mut labels[k], code);
                    never_seen_moving[k] |= parked;
                } else if code != IGNORED
                    && a.footprint
                        .overlaps_rect(&a.pose, min, Vec2::new(min.x + s, min.y + s))
                {
                    band[k] = true;
                }
            }
        }
    }
    for ((&label, in_band), parked) in labels
        .iter()
        .zip(band.iter_mut())
        .zip(never_seen_moving.iter_mut())
    {
        *in_band &= label == Label::F;
        *parked &= label == Label::S;
    }
}

/// The class an actor gives the cells it covers: its own ([`actor_class`]), or [`IGNORED`]
/// when it is one of the `unseen`.
fn actor_code(actor: &Actor, unseen: &[u32]) -> Label {
    if unseen.contains(&actor.id) {
        IGNORED
    } else {
        actor_class(actor)
    }
}

/// The columns and rows of `window` under the bounding box of `actor`'s footprint (its
/// bounding circle's square); `None` when that lies outside the window.
fn cells_under(
    actor: &Actor,
    window: &CellWindow,
) -> Option<(RangeInclusive<usize>, RangeInclusive<usize>)> {
    let (w, h) = (window.width, window.height);
    let s = window.cell_size_m;
    let x0 = window.first_col as f64 * s;
    let y0 = window.first_row as f64 * s;
    let r = actor.footprint.bounding_radius_m();
    let p = actor.pose.position_m;
    let col_of = |v: f64| ((v - x0) / s).floor();
    let row_of = |v: f64| ((v - y0) / s).floor();
    let c0 = col_of(p.x - r).max(0.0);
    let c1 = col_of(p.x + r).min(w as f64 - 1.0);
    let r0 = row_of(p.y - r).max(0.0);
    let r1 = row_of(p.y + r).min(h as f64 - 1.0);
    if c1 < c0 || r1 < r0 {
        return None;
    }
    Some(((c0 as usize)..=(c1 as usize), (r0 as usize)..=(r1 as usize)))
}

/// Claims, in `out` (row-major over `window`, already sized), the building class of every cell
/// whose centre a building covers (I if mapped, U if not) and [`Label::Edge`] for every other
/// cell a building covers in part: at one of `n × n` samples (`n` odd) or by its outline.
fn label_buildings(world: &World, window: &CellWindow, n: usize, out: &mut [Label]) {
    let (w, h) = (window.width, window.height);
    let mid = n / 2;
    let s = window.cell_size_m;
    let sub = s / n as f64;
    let x0 = window.first_col as f64 * s;
    let y0 = window.first_row as f64 * s;
    let lo = Vec2::new(x0, y0);
    let hi = Vec2::new(x0 + w as f64 * s, y0 + h as f64 * s);
    // Window-relative sample index k ↔ coordinate origin + (k + 0.5)·sub.
    let first_sample = |v: f64, origin: f64| ((v - origin) / sub - 0.5).ceil();
    let last_sample = |v: f64, origin: f64| ((v - origin) / sub - 0.5).floor();

    // Scanline over every sample row.
    let mut ids = Vec::new();
    world.buildings_near(lo, hi, &mut ids);
    let mut xs = Vec::new();
    for &id in &ids {
        let b = &world.buildings()[id as usize];
        // The band by exact overlap: a cell the outline crosses holds some of the building,
        // however thin, and the scanner returns from it (a sample can miss a façade 5 cm into
        // the cell). The cells it covers at a sample are claimed by the scanline below.
        for ring in &b.rings {
            for (k, &a) in ring.iter().enumerate() {
                let end = ring[(k + 1) % ring.len()];
                cells_on_segment(a, end, lo, s, (w, h), |col, row| {
                    claim(&mut out[row * w + col], Label::Edge);
                });
            }
        }
        let class = if b.mapped { Label::I } else { Label::U };
        let k0 = first_sample(b.bounds.0.y, y0).max(0.0) as usize;
        let k1 = last_sample(b.bounds.1.y, y0).min((h * n) as f64 - 1.0);
        if k1 < k0 as f64 {
            continue;
        }
        for k in k0..=(k1 as usize) {
            let y = y0 + (k as f64 + 0.5) * sub;
            xs.clear();
            b.crossings_at(y, &mut xs);
            xs.sort_by(f64::total_cmp);
            let row = k / n;
            let centre_row = k % n == mid;
            for pair in xs.chunks_exact(2) {
                let j0 = first_sample(pair[0], x0).max(0.0);
                let j1 = last_sample(pair[1], x0).min((w * n) as f64 - 1.0);
                if j1 < j0 {
                    continue;
                }
                let (j0, j1) = (j0 as usize, j1 as usize);
                for c in j0 / n..=j1 / n {
                    // The centre sample of cell c is sample c·n + mid of this row.
                    let centre = c * n + mid;
                    let inside = centre_row && (j0..=j1).contains(&centre);
                    claim(
                        &mut out[row * w + c],
                        if inside { class } else { Label::Edge },
                    );
                }
            }
        }
    }
}

/// Calls `visit(col, row)` for every cell of a `w × h` grid of `s`-metre cells with origin
/// `origin` that the segment `a`–`b` passes through (Amanatides & Woo's traversal), in order.
fn cells_on_segment(
    a: Vec2,
    b: Vec2,
    origin: Vec2,
    s: f64,
    (w, h): (usize, usize),
    mut visit: impl FnMut(usize, usize),
) {
    let cell = |v: f64, o: f64| ((v - o) / s).floor();
    let (mut col, mut row) = (cell(a.x, origin.x), cell(a.y, origin.y));
    let (end_col, end_row) = (cell(b.x, origin.x), cell(b.y, origin.y));
    if !(col.is_finite() && row.is_finite() && end_col.is_finite() && end_row.is_finite()) {
        return;
    }
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    // Parameter t ∈ [0, 1] along the segment at which it crosses the next column / row line.
    let next = |v: f64, o: f64, c: f64, d: f64| {
        if d > 0.0 {
            ((c + 1.0) * s + o - v) / d
        } else if d < 0.0 {
            (c * s + o - v) / d
        } else {
            f64::INFINITY
        }
    };
    let mut t_col = next(a.x, origin.x, col, dx);
    let mut t_row = next(a.y, origin.y, row, dy);
    let (t_dcol, t_drow) = (s / dx.abs(), s / dy.abs());
    let steps = (end_col - col).abs() + (end_row - row).abs();
    let mut t_enter = 0.0f64;
    for _ in 0..=(steps as u64) {
        // Only a cell whose interior the segment enters: the midpoint of its piece strictly
        // inside (a segment along a cell edge, or through a corner, overlaps nothing there).
        let t_exit = t_col.min(t_row).min(1.0);
        let t_mid = 0.5 * (t_enter + t_exit);
        let (mx, my) = (a.x + dx * t_mid, a.y + dy * t_mid);
        let inside = |m: f64, o: f64, c: f64| c * s + o < m && m < (c + 1.0) * s + o;
        if col >= 0.0
            && row >= 0.0
            && (col as usize) < w
            && (row as usize) < h
            && inside(mx, origin.x, col)
            && inside(my, origin.y, row)
        {
            visit(col as usize, row as usize);
        }
        t_enter = t_exit;
        if t_col < t_row {
            col += dx.signum();
            t_col += t_dcol;
        } else {
            row += dy.signum();
            t_row += t_drow;
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::actors::ActorKind;
    use crate::geometry::Pose2;
    use crate::world::Building;

    fn window() -> CellWindow {
        // 8 × 4 cells of 1 m from (0, 0).
        CellWindow {
            first_col: 0,
            first_row: 0,
            width: 8,
            height: 4,
            cell_size_m: 1.0,
        }
    }

    fn rows(out: &[Label], w: usize) -> Vec<String> {
        // Top row (north) first, for reading.
        out.chunks(w)
            .rev()
            .map(|r| {
                r.iter()
                    .map(|&c| match c {
                        Label::F => '.',
                        Label::I => 'I',
                        Label::U => 'U',
                        Label::S => 'S',
                        Label::M => 'M',
                        Label::Edge => 'e',
                        _ => 'x',
                    })
                    .collect()
            })
            .collect()
    }

    fn centre(world: &World, actors: &[Actor], roles: ActorRoles<'_>) -> CentreTruth {
        let mut truth = CentreTruth::default();
        label_window_centre(world, actors, roles, &window(), &mut truth);
        truth
    }

    fn band_cells(truth: &CentreTruth) -> Vec<usize> {
        (0..truth.band.len()).filter(|&k| truth.band[k]).collect()
    }

    #[test]
    fn centre_rule_a_car_covering_centres_and_its_sliver_in_the_band() {
        let world = World::new(vec![], vec![], (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)));
        // A car 4.5 × 1.8 centred at (4.0, 1.85) heading east: x ∈ [1.75, 6.25], y ∈ [0.95,
        // 2.75]. Centres x = 2.5 … 5.5 and y = 1.5, 2.5 are inside: columns 2–5 of rows 1, 2.
        // Row 0 holds a 5 cm sliver (y ∈ [0.95, 1]) over columns 1–6; columns 1 and 6 of rows
        // 1, 2 hold the car's ends without their centres (1.5 < 1.75, 6.5 > 6.25).
        let mut car = Actor::fixed(0, ActorKind::Car, Pose2::new(Vec2::new(4.0, 1.85), 0.0));
        car.speed_mps = 5.0;
        let truth = centre(&world, &[car.clone()], ActorRoles::default());
        assert_eq!(
            rows(&truth.labels, 8),
            vec!["........", "..MMMM..", "..MMMM..", "........"]
        );
        assert_eq!(band_cells(&truth), vec![1, 2, 3, 4, 5, 6, 9, 14, 17, 22]);
        assert!(truth.never_seen_moving.iter().all(|&b| !b));
        // Under the ego: ignored where it covers a centre, and no band.
        let roles = ActorRoles {
            unseen: &[0],
            never_seen_moving: &[],
        };
        let truth = centre(&world, &[car], roles);
        assert_eq!(truth.labels[8 + 2], IGNORED);
        assert_eq!(truth.labels[8 + 1], Label::F);
        assert!(truth.band.iter().all(|&b| !b));
    }

    #[test]
    fn centre_rule_a_building_corner_is_band_and_its_centre_cell_infrastructure() {
        // Building [1.6, 3.4]²: only the centre (2.5, 2.5) of cell (2, 2) is inside; the eight
        // cells around it hold a corner or a side of it without their centres.
        let square = |lo: f64, hi: f64| {
            Building::new(vec![vec![
                Vec2::new(lo, lo),
                Vec2::new(hi, lo),
                Vec2::new(hi, hi),
                Vec2::new(lo, hi),
            ]])
            .unwrap()
        };
        let world = World::new(
            vec![square(1.6, 3.4)],
            vec![],
            (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)),
        );
        let truth = centre(&world, &[], ActorRoles::default());
        assert_eq!(
            rows(&truth.labels, 8),
            vec!["........", "..I.....", "........", "........"]
        );
        assert_eq!(
            band_cells(&truth),
            vec![9, 10, 11, 17, 19, 25, 26, 27],
            "the 3 × 3 block around cell (2, 2) but its centre"
        );
        // The same corner by a pedestrian standing against it (r 0.3 at (1.45, 1.45): covers
        // the corner cell (1, 1)'s centre): S, not band; the building's band beside it stays.
        let ped = Actor::fixed(
            1,
            ActorKind::Pedestrian,
            Pose2::new(Vec2::new(1.45, 1.45), 0.0),
        );
        let truth = centre(&world, &[ped], ActorRoles::default());
        assert_eq!(truth.labels[8 + 1], Label::S);
        assert!(!truth.band[8 + 1]);
        assert!(truth.band[8 + 2]);
    }

    #[test]
    fn centre_rule_a_thin_object_off_every_centre_is_band_only() {
        // A bollard (r 0.1) at (2.05, 3.05), x ∈ [1.95, 2.15], y ∈ [2.95, 3.15]: the previous
        // rule gave the cell of its centre U; by the centre rule it covers no centre, so the
        // four cells it touches are F, in the band.
        let world = World::new(vec![], vec![], (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)));
        let thin = Actor::fixed(
            1,
            ActorKind::Bollard,
            Pose2::new(Vec2::new(2.05, 3.05), 0.0),
        );
        let truth = centre(&world, std::slice::from_ref(&thin), ActorRoles::default());
        assert!(truth.labels.iter().all(|&l| l == Label::F));
        assert_eq!(band_cells(&truth), vec![17, 18, 25, 26]);
        let mut old = Vec::new();
        label_window(&world, &[thin], &[], &window(), 3, &mut old);
        assert_eq!(old[3 * 8 + 2], Label::U);
    }

    #[test]
    fn never_seen_moving_flags_the_s_cells_of_the_named_road_users_only() {
        let world = World::new(vec![], vec![], (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)));
        // Two pedestrians standing, one walking, each on one cell centre.
        let at = |id, x, speed| {
            let mut a = Actor::fixed(
                id,
                ActorKind::Pedestrian,
                Pose2::new(Vec2::new(x, 1.5), 0.0),
            );
            a.speed_mps = speed;
            a
        };
        let actors = [at(0, 1.5, 0.0), at(1, 3.5, 0.0), at(2, 5.5, 1.2)];
        let roles = ActorRoles {
            unseen: &[],
            never_seen_moving: &[0, 2],
        };
        let truth = centre(&world, &actors, roles);
        assert_eq!(
            rows(&truth.labels, 8),
            vec!["........", "........", ".S.S.M..", "........"]
        );
        // Actor 0 is named and stopped; 1 is not named; 2 is named but moving (M, no pass).
        let flagged: Vec<usize> = (0..32).filter(|&k| truth.never_seen_moving[k]).collect();
        assert_eq!(flagged, vec![8 + 1]);
    }

    #[test]
    fn cells_under_an_actor_are_its_bounding_square_clipped_to_the_window() {
        // A bollard (r 0.1) at (2.05, 3.05): x ∈ [1.95, 2.15], y ∈ [2.95, 3.15], columns 1–2,
        // rows 2–3.
        let bollard = Actor::fixed(
            1,
            ActorKind::Bollard,
            Pose2::new(Vec2::new(2.05, 3.05), 0.0),
        );
        assert_eq!(cells_under(&bollard, &window()), Some((1..=2, 2..=3)));
        // A car 4.5 × 1.8 at (4.0, 1.85): bounding radius hypot(2.25, 0.9) = 2.4233, so
        // x ∈ [1.577, 6.423] (columns 1–6) and y ∈ [−0.573, 4.273], rows −1–4 clipped to 0–3.
        let car = Actor::fixed(0, ActorKind::Car, Pose2::new(Vec2::new(4.0, 1.85), 0.0));
        assert_eq!(cells_under(&car, &window()), Some((1..=6, 0..=3)));
        // Wholly east of the window (x ∈ [9.9, 10.1]): no cell.
        let away = Actor::fixed(2, ActorKind::Bollard, Pose2::new(Vec2::new(10.0, 1.0), 0.0));
        assert_eq!(cells_under(&away, &window()), None);
        // The class an unseen actor gives is IGNORED, whatever its own.
        assert_eq!(actor_code(&car, &[0]), IGNORED);
        assert_eq!(actor_code(&car, &[1]), actor_class(&car));
    }

    #[test]
    fn classes_rank_in_frame_order_and_ignored_above_all() {
        let ranks: Vec<u8> = Label::CLASSES.iter().map(|&l| priority(l)).collect();
        assert!(ranks.windows(2).all(|w| w[0] < w[1]), "{ranks:?}");
        assert!(ranks.iter().all(|&r| r < priority(IGNORED)));
    }

    #[test]
    fn building_cells_by_centre_and_partly_covered_cells_in_the_band() {
        // Building x ∈ [0.9, 2.3], y ∈ [0, 2]. Sample x positions are k + 1/6, k + 1/2, k + 5/6.
        // Cell 1: all in → I. Cell 2: centre 2.5 outside, the building covers x ≤ 2.3 → edge.
        // Cell 0: no sample inside (0.833 < 0.9), but the façade at x = 0.9 is in it → edge.
        // Row 2 only touches the roof line y = 2: not covered.
        let b = Building::new(vec![vec![
            Vec2::new(0.9, 0.0),
            Vec2::new(2.3, 0.0),
            Vec2::new(2.3, 2.0),
            Vec2::new(0.9, 2.0),
        ]])
        .unwrap();
        let world = World::new(vec![b], vec![], (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)));
        let mut out = Vec::new();
        label_window(&world, &[], &[], &window(), 3, &mut out);
        assert_eq!(
            rows(&out, 8),
            vec!["........", "........", "eIe.....", "eIe....."]
        );
        // With one sample (the centre), the same: the band does not depend on the samples.
        label_window(&world, &[], &[], &window(), 1, &mut out);
        assert_eq!(
            rows(&out, 8),
            vec!["........", "........", "eIe.....", "eIe....."]
        );
        // A façade along a cell line, x = 1.0 exactly, puts nothing in cell 0.
        let flush = Building::new(vec![vec![
            Vec2::new(1.0, 0.0),
            Vec2::new(2.3, 0.0),
            Vec2::new(2.3, 2.0),
            Vec2::new(1.0, 2.0),
        ]])
        .unwrap();
        let world = World::new(
            vec![flush],
            vec![],
            (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)),
        );
        label_window(&world, &[], &[], &window(), 3, &mut out);
        assert_eq!(
            rows(&out, 8),
            vec!["........", "........", ".Ie.....", ".Ie....."]
        );
    }

    #[test]
    fn actors_take_speed_classes_and_priority() {
        let world = World::new(vec![], vec![], (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)));
        // A bollard (r = 0.1) at (0.5, 3.5) covers the centre sample only.
        let bollard = Actor::fixed(0, ActorKind::Bollard, Pose2::new(Vec2::new(0.5, 3.5), 0.0));
        // A tiny bollard between samples at (2.05, 3.05): no sample inside, centre cell rule → U.
        let thin = Actor::fixed(
            1,
            ActorKind::Bollard,
            Pose2::new(Vec2::new(2.05, 3.05), 0.0),
        );
        // A car 4.5 × 1.8 centred at (5.0, 1.0) heading east: x ∈ [2.75, 7.25], y ∈ [0.1, 1.9].
        let mut car = Actor::fixed(2, ActorKind::Car, Pose2::new(Vec2::new(5.0, 1.0), 0.0));
        car.speed_mps = 0.49;
        let mut ped = Actor::fixed(
            3,
            ActorKind::Pedestrian,
            Pose2::new(Vec2::new(6.5, 2.5), 0.0),
        );
        ped.speed_mps = 0.5;
        let mut out = Vec::new();
        label_window(
            &world,
            &[bollard, thin, car, ped],
            &[],
            &window(),
            3,
            &mut out,
        );
        // Car columns: cell 2 has samples 2.167, 2.5, 2.833 → 2.833 ≥ 2.75 inside → S;
        // cell 7 sample 7.167 ≤ 7.25 → S. Rows 0, 1: samples y 0.167 … 1.833 within [0.1, 1.9].
        // Pedestrian r 0.3 at (6.5, 2.5): covers samples of cell (6, 2) → M (speed 0.5 ≥ 0.5);
        // M beats S where they would meet.
        assert_eq!(
            rows(&out, 8),
            vec!["U.U.....", "......M.", "..SSSSSS", "..SSSSSS"]
        );
    }

    #[test]
    fn a_sliver_of_an_object_is_in_the_outline_band_not_in_a_class() {
        let world = World::new(vec![], vec![], (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)));
        // A car 4.5 × 1.8 centred at (4.0, 1.85) heading east: x ∈ [1.75, 6.25], y ∈ [0.95,
        // 2.75]. Row 0 (y ∈ [0, 1]) holds a 5 cm sliver, under its top samples at y 0.833.
        let mut car = Actor::fixed(0, ActorKind::Car, Pose2::new(Vec2::new(4.0, 1.85), 0.0));
        car.speed_mps = 5.0;
        let (mut out, mut outline) = (Vec::new(), Vec::new());
        let w = window();
        label_window_with_outline(&world, &[car.clone()], &[], &w, 3, &mut out, &mut outline);
        assert_eq!(
            rows(&out, 8),
            vec!["........", ".MMMMMM.", ".MMMMMM.", "........"]
        );
        let band: Vec<usize> = (0..out.len()).filter(|&k| outline[k]).collect();
        assert_eq!(band, vec![1, 2, 3, 4, 5, 6]);
        // The ego's own sliver is no band: its cells are not scored at all.
        label_window_with_outline(&world, &[car], &[0], &w, 3, &mut out, &mut outline);
        assert!(outline.iter().all(|&b| !b));
        assert_eq!(out[8 + 1], IGNORED);
    }

    #[test]
    fn unmapped_buildings_are_u_and_the_ego_is_ignored() {
        let mut b = Building::new(vec![vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(2.0, 1.0),
            Vec2::new(0.0, 1.0),
        ]])
        .unwrap();
        b.mapped = false;
        let world = World::new(vec![b], vec![], (Vec2::new(0.0, 0.0), Vec2::new(8.0, 4.0)));
        let ego = Actor::fixed(
            5,
            ActorKind::Pedestrian,
            Pose2::new(Vec2::new(5.5, 2.5), 0.0),
        );
        let mut out = Vec::new();
        label_window(&world, &[ego], &[5], &window(), 3, &mut out);
        assert_eq!(out[0], Label::U);
        assert_eq!(out[8 * 2 + 5], IGNORED);
        // Shifted window: global cells from (−2, −1); the building cell (0, 0) is now (2, 1).
        let shifted = CellWindow {
            first_col: -2,
            first_row: -1,
            ..window()
        };
        label_window(&world, &[], &[], &shifted, 3, &mut out);
        assert_eq!(out[8 + 2], Label::U);
        assert_eq!(out[8 + 3], Label::U);
        assert_eq!(out.iter().filter(|&&c| c != Label::F).count(), 2);
    }

    #[test]
    fn mapped_building_cells_are_the_prior_s_building_cells() {
        // Irregular, slanted polygons: truth I ⇔ the map prior's building context, cell for
        // cell, and every edge cell is a cell the prior does not call building.
        let poly = |pts: &[(f64, f64)]| {
            geo::Polygon::new(
                geo::LineString::from(
                    pts.iter()
                        .map(|&(x, y)| geo::coord! { x: x, y: y })
                        .collect::<Vec<_>>(),
                ),
                vec![],
            )
        };
        let buildings = vec![
            poly(&[(1.13, 0.71), (9.37, 2.29), (7.91, 8.83), (2.07, 6.41)]),
            poly(&[(11.3, 1.1), (17.9, 4.7), (12.2, 9.6)]),
        ];
        let extent = geo::Rect::new(
            geo::coord! { x: -5.0, y: -5.0 },
            geo::coord! { x: 25.0, y: 15.0 },
        );
        let map = geodata::LocalMap::new(buildings.clone(), vec![], extent);
        let world = World::from_polygons(&buildings, &[], &extent);
        let window = CellWindow {
            first_col: -4,
            first_row: -3,
            width: 50,
            height: 30,
            cell_size_m: 0.5,
        };
        let mut contexts = vec![geodata::MapContext::Unknown; window.len()];
        geodata::ContextRaster::new(&map).fill(&window, &mut contexts);
        let mut out = Vec::new();
        label_window(&world, &[], &[], &window, 3, &mut out);
        let (mut i_cells, mut edge_cells) = (0, 0);
        for (k, (&t, &c)) in out.iter().zip(&contexts).enumerate() {
            let building = c == geodata::MapContext::Building;
            assert_eq!(
                t == Label::I,
                building,
                "cell {k}: truth {t:?}, prior {c:?}"
            );
            i_cells += usize::from(t == Label::I);
            edge_cells += usize::from(t == Label::Edge);
        }
        // Both classes are present, and the band is a thin ring, not most of the area.
        assert!(
            i_cells > 200 && edge_cells > 20 && edge_cells < i_cells,
            "{i_cells} {edge_cells}"
        );
    }
}
