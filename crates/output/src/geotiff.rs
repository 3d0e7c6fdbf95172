//! A minimal GeoTIFF of the decision map, written here (no GDAL): a baseline TIFF, one
//! uncompressed strip of 8-bit class codes with a colour map (palette), north up, plus the
//! GeoTIFF tags that place it: ModelPixelScale, ModelTiepoint and a GeoKeyDirectory describing
//! the local frame as a user-defined projected CRS (transverse Mercator on WGS84, parameters as
//! GeoKeys, the PROJ string in PCSCitation). Code 0 (unknown) is the no-data value
//! (`GDAL_NODATA`), so QGIS shows the base map through it.
//!
//! References: TIFF 6.0 (Adobe, 1992) §§2, 5 (palette images); OGC GeoTIFF 1.1 (19-008r4)
//! §§7 (model tags), 8 (GeoKeys).

use std::io::Write;
use std::path::Path;

use evigrid::{Label, Window};
use geodata::TransverseMercator;

use crate::atomic::write_atomic;
use crate::error::{OutputError, check_len};
use crate::georef::{GIS_COLOURS, proj_string};

const SHORT: u16 = 3;
const LONG: u16 = 4;
const ASCII: u16 = 2;
const DOUBLE: u16 = 12;

/// One IFD entry: tag, field type, count and the value's little-endian bytes.
struct Entry {
    tag: u16,
    kind: u16,
    count: u32,
    bytes: Vec<u8>,
}

