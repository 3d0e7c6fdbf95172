//! Text on pictures, in a real font: DejaVu Sans (`assets/DejaVuSans.ttf`, Bitstream Vera
//! licence with DejaVu's changes in the public domain, `assets/DejaVuSans-LICENSE.txt`),
//! embedded in the binary and rasterised with `ab_glyph`, anti-aliased by blending each pixel's
//! coverage over what is already drawn.
//!
//! `plotters` 0.3.7 was considered and not taken: its only font backend on crates.io
//! (`ttf`) goes through `font-kit` and the system's fontconfig/FreeType, so a picture would
//! depend on the machine's fonts; its `ab_glyph` backend is not released.

use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;
use std::sync::LazyLock;

use crate::raster::{Rgb, RgbImage};
use ab_glyph::{Font, FontRef, GlyphId, PxScale, ScaleFont, point};

/// The embedded font file.
const FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// The parsed font; `None` only if the embedded file were not a font (a test rules it out), in
/// which case text is left out rather than the picture failing.
static FONT: LazyLock<Option<FontRef<'static>>> =
    LazyLock::new(|| FontRef::try_from_slice(FONT_BYTES).ok());

/// Width in pixels of `text` at a font size of `size_px` (the em height), with kerning.
pub fn text_width(text: &str, size_px: f32) -> u32 {
    let Some(font) = FONT.as_ref() else {
        return 0;
    };
    let scaled = font.as_scaled(PxScale::from(size_px));
    let mut width = 0.0f32;
    let mut previous = None;
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = previous {
            width += scaled.kern(p, id);
        }
        width += scaled.h_advance(id);
        previous = Some(id);
    }
    width.ceil().max(0.0) as u32
}

/// Height in pixels of a line of text at `size_px`: ascent minus descent.
pub fn line_height(size_px: f32) -> u32 {
    FONT.as_ref().map_or(0, |font| {
        let scaled = font.as_scaled(PxScale::from(size_px));
        (scaled.ascent() - scaled.descent()).ceil().max(0.0) as u32
    })
}

/// A glyph rasterised once at a size, its pen at the origin of integer pixel (0, 0) on the
/// baseline: coverage of the box whose top-left pixel is (`left`, `top`).
struct Raster {
    left: i64,
    top: i64,
    width: usize,
    coverage: Vec<f32>,
}

/// Glyphs already rasterised, by glyph and size: figures repeat the same few labels on every
/// frame of a drive, and rasterising outlines was most of the cost of drawing one.
type GlyphCache = HashMap<(u16, u32), Rc<Raster>>;

thread_local! {
    static GLYPHS: RefCell<GlyphCache> = RefCell::new(HashMap::new());
}

/// Bound on [`GLYPHS`] per thread; past it the cache starts again.
const MAX_CACHED_GLYPHS: usize = 4096;

/// The raster of glyph `id` at `scale`, from the cache or made now.
fn raster(font: &FontRef<'static>, id: GlyphId, scale: PxScale) -> Rc<Raster> {
    let key = (id.0, scale.y.to_bits());
    GLYPHS.with(|cache| {
        let mut cache = cache.borrow_mut();
        if let Some(r) = cache.get(&key) {
            return Rc::clone(r);
        }
        let glyph = id.with_scale_and_position(scale, point(0.0, 0.0));
        let made = match font.outline_glyph(glyph) {
            Some(outline) => {
                let bounds = outline.px_bounds();
                let width = bounds.width().max(0.0) as usize;
                let height = bounds.height().max(0.0) as usize;
                let mut coverage = vec![0.0f32; width * height];
                outline.draw(|gx, gy, c| {
                    if let Some(v) = coverage.get_mut(gy as usize * width + gx as usize) {
                        *v = c;
                    }
                });
                Raster {
                    left: bounds.min.x as i64,
                    top: bounds.min.y as i64,
                    width,
                    coverage,
                }
            }
            // A space: nothing to draw.
            None => Raster {
                left: 0,
                top: 0,
                width: 0,
                coverage: Vec::new(),
            },
        };
        if cache.len() >= MAX_CACHED_GLYPHS {
            cache.clear();
        }
        let made = Rc::new(made);
        cache.insert(key, Rc::clone(&made));
        made
    })
}

/// Draws `text` with the top of its line box at `y` and its pen starting at `x`, blending
/// `colour` by each pixel's coverage. Glyphs sit on whole pixels (the pen is rounded), so each
/// is rasterised once per size. Pixels outside the image are skipped.
pub fn draw_text(image: &mut RgbImage, x: i64, y: i64, text: &str, size_px: f32, colour: Rgb) {
    let Some(font) = FONT.as_ref() else {
        return;
    };
    let scale = PxScale::from(size_px);
    let scaled = font.as_scaled(scale);
    let baseline = y + scaled.ascent().round() as i64;
    let mut pen = x as f32;
    let mut previous = None;
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = previous {
            pen += scaled.kern(p, id);
        }
        let r = raster(font, id, scale);
        let (left, top) = (pen.round() as i64 + r.left, baseline + r.top);
        for (k, &coverage) in r.coverage.iter().enumerate() {
            let (gx, gy) = ((k % r.width.max(1)) as i64, (k / r.width.max(1)) as i64);
            blend(image, left + gx, top + gy, colour, coverage);
        }
        pen += scaled.h_advance(id);
        previous = Some(id);
    }
}

