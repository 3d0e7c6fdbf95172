//! `evigrid map`: inspect, render and crop vector maps.
//!
//! ```text
//! evigrid map info FILE [--json]
//! evigrid map render FILE [--cell 0.5] --out map.png [--json]
//! evigrid map crop FILE --bbox LAT1,LON1,LAT2,LON2 --out small.geojson [--json]
//! ```
//!
//! FILE is OSM PBF, OSM XML (optionally gzipped) or GeoJSON, recognised from its content. A file
//! that cannot be read as a map exits with status 2 and one line naming the file and the problem.
//! All the work is the `geodata` crate's.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use geodata::{ContextRaster, LoadOptions, LoadedMap, MapContext, load_map};
use serde::Serialize;

use crate::exit::BadInput;

/// Subcommands of `evigrid map`.
#[derive(Debug, Subcommand)]
pub enum MapCommand {
    /// Extent (lat/lon and metres), counts of buildings, road pieces, parking areas and of the
    /// items skipped, by reason.
    Info(InfoArgs),
    /// Rasterise the whole map into its contexts (building, road, other) as a PNG with a scale bar.
    Render(RenderArgs),
    /// Cut the map to a lat/lon box and write it as a self-contained GeoJSON map.
    Crop(CropArgs),
}

/// Arguments of `evigrid map info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The map file.
    file: PathBuf,
    /// Origin of the local frame as `LAT,LON` in degrees; by default the map's centre.
    #[arg(long, value_name = "LAT,LON")]
    origin: Option<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// Arguments of `evigrid map render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The map file.
    file: PathBuf,
    /// Cell size, metres (SPEC §2 default 0.5 m).
    #[arg(long, default_value_t = 0.5)]
    cell: f64,
    /// The PNG to write (written atomically: a temporary file, then renamed).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing file at --out (never an input).
    #[arg(long)]
    force: bool,
    /// Print the summary (image size, cells per context, scale bar) as JSON on standard output.
    #[arg(long)]
    json: bool,
}

/// Arguments of `evigrid map crop`.
#[derive(Debug, Args)]
pub struct CropArgs {
    /// The map file.
    file: PathBuf,
    /// The box to keep: two opposite corners as `LAT1,LON1,LAT2,LON2`, degrees.
    #[arg(long, value_name = "LAT1,LON1,LAT2,LON2", allow_hyphen_values = true)]
    bbox: String,
    /// The GeoJSON file to write (written atomically).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing file at --out (never an input).
    #[arg(long)]
    force: bool,
    /// Print the counts of what was kept as JSON on standard output.
    #[arg(long)]
    json: bool,
}

/// Runs one `evigrid map` subcommand.
pub fn run(command: MapCommand) -> Result<()> {
    match command {
        MapCommand::Info(args) => info(&args),
        MapCommand::Render(args) => render(&args),
        MapCommand::Crop(args) => crop(&args),
    }
}

/// Largest raster `render` will build (one byte per cell before colouring, three after).
const MAX_RENDER_CELLS: usize = 100_000_000;

/// Colours of the contexts in the picture (RGB).
fn context_colour(context: MapContext) -> [u8; 3] {
    match context {
        MapContext::Unknown => [0, 0, 0],
        MapContext::Other => [236, 232, 218],
        MapContext::Road => [96, 96, 104],
        MapContext::Building => [196, 84, 60],
        // Never rasterised from a map; derived by the `evigrid` method's prior.
        MapContext::BuildingEdge => [226, 170, 150],
    }
}

/// Reads a map; every failure is the user's file, so it is bad input (exit 2).
fn load(file: &Path, origin: Option<&str>) -> Result<LoadedMap> {
    let origin = origin
        .map(|text| parse_numbers::<2>(text).map(|[lat, lon]| (lat, lon)))
        .transpose()
        .map_err(|e| BadInput::new(format!("--origin: {e}")))?;
    load_map(file, &LoadOptions { origin }).map_err(|e| BadInput::new(e.to_string()))
}

