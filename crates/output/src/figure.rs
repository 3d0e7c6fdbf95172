//! Figures a person reads: one or more north-up cell pictures side by side, enlarged, with the
//! map's outlines and the ego's path drawn over them, a title above each, and around them a
//! legend naming the classes, a scale bar and a north arrow.
//!
//! Enlargement is nearest-neighbour by a whole factor, [`readable_scale`] by default: the
//! smallest one that makes a panel at least [`READABLE_SIDE_PX`] pixels on its long side, so a
//! 320 × 320 window of 0.5 m cells becomes 960 × 960 pixels, 6 pixels a metre. A cell stays a
//! square of `scale × scale` identical pixels, so a figure can still be read cell by cell.
//!
//! Over each panel: building and road outlines where the GISGrid's context changes between two
//! cells (a building or road cell beside one that is neither, or a building beside a road),
//! one white pixel wide along the shared cell edge; the ego's path as a reddish-purple line with
//! a black casing, a dot at its last pose.

use crate::raster::{Rgb, RgbImage};
use evigrid::{GisGrid, Label, Window};
use geodata::MapContext;

use crate::error::{MAX_FIGURE_PIXELS, OutputError, check_len};
use crate::text::{draw_text, draw_text_centred, line_height, text_width};
use crate::views::ClassColours;

/// A panel's long side is enlarged to at least this many pixels by [`readable_scale`].
pub const READABLE_SIDE_PX: u32 = 800;
/// Colour of the map outlines.
pub const OUTLINE: Rgb = Rgb([255, 255, 255]);
/// Colour of the ego's path (Okabe–Ito reddish purple), drawn over a black casing.
pub const PATH: Rgb = Rgb([204, 121, 167]);
/// Background and ink of the frame around the panels.
const PAPER: Rgb = Rgb([255, 255, 255]);
const INK: Rgb = Rgb([0, 0, 0]);
/// Outer margin and gap between panels, pixels.
const MARGIN: u32 = 16;

/// The smallest whole enlargement that makes the window at least [`READABLE_SIDE_PX`] pixels on
/// its long side (1 for a window already that large).
pub fn readable_scale(window: &Window) -> u32 {
    let long = window.width().max(window.height()).max(1) as u32;
    READABLE_SIDE_PX.div_ceil(long).max(1)
}

/// What is drawn over every panel of a figure.
#[derive(Clone, Copy, Debug, Default)]
pub struct Overlay<'a> {
    /// The map context per cell (storage order), for the building and road outlines; `None`
    /// draws none (a run without a map).
    pub gis: Option<&'a GisGrid>,
    /// The ego's positions so far, oldest first, world metres (x east, y north).
    pub path: &'a [[f64; 2]],
    /// Estimated velocities to draw as arrows: `(position, velocity)`, world metres and metres
    /// per second; each arrow shows one second of travel.
    pub velocities: &'a [([f64; 2], [f64; 2])],
}

/// The legend of a figure: class colours and what they mean.
#[derive(Clone, Debug)]
pub struct Legend {
    /// Swatches: colour and name, top to bottom.
    pub entries: Vec<([u8; 3], String)>,
    /// A line under the swatches saying how to read the colours (may be empty).
    pub note: String,
}

impl Legend {
    /// The decided classes of `colours`: unknown, F, I, U, S, M, and O when `with_occupied`
    /// (pictures of the two-class baselines).
    pub fn classes(colours: &ClassColours, with_occupied: bool, note: &str) -> Self {
        let mut labels = vec![
            Label::F,
            Label::I,
            Label::U,
            Label::S,
            Label::M,
            Label::Unknown,
        ];
        if with_occupied {
            labels.push(Label::O);
        }
        Self {
            entries: labels
                .into_iter()
                .map(|l| (colours.of(l), class_name(l).to_owned()))
                .collect(),
            note: note.to_owned(),
        }
    }
}

