//! Rasterising a [`LocalMap`] into map contexts for any window of the world-fixed grid.
//!
//! Key design decision: a scanline fill per polygon, driven by a spatial index. For a window,
//! the R-tree returns the polygons whose bounding boxes meet the window; for each of them and each
//! cell row its box covers, the crossings of the row's centre line with the polygon's edges (all
//! rings, so holes come out of the even-odd rule) are sorted, and the cells whose centres lie
//! between a pair of crossings are set. The work is proportional to the cells covered plus
//! edges × rows, never polygons × cells. Roads are drawn first and buildings over them, so a
//! centre inside both is a building (SPEC §4 decision). Bands of rows are filled in parallel.
//!
//! # Boundary rule
//! A centre exactly on a polygon edge follows the half-open crossing rule: an edge from `y0` to
//! `y1` crosses the centre line `y = yc` when `min(y0,y1) ≤ yc < max(y0,y1)`, and a centre at
//! `xc` is inside when the number of crossings at `x > xc` is odd, i.e. spans are `[x_a, x_b)`.
//! For an axis-aligned rectangle `[x0, x1] × [y0, y1]` this means the cells whose centres lie in
//! `[x0, x1) × [y0, y1)`: a centre on the west or south edge is inside, on the east or north edge
//! outside — the same half-open convention as the cells themselves, so two polygons that share an
//! edge never both claim a centre on it. The map extent, in contrast, is closed: a centre on its
//! boundary is inside the map.

use geo::{CoordsIter, Polygon, Rect};
use rayon::prelude::*;
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{AABB, RTree};

use crate::context::{CellWindow, MapContext, cell_centre_coordinate};
use crate::local_map::LocalMap;

/// Rows per band of parallel work; large enough that a band amortises the index query.
const BAND_ROWS: usize = 64;

/// One non-horizontal polygon edge, stored from its lower to its upper end.
#[derive(Clone, Copy, Debug)]
struct Edge {
    /// Lower y, metres (inclusive end of the crossing range).
    y_low: f64,
    /// Upper y, metres (exclusive end).
    y_high: f64,
    /// x at `y_low`.
    x_at_low: f64,
    /// dx/dy along the edge.
    dx_per_dy: f64,
}

impl Edge {
    /// x where the edge crosses `y = yc`, if it does by the half-open rule.
    #[inline]
    fn crossing(&self, yc: f64) -> Option<f64> {
        // Cheap arithmetic: computing it eagerly keeps the test branch-light.
        (self.y_low <= yc && yc < self.y_high)
            .then_some(self.x_at_low + (yc - self.y_low) * self.dx_per_dy)
    }
}

/// A polygon prepared for the scanline fill: its edges and what it paints.
#[derive(Clone, Debug)]
struct PreparedPolygon {
    context: MapContext,
    /// Range into [`ContextRaster::edges`].
    first_edge: usize,
    edge_count: usize,
    /// Bounding box `[min_x, min_y, max_x, max_y]`, metres.
    bbox: [f64; 4],
}

type IndexEntry = GeomWithData<Rectangle<[f64; 2]>, u32>;

/// Builds the map context of any window of the world-fixed grid from a [`LocalMap`].
///
/// Construction indexes the polygons once (O(n log n)); [`ContextRaster::fill`] is then cheap
/// enough to call for every new strip of a window that follows a vehicle.
///
/// ```
/// use geo::{coord, polygon, Rect};
/// use geodata::{CellWindow, ContextRaster, LocalMap, MapContext};
/// // A 2 m × 1 m building at the origin inside a 10 m × 10 m map.
/// let house = polygon![(x: 0.0, y: 0.0), (x: 2.0, y: 0.0), (x: 2.0, y: 1.0), (x: 0.0, y: 1.0)];
/// let extent = Rect::new(coord! { x: -5.0, y: -5.0 }, coord! { x: 5.0, y: 5.0 });
/// let raster = ContextRaster::new(&LocalMap::new(vec![house], vec![], extent));
/// let window = CellWindow { first_col: -1, first_row: 0, width: 4, height: 1, cell_size_m: 1.0 };
/// let mut out = vec![MapContext::Unknown; window.len()];
/// raster.fill(&window, &mut out);
/// // Centres at x = -0.5, 0.5, 1.5, 2.5 on the row y = 0.5.
/// use MapContext::{Building, Other};
/// assert_eq!(out, [Other, Building, Building, Other]);
/// ```
#[derive(Clone, Debug)]
pub struct ContextRaster {
    polygons: Vec<PreparedPolygon>,
    edges: Vec<Edge>,
    index: RTree<IndexEntry>,
    extent: Rect<f64>,
}

