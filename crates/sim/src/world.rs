//! The static world: buildings (exact polygons, ray-castable) and the road surface.
//!
//! Buildings are kept twice: as polygons (for truth labelling by scanline) and as edges in a
//! uniform bucket grid (for ray casting by grid traversal), so neither a ray nor a truth row has
//! to look at every building.

use crate::geometry::{Vec2, ray_segment};

/// One building: its outer ring first, then its holes. Rings do not repeat their first vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct Building {
    /// Outer ring then inner rings, local metres.
    pub rings: Vec<Vec<Vec2>>,
    /// Axis-aligned bounds `(min, max)`, metres.
    pub bounds: (Vec2, Vec2),
    /// Whether the map given to the perception pipeline contains this building. A building
    /// missing from the map is unmapped infrastructure (truth class U).
    pub mapped: bool,
}

impl Building {
    /// A building from rings (outer first). `None` when the outer ring has fewer than three
    /// distinct finite vertices.
    pub fn new(rings: Vec<Vec<Vec2>>) -> Option<Self> {
        let rings: Vec<Vec<Vec2>> = rings
            .into_iter()
            .map(|mut r| {
                if r.len() > 1 && r.first() == r.last() {
                    r.pop();
                }
                r
            })
            .collect();
        let outer = rings.first()?;
        if outer.len() < 3 || outer.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return None;
        }
        let mut lo = Vec2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = Vec2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        for p in outer {
            lo = Vec2::new(lo.x.min(p.x), lo.y.min(p.y));
            hi = Vec2::new(hi.x.max(p.x), hi.y.max(p.y));
        }
        Some(Self {
            rings,
            bounds: (lo, hi),
            mapped: true,
        })
    }

    /// From a `geo` polygon (exterior then interiors).
    pub fn from_polygon(polygon: &geo::Polygon<f64>) -> Option<Self> {
        let ring = |ls: &geo::LineString<f64>| ls.coords().map(|c| Vec2::new(c.x, c.y)).collect();
        let mut rings = vec![ring(polygon.exterior())];
        rings.extend(polygon.interiors().iter().map(ring));
        Self::new(rings)
    }

    /// Back to a `geo` polygon (for handing a map to the pipeline).
    pub fn to_polygon(&self, offset_m: Vec2) -> geo::Polygon<f64> {
        let ls = |r: &Vec<Vec2>| {
            geo::LineString::from(
                r.iter()
                    .map(|p| geo::coord! { x: p.x + offset_m.x, y: p.y + offset_m.y })
                    .collect::<Vec<_>>(),
            )
        };
        geo::Polygon::new(ls(&self.rings[0]), self.rings[1..].iter().map(ls).collect())
    }

    /// Appends the x coordinates where the horizontal line at `y` crosses the building's edges.
    /// Sorted pairs of them bound the inside (even–odd, so holes are respected).
    pub fn crossings_at(&self, y: f64, out: &mut Vec<f64>) {
        crate::geometry::ring_crossings(self.rings.iter().map(Vec::as_slice), y, out);
    }
}

/// A uniform grid of buckets over the world holding item ids (CSR layout: one offsets array, one
/// entries array), so memory is proportional to the items, not to a per-bucket `Vec`.
#[derive(Clone, Debug, Default)]
struct BucketGrid {
    origin: Vec2,
    bucket_m: f64,
    cols: usize,
    rows: usize,
    starts: Vec<u32>,
    entries: Vec<u32>,
}