fn info(args: &InfoArgs) -> Result<()> {
    let loaded = load(&args.file, args.origin.as_deref())?;
    let stats = &loaded.stats;
    if args.json {
        #[derive(Serialize)]
        struct Info<'a> {
            file: &'a Path,
            #[serde(flatten)]
            stats: &'a geodata::MapStats,
        }
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&Info {
                file: &args.file,
                stats
            })?
        );
        return Ok(());
    }
    let (g, m) = (&stats.extent_wgs84, &stats.extent_m);
    let s = &stats.source;
    crate::outln!(
        "file: {} ({})",
        args.file.display(),
        format_name(stats.format)
    );
    crate::outln!(
        "extent: lat {:.7} .. {:.7}, lon {:.7} .. {:.7}",
        g.min_lat,
        g.max_lat,
        g.min_lon,
        g.max_lon
    );
    crate::outln!(
        "extent: {:.1} m east-west x {:.1} m north-south (x {:.1} .. {:.1} m, y {:.1} .. {:.1} m from origin {:.7}, {:.7})",
        m.width_m,
        m.height_m,
        m.min_x_m,
        m.max_x_m,
        m.min_y_m,
        m.max_y_m,
        stats.origin.0,
        stats.origin.1
    );
    crate::outln!(
        "buildings: {} (from {} of {} building ways and {} of {} building relations)",
        stats.buildings,
        s.building_ways_used,
        s.building_ways,
        s.building_relations_used,
        s.building_relations
    );
    crate::outln!(
        "road pieces: {} (from {} centrelines of {} vehicle-road ways; {} highway ways in all)",
        stats.road_pieces,
        stats.road_centrelines,
        s.vehicle_road_ways,
        s.highway_ways
    );
    crate::outln!(
        "below the street (left out): {} vehicle-road ways, {} buildings; under a roof at street level: {} vehicle-road ways (cut through the buildings they cross)",
        s.underground_road_ways,
        s.underground_buildings,
        s.covered_road_ways
    );
    crate::outln!("road areas: {}", stats.road_areas);
    crate::outln!("parking areas: {}", stats.parking_areas);
    if stats.skipped.is_empty() {
        crate::outln!("skipped: none");
    } else {
        let skipped: Vec<String> = stats
            .skipped
            .iter()
            .map(|(reason, count)| format!("{} {count}", reason.name()))
            .collect();
        crate::outln!("skipped: {}", skipped.join(", "));
    }
    Ok(())
}

fn format_name(format: geodata::MapFormat) -> String {
    serde_json::to_value(format)
        .ok()
        .and_then(|v| v.as_str().map(str::to_owned))
        .unwrap_or_else(|| format!("{format:?}"))
}

/// Summary printed by `render --json`.
#[derive(Serialize)]
struct RenderSummary {
    out: PathBuf,
    width_px: usize,
    height_px: usize,
    cell_size_m: f64,
    cells_building: usize,
    cells_road: usize,
    cells_other: usize,
    cells_unknown: usize,
    scale_bar_m: f64,
    scale_bar_block_m: f64,
}

fn render(args: &RenderArgs) -> Result<()> {
    if !(args.cell.is_finite() && args.cell > 0.0) {
        return Err(BadInput::new(format!(
            "--cell {}: must be a positive number of metres",
            args.cell
        )));
    }
    crate::out_dir::check_out_file(&args.out, &[&args.file], args.force)?;
    let loaded = load(&args.file, None)?;
    let extent = loaded.map.extent;
    let window = geodata::CellWindow::covering(&extent, args.cell);
    if window.len() > MAX_RENDER_CELLS || window.is_empty() {
        return Err(BadInput::new(format!(
            "--cell {}: {} x {} cells for a {:.0} m x {:.0} m map is more than {} cells; use a larger cell",
            args.cell,
            window.width,
            window.height,
            extent.width(),
            extent.height(),
            MAX_RENDER_CELLS
        )));
    }
    let raster = ContextRaster::new(&loaded.map);
    let mut contexts = vec![MapContext::Unknown; window.len()];
    raster.fill(&window, &mut contexts);

    let (width, height) = (window.width, window.height);
    let mut pixels = vec![0u8; width * height * 3];
    let mut counts = [0usize; 4];
    for (row, row_contexts) in contexts.chunks(width).enumerate() {
        // Window row 0 is the southernmost; image row 0 is the top.
        let image_row = height - 1 - row;
        for (col, &context) in row_contexts.iter().enumerate() {
            counts[context as usize] += 1;
            let at = (image_row * width + col) * 3;
            pixels[at..at + 3].copy_from_slice(&context_colour(context));
        }
    }
    let bar = ScaleBar::for_width(width as f64 * args.cell);
    bar.draw(&mut pixels, width, height, args.cell);

    let image = output::raster::RgbImage::from_raw(width as u32, height as u32, pixels)
        .context("internal error: image buffer size")?;
    let png = image
        .to_png()
        .with_context(|| format!("{}: PNG encoder", args.out.display()))?;
    write_out(&args.out, &png)?;
    crate::errln!(
        "wrote {} ({width} x {height} px, {} m per pixel); scale bar bottom left: {} m in alternating {} m blocks; colours: building red-brown, road grey, other beige, unknown black",
        args.out.display(),
        args.cell,
        bar.length_m,
        bar.block_m
    );
    if args.json {
        let summary = RenderSummary {
            out: args.out.clone(),
            width_px: width,
            height_px: height,
            cell_size_m: args.cell,
            cells_building: counts[MapContext::Building as usize],
            cells_road: counts[MapContext::Road as usize],
            cells_other: counts[MapContext::Other as usize],
            cells_unknown: counts[MapContext::Unknown as usize],
            scale_bar_m: bar.length_m,
            scale_bar_block_m: bar.block_m,
        };
        crate::outln!("{}", serde_json::to_string_pretty(&summary)?);
    }
    Ok(())
}

