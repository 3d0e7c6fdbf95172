//! The decision map written straight to a palette PNG: the per-frame picture of a run.
//!
//! A decision map has at most eight colours, one per [`Label`], so its PNG needs no RGB: a
//! palette and 1, 2 or 4 bits a pixel (2 for [`ClassColours::THREE_CLASSES`]' four colours) is
//! the same picture for every decoder, with a twelfth of the bytes to filter and deflate, and
//! with fast deflate (`fdeflate`) it is what makes a picture a frame affordable: on the 320 × 320
//! window of KITTI 0013 it costs a small fraction of [`decision_image`](crate::decision_image)
//! then [`write_png`](crate::write_png) (`docs/benchmarks.md`).

use std::io::Write as _;
use std::path::Path;

use crate::raster::RgbImage;
use evigrid::{Label, Window};

use crate::atomic::write_atomic;
use crate::error::{OutputError, check_len};
use crate::views::ClassColours;

/// The palette of `colours` (each distinct colour once, in [`Label::ALL`] order) and each
/// label's index in it, by label code.
fn palette(colours: &ClassColours) -> (Vec<[u8; 3]>, [u8; Label::ALL.len()]) {
    let mut entries: Vec<[u8; 3]> = Vec::with_capacity(Label::ALL.len());
    let mut index = [0u8; Label::ALL.len()];
    for label in Label::ALL {
        let colour = colours.of(label);
        let at = match entries.iter().position(|&c| c == colour) {
            Some(at) => at,
            None => {
                entries.push(colour);
                entries.len() - 1
            }
        };
        // At most eight labels, so at most eight entries.
        index[label as usize] = at as u8;
    }
    (entries, index)
}

/// The smallest PNG bit depth that holds `entries` palette indices.
fn bit_depth(entries: usize) -> (png::BitDepth, u32) {
    match entries {
        0..=2 => (png::BitDepth::One, 1),
        3..=4 => (png::BitDepth::Two, 2),
        5..=16 => (png::BitDepth::Four, 4),
        _ => (png::BitDepth::Eight, 8),
    }
}

/// Writes the decision map (`decisions` in storage order, one pixel per cell, north up, as
/// [`decision_image`](crate::decision_image) paints it with `colours`) to `path` as a palette
/// PNG with fast compression, atomically ([`write_atomic`]).
///
/// # Errors
///
/// [`OutputError::Size`] if `decisions` does not have one entry per window cell;
/// [`OutputError::Png`] or [`OutputError::Io`] naming `path`.
pub fn write_decision_png(
    window: &Window,
    decisions: &[Label],
    colours: &ClassColours,
    path: &Path,
) -> Result<(), OutputError> {
    check_len("decisions", decisions.len(), window)?;
    let (entries, index) = palette(colours);
    let (depth, bits) = bit_depth(entries.len());
    let (w, h) = (window.width(), window.height());
    let per_byte = (8 / bits) as usize;
    let row_bytes = w.div_ceil(per_byte);
    let mut packed = vec![0u8; row_bytes * h];
    // World-order spans run south to north, west to east; image rows run north to south.
    let mut pixel = 0usize;
    for span in window.world_order_spans() {
        for idx in span {
            let (x, row_from_south) = (pixel % w, pixel / w);
            let row = h - 1 - row_from_south;
            let code = u32::from(index[decisions[idx] as usize]);
            // The leftmost pixel in the high bits (PNG's order for depths below 8).
            let shift = 8 - bits * (1 + (x % per_byte) as u32);
            packed[row * row_bytes + x / per_byte] |= (code << shift) as u8;
            pixel += 1;
        }
    }
    write_palette_png(path, (w, h), &entries, depth, &packed)
}

