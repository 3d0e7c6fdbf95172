//! Ring checks and multipolygon ring assembly, shared by the OSM and GeoJSON readers.

use geo::{Coord, LineString, Polygon};

use crate::features::SkipReason;

/// Turns a list of points into a valid closed ring, or says why it cannot be one.
///
/// Closes the ring if the last point differs from the first, drops consecutive repeated points,
/// and rejects rings with fewer than three distinct points ([`SkipReason::DegenerateRing`]) or
/// whose edges cross ([`SkipReason::SelfIntersectingRing`]).
pub(crate) fn clean_ring(points: &[Coord<f64>]) -> Result<LineString<f64>, SkipReason> {
    let mut ring: Vec<Coord<f64>> = Vec::with_capacity(points.len() + 1);
    for point in points {
        if ring.last() != Some(point) {
            ring.push(*point);
        }
    }
    if ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    if ring.len() < 3 {
        return Err(SkipReason::DegenerateRing);
    }
    if !is_simple(&ring) {
        return Err(SkipReason::SelfIntersectingRing);
    }
    ring.push(ring[0]);
    Ok(LineString::new(ring))
}

/// True when no two non-adjacent edges of the (implicitly closed, open-form) ring meet and no
/// two adjacent edges fold back onto each other.
///
/// O(n²) in the number of vertices; building rings have tens of vertices. Rings above
/// [`MAX_CHECKED_VERTICES`] are accepted unchecked: the even-odd fill still gives a sensible
/// interior for them and the quadratic check would dominate loading.
fn is_simple(ring: &[Coord<f64>]) -> bool {
    let n = ring.len();
    if n > MAX_CHECKED_VERTICES {
        return true;
    }
    let edge = |i: usize| (ring[i], ring[(i + 1) % n]);
    for i in 0..n {
        for j in (i + 1)..n {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            let (a, b) = edge(i);
            let (c, d) = edge(j);
            if adjacent {
                // Adjacent edges share one vertex; they are bad only if they overlap (fold back).
                let shared = if j == i + 1 { b } else { a };
                let (p, q) = if j == i + 1 { (a, d) } else { (b, c) };
                if orientation(p, shared, q) == 0.0 && dot(p, shared, q) > 0.0 {
                    return false;
                }
            } else if segments_meet(a, b, c, d) {
                return false;
            }
        }
    }
    true
}

/// Rings with more vertices are not checked for self-intersection (see [`is_simple`]).
const MAX_CHECKED_VERTICES: usize = 2000;

fn orientation(a: Coord<f64>, b: Coord<f64>, c: Coord<f64>) -> f64 {
    (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
}

/// (p − s)·(q − s): positive when p and q lie on the same side of the shared vertex s.
fn dot(p: Coord<f64>, s: Coord<f64>, q: Coord<f64>) -> f64 {
    (p.x - s.x) * (q.x - s.x) + (p.y - s.y) * (q.y - s.y)
}

fn on_segment(a: Coord<f64>, b: Coord<f64>, p: Coord<f64>) -> bool {
    p.x >= a.x.min(b.x) && p.x <= a.x.max(b.x) && p.y >= a.y.min(b.y) && p.y <= a.y.max(b.y)
}

/// Closed segments [a,b] and [c,d] share at least one point.
fn segments_meet(a: Coord<f64>, b: Coord<f64>, c: Coord<f64>, d: Coord<f64>) -> bool {
    let d1 = orientation(c, d, a);
    let d2 = orientation(c, d, b);
    let d3 = orientation(a, b, c);
    let d4 = orientation(a, b, d);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && on_segment(c, d, a))
        || (d2 == 0.0 && on_segment(c, d, b))
        || (d3 == 0.0 && on_segment(a, b, c))
        || (d4 == 0.0 && on_segment(a, b, d))
}

