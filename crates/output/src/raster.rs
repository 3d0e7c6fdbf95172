//! The pictures' pixels and their files: an RGB raster ([`RgbImage`]), its PNG ([`RgbImage::to_png`],
//! and [`rgba_png`] for the one picture with transparency) and the animated GIF of the demo
//! ([`GifAnimation`]).
//!
//! Only what the views, figures and plots need: a buffer of 8-bit RGB pixels, row by row from the
//! top left, that can be painted pixel by pixel, pasted into another ([`RgbImage::replace`]) and
//! turned a quarter ([`RgbImage::rotate270`]). The files are written by the `png` and `gif`
//! encoders directly, with the settings the pictures had through the `image` crate: fast deflate with an
//! adaptive filter per row for PNG, a palette per frame for GIF (the exact colours when a frame
//! has at most 256, else NeuQuant at its fastest).
//!
//! ```
//! use output::raster::{Rgb, RgbImage};
//!
//! let mut image = RgbImage::from_pixel(3, 2, Rgb([255, 255, 255]));
//! image.put_pixel(2, 0, Rgb([230, 0, 0]));
//! assert_eq!(image.get_pixel(2, 0), Rgb([230, 0, 0]));
//! // Turned a quarter anticlockwise: the top-right pixel is now the top-left one.
//! assert_eq!(image.rotate270().get_pixel(0, 0), Rgb([230, 0, 0]));
//! assert!(image.to_png()?.starts_with(b"\x89PNG"));
//! # Ok::<(), png::EncodingError>(())
//! ```

/// A colour: red, green, blue, 0–255 each.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rgb(pub [u8; 3]);

/// A picture of `width × height` [`Rgb`] pixels, stored row by row from the top left, three bytes
/// a pixel ([`RgbImage::as_raw`]). Pixel (`x`, `y`) is column `x` from the left, row `y` from
/// the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbImage {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl RgbImage {
    /// A black picture.
    pub fn new(width: u32, height: u32) -> Self {
        Self::from_pixel(width, height, Rgb([0, 0, 0]))
    }

    /// A picture of one colour.
    pub fn from_pixel(width: u32, height: u32, colour: Rgb) -> Self {
        let pixels = width as usize * height as usize;
        Self {
            width,
            height,
            data: colour.0.repeat(pixels),
        }
    }

    /// The picture of `data` (three bytes a pixel, rows from the top), or `None` if `data` is not
    /// `3 × width × height` bytes long.
    pub fn from_raw(width: u32, height: u32, data: Vec<u8>) -> Option<Self> {
        let expected = (width as usize)
            .checked_mul(height as usize)?
            .checked_mul(3)?;
        (data.len() == expected).then_some(Self {
            width,
            height,
            data,
        })
    }

    /// Width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// (width, height), pixels.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Where pixel (`x`, `y`) starts in [`RgbImage::as_raw`].
    ///
    /// # Panics
    ///
    /// If the pixel is outside the picture.
    fn at(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside a picture of {} × {} px",
            self.width,
            self.height
        );
        (y as usize * self.width as usize + x as usize) * 3
    }

    /// The colour of pixel (`x`, `y`).
    ///
    /// # Panics
    ///
    /// If the pixel is outside the picture (a caller's coordinates, never a file's).
    pub fn get_pixel(&self, x: u32, y: u32) -> Rgb {
        let at = self.at(x, y);
        Rgb([self.data[at], self.data[at + 1], self.data[at + 2]])
    }

    /// Paints pixel (`x`, `y`) `colour`.
    ///
    /// # Panics
    ///
    /// If the pixel is outside the picture (a caller's coordinates, never a file's).
    pub fn put_pixel(&mut self, x: u32, y: u32, colour: Rgb) {
        let at = self.at(x, y);
        self.data[at..at + 3].copy_from_slice(&colour.0);
    }

    /// Every pixel's colour, row by row from the top left.
    pub fn pixels(&self) -> impl Iterator<Item = Rgb> + '_ {
        self.data.chunks_exact(3).map(|p| Rgb([p[0], p[1], p[2]]))
    }

    /// Every pixel as (`x`, `y`, colour), row by row from the top left.
    pub fn enumerate_pixels(&self) -> impl Iterator<Item = (u32, u32, Rgb)> + '_ {
        // A picture of width 0 has no pixel; max(1) only keeps the division defined.
        let width = self.width.max(1);
        self.pixels().enumerate().map(move |(k, p)| {
            // k < width × height, both u32, so both quotients fit.
            let k = k as u64;
            let w = u64::from(width);
            ((k % w) as u32, (k / w) as u32, p)
        })
    }

    /// The pixels, three bytes each, row by row from the top left.
    pub fn as_raw(&self) -> &[u8] {
        &self.data
    }

    /// The pixels to write in place, three bytes each, row by row from the top left.
    pub fn as_raw_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }

    /// The pixels, three bytes each, row by row from the top left.
    pub fn into_raw(self) -> Vec<u8> {
        self.data
    }

    /// Pastes `top` with its top-left corner at (`x`, `y`) of this picture (either may be
    /// negative); what falls outside this picture is left out.
    pub fn replace(&mut self, top: &RgbImage, x: i64, y: i64) {
        // The columns and rows of `top` that land inside: top's column c lands at x + c.
        let span = |offset: i64, inner: u32, outer: u32| {
            let first = offset.saturating_neg().clamp(0, i64::from(inner));
            let end = i64::from(outer)
                .saturating_sub(offset)
                .clamp(first, i64::from(inner));
            (first, end)
        };
        let (c0, c1) = span(x, top.width, self.width);
        let (r0, r1) = span(y, top.height, self.height);
        let bytes = (c1 - c0) as usize * 3;
        if bytes == 0 {
            return;
        }
        for r in r0..r1 {
            // Inside both pictures by the spans above, so non-negative and in range.
            let from = top.at(c0 as u32, r as u32);
            let to = self.at((x + c0) as u32, (y + r) as u32);
            self.data[to..to + bytes].copy_from_slice(&top.data[from..from + bytes]);
        }
    }

    /// The picture turned a quarter anticlockwise (270° clockwise): `height × width`, its top row
    /// this picture's right column, read top to bottom as that column bottom to top.
    pub fn rotate270(&self) -> RgbImage {
        let mut turned = RgbImage::new(self.height, self.width);
        for (x, y, p) in self.enumerate_pixels() {
            turned.put_pixel(y, self.width - 1 - x, p);
        }
        turned
    }

    /// The picture as the bytes of a PNG file: 8-bit RGB, fast deflate, an adaptive filter per
    /// row.
    ///
    /// # Errors
    ///
    /// The encoder's, for a picture PNG cannot hold (a side of 0 pixels).
    pub fn to_png(&self) -> Result<Vec<u8>, png::EncodingError> {
        encode_png(self.width, self.height, png::ColorType::Rgb, &self.data)
    }
}