fn shorts(tag: u16, values: &[u16]) -> Entry {
    Entry {
        tag,
        kind: SHORT,
        count: values.len() as u32,
        bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

fn long(tag: u16, value: u32) -> Entry {
    Entry {
        tag,
        kind: LONG,
        count: 1,
        bytes: value.to_le_bytes().to_vec(),
    }
}

fn doubles(tag: u16, values: &[f64]) -> Entry {
    Entry {
        tag,
        kind: DOUBLE,
        count: values.len() as u32,
        bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

fn ascii(tag: u16, text: &str) -> Entry {
    let mut bytes = text.as_bytes().to_vec();
    bytes.push(0);
    Entry {
        tag,
        kind: ASCII,
        count: bytes.len() as u32,
        bytes,
    }
}

/// The TIFF bytes of one 8-bit palette image with `entries` (sorted by tag here) and the
/// pixels after them.
fn encode(mut entries: Vec<Entry>, pixels: &[u8]) -> Result<Vec<u8>, String> {
    entries.sort_by_key(|e| e.tag);
    let ifd_len = 2 + 12 * entries.len() + 4;
    let mut data_at = 8 + ifd_len;
    let out_of_line: usize = entries
        .iter()
        .filter(|e| e.bytes.len() > 4)
        .map(|e| e.bytes.len().div_ceil(2) * 2)
        .sum();
    let pixels_at = u32::try_from(data_at + out_of_line).map_err(|_| "image over 4 GB")?;
    let mut ifd = Vec::with_capacity(ifd_len);
    let mut extra = Vec::with_capacity(out_of_line);
    ifd.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for e in &mut entries {
        if e.tag == 273 {
            // StripOffsets: known only now.
            e.bytes = pixels_at.to_le_bytes().to_vec();
        }
        ifd.extend_from_slice(&e.tag.to_le_bytes());
        ifd.extend_from_slice(&e.kind.to_le_bytes());
        ifd.extend_from_slice(&e.count.to_le_bytes());
        if e.bytes.len() <= 4 {
            let mut value = [0u8; 4];
            value[..e.bytes.len()].copy_from_slice(&e.bytes);
            ifd.extend_from_slice(&value);
        } else {
            let at = u32::try_from(data_at).map_err(|_| "image over 4 GB")?;
            ifd.extend_from_slice(&at.to_le_bytes());
            extra.extend_from_slice(&e.bytes);
            // Values start on a word boundary (TIFF 6.0 §2).
            if e.bytes.len() % 2 == 1 {
                extra.push(0);
            }
            data_at += e.bytes.len().div_ceil(2) * 2;
        }
    }
    ifd.extend_from_slice(&0u32.to_le_bytes()); // no next IFD
    let mut out = Vec::with_capacity(8 + ifd.len() + extra.len() + pixels.len());
    out.extend_from_slice(b"II");
    out.extend_from_slice(&42u16.to_le_bytes());
    out.extend_from_slice(&8u32.to_le_bytes());
    out.extend_from_slice(&ifd);
    out.extend_from_slice(&extra);
    out.extend_from_slice(pixels);
    Ok(out)
}

/// Writes the decision map as a GeoTIFF at `path`: pixel values are [`Label`] codes
/// (0 unknown = no data, 1 F … 5 M, 6 O), coloured by [`GIS_COLOURS`].
///
/// # Errors
///
/// [`OutputError::Size`] if `decisions` does not have the window's size; [`OutputError::Io`]
/// naming `path` (also for an image too large for a classic TIFF).
pub fn write_geotiff(
    window: &Window,
    decisions: &[Label],
    projection: &TransverseMercator,
    path: &Path,
) -> Result<(), OutputError> {
    check_len("decisions", decisions.len(), window)?;
    let (width, height) = (window.width(), window.height());
    let mut pixels = vec![0u8; width * height];
    // A row may come as two spans (the window's storage wraps), so count cells, not spans.
    let cells = window.world_order_spans().flat_map(|span| &decisions[span]);
    for (k, &label) in cells.enumerate() {
        let (row, col) = (k / width, k % width);
        pixels[(height - 1 - row) * width + col] = label as u8;
    }
    // ColorMap: all reds, then greens, then blues, 16 bits each.
    let mut palette = vec![0u16; 3 * 256];
    for (label, rgba) in GIS_COLOURS {
        for channel in 0..3 {
            palette[channel * 256 + label as usize] = u16::from(rgba[channel]) * 257;
        }
    }
    let s = window.cell_size_m();
    let west = window.first_col() as f64 * s;
    let north = (window.first_row() + height as i64) as f64 * s;
    let (lat, lon) = projection.origin();
    let gt_citation = "evigrid local transverse Mercator|";
    let pcs_citation = format!("{}|", proj_string(projection));
    let user_defined = 32767;
    // GeoKeyDirectory: header, then (key, location, count, value) sorted by key; location 0 is
    // a SHORT value in place, 34736 an index into GeoDoubleParams, 34737 into GeoAsciiParams.
    let keys: [[u16; 4]; 15] = [
        [1024, 0, 1, 1],                            // GTModelType: projected
        [1025, 0, 1, 1],                            // GTRasterType: PixelIsArea
        [1026, 34737, gt_citation.len() as u16, 0], // GTCitation
        [2048, 0, 1, 4326],                         // GeographicType: WGS 84
        [2054, 0, 1, 9102],                         // GeogAngularUnits: degree
        [3072, 0, 1, user_defined],                 // ProjectedCSType: user-defined
        [
            3073,
            34737,
            pcs_citation.len() as u16,
            gt_citation.len() as u16,
        ], // PCSCitation
        [3074, 0, 1, user_defined],                 // Projection: user-defined
        [3075, 0, 1, 1],                            // ProjCoordTrans: transverse Mercator
        [3076, 0, 1, 9001],                         // ProjLinearUnits: metre
        [3080, 34736, 1, 0],                        // ProjNatOriginLong
        [3081, 34736, 1, 1],                        // ProjNatOriginLat
        [3082, 34736, 1, 2],                        // ProjFalseEasting
        [3083, 34736, 1, 3],                        // ProjFalseNorthing
        [3092, 34736, 1, 4],                        // ProjScaleAtNatOrigin
    ];
    let mut directory = vec![1, 1, 0, keys.len() as u16];
    directory.extend(keys.iter().flatten());
    let size = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    let entries = vec![
        long(256, size(width)),
        long(257, size(height)),
        shorts(258, &[8]),
        shorts(259, &[1]),
        shorts(262, &[3]),
        long(273, 0),
        shorts(277, &[1]),
        long(278, size(height)),
        long(279, size(pixels.len())),
        shorts(284, &[1]),
        shorts(320, &palette),
        shorts(339, &[1]),
        doubles(33550, &[s, s, 0.0]),
        doubles(33922, &[0.0, 0.0, 0.0, west, north, 0.0]),
        shorts(34735, &directory),
        doubles(34736, &[lon, lat, 0.0, 0.0, 1.0]),
        ascii(34737, &format!("{gt_citation}{pcs_citation}")),
        ascii(42113, "0"),
    ];
    let bytes = encode(entries, &pixels).map_err(|e| OutputError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, e),
    })?;
    write_atomic(path, |f| f.write_all(&bytes))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::testing::{decisions, window};

    /// The value of `tag` in the first IFD as (type, count, value bytes).
    fn field(tiff: &[u8], tag: u16) -> Option<(u16, u32, Vec<u8>)> {
        let u16_at = |at: usize| u16::from_le_bytes([tiff[at], tiff[at + 1]]);
        let u32_at = |at: usize| u32::from_le_bytes(tiff[at..at + 4].try_into().unwrap());
        let ifd = u32_at(4) as usize;
        for k in 0..u16_at(ifd) as usize {
            let e = ifd + 2 + 12 * k;
            if u16_at(e) == tag {
                let (kind, count) = (u16_at(e + 2), u32_at(e + 4));
                let len = count as usize * [0, 1, 1, 2, 4, 8, 1, 1, 2, 4, 8, 4, 8][kind as usize];
                let at = if len <= 4 {
                    e + 8
                } else {
                    u32_at(e + 8) as usize
                };
                return Some((kind, count, tiff[at..at + len].to_vec()));
            }
        }
        None
    }

    #[test]
    fn tiepoint_scale_pixels_and_keys_place_the_map() {
        let w = window();
        let d = decisions(&w, |col, row| match (col, row) {
            (10, -1) => Label::F,
            (12, 0) => Label::M,
            _ => Label::Unknown,
        });
        let projection = TransverseMercator::new(60.17, 24.94).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.tif");
        write_geotiff(&w, &d, &projection, &path).unwrap();
        let tiff = std::fs::read(&path).unwrap();
        assert_eq!(&tiff[..4], b"II*\0");
        let f64s = |bytes: Vec<u8>| -> Vec<f64> {
            bytes
                .chunks(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect()
        };
        // North-west corner of cells (10..13, -1..1) of 0.5 m: (5.0, 0.5).
        let tiepoint = f64s(field(&tiff, 33922).unwrap().2);
        assert_eq!(tiepoint, [0.0, 0.0, 0.0, 5.0, 0.5, 0.0]);
        assert_eq!(f64s(field(&tiff, 33550).unwrap().2), [0.5, 0.5, 0.0]);
        assert_eq!(
            f64s(field(&tiff, 34736).unwrap().2),
            [24.94, 60.17, 0.0, 0.0, 1.0]
        );
        let offset = u32::from_le_bytes(field(&tiff, 273).unwrap().2.try_into().unwrap());
        let pixels = &tiff[offset as usize..offset as usize + 6];
        assert_eq!(pixels, [0, 0, 5, 1, 0, 0]);
        let text = String::from_utf8(field(&tiff, 34737).unwrap().2).unwrap();
        assert!(
            text.contains("+proj=tmerc +lat_0=60.17 +lon_0=24.94"),
            "{text}"
        );
    }
}