/// The mixtures the pignistic view's key shows: the classes mixed, in equal parts, and what
/// such a colour means.
pub const PIGNISTIC_MIXES: [(&[Label], &str); 3] = [
    (&[Label::F, Label::M], "F + M half each: free or moving"),
    (&[Label::U, Label::S], "U + S half each: static, which?"),
    (
        &[Label::F, Label::I, Label::U, Label::S, Label::M],
        "all five equal: no evidence",
    ),
];

/// The colour the pignistic view gives a cell whose betP is spread equally over `labels`: the
/// mean of their colours, rounded as `pignistic_image` rounds.
pub fn mixed_colour(colours: &ClassColours, labels: &[Label]) -> [u8; 3] {
    let mut rgb = [0.0f32; 3];
    for &label in labels {
        for (sum, c) in rgb.iter_mut().zip(colours.of(label)) {
            *sum += f32::from(c) / labels.len().max(1) as f32;
        }
    }
    rgb.map(|v| v.round().clamp(0.0, 255.0) as u8)
}

impl Legend {
    /// The pignistic view's legend: the classes' pure colours, then a key to the mixed ones
    /// ([`PIGNISTIC_MIXES`]), under `note`.
    pub fn pignistic(colours: &ClassColours, note: &str) -> Self {
        let mut legend = Self::classes(colours, false, note);
        for (labels, name) in PIGNISTIC_MIXES {
            legend
                .entries
                .push((mixed_colour(colours, labels), name.to_owned()));
        }
        legend
    }
}

/// A label's name for people: its letter and what it stands for.
pub fn class_name(label: Label) -> &'static str {
    match label {
        Label::Unknown => "unknown",
        Label::F => "F  free",
        Label::I => "I  mapped infrastructure",
        Label::U => "U  unmapped infrastructure",
        Label::S => "S  stopped object",
        Label::M => "M  moving object",
        Label::O => "O  occupied, class unresolved",
        Label::Edge => "edge (truth only)",
    }
}

/// Font sizes, pixels.
const TITLE_PX: f32 = 22.0;
const LABEL_PX: f32 = 16.0;

/// The figure of `panels` (title, north-up one-pixel-per-cell picture of `window`, as the
/// views make), each enlarged `scale` times, side by side, with `overlay` drawn over each and
/// `legend`, a scale bar and a north arrow around them.
///
/// # Errors
///
/// [`OutputError::Size`] if a panel is not `window`-sized, or the overlay's GISGrid does not have
/// one cell per window cell.
pub fn figure(
    window: &Window,
    panels: &[(&str, &RgbImage)],
    overlay: &Overlay<'_>,
    legend: &Legend,
    scale: u32,
) -> Result<RgbImage, OutputError> {
    let scale = scale.max(1);
    check_panels(window, panels, overlay)?;
    let layout = FigureLayout::new(window, panels.len(), legend, scale)?;
    let mut canvas = RgbImage::from_pixel(layout.width, layout.height, PAPER);
    draw_panels(&mut canvas, window, panels, overlay, &layout);
    draw_legend(&mut canvas, legend, overlay, &layout);
    draw_scale_bar(&mut canvas, window, &layout);
    Ok(canvas)
}

/// Checks that every panel, and the overlay's GISGrid, has one cell per cell of `window`.
fn check_panels(
    window: &Window,
    panels: &[(&str, &RgbImage)],
    overlay: &Overlay<'_>,
) -> Result<(), OutputError> {
    let (w, h) = (window.width() as u32, window.height() as u32);
    for (_, panel) in panels {
        if panel.dimensions() != (w, h) {
            return Err(OutputError::Size {
                what: "panel",
                len: (panel.width() * panel.height()) as usize,
                expected: window.len(),
            });
        }
    }
    if let Some(gis) = overlay.gis {
        check_len("GISGrid", gis.len(), window)?;
    }
    Ok(())
}

/// Where the parts of a figure go, pixels: the panels in a row under their titles, the legend
/// to their right, the scale bar under them.
struct FigureLayout {
    /// The enlargement of a cell.
    scale: u32,
    /// A panel's width and height.
    panel_px: (u32, u32),
    /// The panels' top edge (under the titles).
    top: u32,
    /// The legend's left edge.
    legend_x: u32,
    /// A legend line's height, also a swatch's side.
    label_h: u32,
    /// The whole figure's width and height.
    width: u32,
    height: u32,
}