impl ContextRaster {
    /// Prepares the map for rasterising: flattens polygon edges and builds the R-tree over their
    /// bounding boxes. Polygons with non-finite coordinates or no area-spanning edge are dropped.
    pub fn new(map: &LocalMap) -> Self {
        let mut polygons = Vec::with_capacity(map.roads.len() + map.buildings.len());
        let mut edges = Vec::new();
        // Roads get the lower indices: candidates are painted in index order, so buildings are
        // painted last and win where both hold a centre.
        let tagged = map
            .roads
            .iter()
            .map(|p| (p, MapContext::Road))
            .chain(map.buildings.iter().map(|p| (p, MapContext::Building)));
        for (polygon, context) in tagged {
            if let Some(prepared) = prepare(polygon, context, &mut edges) {
                polygons.push(prepared);
            }
        }
        let entries = polygons
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let rect = Rectangle::from_corners([p.bbox[0], p.bbox[1]], [p.bbox[2], p.bbox[3]]);
                GeomWithData::new(rect, k as u32)
            })
            .collect();
        Self {
            polygons,
            edges,
            index: RTree::bulk_load(entries),
            extent: map.extent,
        }
    }

    /// The map's extent, local metres.
    pub fn extent(&self) -> Rect<f64> {
        self.extent
    }

    /// Number of polygons indexed (roads and buildings).
    pub fn polygon_count(&self) -> usize {
        self.polygons.len()
    }

    /// Writes the context of every cell of `window` into `out[row_in_window * width +
    /// col_in_window]` (row 0 south), by the cell-centre rule: building, else road, else other;
    /// unknown where the centre is outside the map's extent (SPEC §4, eq 34-38).
    ///
    /// `out` should hold `window.len()` cells; cells beyond it are left untouched and, if it is
    /// shorter, only the whole rows that fit are written. A window with a non-positive or
    /// non-finite cell size, or with cell indices beyond ±2⁴⁸ (where cell centres stop being
    /// exact in f64), is all [`MapContext::Unknown`].
    pub fn fill(&self, window: &CellWindow, out: &mut [MapContext]) {
        if window.width == 0 || window.height == 0 {
            return;
        }
        let rows_available = (out.len() / window.width).min(window.height);
        let out = &mut out[..rows_available * window.width];
        if !(window.cell_size_m.is_finite() && window.cell_size_m > 0.0 && indices_in_range(window))
        {
            out.fill(MapContext::Unknown);
            return;
        }
        out.par_chunks_mut(BAND_ROWS * window.width)
            .enumerate()
            .for_each_init(Vec::new, |scratch, (band, cells)| {
                let band_window = CellWindow {
                    first_row: window.first_row + (band * BAND_ROWS) as i64,
                    height: cells.len() / window.width,
                    ..*window
                };
                self.fill_band(&band_window, cells, scratch);
            });
    }

    /// Rasterises the whole extent at `cell_size_m`: the covering window and its contexts.
    pub fn rasterise_extent(&self, cell_size_m: f64) -> (CellWindow, Vec<MapContext>) {
        let window = CellWindow::covering(&self.extent, cell_size_m);
        let mut out = vec![MapContext::Unknown; window.len()];
        self.fill(&window, &mut out);
        (window, out)
    }

    /// The context at one point, by the same rules as [`fill`](Self::fill) (point-in-polygon by
    /// counting crossings). For spot checks; use `fill` for many cells.
    pub fn context_at(&self, x_m: f64, y_m: f64) -> MapContext {
        if !self.extent_contains(x_m, y_m) {
            return MapContext::Unknown;
        }
        let mut context = MapContext::Other;
        for entry in self.index.locate_all_at_point(&[x_m, y_m]) {
            let polygon = &self.polygons[entry.data as usize];
            let edges = &self.edges[polygon.first_edge..polygon.first_edge + polygon.edge_count];
            let crossings_east = edges
                .iter()
                .filter_map(|e| e.crossing(y_m))
                .filter(|&x| x > x_m)
                .count();
            if crossings_east % 2 == 1 && polygon.context as u8 > context as u8 {
                context = polygon.context;
            }
        }
        context
    }

    fn extent_contains(&self, x_m: f64, y_m: f64) -> bool {
        let (min, max) = (self.extent.min(), self.extent.max());
        min.x <= x_m && x_m <= max.x && min.y <= y_m && y_m <= max.y
    }

    /// Fills one band of rows (`cells` holds exactly the band's rows).
    fn fill_band(&self, window: &CellWindow, cells: &mut [MapContext], crossings: &mut Vec<f64>) {
        let s = window.cell_size_m;
        let width = window.width;
        let last_col = window.first_col + width as i64 - 1;
        let last_row = window.first_row + window.height as i64 - 1;
        // Columns and rows whose centres lie inside the closed extent, clipped to the window.
        let (min, max) = (self.extent.min(), self.extent.max());
        let col_range = (
            first_centre_at_or_after(min.x, s, window.first_col, last_col),
            first_centre_after(max.x, s, window.first_col, last_col),
        );
        let row_range = (
            first_centre_at_or_after(min.y, s, window.first_row, last_row),
            first_centre_after(max.y, s, window.first_row, last_row),
        );
        for (r, row_cells) in cells.chunks_mut(width).enumerate() {
            let row = window.first_row + r as i64;
            if row < row_range.0 || row >= row_range.1 {
                row_cells.fill(MapContext::Unknown);
                continue;
            }
            for (c, cell) in row_cells.iter_mut().enumerate() {
                let col = window.first_col + c as i64;
                *cell = if col >= col_range.0 && col < col_range.1 {
                    MapContext::Other
                } else {
                    MapContext::Unknown
                };
            }
        }
        if col_range.0 >= col_range.1 || row_range.0 >= row_range.1 {
            return;
        }
        // Polygons whose boxes meet the box of the cell centres to paint.
        let query = AABB::from_corners(
            [
                cell_centre_coordinate(col_range.0, s),
                cell_centre_coordinate(row_range.0, s),
            ],
            [
                cell_centre_coordinate(col_range.1 - 1, s),
                cell_centre_coordinate(row_range.1 - 1, s),
            ],
        );
        let mut candidates: Vec<u32> = self
            .index
            .locate_in_envelope_intersecting(&query)
            .map(|entry| entry.data)
            .collect();
        candidates.sort_unstable();
        for k in candidates {
            let polygon = &self.polygons[k as usize];
            let edges = &self.edges[polygon.first_edge..polygon.first_edge + polygon.edge_count];
            let rows = (
                first_centre_at_or_after(polygon.bbox[1], s, row_range.0, row_range.1 - 1),
                first_centre_after(polygon.bbox[3], s, row_range.0, row_range.1 - 1),
            );
            for row in rows.0..rows.1 {
                let yc = cell_centre_coordinate(row, s);
                crossings.clear();
                crossings.extend(edges.iter().filter_map(|e| e.crossing(yc)));
                crossings.sort_unstable_by(f64::total_cmp);
                let row_cells = &mut cells[(row - window.first_row) as usize * width..][..width];
                for pair in crossings.chunks_exact(2) {
                    // Centres in [pair[0], pair[1]): first centre ≥ start up to first ≥ end.
                    let start = first_centre_at_or_after(pair[0], s, col_range.0, col_range.1 - 1);
                    let end = first_centre_at_or_after(pair[1], s, col_range.0, col_range.1 - 1);
                    for col in start..end {
                        row_cells[(col - window.first_col) as usize] = polygon.context;
                    }
                }
            }
        }
    }
}