/// The bytes of an 8-bit RGBA PNG file of `width × height` pixels from `rgba` (four bytes a
/// pixel, red, green, blue, opacity; rows from the top), with the settings of
/// [`RgbImage::to_png`].
///
/// # Errors
///
/// The encoder's, for a picture PNG cannot hold or `rgba` of the wrong length.
pub fn rgba_png(width: u32, height: u32, rgba: &[u8]) -> Result<Vec<u8>, png::EncodingError> {
    encode_png(width, height, png::ColorType::Rgba, rgba)
}

/// Encodes 8-bit pixels of `colour` type as PNG: fast deflate (`fdeflate`) and the adaptive
/// filter (the best of the five filters for each row).
fn encode_png(
    width: u32,
    height: u32,
    colour: png::ColorType,
    data: &[u8],
) -> Result<Vec<u8>, png::EncodingError> {
    let mut encoded = Vec::new();
    let mut encoder = png::Encoder::new(&mut encoded, width, height);
    encoder.set_color(colour);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    // After the compression, which would choose a filter of its own.
    encoder.set_filter(png::Filter::Adaptive);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(data)?;
    writer.finish()?;
    Ok(encoded)
}

/// Why a GIF frame could not be added.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GifError {
    /// A frame has a side GIF cannot hold.
    #[error("a GIF frame of {width} × {height} px is too large (at most 65535 px a side)")]
    TooLarge {
        /// Width of the frame, pixels.
        width: u32,
        /// Height of the frame, pixels.
        height: u32,
    },
    /// A frame's size differs from the first frame's.
    #[error(
        "a GIF frame of {width} × {height} px in an animation of {first_width} × {first_height} px"
    )]
    FrameSize {
        /// Width of the frame, pixels.
        width: u32,
        /// Height of the frame, pixels.
        height: u32,
        /// Width of the first frame, pixels.
        first_width: u16,
        /// Height of the first frame, pixels.
        first_height: u16,
    },
    /// The GIF encoder failed.
    #[error("GIF encoder: {0}")]
    Encoder(#[from] gif::EncodingError),
}

