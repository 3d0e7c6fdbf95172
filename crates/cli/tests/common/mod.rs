//! Helpers shared by the command-line integration tests.

#![allow(clippy::unwrap_used, dead_code)]

/// Decodes the PNG at `path` with the `png` decoder, palettes expanded to their colours:
/// (width, height, colour type after expansion, pixels row by row from the top).
pub fn read_png(path: &std::path::Path) -> (u32, u32, png::ColorType, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    pixels.truncate(info.buffer_size());
    (info.width, info.height, info.color_type, pixels)
}
