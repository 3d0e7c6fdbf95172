//! The nav2 `map_server` pair: a PGM (P5) image and its YAML, loaded by `map_server` as the
//! decided occupancy grid.
//!
//! `map_server` (mode `trinary`, `negate: 0`) reads a pixel value `v` as occupancy
//! `p = (255 − v) / 255`: occupied if `p > occupied_thresh`, free if `p < free_thresh`, unknown
//! otherwise. With the thresholds written here (0.65, 0.25) the pixels are 0 occupied
//! (p = 1), 254 free (p = 0.004) and 128 unknown (p = 0.50). ROS 1's `map_saver` writes 205 for
//! unknown, which under `free_thresh: 0.25` loads as *free* (p = 0.196); 128 is unknown under
//! any thresholds around the middle. Rows go north to south (the image's top row is the map's
//! northern edge): `map_server` puts the image's bottom-left pixel at `origin`.

use std::io::Write;
use std::path::Path;

use evigrid::{Label, Window};

use crate::atomic::write_atomic;
use crate::error::{OutputError, check_len};
use crate::mcap::occupancy;

/// Pixel of an occupied cell.
pub const PGM_OCCUPIED: u8 = 0;
/// Pixel of a free cell.
pub const PGM_FREE: u8 = 254;
/// Pixel of an unknown cell.
pub const PGM_UNKNOWN: u8 = 128;
/// `occupied_thresh` of the YAML.
pub const OCCUPIED_THRESH: f64 = 0.65;
/// `free_thresh` of the YAML.
pub const FREE_THRESH: f64 = 0.25;

/// Writes `<stem>.pgm` and `<stem>.yaml` (the YAML names the PGM by its file name, so the pair
/// moves together).
///
/// # Errors
///
/// [`OutputError::Size`] if `decisions` does not have the window's size; [`OutputError::Io`]
/// naming the file.
pub fn write_nav2_map(
    window: &Window,
    decisions: &[Label],
    yaml_path: &Path,
) -> Result<(), OutputError> {
    check_len("decisions", decisions.len(), window)?;
    let pgm_path = yaml_path.with_extension("pgm");
    let (width, height) = (window.width(), window.height());
    let mut pixels = vec![PGM_UNKNOWN; width * height];
    // World order is south to north; the image is north to south.
    // A row may come as two spans (the window's storage wraps), so count cells, not spans.
    let cells = window.world_order_spans().flat_map(|span| &decisions[span]);
    for (k, &label) in cells.enumerate() {
        let (row, col) = (k / width, k % width);
        pixels[(height - 1 - row) * width + col] = match occupancy(label) {
            0 => PGM_FREE,
            100 => PGM_OCCUPIED,
            _ => PGM_UNKNOWN,
        };
    }
    write_atomic(&pgm_path, |file| {
        write!(file, "P5\n{width} {height}\n255\n")?;
        file.write_all(&pixels)
    })?;
    let image = pgm_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let s = window.cell_size_m();
    let (x0, y0) = (window.first_col() as f64 * s, window.first_row() as f64 * s);
    // The image name is quoted: a YAML scalar may not be read back as written otherwise.
    let yaml = format!(
        "image: {image:?}\nmode: trinary\nresolution: {s:?}\norigin: [{x0:?}, {y0:?}, 0.0]\n\
         negate: 0\noccupied_thresh: {OCCUPIED_THRESH}\nfree_thresh: {FREE_THRESH}\n"
    );
    write_atomic(yaml_path, |file| file.write_all(yaml.as_bytes()))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::testing::{decisions, window};

    #[test]
    fn the_pgm_is_north_up_and_loads_back_under_nav2_rules() {
        let w = window();
        let d = decisions(&w, |col, row| match (col, row) {
            (10, -1) => Label::F,
            (12, 0) => Label::M,
            _ => Label::Unknown,
        });
        let dir = tempfile::tempdir().unwrap();
        let yaml = dir.path().join("map.yaml");
        write_nav2_map(&w, &d, &yaml).unwrap();
        let pgm = std::fs::read(dir.path().join("map.pgm")).unwrap();
        let header = b"P5\n3 2\n255\n";
        assert_eq!(&pgm[..header.len()], header);
        let pixels = &pgm[header.len()..];
        // Top row is row 0 (north): M at its east end; bottom row: F at its west end.
        assert_eq!(pixels, [128, 128, 0, 254, 128, 128]);
        // nav2's reading of each pixel value.
        let load = |v: u8| {
            let p = (255.0 - f64::from(v)) / 255.0;
            if p > OCCUPIED_THRESH {
                100
            } else if p < FREE_THRESH {
                0
            } else {
                -1
            }
        };
        assert_eq!(
            [PGM_OCCUPIED, PGM_FREE, PGM_UNKNOWN].map(load),
            [100, 0, -1]
        );
        let text = std::fs::read_to_string(&yaml).unwrap();
        assert!(text.contains("image: \"map.pgm\"\n"), "{text}");
        assert!(text.contains("origin: [5.0, -0.5, 0.0]"), "{text}");
    }
}