/// Writes `image` to `path` as a palette PNG with fast compression, atomically: the frame
/// picture ([`frame_picture`](crate::frame_picture): the decision map, the ego's cross and the
/// legend strip) has a few dozen colours (the classes', the ego's, the strip's paper, ink and
/// the text's grey edges), so one byte a pixel at most instead of three, the same pixels for
/// every decoder. A picture of more than 256 colours is written as RGB ([`write_png`](crate::write_png)).
///
/// # Errors
///
/// [`OutputError::Png`] or [`OutputError::Io`] naming `path`.
pub fn write_indexed_png(image: &RgbImage, path: &Path) -> Result<(), OutputError> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let mut entries: Vec<[u8; 3]> = Vec::new();
    let mut codes = Vec::with_capacity(w * h);
    // Runs of one colour are the rule (a map's cells): look up only when the colour changes.
    let mut last: Option<([u8; 3], u8)> = None;
    for pixel in image.as_raw().chunks_exact(3) {
        let colour = [pixel[0], pixel[1], pixel[2]];
        let code = match last {
            Some((c, code)) if c == colour => code,
            _ => {
                let code = match entries.iter().position(|&c| c == colour) {
                    Some(at) => at,
                    None if entries.len() < 256 => {
                        entries.push(colour);
                        entries.len() - 1
                    }
                    None => return crate::write_png(image, path),
                };
                // At most 256 entries, so the index fits a byte.
                let code = code as u8;
                last = Some((colour, code));
                code
            }
        };
        codes.push(code);
    }
    let (depth, bits) = bit_depth(entries.len());
    let packed = if bits == 8 {
        // One byte a pixel: the codes are the rows as they are.
        codes
    } else {
        let per_byte = (8 / bits) as usize;
        let row_bytes = w.div_ceil(per_byte);
        let mut packed = vec![0u8; row_bytes * h];
        if w > 0 {
            for (row, codes) in packed
                .chunks_exact_mut(row_bytes)
                .zip(codes.chunks_exact(w))
            {
                for (x, &code) in codes.iter().enumerate() {
                    let shift = 8 - bits * (1 + (x % per_byte) as u32);
                    row[x / per_byte] |= (u32::from(code) << shift) as u8;
                }
            }
        }
        packed
    };
    write_palette_png(path, (w, h), &entries, depth, &packed)
}