/// Largest cell index magnitude handled: well inside the 2⁵³ range where `(k + 0.5)·s` is exact
/// in k, and far from i64 overflow in index arithmetic.
const MAX_CELL_INDEX: i64 = 1 << 48;

fn indices_in_range(window: &CellWindow) -> bool {
    let fits = |first: i64, count: usize| {
        i64::try_from(count).is_ok_and(|count| {
            first.unsigned_abs() < MAX_CELL_INDEX.unsigned_abs()
                && count < MAX_CELL_INDEX
                && (first + count).abs() < MAX_CELL_INDEX
        })
    };
    fits(window.first_col, window.width) && fits(window.first_row, window.height)
}

/// The first cell index `k` in `lo..=hi` whose centre `(k+0.5)·s` is `≥ v`, or `hi + 1` if none
/// (and `lo` if all are).
fn first_centre_at_or_after(v: f64, s: f64, lo: i64, hi: i64) -> i64 {
    if v.is_nan() {
        return hi + 1;
    }
    // Estimate, clamped to the range so that the exact correction below moves at most a step or
    // two, then settle on the exact comparison with the centre as computed everywhere else.
    let guess = (v / s - 0.5).ceil();
    let mut k = if guess <= lo as f64 {
        lo
    } else if guess > hi as f64 {
        hi + 1
    } else {
        guess as i64
    };
    while k > lo && cell_centre_coordinate(k - 1, s) >= v {
        k -= 1;
    }
    while k <= hi && cell_centre_coordinate(k, s) < v {
        k += 1;
    }
    k
}