/// Joins ways (as node-id sequences) end to end into closed rings.
///
/// Each way is used once, possibly reversed. Returns the closed rings (as node-id sequences,
/// first = last) and the number of chains that could not be closed.
pub(crate) fn assemble_rings(ways: &[Vec<i64>]) -> (Vec<Vec<i64>>, usize) {
    let mut used = vec![false; ways.len()];
    let mut rings = Vec::new();
    let mut open = 0;
    for start in 0..ways.len() {
        if used[start] || ways[start].len() < 2 {
            used[start] = true;
            continue;
        }
        used[start] = true;
        let mut chain = ways[start].clone();
        loop {
            let (first, last) = (chain[0], chain[chain.len() - 1]);
            if first == last && chain.len() > 3 {
                break;
            }
            let next = (0..ways.len()).find(|&k| {
                !used[k]
                    && ways[k].len() >= 2
                    && (ways[k][0] == last || ways[k][ways[k].len() - 1] == last)
            });
            let Some(k) = next else { break };
            used[k] = true;
            if ways[k][0] == last {
                chain.extend_from_slice(&ways[k][1..]);
            } else {
                chain.extend(ways[k].iter().rev().skip(1));
            }
        }
        if chain[0] == chain[chain.len() - 1] && chain.len() > 3 {
            rings.push(chain);
        } else {
            open += 1;
        }
    }
    (rings, open)
}

/// Groups outer and inner rings into polygons: each inner ring goes to the first outer ring that
/// strictly contains one of its vertices. Returns the polygons and the number of inner rings that fit none.
pub(crate) fn group_rings(
    outers: Vec<LineString<f64>>,
    inners: Vec<LineString<f64>>,
) -> (Vec<Polygon<f64>>, usize) {
    use geo::Contains;
    let mut holes: Vec<Vec<LineString<f64>>> = vec![Vec::new(); outers.len()];
    let shells: Vec<Polygon<f64>> = outers
        .iter()
        .map(|ring| Polygon::new(ring.clone(), Vec::new()))
        .collect();
    let mut orphans = 0;
    for inner in inners {
        // Any vertex strictly inside decides: inner rings often touch their outer ring.
        match shells
            .iter()
            .position(|shell| inner.0.iter().any(|vertex| shell.contains(vertex)))
        {
            Some(k) => holes[k].push(inner),
            None => orphans += 1,
        }
    }
    let polygons = outers
        .into_iter()
        .zip(holes)
        .map(|(outer, holes)| Polygon::new(outer, holes))
        .collect();
    (polygons, orphans)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coords(points: &[(f64, f64)]) -> Vec<Coord<f64>> {
        points.iter().map(|&(x, y)| Coord { x, y }).collect()
    }

    #[test]
    fn clean_ring_accepts_closes_and_rejects() {
        let square = coords(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        let ring = clean_ring(&square);
        assert_eq!(
            ring.map(|r| r.0.len()),
            Ok(5),
            "closed by repeating the first point"
        );
        let bowtie = coords(&[(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0), (0.0, 0.0)]);
        assert_eq!(clean_ring(&bowtie), Err(SkipReason::SelfIntersectingRing));
        let line = coords(&[(0.0, 0.0), (1.0, 0.0), (0.0, 0.0)]);
        assert_eq!(clean_ring(&line), Err(SkipReason::DegenerateRing));
        let spike = coords(&[(0.0, 0.0), (2.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 0.0)]);
        assert_eq!(clean_ring(&spike), Err(SkipReason::SelfIntersectingRing));
    }

    #[test]
    fn rings_assemble_from_pieces_in_any_direction() {
        // A square 1-2-3-4 split into three ways, the middle one reversed, plus a dangling way.
        let ways = vec![vec![1, 2], vec![3, 2], vec![3, 4, 1], vec![7, 8]];
        let (rings, open) = assemble_rings(&ways);
        assert_eq!(rings, vec![vec![1, 2, 3, 4, 1]]);
        assert_eq!(open, 1);
    }

    #[test]
    fn inner_rings_go_to_the_outer_that_holds_them() {
        let outer_a = LineString::from(vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 0.0)]);
        let outer_b = LineString::from(vec![
            (20.0, 0.0),
            (30.0, 0.0),
            (30.0, 10.0),
            (20.0, 10.0),
            (20.0, 0.0),
        ]);
        let inner = LineString::from(vec![(22.0, 2.0), (24.0, 2.0), (24.0, 4.0), (22.0, 2.0)]);
        let stray = LineString::from(vec![(50.0, 2.0), (54.0, 2.0), (54.0, 4.0), (50.0, 2.0)]);
        let (polygons, orphans) = group_rings(vec![outer_a, outer_b], vec![inner, stray]);
        assert_eq!(polygons[0].interiors().len(), 0);
        assert_eq!(polygons[1].interiors().len(), 1);
        assert_eq!(orphans, 1);
    }
}