/// An animated GIF that loops for ever, built in memory frame by frame: every frame the size of
/// the first, with its own palette and delay.
///
/// ```
/// use output::raster::{GifAnimation, Rgb, RgbImage};
///
/// let mut gif = GifAnimation::new(30);
/// gif.push(&RgbImage::from_pixel(4, 2, Rgb([0, 0, 0])), 100)?;
/// gif.push(&RgbImage::from_pixel(4, 2, Rgb([255, 255, 255])), 100)?;
/// assert!(gif.finish()?.starts_with(b"GIF89a"));
/// # Ok::<(), output::raster::GifError>(())
/// ```
pub struct GifAnimation {
    speed: i32,
    /// The encoder, from the first frame on.
    encoder: Option<gif::Encoder<Vec<u8>>>,
    /// The first frame's size, pixels.
    size: (u16, u16),
}

impl std::fmt::Debug for GifAnimation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GifAnimation")
            .field("speed", &self.speed)
            .field("started", &self.encoder.is_some())
            .field("size", &self.size)
            .finish()
    }
}

impl GifAnimation {
    /// An animation with no frame yet. `speed` (clamped to 1–30) is NeuQuant's for frames of
    /// more than 256 colours: 1 the best palette, 30 the fastest; frames of at most 256 colours
    /// keep their exact colours at any speed.
    pub fn new(speed: i32) -> Self {
        Self {
            speed: speed.clamp(1, 30),
            encoder: None,
            size: (0, 0),
        }
    }

    /// Adds `frame`, shown for `delay_ms` milliseconds (GIF counts hundredths: rounded down, at
    /// most 655.35 s).
    ///
    /// # Errors
    ///
    /// [`GifError::TooLarge`] for a side above 65535 px, [`GifError::FrameSize`] for a frame
    /// of another size than the first; [`GifError::Encoder`] if the encoder fails.
    pub fn push(&mut self, frame: &RgbImage, delay_ms: u32) -> Result<(), GifError> {
        let (width, height) = frame.dimensions();
        let (Ok(w), Ok(h)) = (u16::try_from(width), u16::try_from(height)) else {
            return Err(GifError::TooLarge { width, height });
        };
        let encoder = match &mut self.encoder {
            Some(encoder) => {
                let (first_width, first_height) = self.size;
                if (first_width, first_height) != (w, h) {
                    return Err(GifError::FrameSize {
                        width,
                        height,
                        first_width,
                        first_height,
                    });
                }
                encoder
            }
            None => {
                // No global palette: every frame carries its own.
                let mut encoder = gif::Encoder::new(Vec::new(), w, h, &[])?;
                encoder.set_repeat(gif::Repeat::Infinite)?;
                self.size = (w, h);
                self.encoder.insert(encoder)
            }
        };
        let mut gif_frame = gif::Frame::from_rgb_speed(w, h, frame.as_raw(), self.speed);
        gif_frame.delay = u16::try_from(delay_ms / 10).unwrap_or(u16::MAX);
        gif_frame.dispose = gif::DisposalMethod::Background;
        encoder.write_frame(&gif_frame)?;
        Ok(())
    }