/// Draws `text` centred horizontally on `centre_x`.
pub fn draw_text_centred(
    image: &mut RgbImage,
    centre_x: i64,
    y: i64,
    text: &str,
    size_px: f32,
    colour: Rgb,
) {
    let half = i64::from(text_width(text, size_px) / 2);
    draw_text(image, centre_x - half, y, text, size_px, colour);
}

/// Draws `text` turned a quarter anticlockwise (reading bottom to top, as a y-axis title),
/// centred vertically on `centre_y` with the line box's top at column `x`.
pub fn draw_text_vertical(
    image: &mut RgbImage,
    x: i64,
    centre_y: i64,
    text: &str,
    size_px: f32,
    colour: Rgb,
) {
    let (w, h) = (text_width(text, size_px), line_height(size_px));
    if w == 0 || h == 0 {
        return;
    }
    // Draw on a white strip, turn it, and keep the darkness of each pixel as coverage so the
    // text blends over whatever is below it.
    let mut strip = RgbImage::from_pixel(w, h, Rgb([255, 255, 255]));
    draw_text(&mut strip, 0, 0, text, size_px, Rgb([0, 0, 0]));
    let turned = strip.rotate270();
    let top = centre_y - i64::from(w / 2);
    for (sx, sy, p) in turned.enumerate_pixels() {
        let coverage = 1.0 - f32::from(p.0[0]) / 255.0;
        blend(
            image,
            x + i64::from(sx),
            top + i64::from(sy),
            colour,
            coverage,
        );
    }
}

/// Mixes `colour` into the pixel (`x`, `y`) in proportion `coverage`, if it is in the image.
fn blend(image: &mut RgbImage, x: i64, y: i64, colour: Rgb, coverage: f32) {
    if x < 0 || y < 0 || x >= i64::from(image.width()) || y >= i64::from(image.height()) {
        return;
    }
    let a = coverage.clamp(0.0, 1.0);
    if a <= 0.0 {
        return;
    }
    let (x, y) = (x as u32, y as u32);
    let mut pixel = image.get_pixel(x, y);
    for (dst, src) in pixel.0.iter_mut().zip(colour.0) {
        *dst = (f32::from(*dst) * (1.0 - a) + f32::from(src) * a).round() as u8;
    }
    image.put_pixel(x, y, pixel);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_font_parses_and_measures() {
        assert!(FONT.is_some());
        // Longer text is wider; a bigger size is wider and taller.
        assert!(text_width("IoU", 16.0) > text_width("I", 16.0));
        assert!(text_width("truth", 24.0) > text_width("truth", 12.0));
        assert!(line_height(24.0) > line_height(12.0));
        assert_eq!(text_width("", 16.0), 0);
    }

    #[test]
    fn text_inks_inside_its_box_only() {
        let mut image = RgbImage::from_pixel(120, 40, Rgb([255, 255, 255]));
        draw_text(&mut image, 10, 5, "Moving", 20.0, Rgb([0, 0, 0]));
        let w = text_width("Moving", 20.0);
        let h = line_height(20.0);
        let mut dark = 0;
        for (x, y, p) in image.enumerate_pixels() {
            if p.0[0] < 128 {
                dark += 1;
                assert!((10..=10 + w + 1).contains(&x), "x {x}");
                assert!((5..=5 + h).contains(&y), "y {y}");
            }
        }
        assert!(dark > 50, "{dark} dark pixels");
    }

    #[test]
    fn vertical_text_is_taller_than_wide_and_clipping_is_safe() {
        let mut image = RgbImage::from_pixel(40, 120, Rgb([255, 255, 255]));
        draw_text_vertical(&mut image, 5, 60, "truth", 20.0, Rgb([0, 0, 0]));
        let dark: Vec<(u32, u32)> = image
            .enumerate_pixels()
            .filter(|(_, _, p)| p.0[0] < 128)
            .map(|(x, y, _)| (x, y))
            .collect();
        let span = |f: fn(&(u32, u32)) -> u32| {
            dark.iter().map(f).max().unwrap_or(0) - dark.iter().map(f).min().unwrap_or(0)
        };
        assert!(span(|p| p.1) > 2 * span(|p| p.0));
        // Off the image on every side: nothing drawn, no panic.
        let mut small = RgbImage::from_pixel(4, 4, Rgb([255, 255, 255]));
        draw_text(&mut small, -50, -50, "É%~", 30.0, Rgb([0, 0, 0]));
        draw_text(&mut small, 100, 100, "x", 30.0, Rgb([0, 0, 0]));
        draw_text_vertical(&mut small, -100, -100, "x", 30.0, Rgb([0, 0, 0]));
    }
}