impl FigureLayout {
    /// The layout of `panel_count` panels of `window` enlarged `scale` times, beside `legend`.
    ///
    /// # Errors
    ///
    /// [`OutputError::FigureTooLarge`] if the panels hold more than [`MAX_FIGURE_PIXELS`].
    fn new(
        window: &Window,
        panel_count: usize,
        legend: &Legend,
        scale: u32,
    ) -> Result<Self, OutputError> {
        let (w, h) = (window.width() as u32, window.height() as u32);
        // A panel's size in u64 first: a large window times a large scale must be an error,
        // not an overflow.
        let (pw64, ph64) = (
            u64::from(w) * u64::from(scale),
            u64::from(h) * u64::from(scale),
        );
        let too_large = OutputError::FigureTooLarge {
            width: pw64 * panel_count.max(1) as u64,
            height: ph64,
        };
        if (pw64 * panel_count.max(1) as u64).saturating_mul(ph64) > MAX_FIGURE_PIXELS {
            return Err(too_large);
        }
        let (pw, ph) = (pw64 as u32, ph64 as u32);
        let title_h = line_height(TITLE_PX) + 8;
        let label_h = line_height(LABEL_PX);
        let swatch = label_h;
        let legend_w = legend
            .entries
            .iter()
            .map(|(_, name)| swatch + 8 + text_width(name, LABEL_PX))
            .chain([text_width(&legend.note, LABEL_PX * 0.85)])
            .max()
            .unwrap_or(0)
            .max(120);
        let n = panel_count.max(1) as u32;
        let footer_h = label_h * 2 + 16;
        let legend_h = (legend.entries.len() as u32 + 6) * (label_h + 6) + 140;
        Ok(Self {
            scale,
            panel_px: (pw, ph),
            top: MARGIN + title_h,
            legend_x: MARGIN + n * (pw + MARGIN),
            label_h,
            width: MARGIN + n * (pw + MARGIN) + legend_w + MARGIN,
            height: MARGIN + title_h + ph.max(legend_h) + footer_h + MARGIN,
        })
    }
}

/// Each panel enlarged in its place, under its title, with the overlay drawn over it.
fn draw_panels(
    canvas: &mut RgbImage,
    window: &Window,
    panels: &[(&str, &RgbImage)],
    overlay: &Overlay<'_>,
    layout: &FigureLayout,
) {
    let (w, h) = (window.width() as u32, window.height() as u32);
    let (scale, top) = (layout.scale, layout.top);
    let context = overlay.gis.map(|g| context_north_up(window, g));
    for (k, (title, panel)) in panels.iter().enumerate() {
        let left = MARGIN + k as u32 * (layout.panel_px.0 + MARGIN);
        draw_text(
            canvas,
            i64::from(left),
            i64::from(MARGIN),
            title,
            TITLE_PX,
            INK,
        );
        enlarge_into(canvas, panel, (left, top), scale);
        if let Some(context) = &context {
            draw_outlines(canvas, (left, top), (w, h), scale, context);
        }
        draw_path(canvas, window, (left, top), scale, overlay.path);
        draw_velocities(canvas, window, (left, top), scale, overlay.velocities);
    }
}