/// A scale bar of a round length, drawn as alternating black and white blocks.
struct ScaleBar {
    length_m: f64,
    block_m: f64,
}

impl ScaleBar {
    /// About a fifth of the map's width, rounded down to 1, 2 or 5 × 10ⁿ metres; blocks of 10 m
    /// for bars up to 200 m, 50 m up to 1 km, else a fifth of the bar.
    fn for_width(map_width_m: f64) -> Self {
        let target = (map_width_m / 5.0).max(1.0);
        let decade = 10f64.powf(target.log10().floor());
        let length_m = [5.0, 2.0, 1.0]
            .into_iter()
            .map(|k| k * decade)
            .find(|&l| l <= target)
            .unwrap_or(decade);
        let block_m = if length_m <= 10.0 {
            length_m / 5.0
        } else if length_m <= 200.0 {
            10.0
        } else if length_m <= 1000.0 {
            50.0
        } else {
            length_m / 5.0
        };
        Self { length_m, block_m }
    }

    /// Draws the bar in the bottom-left corner with a white margin around it.
    fn draw(&self, pixels: &mut [u8], width: usize, height: usize, cell_m: f64) {
        let length_px = (self.length_m / cell_m).round() as usize;
        let block_px = ((self.block_m / cell_m).round() as usize).max(1);
        let bar_px = (height / 80).clamp(3, 40);
        let margin = bar_px;
        if length_px + 4 * margin > width || 4 * bar_px > height {
            return; // too small a picture for a bar
        }
        let mut fill = |x0: usize, y0: usize, w: usize, h: usize, colour: [u8; 3]| {
            for y in y0..(y0 + h).min(height) {
                for x in x0..(x0 + w).min(width) {
                    let at = (y * width + x) * 3;
                    pixels[at..at + 3].copy_from_slice(&colour);
                }
            }
        };
        let (x0, y0) = (margin, height - 2 * margin - bar_px);
        // White background, then alternating blocks; the first block black.
        fill(
            x0 - margin / 2,
            y0 - margin / 2,
            length_px + margin,
            bar_px + margin,
            [255, 255, 255],
        );
        let mut x = 0;
        let mut black = true;
        while x < length_px {
            let w = block_px.min(length_px - x);
            fill(
                x0 + x,
                y0,
                w,
                bar_px,
                if black { [0, 0, 0] } else { [255, 255, 255] },
            );
            x += w;
            black = !black;
        }
        // Thin outline so the white blocks stay visible against the white margin.
        fill(x0, y0, length_px, 1, [0, 0, 0]);
        fill(x0, y0 + bar_px - 1, length_px, 1, [0, 0, 0]);
        fill(x0 + length_px - 1, y0, 1, bar_px, [0, 0, 0]);
    }
}