impl BucketGrid {
    /// Builds the grid from item bounding boxes.
    fn build(origin: Vec2, extent_max: Vec2, bucket_m: f64, boxes: &[(Vec2, Vec2)]) -> Self {
        let cols = (((extent_max.x - origin.x) / bucket_m).ceil() as usize).max(1);
        let rows = (((extent_max.y - origin.y) / bucket_m).ceil() as usize).max(1);
        let mut grid = Self {
            origin,
            bucket_m,
            cols,
            rows,
            starts: vec![0; cols * rows + 1],
            entries: Vec::new(),
        };
        // Two passes (count, then place) give the CSR arrays without per-bucket vectors.
        for b in boxes {
            let (c0, r0, c1, r1) = grid.span(b.0, b.1);
            for r in r0..=r1 {
                for c in c0..=c1 {
                    grid.starts[r * cols + c + 1] += 1;
                }
            }
        }
        for i in 0..cols * rows {
            grid.starts[i + 1] += grid.starts[i];
        }
        grid.entries = vec![0; grid.starts[cols * rows] as usize];
        let mut fill = grid.starts.clone();
        for (id, b) in boxes.iter().enumerate() {
            let (c0, r0, c1, r1) = grid.span(b.0, b.1);
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let k = r * cols + c;
                    grid.entries[fill[k] as usize] = id as u32;
                    fill[k] += 1;
                }
            }
        }
        grid
    }

    fn clamp_col(&self, x: f64) -> usize {
        (((x - self.origin.x) / self.bucket_m).floor().max(0.0) as usize).min(self.cols - 1)
    }
    fn clamp_row(&self, y: f64) -> usize {
        (((y - self.origin.y) / self.bucket_m).floor().max(0.0) as usize).min(self.rows - 1)
    }
    fn span(&self, lo: Vec2, hi: Vec2) -> (usize, usize, usize, usize) {
        (
            self.clamp_col(lo.x),
            self.clamp_row(lo.y),
            self.clamp_col(hi.x),
            self.clamp_row(hi.y),
        )
    }
    fn bucket(&self, col: usize, row: usize) -> &[u32] {
        let k = row * self.cols + col;
        &self.entries[self.starts[k] as usize..self.starts[k + 1] as usize]
    }
    fn max_corner(&self) -> Vec2 {
        Vec2::new(
            self.origin.x + self.cols as f64 * self.bucket_m,
            self.origin.y + self.rows as f64 * self.bucket_m,
        )
    }
}

/// One building edge, for ray casting.
#[derive(Clone, Copy, Debug)]
struct Edge {
    a: Vec2,
    b: Vec2,
    building: u32,
}

/// The static world the simulated sensor sees.
#[derive(Clone, Debug)]
pub struct World {
    buildings: Vec<Building>,
    roads: Vec<Vec<Vec<Vec2>>>,
    extent: (Vec2, Vec2),
    edges: Vec<Edge>,
    edge_index: BucketGrid,
    building_index: BucketGrid,
}

/// Bucket side of the spatial indices, metres. About one small building: a ray visits few
/// buckets and a bucket holds few edges in city centres.
const BUCKET_M: f64 = 8.0;

impl World {
    /// A world from buildings, road-surface rings (each polygon: outer ring then holes) and the
    /// extent `(min, max)` of the area, local metres. Buildings outside the extent still count.
    pub fn new(buildings: Vec<Building>, roads: Vec<Vec<Vec<Vec2>>>, extent: (Vec2, Vec2)) -> Self {
        // The index must cover every building even when the declared extent does not.
        let mut lo = extent.0;
        let mut hi = extent.1;
        for b in &buildings {
            lo = Vec2::new(lo.x.min(b.bounds.0.x), lo.y.min(b.bounds.0.y));
            hi = Vec2::new(hi.x.max(b.bounds.1.x), hi.y.max(b.bounds.1.y));
        }
        let mut edges = Vec::new();
        for (id, b) in buildings.iter().enumerate() {
            for ring in &b.rings {
                let n = ring.len();
                for i in 0..n {
                    edges.push(Edge {
                        a: ring[i],
                        b: ring[(i + 1) % n],
                        building: id as u32,
                    });
                }
            }
        }
        let edge_boxes: Vec<(Vec2, Vec2)> = edges
            .iter()
            .map(|e| {
                (
                    Vec2::new(e.a.x.min(e.b.x), e.a.y.min(e.b.y)),
                    Vec2::new(e.a.x.max(e.b.x), e.a.y.max(e.b.y)),
                )
            })
            .collect();
        let building_boxes: Vec<(Vec2, Vec2)> = buildings.iter().map(|b| b.bounds).collect();
        let edge_index = BucketGrid::build(lo, hi, BUCKET_M, &edge_boxes);
        let building_index = BucketGrid::build(lo, hi, BUCKET_M, &building_boxes);
        Self {
            buildings,
            roads,
            extent,
            edges,
            edge_index,
            building_index,
        }
    }

    /// A world from polygons in local metres (as `geodata::LocalMap` holds them).
    pub fn from_polygons(
        buildings: &[geo::Polygon<f64>],
        roads: &[geo::Polygon<f64>],
        extent: &geo::Rect<f64>,
    ) -> Self {
        let ring = |ls: &geo::LineString<f64>| -> Vec<Vec2> {
            let mut r: Vec<Vec2> = ls.coords().map(|c| Vec2::new(c.x, c.y)).collect();
            if r.len() > 1 && r.first() == r.last() {
                r.pop();
            }
            r
        };
        let roads = roads
            .iter()
            .map(|p| {
                let mut rings = vec![ring(p.exterior())];
                rings.extend(p.interiors().iter().map(ring));
                rings
            })
            .collect();
        let buildings = buildings
            .iter()
            .filter_map(Building::from_polygon)
            .collect();
        let (min, max) = (extent.min(), extent.max());
        Self::new(
            buildings,
            roads,
            (Vec2::new(min.x, min.y), Vec2::new(max.x, max.y)),
        )
    }