/// The first cell index `k` in `lo..=hi` whose centre is `> v`, or `hi + 1` if none.
fn first_centre_after(v: f64, s: f64, lo: i64, hi: i64) -> i64 {
    let mut k = first_centre_at_or_after(v, s, lo, hi);
    while k <= hi && cell_centre_coordinate(k, s) <= v {
        k += 1;
    }
    k
}

/// Flattens the rings of `polygon` into `edges`; `None` if nothing finite remains.
fn prepare(
    polygon: &Polygon<f64>,
    context: MapContext,
    edges: &mut Vec<Edge>,
) -> Option<PreparedPolygon> {
    if polygon
        .coords_iter()
        .any(|c| !(c.x.is_finite() && c.y.is_finite()))
    {
        return None;
    }
    let first_edge = edges.len();
    let mut bbox = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for ring in std::iter::once(polygon.exterior()).chain(polygon.interiors()) {
        let points = &ring.0;
        let n = points.len();
        if n < 3 {
            continue;
        }
        // geo closes rings, but be robust to an unclosed one: edge from the last to the first.
        let closed = points.first() == points.last();
        let edge_count = if closed { n - 1 } else { n };
        for i in 0..edge_count {
            let a = points[i];
            let b = points[(i + 1) % n];
            bbox = [
                bbox[0].min(a.x),
                bbox[1].min(a.y),
                bbox[2].max(a.x),
                bbox[3].max(a.y),
            ];
            if a.y == b.y {
                continue; // a horizontal edge never crosses a centre line under the half-open rule
            }
            let (low, high) = if a.y < b.y { (a, b) } else { (b, a) };
            edges.push(Edge {
                y_low: low.y,
                y_high: high.y,
                x_at_low: low.x,
                dx_per_dy: (high.x - low.x) / (high.y - low.y),
            });
        }
    }
    let edge_count = edges.len() - first_edge;
    (edge_count >= 2).then_some(PreparedPolygon {
        context,
        first_edge,
        edge_count,
        bbox,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use MapContext::{Building, Other, Road, Unknown};
    use geo::{LineString, coord, polygon};

    fn big_extent() -> Rect<f64> {
        Rect::new(
            coord! { x: -100.0, y: -100.0 },
            coord! { x: 100.0, y: 100.0 },
        )
    }

    /// Rasterises `map` on the window and returns the set of (col, row) with `context`.
    fn cells_with(map: &LocalMap, window: &CellWindow, context: MapContext) -> Vec<(i64, i64)> {
        let raster = ContextRaster::new(map);
        let mut out = vec![Unknown; window.len()];
        raster.fill(window, &mut out);
        let mut cells = Vec::new();
        for row in 0..window.height {
            for col in 0..window.width {
                if out[row * window.width + col] == context {
                    cells.push((window.first_col + col as i64, window.first_row + row as i64));
                }
            }
        }
        cells
    }

    fn window(first_col: i64, first_row: i64, width: usize, height: usize, s: f64) -> CellWindow {
        CellWindow {
            first_col,
            first_row,
            width,
            height,
            cell_size_m: s,
        }
    }

    #[test]
    fn square_covers_the_cells_whose_centres_it_holds() {
        // Square [0.2, 2.2] × [0.2, 1.2] at s = 1: centres 0.5, 1.5 in x (2.5 > 2.2), 0.5 in y
        // (1.5 > 1.2) → cells (0,0), (1,0).
        let square =
            polygon![(x: 0.2, y: 0.2), (x: 2.2, y: 0.2), (x: 2.2, y: 1.2), (x: 0.2, y: 1.2)];
        let map = LocalMap::new(vec![square], vec![], big_extent());
        let cells = cells_with(&map, &window(-1, -1, 5, 4, 1.0), Building);
        assert_eq!(cells, vec![(0, 0), (1, 0)]);
    }

    #[test]
    fn concave_l_shape() {
        // L = [0,3]×[0,1] ∪ [0,1]×[1,3], s = 1, centres at k + 0.5.
        // Row 0 (y 0.5): x in [0,3) → cols 0,1,2. Rows 1,2 (y 1.5, 2.5): x in [0,1) → col 0.
        let l_shape = polygon![
            (x: 0.0, y: 0.0), (x: 3.0, y: 0.0), (x: 3.0, y: 1.0),
            (x: 1.0, y: 1.0), (x: 1.0, y: 3.0), (x: 0.0, y: 3.0)
        ];
        let map = LocalMap::new(vec![], vec![l_shape], big_extent());
        let cells = cells_with(&map, &window(-2, -2, 8, 8, 1.0), Road);
        assert_eq!(cells, vec![(0, 0), (1, 0), (2, 0), (0, 1), (0, 2)]);
    }

    #[test]
    fn polygon_with_hole() {
        // Outer [0,4]², hole [1,3]², s = 1: the 16 centres minus the 4 in the hole
        // ((1,1), (2,1), (1,2), (2,2)) → 12 cells.
        let outer = LineString::from(vec![
            (0.0, 0.0),
            (4.0, 0.0),
            (4.0, 4.0),
            (0.0, 4.0),
            (0.0, 0.0),
        ]);
        let hole = LineString::from(vec![
            (1.0, 1.0),
            (1.0, 3.0),
            (3.0, 3.0),
            (3.0, 1.0),
            (1.0, 1.0),
        ]);
        let map = LocalMap::new(vec![Polygon::new(outer, vec![hole])], vec![], big_extent());
        let cells = cells_with(&map, &window(0, 0, 4, 4, 1.0), Building);
        let expected: Vec<(i64, i64)> = (0..4)
            .flat_map(|row| (0..4).map(move |col| (col, row)))
            .filter(|&(col, row)| !((1..=2).contains(&col) && (1..=2).contains(&row)))
            .collect();
        assert_eq!(cells, expected);
    }

    #[test]
    fn centre_exactly_on_an_edge_is_half_open() {
        // Square [0.5, 2.5] × [0.5, 2.5] at s = 1: every edge passes through centres.
        // Half-open rule: x in [0.5, 2.5), y in [0.5, 2.5) → cols 0,1 and rows 0,1.
        let square =
            polygon![(x: 0.5, y: 0.5), (x: 2.5, y: 0.5), (x: 2.5, y: 2.5), (x: 0.5, y: 2.5)];
        let map = LocalMap::new(vec![square], vec![], big_extent());
        let cells = cells_with(&map, &window(-1, -1, 5, 5, 1.0), Building);
        assert_eq!(cells, vec![(0, 0), (1, 0), (0, 1), (1, 1)]);
        // The same at s = 0.2, where centres are not exact binary fractions: edges at x = 0.3
        // (centre of cell 1) and x = 0.7 (centre of cell 3) → cols 1, 2; same for rows.
        let square =
            polygon![(x: 0.3, y: 0.3), (x: 0.7, y: 0.3), (x: 0.7, y: 0.7), (x: 0.3, y: 0.7)];
        let map = LocalMap::new(vec![square], vec![], big_extent());
        let raster = ContextRaster::new(&map);
        let w = window(0, 0, 5, 5, 0.2);
        let mut out = vec![Unknown; w.len()];
        raster.fill(&w, &mut out);
        for row in 0..5i64 {
            for col in 0..5i64 {
                let (xc, yc) = w.cell_centre(col, row);
                let inside = (0.3..0.7).contains(&xc) && (0.3..0.7).contains(&yc);
                let expected = if inside { Building } else { Other };
                assert_eq!(
                    out[(row * 5 + col) as usize],
                    expected,
                    "cell ({col},{row}) centre ({xc},{yc})"
                );
            }
        }
    }

    #[test]
    fn shared_edge_is_claimed_once() {
        // Two roads meeting at x = 1.5 (a column of centres): every centre goes to exactly one.
        let west = polygon![(x: 0.0, y: 0.0), (x: 1.5, y: 0.0), (x: 1.5, y: 2.0), (x: 0.0, y: 2.0)];
        let east = polygon![(x: 1.5, y: 0.0), (x: 3.0, y: 0.0), (x: 3.0, y: 2.0), (x: 1.5, y: 2.0)];
        let only_west = cells_with(
            &LocalMap::new(vec![west.clone()], vec![], big_extent()),
            &window(0, 0, 3, 2, 1.0),
            Building,
        );
        let only_east = cells_with(
            &LocalMap::new(vec![east], vec![], big_extent()),
            &window(0, 0, 3, 2, 1.0),
            Building,
        );
        assert_eq!(only_west, vec![(0, 0), (0, 1)]);
        assert_eq!(only_east, vec![(1, 0), (2, 0), (1, 1), (2, 1)]);
    }

    #[test]
    fn building_wins_over_road_and_extent_bounds_everything() {
        let road = polygon![(x: 0.0, y: 0.0), (x: 4.0, y: 0.0), (x: 4.0, y: 1.0), (x: 0.0, y: 1.0)];
        let house =
            polygon![(x: 1.0, y: 0.0), (x: 2.0, y: 0.0), (x: 2.0, y: 1.0), (x: 1.0, y: 1.0)];
        // Extent [0, 3] × [0, 3], closed: centres 0.5..2.5 inside, 3.5 outside.
        let extent = Rect::new(coord! { x: 0.0, y: 0.0 }, coord! { x: 3.0, y: 3.0 });
        let map = LocalMap::new(vec![house], vec![road], extent);
        let raster = ContextRaster::new(&map);
        let w = window(-1, 0, 6, 1, 1.0);
        let mut out = vec![Other; w.len()];
        raster.fill(&w, &mut out);
        assert_eq!(out, [Unknown, Road, Building, Road, Unknown, Unknown]);
    }

    #[test]
    fn fill_agrees_with_point_queries_on_a_real_shaped_map() -> Result<(), crate::MapError> {
        // Roads buffered from centrelines at odd angles and a building with a hole, rasterised at
        // a cell size that puts centres at non-binary positions; every cell must match the
        // independent crossing count of `context_at`.
        let text = r#"{"type":"FeatureCollection","bbox":[-30,-30,40,35],"features":[
          {"type":"Feature","properties":{"highway":"primary"},
           "geometry":{"type":"LineString","coordinates":[[-25,-20],[3.3,4.1],[30,7.7],[31,30]]}},
          {"type":"Feature","properties":{"building":"yes"},
           "geometry":{"type":"Polygon","coordinates":[[[0,0],[12.3,1],[11,14.2],[-1,12]],
                                                       [[3,3],[8,3.5],[7,9],[3,3]]]}}]}"#;
        let map = LocalMap::from_local_geojson(text)?;
        let raster = ContextRaster::new(&map);
        let w = window(-170, -160, 380, 350, 0.2);
        let mut out = vec![Unknown; w.len()];
        raster.fill(&w, &mut out);
        let mut counts = [0usize; 4];
        for row in 0..w.height {
            for col in 0..w.width {
                let (xc, yc) = w.cell_centre(w.first_col + col as i64, w.first_row + row as i64);
                let got = out[row * w.width + col];
                assert_eq!(got, raster.context_at(xc, yc), "cell centre ({xc}, {yc})");
                counts[got as usize] += 1;
            }
        }
        assert!(
            counts.iter().all(|&n| n > 100),
            "all four contexts present: {counts:?}"
        );
        Ok(())
    }

    #[test]
    fn degenerate_windows_and_buffers_do_not_panic() {
        let map = LocalMap::new(vec![], vec![], big_extent());
        let raster = ContextRaster::new(&map);
        let mut short = vec![Building; 3];
        raster.fill(&window(0, 0, 2, 2, 1.0), &mut short);
        assert_eq!(
            short,
            [Other, Other, Building],
            "only the whole row that fits is written"
        );
        let mut out = vec![Building; 4];
        raster.fill(&window(0, 0, 2, 2, f64::NAN), &mut out);
        assert_eq!(out, [Unknown; 4]);
        raster.fill(&window(i64::MAX - 1, i64::MIN, 2, 2, 1.0), &mut out);
        assert_eq!(out, [Unknown; 4]);
        out.fill(Building);
        raster.fill(&window(0, i64::MIN, 2, 2, 1.0), &mut out);
        assert_eq!(out, [Unknown; 4]);
    }
}