/// Summary printed by `crop --json`.
#[derive(Serialize)]
struct CropSummary {
    out: PathBuf,
    buildings: usize,
    road_centrelines: usize,
    road_areas: usize,
    parking_areas: usize,
}

fn crop(args: &CropArgs) -> Result<()> {
    let [lat1, lon1, lat2, lon2] =
        parse_numbers::<4>(&args.bbox).map_err(|e| BadInput::new(format!("--bbox: {e}")))?;
    for (lat, lon) in [(lat1, lon1), (lat2, lon2)] {
        if lat.abs() > 90.0 || lon.abs() > 180.0 {
            return Err(BadInput::new(format!(
                "--bbox: corner lat {lat}, lon {lon} is outside WGS84 ranges"
            )));
        }
    }
    if lat1 == lat2 || lon1 == lon2 {
        return Err(BadInput::new(format!(
            "--bbox {}: the box is empty",
            args.bbox
        )));
    }
    crate::out_dir::check_out_file(&args.out, &[&args.file], args.force)?;
    let loaded = load(&args.file, None)?;
    let bbox = geodata::GeoBox {
        min_lat: lat1.min(lat2),
        min_lon: lon1.min(lon2),
        max_lat: lat1.max(lat2),
        max_lon: lon1.max(lon2),
    };
    let cropped = loaded.features.crop(&bbox);
    let text = serde_json::to_string(&cropped.to_geojson())?;
    write_out(&args.out, text.as_bytes())?;
    let summary = CropSummary {
        out: args.out.clone(),
        buildings: cropped.buildings.len(),
        road_centrelines: cropped.roads.len(),
        road_areas: cropped.road_areas.len(),
        parking_areas: cropped.parking.len(),
    };
    crate::errln!(
        "wrote {}: {} buildings, {} road centrelines, {} road areas, {} parking areas",
        args.out.display(),
        summary.buildings,
        summary.road_centrelines,
        summary.road_areas,
        summary.parking_areas
    );
    if args.json {
        crate::outln!("{}", serde_json::to_string_pretty(&summary)?);
    }
    Ok(())
}

/// Parses `N` comma-separated finite numbers.
fn parse_numbers<const N: usize>(text: &str) -> std::result::Result<[f64; N], String> {
    let numbers: Vec<f64> = text
        .split(',')
        .map(|part| {
            part.trim()
                .parse::<f64>()
                .map_err(|_| format!("{part:?} is not a number"))
        })
        .collect::<std::result::Result<_, _>>()?;
    let numbers: [f64; N] = numbers
        .try_into()
        .map_err(|v: Vec<f64>| format!("expected {N} comma-separated numbers, got {}", v.len()))?;
    if numbers.iter().any(|v| !v.is_finite()) {
        return Err(format!("{text:?} holds a non-finite number"));
    }
    Ok(numbers)
}

/// Writes `bytes` to `--out` atomically; a failure is the user's (a missing directory, no
/// permission), so it exits with status 2.
fn write_out(path: &Path, bytes: &[u8]) -> Result<()> {
    output::write_atomic(path, |file| file.write_all(bytes))
        .map_err(|e| BadInput::new(format!("--out {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_bar_lengths_are_round() {
        // 1012 m wide map: a fifth is 202 m → 200 m bar in 10 m blocks.
        let bar = ScaleBar::for_width(1012.0);
        assert_eq!((bar.length_m, bar.block_m), (200.0, 10.0));
        // 2197 m: 439 m → 200 m.
        assert_eq!(ScaleBar::for_width(2197.0).length_m, 200.0);
        // 3000 m: 600 m → 500 m in 50 m blocks.
        let bar = ScaleBar::for_width(3000.0);
        assert_eq!((bar.length_m, bar.block_m), (500.0, 50.0));
        // 223 m: 44.6 m → 20 m in 10 m blocks.
        assert_eq!(ScaleBar::for_width(223.0).length_m, 20.0);
    }

    #[test]
    fn numbers_are_parsed_strictly() {
        assert_eq!(parse_numbers::<2>("60.1, 24.9"), Ok([60.1, 24.9]));
        assert!(parse_numbers::<2>("60.1").is_err());
        assert!(parse_numbers::<2>("60.1,x").is_err());
        assert!(parse_numbers::<2>("60.1,inf").is_err());
    }
}
