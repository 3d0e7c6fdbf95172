//! Fixtures shared by the tests of the views and the exports.
#![allow(clippy::unwrap_used)]

use evigrid::{Label, Window};

/// A 3 × 2 window at cells (10..13, -1..1), scrolled so storage and world order differ.
pub(crate) fn window() -> Window {
    let mut w = Window::new(3, 2, 0.5).unwrap();
    w.move_to(10, -1);
    w
}

/// Labels in storage order from a function of the global cell.
pub(crate) fn decisions(w: &Window, f: impl Fn(i64, i64) -> Label) -> Vec<Label> {
    (0..w.len())
        .map(|idx| {
            let c = w.cell_of_storage(idx).unwrap();
            f(c.col, c.row)
        })
        .collect()
}

/// Decodes a PNG file's bytes, palettes expanded to their colours and bit depths below 8 to
/// bytes: (colour type after expansion, width, height, pixels row by row from the top).
pub(crate) fn decode_png(bytes: &[u8]) -> (png::ColorType, u32, u32, Vec<u8>) {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.color_type, info.width, info.height, buf)
}

/// The RGB picture of the PNG file at `path` (an RGB or a palette PNG without transparency).
pub(crate) fn read_rgb(path: &std::path::Path) -> crate::raster::RgbImage {
    let (colour, w, h, data) = decode_png(&std::fs::read(path).unwrap());
    assert_eq!(colour, png::ColorType::Rgb, "{}", path.display());
    crate::raster::RgbImage::from_raw(w, h, data).unwrap()
}