    /// Buildings, in id order.
    pub fn buildings(&self) -> &[Building] {
        &self.buildings
    }
    /// Marks building `id` as absent from the map handed to the pipeline (it stays in the world).
    pub fn set_mapped(&mut self, id: usize, mapped: bool) {
        if let Some(b) = self.buildings.get_mut(id) {
            b.mapped = mapped;
        }
    }
    /// Road-surface polygons (outer ring then holes), local metres.
    pub fn roads(&self) -> &[Vec<Vec<Vec2>>] {
        &self.roads
    }
    /// Extent `(min, max)` of the area, local metres.
    pub fn extent(&self) -> (Vec2, Vec2) {
        self.extent
    }

    /// First building edge hit by the ray (`origin`, unit `direction`) within `max_range_m`:
    /// `(range_m, building_id)`. Walks the bucket grid cell by cell (Amanatides–Woo) and stops as
    /// soon as the best hit lies before the exit of the current bucket.
    pub fn ray_cast_buildings(
        &self,
        origin: Vec2,
        direction: Vec2,
        max_range_m: f64,
    ) -> Option<(f64, u32)> {
        let g = &self.edge_index;
        let lo = g.origin;
        let hi = g.max_corner();
        // Clip the ray to the indexed rectangle.
        let mut t0: f64 = 0.0;
        let mut t1 = max_range_m;
        for (o, d, a, b) in [
            (origin.x, direction.x, lo.x, hi.x),
            (origin.y, direction.y, lo.y, hi.y),
        ] {
            if d == 0.0 {
                if o < a || o > b {
                    return None;
                }
            } else {
                let (ta, tb) = ((a - o) / d, (b - o) / d);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        if t0 > t1 {
            return None;
        }
        let start = origin.plus(direction.scale(t0));
        let mut col = g.clamp_col(start.x) as i64;
        let mut row = g.clamp_row(start.y) as i64;
        let step_c: i64 = if direction.x > 0.0 { 1 } else { -1 };
        let step_r: i64 = if direction.y > 0.0 { 1 } else { -1 };
        let boundary = |idx: i64, step: i64, origin_axis: f64, o: f64, d: f64| -> f64 {
            if d == 0.0 {
                return f64::INFINITY;
            }
            let edge = origin_axis + (idx + i64::from(step > 0)) as f64 * g.bucket_m;
            (edge - o) / d
        };
        let mut t_next_c = boundary(col, step_c, lo.x, origin.x, direction.x);
        let mut t_next_r = boundary(row, step_r, lo.y, origin.y, direction.y);
        let dt_c = if direction.x == 0.0 {
            f64::INFINITY
        } else {
            g.bucket_m / direction.x.abs()
        };
        let dt_r = if direction.y == 0.0 {
            f64::INFINITY
        } else {
            g.bucket_m / direction.y.abs()
        };
        let mut best: Option<(f64, u32)> = None;
        loop {
            for &e in g.bucket(col as usize, row as usize) {
                let edge = &self.edges[e as usize];
                if let Some(t) = ray_segment(origin, direction, edge.a, edge.b)
                    && t <= max_range_m
                    && best.is_none_or(|(bt, _)| t < bt)
                {
                    best = Some((t, edge.building));
                }
            }
            let t_exit = t_next_c.min(t_next_r);
            if best.is_some_and(|(bt, _)| bt <= t_exit) || t_exit > t1 {
                break;
            }
            if t_next_c < t_next_r {
                col += step_c;
                t_next_c += dt_c;
            } else {
                row += step_r;
                t_next_r += dt_r;
            }
            if col < 0 || row < 0 || col >= g.cols as i64 || row >= g.rows as i64 {
                break;
            }
        }
        best
    }

    /// Ids of buildings whose bounds may intersect the rectangle `[lo, hi]`, sorted, no repeats.
    pub fn buildings_near(&self, lo: Vec2, hi: Vec2, out: &mut Vec<u32>) {
        out.clear();
        let g = &self.building_index;
        let (c0, r0, c1, r1) = g.span(lo, hi);
        for r in r0..=r1 {
            for c in c0..=c1 {
                out.extend_from_slice(g.bucket(c, r));
            }
        }
        out.sort_unstable();
        out.dedup();
        out.retain(|&id| {
            let b = &self.buildings[id as usize].bounds;
            b.0.x <= hi.x && b.1.x >= lo.x && b.0.y <= hi.y && b.1.y >= lo.y
        });
    }

    /// Whether a point lies inside any building (even–odd per building).
    pub fn building_at(&self, p: Vec2) -> Option<u32> {
        let mut ids = Vec::new();
        self.buildings_near(p, p, &mut ids);
        ids.into_iter().find(|&id| {
            let b = &self.buildings[id as usize];
            let mut xs = Vec::new();
            b.crossings_at(p.y, &mut xs);
            xs.iter().filter(|&&x| x > p.x).count() % 2 == 1
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn square(x0: f64, y0: f64, side: f64) -> Building {
        Building::new(vec![vec![
            Vec2::new(x0, y0),
            Vec2::new(x0 + side, y0),
            Vec2::new(x0 + side, y0 + side),
            Vec2::new(x0, y0 + side),
        ]])
        .unwrap()
    }

    fn world() -> World {
        // A 10 m square building with its west wall at x = 20, spanning y ∈ [−5, 5],
        // and a far one so the ray has to walk many buckets.
        World::new(
            vec![square(20.0, -5.0, 10.0), square(100.0, 40.0, 5.0)],
            vec![],
            (Vec2::new(-50.0, -50.0), Vec2::new(150.0, 150.0)),
        )
    }

    #[test]
    fn ray_cast_returns_exact_range_to_square_building() {
        let w = world();
        // Straight east from the origin: west wall at exactly 20 m.
        let (t, id) = w
            .ray_cast_buildings(Vec2::default(), Vec2::new(1.0, 0.0), 80.0)
            .unwrap();
        assert_relative_eq!(t, 20.0, epsilon = 1e-12);
        assert_eq!(id, 0);
        // At angle θ with tan θ = 0.2: hits x = 20 at y = 4 (inside the wall), range 20/cos θ.
        let theta = 0.2f64.atan();
        let (t, _) = w
            .ray_cast_buildings(Vec2::default(), Vec2::from_angle(theta), 80.0)
            .unwrap();
        assert_relative_eq!(t, 20.0 / theta.cos(), epsilon = 1e-9);
        // Beyond the max range: nothing.
        assert!(
            w.ray_cast_buildings(Vec2::default(), Vec2::new(1.0, 0.0), 19.9)
                .is_none()
        );
        // North-east towards the far building's south-west corner region: (100, 42) is on its
        // west wall; direction from (0, 0) to (100, 42) → range = |(100, 42)|.
        let target = Vec2::new(100.0, 42.0);
        let (t, id) = w
            .ray_cast_buildings(Vec2::default(), target.scale(1.0 / target.norm()), 200.0)
            .unwrap();
        assert_eq!(id, 1);
        assert_relative_eq!(t, target.norm(), epsilon = 1e-9);
    }

    #[test]
    fn ray_cast_from_outside_index_and_backwards() {
        let w = world();
        // Start west of the indexed area: the ray is clipped in and still hits at 20 + 80.
        let (t, _) = w
            .ray_cast_buildings(Vec2::new(-80.0, 0.0), Vec2::new(1.0, 0.0), 200.0)
            .unwrap();
        assert_relative_eq!(t, 100.0, epsilon = 1e-9);
        // From inside facing west toward nothing.
        assert!(
            w.ray_cast_buildings(Vec2::default(), Vec2::new(-1.0, 0.0), 200.0)
                .is_none()
        );
    }

    #[test]
    fn building_lookup_respects_holes() {
        let mut b = square(0.0, 0.0, 10.0);
        b.rings.push(vec![
            Vec2::new(4.0, 4.0),
            Vec2::new(6.0, 4.0),
            Vec2::new(6.0, 6.0),
            Vec2::new(4.0, 6.0),
        ]);
        let w = World::new(
            vec![b],
            vec![],
            (Vec2::new(0.0, 0.0), Vec2::new(10.0, 10.0)),
        );
        assert_eq!(w.building_at(Vec2::new(1.0, 1.0)), Some(0));
        assert_eq!(w.building_at(Vec2::new(5.0, 5.0)), None);
        assert_eq!(w.building_at(Vec2::new(11.0, 5.0)), None);
    }
}
