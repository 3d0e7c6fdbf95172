//! The decision map georeferenced for GIS: a PNG of one pixel per cell, north up, with its world
//! file (`.pgw`), the local frame's WKT (`.prj`) and a GDAL side file (`.png.aux.xml`, the same
//! WKT: GDAL, and so QGIS, reads a PNG's CRS from it), so that QGIS lays it on OpenStreetMap.
//!
//! The local frame is [`geodata::TransverseMercator`]: WGS84, central meridian and latitude of
//! origin through the origin, scale 1, no false easting or northing, i.e. the PROJ string
//! `+proj=tmerc +lat_0=LAT +lon_0=LON +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs`.

use std::io::Write;
use std::path::{Path, PathBuf};

use evigrid::{Label, Window};
use geodata::TransverseMercator;

use crate::atomic::write_atomic;
use crate::error::{OutputError, check_len};
use crate::views::COLOURS;

/// `rgb` with opacity `alpha`.
const fn with_alpha(rgb: [u8; 3], alpha: u8) -> [u8; 4] {
    [rgb[0], rgb[1], rgb[2], alpha]
}

/// Colours of the classes: the one palette of every output ([`COLOURS`], Okabe–Ito), free
/// cells a little see-through and unknown cells transparent, so the base map shows through.
pub const GIS_COLOURS: [(Label, [u8; 4]); 8] = [
    (Label::Unknown, with_alpha(COLOURS.unknown, 0)),
    (Label::F, with_alpha(COLOURS.classes[0], 160)),
    (Label::I, with_alpha(COLOURS.classes[1], 255)),
    (Label::U, with_alpha(COLOURS.classes[2], 255)),
    (Label::S, with_alpha(COLOURS.classes[3], 255)),
    (Label::M, with_alpha(COLOURS.classes[4], 255)),
    (Label::O, with_alpha(COLOURS.occupied, 255)),
    (Label::Edge, with_alpha(COLOURS.occupied, 255)),
];

/// The colour of `label` in [`GIS_COLOURS`] (red, green, blue, alpha); the Foxglove grid's
/// colour fields are these too.
pub fn gis_colour(label: Label) -> [u8; 4] {
    GIS_COLOURS
        .iter()
        .find(|(l, _)| *l == label)
        .map_or([0, 0, 0, 0], |(_, c)| *c)
}

/// The PROJ string of the local frame.
pub fn proj_string(projection: &TransverseMercator) -> String {
    let (lat, lon) = projection.origin();
    format!(
        "+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
    )
}

