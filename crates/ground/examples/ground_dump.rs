//! Prints the points of one scan with a given label, in 1 m squares: where the local method
//! puts them. Run: `cargo run --release -p evigrid-ground --example ground_dump -- SCAN LABEL`
//! with LABEL one of ground, obstacle, overhanging, below_ground.

use ground::{GroundParams, GroundSegmenter, PointLabel};

#[path = "../tests/common/mod.rs"]
mod common;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [scan, label] = &args[..] else {
        return Err("usage: ground_dump SCAN LABEL".into());
    };
    let want = match label.as_str() {
        "ground" => PointLabel::Ground,
        "obstacle" => PointLabel::Obstacle,
        "overhanging" => PointLabel::Overhanging,
        "below_ground" => PointLabel::BelowGround,
        _ => return Err(format!("unknown label {label}").into()),
    };
    let points = common::read_points(std::path::Path::new(scan))?;
    let mut segmenter = GroundSegmenter::new(GroundParams::default())?;
    let result = segmenter.segment(&points);
    let mut squares = std::collections::BTreeMap::new();
    for (i, p) in points.iter().enumerate() {
        if result.labels()[i] == want {
            let e = squares
                .entry((p[0].floor() as i32, p[1].floor() as i32))
                .or_insert((0usize, f32::INFINITY, f32::NEG_INFINITY, 0.0f32));
            e.0 += 1;
            e.1 = e.1.min(p[2]);
            e.2 = e.2.max(p[2]);
            e.3 = result.ground_z_m()[i];
        }
    }
    let mut rows: Vec<_> = squares.into_iter().collect();
    rows.sort_by_key(|row| std::cmp::Reverse(row.1.0));
    println!("square (x, y): points, z min..max, a ground z");
    for ((x, y), (n, lo, hi, g)) in rows.iter().take(30) {
        println!("({x:4}, {y:4}): {n:5}  z {lo:6.2}..{hi:6.2}  ground {g:6.2}");
    }
    Ok(())
}