/// The legend right of the panels: swatches, the overlay's lines, the note, then the north
/// arrow.
fn draw_legend(
    canvas: &mut RgbImage,
    legend: &Legend,
    overlay: &Overlay<'_>,
    layout: &FigureLayout,
) {
    let (lx, label_h) = (layout.legend_x, layout.label_h);
    let swatch = label_h;
    let mut y = layout.top;
    for (colour, name) in &legend.entries {
        fill(canvas, lx, y, swatch, swatch, INK);
        fill(canvas, lx + 1, y + 1, swatch - 2, swatch - 2, Rgb(*colour));
        legend_label(canvas, lx + swatch + 8, y, name);
        y += label_h + 6;
    }
    y += 6;
    if overlay.gis.is_some() {
        fill(canvas, lx, y, swatch, swatch, Rgb([90, 90, 90]));
        fill(canvas, lx + 2, y + swatch / 2, swatch - 4, 1, OUTLINE);
        let text = "map outline (buildings, roads)";
        legend_label(canvas, lx + swatch + 8, y, text);
        y += label_h + 6;
    }
    let mid = |y: u32| f64::from(y + swatch / 2);
    let (x0, x1) = (f64::from(lx + 2), f64::from(lx + swatch - 2));
    let all = [0, 0, i64::from(layout.width), i64::from(layout.height)];
    if !overlay.path.is_empty() {
        let mid = mid(y);
        stroke(canvas, [x0, mid], [x1, mid], 2, INK, all);
        stroke(canvas, [x0, mid], [x1, mid], 1, PATH, all);
        legend_label(canvas, lx + swatch + 8, y, "ego path");
        y += label_h + 6;
    }
    if !overlay.velocities.is_empty() {
        let mid = mid(y);
        stroke(canvas, [x0, mid], [x1, mid], 1, INK, all);
        stroke(canvas, [x1 - 4.0, mid - 4.0], [x1, mid], 1, INK, all);
        stroke(canvas, [x1 - 4.0, mid + 4.0], [x1, mid], 1, INK, all);
        legend_label(canvas, lx + swatch + 8, y, "velocity (1 s of travel)");
        y += label_h + 6;
    }
    if !legend.note.is_empty() {
        y += 4;
        draw_text(
            canvas,
            i64::from(lx),
            i64::from(y),
            &legend.note,
            LABEL_PX * 0.85,
            INK,
        );
        y += label_h + 6;
    }
    draw_north_arrow(canvas, lx + 30, y + 16);
}

/// The scale bar under the first panel: a round length near a fifth of the panel's width,
/// and what it and a cell measure.
fn draw_scale_bar(canvas: &mut RgbImage, window: &Window, layout: &FigureLayout) {
    let scale = layout.scale;
    let (pw, ph) = layout.panel_px;
    let metres_per_px = window.cell_size_m() / f64::from(scale);
    let bar_m = round_length(f64::from(pw) * metres_per_px / 5.0);
    let bar_px = (bar_m / metres_per_px).round() as u32;
    let by = layout.top + ph + 10;
    fill(canvas, MARGIN, by, bar_px, 4, INK);
    fill(canvas, MARGIN, by - 4, 2, 12, INK);
    fill(
        canvas,
        MARGIN + bar_px.saturating_sub(2),
        by - 4,
        2,
        12,
        INK,
    );
    let label = format!(
        "{} m   (1 cell = {} m = {scale} px)",
        format_metres(bar_m),
        format_metres(window.cell_size_m())
    );
    draw_text(
        canvas,
        i64::from(MARGIN),
        i64::from(by + 10),
        &label,
        LABEL_PX,
        INK,
    );
}

/// Nearest-neighbour enlargement of `panel` into `canvas` with its top-left corner at
/// (`left`, `top`): each row is widened once and copied `scale` times (the canvas is made to
/// hold it).
fn enlarge_into(canvas: &mut RgbImage, panel: &RgbImage, (left, top): (u32, u32), scale: u32) {
    let canvas_width = canvas.width() as usize;
    let mut wide = Vec::with_capacity(panel.width() as usize * scale as usize * 3);
    let buffer = canvas.as_raw_mut();
    let row_bytes = panel.width() as usize * 3;
    for (y, row) in panel.as_raw().chunks_exact(row_bytes.max(1)).enumerate() {
        wide.clear();
        for p in row.chunks_exact(3) {
            for _ in 0..scale {
                wide.extend_from_slice(p);
            }
        }
        for dy in 0..scale as usize {
            let start =
                ((top as usize + y * scale as usize + dy) * canvas_width + left as usize) * 3;
            if let Some(dst) = buffer.get_mut(start..start + wide.len()) {
                dst.copy_from_slice(&wide);
            }
        }
    }
}