/// The local frame as OGC WKT 1 (the form `.prj` files and GDAL read).
pub fn wkt(projection: &TransverseMercator) -> String {
    let (lat, lon) = projection.origin();
    format!(
        "PROJCS[\"evigrid local transverse Mercator\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",\
         SPHEROID[\"WGS 84\",6378137,298.257223563]],PRIMEM[\"Greenwich\",0],\
         UNIT[\"degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],\
         PARAMETER[\"latitude_of_origin\",{lat}],PARAMETER[\"central_meridian\",{lon}],\
         PARAMETER[\"scale_factor\",1],PARAMETER[\"false_easting\",0],\
         PARAMETER[\"false_northing\",0],UNIT[\"metre\",1],AXIS[\"Easting\",EAST],\
         AXIS[\"Northing\",NORTH]]"
    )
}

/// The six lines of an ESRI world file for the window's image: pixel size in x, two rotation
/// terms, pixel size in y (negative: rows go south), and the centre of the top-left pixel.
pub fn world_file(window: &Window) -> String {
    let s = window.cell_size_m();
    let west = window.first_col() as f64 * s;
    let north = (window.first_row() + window.height() as i64) as f64 * s;
    format!(
        "{s}\n0\n0\n{}\n{}\n{}\n",
        -s,
        west + 0.5 * s,
        north - 0.5 * s
    )
}

/// Writes `png_path` and, beside it, the world file (`.pgw`), the `.prj` and the
/// `.png.aux.xml`. Returns the files written.
///
/// # Errors
///
/// [`OutputError::Size`] if `decisions` does not have the window's size; [`OutputError::Png`]
/// or [`OutputError::Io`] naming the file.
pub fn write_georeferenced_png(
    window: &Window,
    decisions: &[Label],
    projection: &TransverseMercator,
    png_path: &Path,
) -> Result<Vec<PathBuf>, OutputError> {
    check_len("decisions", decisions.len(), window)?;
    let (width, height) = (window.width(), window.height());
    let size = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    // Four bytes a pixel, rows from the top (the north).
    let mut rgba = vec![0u8; window.len() * 4];
    // A row may come as two spans (the window's storage wraps), so count cells, not spans.
    let cells = window.world_order_spans().flat_map(|span| &decisions[span]);
    for (k, &label) in cells.enumerate() {
        let (row, col) = (k / width, k % width);
        let at = ((height - 1 - row) * width + col) * 4;
        rgba[at..at + 4].copy_from_slice(&gis_colour(label));
    }
    let encoded = crate::raster::rgba_png(size(width), size(height), &rgba).map_err(|source| {
        OutputError::Png {
            path: png_path.to_path_buf(),
            source,
        }
    })?;
    write_atomic(png_path, |f| f.write_all(&encoded))?;
    let wkt = wkt(projection);
    let pgw = png_path.with_extension("pgw");
    let prj = png_path.with_extension("prj");
    let mut aux_name = png_path.as_os_str().to_owned();
    aux_name.push(".aux.xml");
    let aux = PathBuf::from(aux_name);
    write_atomic(&pgw, |f| f.write_all(world_file(window).as_bytes()))?;
    write_atomic(&prj, |f| f.write_all(wkt.as_bytes()))?;
    let xml = format!(
        "<PAMDataset>\n  <SRS>{}</SRS>\n</PAMDataset>\n",
        wkt.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;")
    );
    write_atomic(&aux, |f| f.write_all(xml.as_bytes()))?;
    Ok(vec![png_path.to_path_buf(), pgw, prj, aux])
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::testing::{decisions, window};

    #[test]
    fn the_world_file_puts_the_top_left_pixel_centre_at_the_north_west_cell() {
        // Cells (10..13, -1..1) of 0.5 m: x 5.0..6.5, y -0.5..0.5.
        let w = window();
        let lines: Vec<f64> = world_file(&w).lines().map(|l| l.parse().unwrap()).collect();
        assert_eq!(lines, [0.5, 0.0, 0.0, -0.5, 5.25, 0.25]);
    }

    #[test]
    fn the_png_is_north_up_with_sidecars() {
        let w = window();
        let d = decisions(&w, |col, row| match (col, row) {
            (10, -1) => Label::F,
            (12, 0) => Label::M,
            _ => Label::Unknown,
        });
        let projection = TransverseMercator::new(60.17, 24.94).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let files =
            write_georeferenced_png(&w, &d, &projection, &dir.path().join("d.png")).unwrap();
        assert_eq!(files.len(), 4);
        let (colour, width, height, rgba) =
            crate::testing::decode_png(&std::fs::read(dir.path().join("d.png")).unwrap());
        assert_eq!((colour, width, height), (png::ColorType::Rgba, 3, 2));
        // Pixel (x, y) at bytes 4 (y * 3 + x)..: (2, 0) moving, (0, 1) free, (0, 0) unknown.
        assert_eq!(rgba[8..12], gis_colour(Label::M));
        assert_eq!(rgba[12..16], gis_colour(Label::F));
        assert_eq!(rgba[3], 0);
        let prj = std::fs::read_to_string(dir.path().join("d.prj")).unwrap();
        assert!(
            prj.contains("PARAMETER[\"central_meridian\",24.94]"),
            "{prj}"
        );
        assert!(proj_string(&projection).contains("+lat_0=60.17 +lon_0=24.94"));
    }
}