/// Encodes packed palette indices (`depth` bits a pixel, rows padded to a byte) with `entries`
/// as the palette, fast compression, and writes them to `path` atomically.
fn write_palette_png(
    path: &Path,
    (w, h): (usize, usize),
    entries: &[[u8; 3]],
    depth: png::BitDepth,
    packed: &[u8],
) -> Result<(), OutputError> {
    let image_error = |source: png::EncodingError| OutputError::Png {
        path: path.to_path_buf(),
        source,
    };
    let mut encoded = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut encoded, w as u32, h as u32);
        encoder.set_color(png::ColorType::Indexed);
        encoder.set_depth(depth);
        encoder.set_palette(entries.concat());
        encoder.set_compression(png::Compression::Fast);
        let mut writer = encoder.write_header().map_err(image_error)?;
        writer.write_image_data(packed).map_err(image_error)?;
        writer.finish().map_err(image_error)?;
    }
    write_atomic(path, |file| file.write_all(&encoded))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::raster::Rgb;
    use crate::testing::window;
    use crate::{decision_image, write_png};

    /// Every label somewhere, in an irregular pattern, on a window that has moved (its storage
    /// wraps) and whose width is not a multiple of four pixels.
    fn scene() -> (Window, Vec<Label>) {
        let mut w = Window::new(13, 7, 0.5).unwrap();
        let _ = w.move_to(5, -3);
        let d = (0..w.len())
            .map(|i| Label::ALL[(i * 7 + i / 5) % Label::ALL.len()])
            .collect();
        (w, d)
    }

    #[test]
    fn the_palette_png_has_the_pixels_of_the_rgb_picture() {
        let dir = tempfile::tempdir().unwrap();
        for (colours, entries) in [
            (ClassColours::THREE_CLASSES, 4),
            (ClassColours::FIVE_CLASSES, 7),
            (ClassColours::OKABE_ITO, 7),
        ] {
            assert_eq!(palette(&colours).0.len(), entries);
            let (w, d) = scene();
            let rgb = dir.path().join("rgb.png");
            let indexed = dir.path().join("indexed.png");
            write_png(&decision_image(&w, &d, &colours).unwrap(), &rgb).unwrap();
            write_decision_png(&w, &d, &colours, &indexed).unwrap();
            let expected = crate::testing::read_rgb(&rgb);
            let read = crate::testing::read_rgb(&indexed);
            assert_eq!(read.dimensions(), (13, 7));
            assert_eq!(read, expected);
        }
    }

    #[test]
    fn three_classes_take_two_bits_a_pixel() {
        // Unknown black, F green, I/U/S/O/Edge blue, M red: four colours.
        let (entries, index) = palette(&ClassColours::THREE_CLASSES);
        assert_eq!(
            entries,
            [[0, 0, 0], [0, 190, 0], [40, 80, 255], [230, 0, 0]]
        );
        assert_eq!(index, [0, 1, 2, 2, 2, 3, 2, 2]);
        assert_eq!(bit_depth(4), (png::BitDepth::Two, 2));
        assert_eq!(bit_depth(5), (png::BitDepth::Four, 4));
        assert_eq!(bit_depth(17), (png::BitDepth::Eight, 8));
        // Header byte 24 of a PNG is the IHDR's bit depth, byte 25 its colour type (3: palette).
        let w = window();
        let d = vec![Label::F; w.len()];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        write_decision_png(&w, &d, &ClassColours::THREE_CLASSES, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!((bytes[24], bytes[25]), (2, 3));
    }

    #[test]
    fn the_frame_picture_is_written_as_a_palette_png_with_its_pixels() {
        // The legend strip's text, the ego's cross and every class: the same pixels as RGB,
        // one byte a pixel at most (colour type 3).
        let (w, d) = scene();
        let picture = crate::frame_picture(&w, &d, [3.0, -1.0], &crate::COLOURS).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.png");
        write_indexed_png(&picture, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes[25], 3);
        assert!(bytes[24] <= 8);
        assert_eq!(crate::testing::read_rgb(&path), picture);
        // 257 colours fall back to RGB (colour type 2), the same pixels.
        let mut many = RgbImage::new(257, 1);
        for x in 0..257 {
            many.put_pixel(x, 0, Rgb([(x % 256) as u8, (x / 256) as u8, 7]));
        }
        write_indexed_png(&many, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes[25], 2);
        assert_eq!(crate::testing::read_rgb(&path), many);
    }

    #[test]
    fn a_picture_of_few_colours_is_packed_below_a_byte_a_pixel() {
        // Five pixels a row (not a whole number of bytes at 2 or 4 bits), three rows.
        for colours in [3usize, 9] {
            let mut picture = RgbImage::new(5, 3);
            for y in 0..3 {
                for x in 0..5 {
                    let k = ((x * 7 + y * 3) as usize % colours) as u8;
                    picture.put_pixel(x, y, Rgb([10 * k, 255 - k, 3]));
                }
            }
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("f.png");
            write_indexed_png(&picture, &path).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            // Bit depth 2 for three colours, 4 for nine; colour type 3, palette.
            assert_eq!(
                (bytes[24], bytes[25]),
                (if colours == 3 { 2 } else { 4 }, 3)
            );
            assert_eq!(crate::testing::read_rgb(&path), picture);
        }
    }

    #[test]
    fn decisions_of_the_wrong_size_are_refused_and_write_nothing() {
        let w = window();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        let error =
            write_decision_png(&w, &[Label::F], &ClassColours::THREE_CLASSES, &path).unwrap_err();
        assert!(matches!(error, OutputError::Size { .. }), "{error}");
        assert!(!path.exists());
    }
}