/// 1, 2 or 5 times a power of ten, the largest not above `m` (at least 1 cm).
fn round_length(m: f64) -> f64 {
    let m = if m.is_finite() { m.max(0.01) } else { 1.0 };
    let decade = 10f64.powf(m.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|k| k * decade)
        .find(|&l| l <= m)
        .unwrap_or(decade)
}

/// A length in metres without a needless fraction ("50", "0.5").
fn format_metres(m: f64) -> String {
    if (m - m.round()).abs() < 1e-9 {
        format!("{}", m.round() as i64)
    } else {
        format!("{m}")
    }
}

/// The map context in image order (row 0 north), as outline classes: 0 neither, 1 road,
/// 2 building.
fn context_north_up(window: &Window, gis: &GisGrid) -> Vec<u8> {
    let (w, h) = (window.width(), window.height());
    let mut out = vec![0u8; w * h];
    let mut k = 0usize;
    for span in window.world_order_spans() {
        for idx in span {
            let (x, row_from_south) = (k % w, k / w);
            let class = match gis.context.get(idx) {
                Some(MapContext::Building) => 2,
                Some(MapContext::Road) => 1,
                _ => 0,
            };
            if let Some(cell) = out.get_mut((h - 1 - row_from_south) * w + x) {
                *cell = class;
            }
            k += 1;
        }
    }
    out
}

/// One-pixel lines along every cell edge where the outline class changes.
fn draw_outlines(
    canvas: &mut RgbImage,
    (left, top): (u32, u32),
    (w, h): (u32, u32),
    scale: u32,
    context: &[u8],
) {
    let at = |x: u32, y: u32| context[(y * w + x) as usize];
    for y in 0..h {
        for x in 0..w {
            let here = at(x, y);
            if x + 1 < w && here != at(x + 1, y) {
                // The first pixel column of the east cell.
                fill(
                    canvas,
                    left + (x + 1) * scale,
                    top + y * scale,
                    1,
                    scale,
                    OUTLINE,
                );
            }
            if y + 1 < h && here != at(x, y + 1) {
                fill(
                    canvas,
                    left + x * scale,
                    top + (y + 1) * scale,
                    scale,
                    1,
                    OUTLINE,
                );
            }
        }
    }
}

/// Where world metres fall on a panel's canvas pixels.
struct PanelPixels {
    cell_size_m: f64,
    first_col: f64,
    /// Row index of the panel's north edge, in cells.
    north_row: f64,
    left: f64,
    top: f64,
    scale: f64,
    width_px: f64,
    height_px: f64,
}

impl PanelPixels {
    fn new(window: &Window, (left, top): (u32, u32), scale: u32) -> Self {
        let scale = f64::from(scale);
        Self {
            cell_size_m: window.cell_size_m(),
            first_col: window.first_col() as f64,
            north_row: window.first_row() as f64 + window.height() as f64,
            left: f64::from(left),
            top: f64::from(top),
            scale,
            width_px: window.width() as f64 * scale,
            height_px: window.height() as f64 * scale,
        }
    }

    /// World `(x east, y north)` metres to canvas `(x, y)` pixels (north up).
    fn pixel(&self, p: [f64; 2]) -> [f64; 2] {
        [
            self.left + (p[0] / self.cell_size_m - self.first_col) * self.scale,
            self.top + (self.north_row - p[1] / self.cell_size_m) * self.scale,
        ]
    }

    /// The panel's pixels: `[x0, y0, x1, y1]`, ends excluded.
    fn rect(&self) -> [i64; 4] {
        [
            self.left as i64,
            self.top as i64,
            (self.left + self.width_px) as i64,
            (self.top + self.height_px) as i64,
        ]
    }
}

