//! Where two methods disagree, for one scan: a top view (magenta: obstacle for the first method
//! only; cyan: obstacle for the second only; dim green: ground for both; white: obstacle for
//! both) and a histogram of the disagreements by range and height above the second's ground.
//!
//! Run: `cargo run --release -p evigrid-ground --example ground_diff -- SCAN OUT.ppm [PIXELS_PER_M]`
//! (10 by default: ±40 m).

use ground::{GroundMethod, GroundParams, GroundSegmenter, PointLabel};

#[path = "../tests/common/mod.rs"]
mod common;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (scan, out, px_per_m) = match &args[..] {
        [scan, out] => (scan, out, 10.0),
        [scan, out, scale] => (scan, out, scale.parse::<f32>()?),
        _ => return Err("usage: ground_diff SCAN OUT.ppm [PIXELS_PER_M]".into()),
    };
    let points = common::read_points(std::path::Path::new(scan))?;
    let run = |method| -> Result<_, Box<dyn std::error::Error>> {
        let mut s = GroundSegmenter::new(GroundParams {
            method,
            ..GroundParams::default()
        })?;
        let r = s.segment(&points);
        Ok((r.labels().to_vec(), r.ground_z_m().to_vec()))
    };
    let (a, _) = run(GroundMethod::GlobalPlane)?;
    let (b, bz) = run(GroundMethod::LocalHeight)?;
    const SIZE: usize = 800;
    let mut image = vec![0u8; SIZE * SIZE * 3];
    let mut hist = std::collections::BTreeMap::new();
    // Lowest return per 1 m square, to show ground points lifted above it (orange).
    let mut lowest = std::collections::HashMap::new();
    let square = |p: &[f32; 3]| (p[0].floor() as i32, p[1].floor() as i32);
    for p in points.iter().filter(|p| p.iter().all(|v| v.is_finite())) {
        let e = lowest.entry(square(p)).or_insert(f32::INFINITY);
        *e = e.min(p[2]);
    }
    let lifted =
        |i: usize| b[i] == PointLabel::Ground && points[i][2] - lowest[&square(&points[i])] > 0.3;
    for pass in 0..2 {
        for (i, p) in points.iter().enumerate() {
            let (oa, ob) = (a[i] == PointLabel::Obstacle, b[i] == PointLabel::Obstacle);
            let rgb = match (oa, ob) {
                _ if lifted(i) => [255, 150, 0],
                (true, false) => [255, 0, 255],
                (false, true) => [0, 255, 255],
                (true, true) => [255, 255, 255],
                _ if b[i] == PointLabel::Ground => [0, 110, 0],
                _ => [90, 90, 90],
            };
            if (oa != ob || lifted(i)) != (pass == 1) {
                continue;
            }
            if oa != ob {
                let r = (p[0].hypot(p[1]) / 5.0) as i32 * 5;
                let h = ((p[2] - bz[i]) / 0.1).floor() as i32;
                *hist.entry((oa, r, h.clamp(-5, 30))).or_insert(0usize) += 1;
            }
            let col = (SIZE as f32 / 2.0 - p[1] * px_per_m) as isize;
            let row = (SIZE as f32 / 2.0 - p[0] * px_per_m) as isize;
            if (0..SIZE as isize).contains(&col) && (0..SIZE as isize).contains(&row) {
                let at = (row as usize * SIZE + col as usize) * 3;
                image[at..at + 3].copy_from_slice(&rgb);
            }
        }
    }
    let mut bytes = format!("P6\n{SIZE} {SIZE}\n255\n").into_bytes();
    bytes.extend_from_slice(&image);
    std::fs::write(out, bytes)?;
    let mut by_range = std::collections::BTreeMap::new();
    for ((first_only, r, _), n) in &hist {
        *by_range.entry((*first_only, *r)).or_insert(0) += n;
    }
    println!("disagreements (first_only, range bin 5 m): count");
    for (k, n) in by_range {
        println!("  {k:?}: {n}");
    }
    let mut by_h = std::collections::BTreeMap::new();
    for ((first_only, _, h), n) in &hist {
        *by_h.entry((*first_only, *h)).or_insert(0) += n;
    }
    println!("disagreements (first_only, height above local ground, dm): count");
    for (k, n) in by_h {
        println!("  {k:?}: {n}");
    }
    Ok(())
}