    /// The GIF file's bytes (a GIF of no frame if none was pushed: a 0 × 0 picture).
    ///
    /// # Errors
    ///
    /// [`GifError::Encoder`] if the encoder fails.
    pub fn finish(self) -> Result<Vec<u8>, GifError> {
        let encoder = match self.encoder {
            Some(encoder) => encoder,
            None => gif::Encoder::new(Vec::new(), 0, 0, &[])?,
        };
        Ok(encoder.into_inner()?)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::testing::decode_png;

    const R: Rgb = Rgb([255, 0, 0]);
    const G: Rgb = Rgb([0, 255, 0]);
    const B: Rgb = Rgb([0, 0, 255]);
    const W: Rgb = Rgb([255, 255, 255]);
    const K: Rgb = Rgb([0, 0, 0]);

    /// A picture from rows of colours.
    fn picture(rows: &[&[Rgb]]) -> RgbImage {
        let data = rows
            .iter()
            .flat_map(|r| r.iter().flat_map(|p| p.0))
            .collect();
        RgbImage::from_raw(rows[0].len() as u32, rows.len() as u32, data).unwrap()
    }

    #[test]
    fn pixels_are_stored_row_by_row_from_the_top_left() {
        let mut image = RgbImage::new(3, 2);
        assert_eq!(image.as_raw(), [0; 18]);
        image.put_pixel(2, 0, R);
        image.put_pixel(0, 1, G);
        // Pixel (2, 0) at bytes 6..9, pixel (0, 1) at 9..12.
        assert_eq!(
            image.as_raw(),
            [0, 0, 0, 0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 0, 0, 0, 0]
        );
        assert_eq!(image.get_pixel(2, 0), R);
        assert_eq!(image.get_pixel(0, 1), G);
        assert_eq!(image.dimensions(), (3, 2));
        let all: Vec<(u32, u32, Rgb)> = image.enumerate_pixels().collect();
        assert_eq!(all.len(), 6);
        assert_eq!(all[2], (2, 0, R));
        assert_eq!(all[3], (0, 1, G));
        assert_eq!(all[5], (2, 1, K));
        image.as_raw_mut()[0] = 9;
        assert_eq!(image.clone().into_raw()[0], 9);
        assert_eq!(image.pixels().next(), Some(Rgb([9, 0, 0])));
        assert_eq!(
            RgbImage::from_pixel(1, 2, B).into_raw(),
            [0, 0, 255, 0, 0, 255]
        );
    }

    #[test]
    fn raw_data_of_the_wrong_length_is_refused() {
        assert!(RgbImage::from_raw(2, 2, vec![0; 11]).is_none());
        assert!(RgbImage::from_raw(2, 2, vec![0; 13]).is_none());
        assert!(RgbImage::from_raw(u32::MAX, u32::MAX, Vec::new()).is_none());
        assert_eq!(
            RgbImage::from_raw(0, 5, Vec::new())
                .unwrap()
                .pixels()
                .count(),
            0
        );
    }

    #[test]
    #[should_panic(expected = "outside a picture of 2 × 1 px")]
    fn a_pixel_outside_panics_with_its_coordinates() {
        let _ = RgbImage::new(2, 1).get_pixel(2, 0);
    }

    #[test]
    fn replace_pastes_and_clips_on_every_side() {
        let top = picture(&[&[R, G], &[B, K]]);
        // Inside: at (1, 1) of a 4 × 3 white picture.
        let mut image = RgbImage::from_pixel(4, 3, W);
        image.replace(&top, 1, 1);
        assert_eq!(
            image,
            picture(&[&[W, W, W, W], &[W, R, G, W], &[W, B, K, W]])
        );
        // Over the top-left corner: only K lands, at (0, 0).
        let mut image = RgbImage::from_pixel(3, 2, W);
        image.replace(&top, -1, -1);
        assert_eq!(image, picture(&[&[K, W, W], &[W, W, W]]));
        // Over the bottom-right corner: only R lands, at (2, 1).
        let mut image = RgbImage::from_pixel(3, 2, W);
        image.replace(&top, 2, 1);
        assert_eq!(image, picture(&[&[W, W, W], &[W, W, R]]));
        // Wholly outside, on each side: nothing changes.
        for (x, y) in [(-2, 0), (3, 0), (0, -2), (0, 2), (i64::MIN, i64::MAX)] {
            let mut image = RgbImage::from_pixel(3, 2, W);
            image.replace(&top, x, y);
            assert_eq!(image, RgbImage::from_pixel(3, 2, W), "at ({x}, {y})");
        }
    }

    #[test]
    fn rotate270_turns_a_quarter_anticlockwise() {
        // R G B      B K
        // K W R  ->  G W
        //            R K
        let image = picture(&[&[R, G, B], &[K, W, R]]);
        let turned = image.rotate270();
        assert_eq!(turned, picture(&[&[B, R], &[G, W], &[R, K]]));
        // Four quarter turns are none.
        let back = turned.rotate270().rotate270().rotate270();
        assert_eq!(back, image);
    }

    #[test]
    fn png_keeps_every_pixel() {
        let image = picture(&[&[R, G, B], &[K, W, Rgb([1, 2, 3])]]);
        let (colour, w, h, data) = decode_png(&image.to_png().unwrap());
        assert_eq!((colour, w, h), (png::ColorType::Rgb, 3, 2));
        assert_eq!(data, image.as_raw());
        let rgba = [1, 2, 3, 0, 4, 5, 6, 160];
        let (colour, w, h, data) = decode_png(&rgba_png(2, 1, &rgba).unwrap());
        assert_eq!((colour, w, h), (png::ColorType::Rgba, 2, 1));
        assert_eq!(data, rgba);
        // A side of 0, or too few bytes: the encoder's error, no panic.
        assert!(RgbImage::new(0, 3).to_png().is_err());
        assert!(rgba_png(2, 1, &rgba[..4]).is_err());
    }

    /// Each frame of a decoded GIF: its delay (hundredths of a second) and RGBA pixels.
    type Frames = Vec<(u16, Vec<u8>)>;

    /// Decodes a GIF: (screen size, loops, frames).
    fn decode_gif(bytes: &[u8]) -> ((u16, u16), gif::Repeat, Frames) {
        let mut options = gif::DecodeOptions::new();
        options.set_color_output(gif::ColorOutput::RGBA);
        let mut decoder = options.read_info(std::io::Cursor::new(bytes)).unwrap();
        let mut frames = Vec::new();
        while let Some(frame) = decoder.read_next_frame().unwrap() {
            frames.push((frame.delay, frame.buffer.to_vec()));
        }
        let screen = (decoder.width(), decoder.height());
        (screen, decoder.repeat(), frames)
    }

    #[test]
    fn the_gif_loops_and_keeps_each_frames_colours_and_delay() {
        let first = picture(&[&[R, G, B], &[K, W, R]]);
        let second = picture(&[&[W, W, W], &[W, W, K]]);
        let mut gif = GifAnimation::new(30);
        gif.push(&first, 100).unwrap();
        // 1,234 ms: 123 hundredths.
        gif.push(&second, 1_234).unwrap();
        let (screen, repeat, frames) = decode_gif(&gif.finish().unwrap());
        assert_eq!(screen, (3, 2));
        assert_eq!(repeat, gif::Repeat::Infinite);
        assert_eq!(frames.len(), 2);
        let rgba = |image: &RgbImage| -> Vec<u8> {
            image
                .pixels()
                .flat_map(|p| [p.0[0], p.0[1], p.0[2], 255])
                .collect()
        };
        assert_eq!(frames[0], (10, rgba(&first)));
        assert_eq!(frames[1], (123, rgba(&second)));
    }

    #[test]
    fn a_frame_of_many_colours_is_quantised_to_a_palette_close_to_it() {
        // 128 × 128 colours: NeuQuant's palette of at most 256, each pixel near its colour.
        let data: Vec<u8> = (0..128u32 * 128)
            .flat_map(|k| [(k % 128 * 2) as u8, (k / 128 * 2) as u8, 128])
            .collect();
        let image = RgbImage::from_raw(128, 128, data).unwrap();
        let mut gif = GifAnimation::new(30);
        gif.push(&image, 50).unwrap();
        let (_, _, frames) = decode_gif(&gif.finish().unwrap());
        let decoded = &frames[0].1;
        let colours: std::collections::HashSet<&[u8]> = decoded.chunks_exact(4).collect();
        assert!(
            colours.len() <= 256 && colours.len() > 100,
            "{}",
            colours.len()
        );
        let errors: Vec<u8> = image
            .as_raw()
            .chunks_exact(3)
            .zip(decoded.chunks_exact(4))
            .flat_map(|(a, b)| (0..3).map(move |c| a[c].abs_diff(b[c])))
            .collect();
        let mean = errors.iter().map(|&e| f64::from(e)).sum::<f64>() / errors.len() as f64;
        let worst = errors.iter().max().copied().unwrap_or(0);
        // Measured: mean 5.5, worst 48 (NeuQuant at its fastest; the gif crate's).
        assert!(mean < 8.0 && worst <= 64, "mean {mean}, worst {worst}");
    }

    #[test]
    fn frames_of_another_size_or_too_large_are_refused() {
        let mut gif = GifAnimation::new(30);
        let error = gif.push(&RgbImage::new(65_536, 1), 10).unwrap_err();
        assert!(
            matches!(error, GifError::TooLarge { width: 65_536, .. }),
            "{error}"
        );
        gif.push(&RgbImage::new(2, 2), 10).unwrap();
        let error = gif.push(&RgbImage::new(3, 2), 10).unwrap_err();
        assert_eq!(
            error.to_string(),
            "a GIF frame of 3 × 2 px in an animation of 2 × 2 px"
        );
        // The animation is still whole: one frame.
        let (_, _, frames) = decode_gif(&gif.finish().unwrap());
        assert_eq!(frames.len(), 1);
    }
}