/// The ego's path over a panel, and a dot at its last pose.
fn draw_path(
    canvas: &mut RgbImage,
    window: &Window,
    (left, top): (u32, u32),
    scale: u32,
    path: &[[f64; 2]],
) {
    let panel = PanelPixels::new(window, (left, top), scale);
    let (to_px, rect) = (|p: &[f64; 2]| panel.pixel(*p), panel.rect());
    let inside = |q: [f64; 2]| {
        q[0] >= rect[0] as f64
            && q[1] >= rect[1] as f64
            && q[0] < rect[2] as f64
            && q[1] < rect[3] as f64
    };
    let points: Vec<[f64; 2]> = path
        .iter()
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .map(to_px)
        .collect();
    let clip = |canvas: &mut RgbImage, a: [f64; 2], b: [f64; 2], r: i64, c: Rgb| {
        if inside(a) || inside(b) {
            stroke(canvas, a, b, r, c, rect);
        }
    };
    for (radius, colour) in [(2, INK), (1, PATH)] {
        for pair in points.windows(2) {
            clip(canvas, pair[0], pair[1], radius, colour);
        }
    }
    if let Some(&last) = points.last()
        && inside(last)
    {
        clip(canvas, last, last, 5, INK);
        clip(canvas, last, last, 4, PATH);
    }
}

/// One legend entry's text, right of its symbol.
fn legend_label(canvas: &mut RgbImage, x: u32, y: u32, text: &str) {
    draw_text(canvas, i64::from(x), i64::from(y), text, LABEL_PX, INK);
}

/// Velocity arrows over a panel: from each position, one second of travel, with a head.
fn draw_velocities(
    canvas: &mut RgbImage,
    window: &Window,
    (left, top): (u32, u32),
    scale: u32,
    arrows: &[([f64; 2], [f64; 2])],
) {
    let panel = PanelPixels::new(window, (left, top), scale);
    let (to_px, rect) = (|p: [f64; 2]| panel.pixel(p), panel.rect());
    for &(p, v) in arrows {
        let finite = p.iter().chain(&v).all(|x| x.is_finite());
        // At most 100 m/s: a larger value is an estimate gone wrong, not worth a long line.
        if !finite || v[0].hypot(v[1]) > 100.0 {
            continue;
        }
        let (a, b) = (to_px(p), to_px([p[0] + v[0], p[1] + v[1]]));
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let length = dx.hypot(dy);
        if length < 1.0 {
            continue;
        }
        // The head: two strokes back from the tip at ±30°, 6 px long.
        let (ux, uy) = (dx / length, dy / length);
        let head = |turn: f64| {
            let (c, sn) = (turn.cos(), turn.sin());
            [
                b[0] - 6.0 * (ux * c - uy * sn),
                b[1] - 6.0 * (ux * sn + uy * c),
            ]
        };
        for (radius, colour) in [(2, PAPER), (1, INK)] {
            stroke(canvas, a, b, radius, colour, rect);
            stroke(canvas, head(0.5), b, radius, colour, rect);
            stroke(canvas, head(-0.5), b, radius, colour, rect);
        }
    }
}

/// A line of half-width `radius` pixels from `a` to `b`: discs stamped every half pixel, kept
/// inside `rect` (x0, y0, x1, y1; ends excluded).
fn stroke(
    canvas: &mut RgbImage,
    a: [f64; 2],
    b: [f64; 2],
    radius: i64,
    colour: Rgb,
    rect: [i64; 4],
) {
    let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    // A jump across the whole picture (a pose error) is drawn, but never more than 10⁵ steps.
    let steps = ((length * 2.0).ceil() as usize).clamp(1, 100_000);
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        let (cx, cy) = (
            (a[0] + t * (b[0] - a[0])).round() as i64,
            (a[1] + t * (b[1] - a[1])).round() as i64,
        );
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                let (x, y) = (cx + dx, cy + dy);
                let in_rect = x >= rect[0] && y >= rect[1] && x < rect[2] && y < rect[3];
                if dx * dx + dy * dy <= radius * radius && in_rect {
                    put(canvas, x, y, colour);
                }
            }
        }
    }
}

/// An arrow pointing up (north: images are north-up) with an N above it, centred on `cx`.
fn draw_north_arrow(canvas: &mut RgbImage, cx: u32, top: u32) {
    let size = LABEL_PX * 1.4;
    draw_text_centred(canvas, i64::from(cx), i64::from(top), "N", size, INK);
    let tip = top + line_height(size) + 2;
    let head = 14u32;
    for dy in 0..head {
        let half = dy / 2;
        fill(canvas, cx - half, tip + dy, 2 * half + 1, 1, INK);
    }
    fill(canvas, cx - 1, tip + head, 3, 26, INK);
}

/// Fills a rectangle, clipped to the canvas.
fn fill(canvas: &mut RgbImage, x: u32, y: u32, w: u32, h: u32, colour: Rgb) {
    let (x1, y1) = (
        x.saturating_add(w).min(canvas.width()),
        y.saturating_add(h).min(canvas.height()),
    );
    for py in y..y1 {
        for px in x..x1 {
            canvas.put_pixel(px, py, colour);
        }
    }
}

/// Sets one pixel if it is on the canvas.
fn put(canvas: &mut RgbImage, x: i64, y: i64, colour: Rgb) {
    if x >= 0 && y >= 0 && x < i64::from(canvas.width()) && y < i64::from(canvas.height()) {
        canvas.put_pixel(x as u32, y as u32, colour);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::views::decision_image;

    fn setup() -> (Window, Vec<Label>, GisGrid) {
        // 20 × 10 cells of 0.5 m from world cell (100, 50): x 50–60 m, y 25–30 m.
        let mut w = Window::new(20, 10, 0.5).unwrap();
        w.move_to(100, 50);
        let d = vec![Label::F; w.len()];
        let mut gis = GisGrid::new(20, 10);
        // A building on world columns 110..115, every row.
        for idx in 0..w.len() {
            let c = w.cell_of_storage(idx).unwrap();
            if (110..115).contains(&c.col) {
                gis.context[idx] = MapContext::Building;
            }
        }
        (w, d, gis)
    }

    #[test]
    fn scale_reaches_the_readable_size() {
        assert_eq!(readable_scale(&Window::new(320, 320, 0.5).unwrap()), 3);
        assert_eq!(readable_scale(&Window::new(800, 10, 0.5).unwrap()), 1);
        assert_eq!(readable_scale(&Window::new(801, 10, 0.5).unwrap()), 1);
        assert_eq!(readable_scale(&Window::new(799, 10, 0.5).unwrap()), 2);
        assert_eq!(round_length(64.0), 50.0);
        assert_eq!(round_length(19.9), 10.0);
        assert_eq!(round_length(0.3), 0.2);
        assert_eq!(format_metres(50.0), "50");
        assert_eq!(format_metres(0.5), "0.5");
    }

    #[test]
    fn panels_are_enlarged_cell_for_cell_with_outlines_and_path() {
        let (w, d, gis) = setup();
        let colours = ClassColours::OKABE_ITO;
        let cells = decision_image(&w, &d, &colours).unwrap();
        // The ego drove west to east along y = 27.6 m, through x = 51 … 59 m.
        let path = [[51.0, 27.6], [55.0, 27.6], [59.0, 27.6]];
        let overlay = Overlay {
            gis: Some(&gis),
            path: &path,
            velocities: &[],
        };
        let legend = Legend::classes(&colours, false, "");
        let scale = 8;
        let fig = figure(
            &w,
            &[("a", &cells), ("b", &cells)],
            &overlay,
            &legend,
            scale,
        )
        .unwrap();
        let top = MARGIN + line_height(TITLE_PX) + 8;
        let free = Rgb(colours.classes[0]);
        // Panel 0, cell (1, 1) from the north-west: a free square of 8 × 8 pixels.
        for dy in 0..scale {
            for dx in 0..scale {
                assert_eq!(fig.get_pixel(MARGIN + 8 + dx, top + 8 + dy), free);
            }
        }
        // The building starts at window column 10: a white line on that cell's first pixel
        // column, in both panels, away from the path.
        for panel in 0..2 {
            let left = MARGIN + panel * (20 * scale + MARGIN);
            assert_eq!(fig.get_pixel(left + 10 * scale, top + scale / 2), OUTLINE);
            assert_eq!(fig.get_pixel(left + 10 * scale + 1, top + scale / 2), free);
            // …and where it ends (column 15).
            assert_eq!(fig.get_pixel(left + 15 * scale, top + scale / 2), OUTLINE);
        }
        // The path at y = 27.6 m: row from north (30 − 27.6)/0.5 = 4.8 cells = 38.4 px; at
        // x = 53 m, column 6 cells = 48 px: path colour there, the casing 2 px off it.
        let (px, py) = (MARGIN + 48, top + 38);
        assert_eq!(fig.get_pixel(px, py), PATH);
        assert_eq!(fig.get_pixel(px, py + 2), INK);
        assert_eq!(fig.get_pixel(px, py + 6), free);
        // The legend swatches: F first, right of the second panel.
        let lx = MARGIN + 2 * (20 * scale + MARGIN);
        assert_eq!(fig.get_pixel(lx + 4, top + 4), free);
        // Wrong panel size, wrong GISGrid size: errors, not panics.
        let small = RgbImage::new(3, 3);
        assert!(figure(&w, &[("x", &small)], &overlay, &legend, 2).is_err());
        let bad_gis = GisGrid::new(3, 3);
        let bad = Overlay {
            gis: Some(&bad_gis),
            path: &path,
            velocities: &[],
        };
        assert!(figure(&w, &[("x", &cells)], &bad, &legend, 2).is_err());
        // An enlargement past any memory: an error, not an overflow or an abort.
        assert!(matches!(
            figure(&w, &[("x", &cells)], &overlay, &legend, u32::MAX),
            Err(OutputError::FigureTooLarge { .. })
        ));
    }

    #[test]
    fn hostile_paths_are_clipped() {
        let (w, d, _) = setup();
        let cells = decision_image(&w, &d, &ClassColours::OKABE_ITO).unwrap();
        let path = [[f64::NAN, 1.0], [-1e12, 1e12], [1e12, -1e12], [55.0, 27.0]];
        let overlay = Overlay {
            gis: None,
            path: &path,
            velocities: &[],
        };
        let legend = Legend::classes(&ClassColours::OKABE_ITO, true, "note");
        let fig = figure(&w, &[("x", &cells)], &overlay, &legend, 1).unwrap();
        assert!(fig.width() > 20 && fig.height() > 10);
    }

    #[test]
    fn a_velocity_is_an_arrow_of_one_second_of_travel() {
        let (w, d, _) = setup();
        let cells = decision_image(&w, &d, &ClassColours::OKABE_ITO).unwrap();
        // At (52.25, 27.25) m moving east at 4 m/s: to x = 56.25 m, eight cells at 0.5 m.
        // Hostile ones (non-finite, absurd speed) are skipped, not drawn.
        let arrows = [
            ([52.25, 27.25], [4.0, 0.0]),
            ([f64::NAN, 27.0], [1.0, 0.0]),
            ([55.0, 27.0], [1e9, 0.0]),
        ];
        let overlay = Overlay {
            gis: None,
            path: &[],
            velocities: &arrows,
        };
        let legend = Legend::classes(&ClassColours::OKABE_ITO, false, "");
        let scale = 4;
        let fig = figure(&w, &[("a", &cells)], &overlay, &legend, scale).unwrap();
        let top = MARGIN + line_height(TITLE_PX) + 8;
        // Row from the north: (30 − 27.25) / 0.5 = 5.5 cells; columns 4.5 … 12.5 cells.
        let y = top + (5.5 * 4.0) as u32;
        let x = |col: f64| MARGIN + (col * 4.0) as u32;
        for col in [5.5, 8.0, 11.5] {
            assert_eq!(fig.get_pixel(x(col), y), INK, "column {col}");
        }
        // Beyond the tip: the free colour again.
        assert_eq!(
            fig.get_pixel(x(14.5), y),
            Rgb(ClassColours::OKABE_ITO.classes[0])
        );
    }
}
