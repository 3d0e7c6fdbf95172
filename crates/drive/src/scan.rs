//! Reading lidar scans: PCD v0.7 (ascii and binary) and KITTI Velodyne `.bin` files.
//!
//! A scan is a list of points in the *sensor* frame (metres), with an intensity per point when
//! the file has one. Nothing is filtered here: NaN or far points are the sensor model's business,
//! which counts what it drops.
//!
//! The PCD reader is a small one of our own: it accepts fields `x y z` and optionally
//! `intensity` in any order among other fields, of type `F` with size 4 or 8 (intensity may also
//! be an unsigned or signed integer), `COUNT` 1 for those fields, `DATA ascii` or `DATA binary`.
//! `binary_compressed` is refused with a clear error.
//!
//! Both readers treat the file as hostile: nothing is allocated in proportion to a number read
//! from a header before that number has been checked, with overflow-checked arithmetic, against
//! the bytes actually present, and no file above [`MAX_SCAN_BYTES`] is read at all. A PCD whose
//! `POINTS` disagrees with `WIDTH × HEIGHT` is refused rather than guessed at.

use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Largest scan file read, in bytes (2 GiB). A Velodyne HDL-64E scan is about 2 MB as KITTI
/// `.bin` and 5 MB as ascii PCD; even a merged map-sized cloud of 100 million points fits. The
/// bound keeps a mistaken path (a disk image, a device) from exhausting memory.
pub const MAX_SCAN_BYTES: u64 = 2 << 30;

/// Why a scan file could not be read. Every variant names the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScanError {
    /// The file or directory could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A PCD header line is malformed or a required header line is missing.
    #[error("{path}: PCD header: {message}")]
    Header {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A required field (`x`, `y` or `z`) is not in the file.
    #[error("{path}: PCD has no field `{field}`")]
    MissingField {
        /// The file.
        path: PathBuf,
        /// The missing field.
        field: &'static str,
    },
    /// A field has a type/size or count this reader does not handle.
    #[error("{path}: PCD field `{field}` has unsupported TYPE {kind} SIZE {size} COUNT {count}")]
    UnsupportedField {
        /// The file.
        path: PathBuf,
        /// Field name.
        field: String,
        /// PCD type letter (`F`, `U`, `I`).
        kind: char,
        /// Size in bytes.
        size: usize,
        /// Element count.
        count: usize,
    },
    /// The `DATA` encoding is not `ascii` or `binary`.
    #[error("{path}: PCD DATA `{encoding}` is not supported (use ascii or binary)")]
    UnsupportedEncoding {
        /// The file.
        path: PathBuf,
        /// The encoding named in the header.
        encoding: String,
    },
    /// The data section is shorter than the header announces.
    #[error("{path}: expected {expected} points, data holds {found}")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Points announced by the header.
        expected: usize,
        /// Complete points present.
        found: usize,
    },
    /// An ascii data line could not be parsed.
    #[error("{path}: line {line}: {message}")]
    AsciiData {
        /// The file.
        path: PathBuf,
        /// 1-based line number in the file.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A KITTI `.bin` file's length is not a whole number of 16-byte records.
    #[error(
        "{path}: {len} bytes is not a whole number of 16-byte KITTI records (x y z intensity f32)"
    )]
    KittiLength {
        /// The file.
        path: PathBuf,
        /// File length in bytes.
        len: usize,
    },
    /// The file is larger than [`MAX_SCAN_BYTES`].
    #[error("{path}: {len} bytes or more, above the {max}-byte limit for a scan")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Bytes seen (at least this many).
        len: u64,
        /// The limit.
        max: u64,
    },
    /// The file's extension is neither `.pcd` nor `.bin`.
    #[error("{path}: unknown scan format (expected .pcd or .bin)")]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
}

/// One lidar scan: points in the sensor frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scan {
    /// Points `[x, y, z]` in the sensor frame, metres (x forward, y left, z up for KITTI).
    pub points_in_sensor: Vec<[f32; 3]>,
    /// Intensity per point when the file has it (same length as the points), else empty.
    pub intensity: Vec<f32>,
}

impl Scan {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points_in_sensor.len()
    }

    /// True for a scan without points.
    pub fn is_empty(&self) -> bool {
        self.points_in_sensor.is_empty()
    }
}

/// Reads a scan, choosing the format by extension: `.pcd` (PCD v0.7) or `.bin` (KITTI).
///
/// # Errors
///
/// Any [`ScanError`], naming the file.
pub fn read_scan(path: &Path) -> Result<Scan, ScanError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
    {
        Some(ext) if ext == "pcd" => read_pcd(path),
        Some(ext) if ext == "bin" => read_kitti_bin(path),
        _ => Err(ScanError::UnknownFormat {
            path: path.to_path_buf(),
        }),
    }
}

/// The `.pcd` and `.bin` files of a directory, sorted by file name (the scan order).
///
/// # Errors
///
/// [`ScanError::Io`] if the directory cannot be listed.
pub fn list_scans(dir: &Path) -> Result<Vec<PathBuf>, ScanError> {
    let io = |source| ScanError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut paths = Vec::new();
    for entry in fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if path.is_file() && matches!(ext.as_deref(), Some("pcd" | "bin")) {
            paths.push(path);
        }
    }
    paths.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    Ok(paths)
}

/// Reads a whole file of at most [`MAX_SCAN_BYTES`], checking the length before reading and
/// bounding the read itself (for files whose metadata lies: devices, pipes, growing files).
fn read_bounded(path: &Path) -> Result<Vec<u8>, ScanError> {
    let io = |source| ScanError::Io {
        path: path.to_path_buf(),
        source,
    };
    let too_large = |len| ScanError::TooLarge {
        path: path.to_path_buf(),
        len,
        max: MAX_SCAN_BYTES,
    };
    // Checked before opening: opening a FIFO with no writer blocks forever.
    if !fs::metadata(path).map_err(io)?.is_file() {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file",
        )));
    }
    let file = fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    if len > MAX_SCAN_BYTES {
        return Err(too_large(len));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.take(MAX_SCAN_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_SCAN_BYTES {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// Reads a KITTI Velodyne `.bin` file: little-endian `f32` records `x y z intensity`.
///
/// # Errors
///
/// [`ScanError::Io`], or [`ScanError::KittiLength`] if the length is not a multiple of 16.
pub fn read_kitti_bin(path: &Path) -> Result<Scan, ScanError> {
    let bytes = read_bounded(path)?;
    parse_kitti_bin(&bytes, path)
}

/// Parses the bytes of a KITTI `.bin` file; `path` only names the source in errors.
///
/// # Errors
///
/// [`ScanError::KittiLength`] if the length is not a multiple of 16.
pub fn parse_kitti_bin(bytes: &[u8], path: &Path) -> Result<Scan, ScanError> {
    if !bytes.len().is_multiple_of(16) {
        return Err(ScanError::KittiLength {
            path: path.to_path_buf(),
            len: bytes.len(),
        });
    }
    // Each vector filled from an iterator of known length over 16-byte records: no capacity
    // or bounds check per point.
    // (The length is a multiple of 16: nothing is left over.)
    let (records, _) = bytes.as_chunks::<16>();
    let f = |r: &[u8; 16], i: usize| f32::from_le_bytes([r[i], r[i + 1], r[i + 2], r[i + 3]]);
    Ok(Scan {
        points_in_sensor: records
            .iter()
            .map(|r| [f(r, 0), f(r, 4), f(r, 8)])
            .collect(),
        intensity: records.iter().map(|r| f(r, 12)).collect(),
    })
}

/// Reads a PCD v0.7 file (ascii or binary data).
///
/// # Errors
///
/// Any [`ScanError`], naming the file.
pub fn read_pcd(path: &Path) -> Result<Scan, ScanError> {
    let bytes = read_bounded(path)?;
    parse_pcd(&bytes, path)
}

/// How one field is stored in a PCD record.
#[derive(Debug, Clone)]
struct PcdField {
    name: String,
    kind: char,
    size: usize,
    count: usize,
    /// Byte offset inside a binary record; element offset inside an ascii line.
    offset: usize,
    column: usize,
}

impl PcdField {
    /// Decodes this field (first element) from a little-endian binary record.
    fn decode(&self, record: &[u8]) -> f32 {
        let b = &record[self.offset..self.offset + self.size];
        match (self.kind, self.size) {
            ('F', 4) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            ('F', 8) => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32,
            ('U', 1) => f32::from(b[0]),
            ('U', 2) => f32::from(u16::from_le_bytes([b[0], b[1]])),
            ('U', 4) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            ('I', 1) => f32::from(b[0] as i8),
            ('I', 2) => f32::from(i16::from_le_bytes([b[0], b[1]])),
            ('I', 4) => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            // Unreachable: `check_supported` refused every other combination.
            _ => f32::NAN,
        }
    }
}

/// Parses the bytes of a PCD v0.7 file; `path` only names the source in errors.
///
/// # Errors
///
/// Any [`ScanError`] but `Io`, naming `path`.
pub fn parse_pcd(bytes: &[u8], path: &Path) -> Result<Scan, ScanError> {
    let header = read_pcd_header(bytes, path)?;
    let layout = header.layout(path)?;
    let (Some(fx), Some(fy), Some(fz)) = (
        layout.field("x", true, path)?,
        layout.field("y", true, path)?,
        layout.field("z", true, path)?,
    ) else {
        // `field` with `required` never returns Ok(None).
        return Err(ScanError::MissingField {
            path: path.to_path_buf(),
            field: "x",
        });
    };
    let fi = layout.field("intensity", false, path)?;
    let data = &bytes[header.data_start..];
    // What the data can hold at most, so that no header number sizes an allocation: a binary
    // record is `record_len` bytes (at least 12: x, y, z are 4 or 8 bytes); an ascii point is a
    // line of at least `column` (at least 3) numbers, each followed by a separator.
    let capacity = match header.encoding.as_str() {
        "binary" => data.len() / layout.record_len.max(1),
        _ => data.len() / layout.column.saturating_mul(2).max(1) + 1,
    }
    .min(layout.expected);
    let mut scan = Scan {
        points_in_sensor: Vec::with_capacity(capacity),
        intensity: Vec::with_capacity(if fi.is_some() { capacity } else { 0 }),
    };
    let fields = PcdPointFields {
        xyz: [fx, fy, fz],
        intensity: fi,
    };
    match header.encoding.as_str() {
        "binary" => decode_pcd_binary(data, &layout, &fields, &mut scan, path)?,
        "ascii" => decode_pcd_ascii(data, header.lines, &layout, &fields, &mut scan, path)?,
        other => {
            return Err(ScanError::UnsupportedEncoding {
                path: path.to_path_buf(),
                encoding: other.to_string(),
            });
        }
    }
    Ok(scan)
}

/// A PCD header as written: its keys' values, the data's encoding and where the data starts.
#[derive(Debug)]
struct PcdHeader {
    names: Vec<String>,
    sizes: Vec<usize>,
    kinds: Vec<char>,
    counts: Vec<usize>,
    width: Option<usize>,
    height: usize,
    points: Option<usize>,
    /// The `DATA` line's first word, lower case (`binary`, `ascii`, or unsupported).
    encoding: String,
    /// Byte offset of the data: just after the `DATA` line.
    data_start: usize,
    /// Lines up to and including the `DATA` line.
    lines: usize,
}

/// What the PCD header of `path` says its records are: its fields' sizes and offsets, the
/// record's length and the values of an ascii line, and how many points follow.
#[derive(Debug)]
struct PcdLayout {
    fields: Vec<PcdField>,
    /// Bytes of a binary record.
    record_len: usize,
    /// Values of an ascii line.
    column: usize,
    /// Points the data holds.
    expected: usize,
}

/// The fields a point is read from: x, y, z and, if the file has it, intensity.
struct PcdPointFields {
    xyz: [PcdField; 3],
    intensity: Option<PcdField>,
}

/// The error for a bad header of `path`.
fn pcd_header_error(path: &Path, message: String) -> ScanError {
    ScanError::Header {
        path: path.to_path_buf(),
        message,
    }
}

/// Reads the header lines of a PCD file up to its `DATA` line.
fn read_pcd_header(bytes: &[u8], path: &Path) -> Result<PcdHeader, ScanError> {
    let header_error = |message: String| pcd_header_error(path, message);
    let mut header = PcdHeader {
        names: Vec::new(),
        sizes: Vec::new(),
        kinds: Vec::new(),
        counts: Vec::new(),
        width: None,
        height: 1,
        points: None,
        encoding: String::new(),
        data_start: 0,
        lines: 0,
    };
    let mut cursor = 0usize;
    let mut line_number = 0usize;
    header.encoding = loop {
        let Some(rel_end) = bytes[cursor..].iter().position(|&b| b == b'\n') else {
            return Err(header_error("no DATA line".into()));
        };
        let line = String::from_utf8_lossy(&bytes[cursor..cursor + rel_end]).into_owned();
        cursor += rel_end + 1;
        line_number += 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or_default().to_ascii_uppercase();
        let values: Vec<&str> = words.collect();
        let parse_all = |what: &str| parse_pcd_counts(&values, what, line_number, path);
        let parse_one = |what: &str| -> Result<usize, ScanError> {
            match parse_all(what)?.as_slice() {
                [v] => Ok(*v),
                _ => Err(header_error(format!(
                    "line {line_number}: {what} needs one value"
                ))),
            }
        };
        match key.as_str() {
            "VERSION" | "VIEWPOINT" => {}
            "FIELDS" => header.names = values.iter().map(|s| s.to_string()).collect(),
            "SIZE" => header.sizes = parse_all("SIZE")?,
            "COUNT" => header.counts = parse_all("COUNT")?,
            "TYPE" => header.kinds = parse_pcd_types(&values, line_number, path)?,
            "WIDTH" => header.width = Some(parse_one("WIDTH")?),
            "HEIGHT" => header.height = parse_one("HEIGHT")?,
            "POINTS" => header.points = Some(parse_one("POINTS")?),
            "DATA" => {
                break values
                    .first()
                    .map(|s| s.to_ascii_lowercase())
                    .unwrap_or_default();
            }
            other => {
                return Err(header_error(format!(
                    "line {line_number}: unknown key `{other}`"
                )));
            }
        }
    };
    header.data_start = cursor;
    header.lines = line_number;
    Ok(header)
}

/// The numbers of a `SIZE`, `COUNT`, `WIDTH`, `HEIGHT` or `POINTS` line (`what`).
fn parse_pcd_counts(
    values: &[&str],
    what: &str,
    line_number: usize,
    path: &Path,
) -> Result<Vec<usize>, ScanError> {
    values
        .iter()
        .map(|v| {
            v.parse::<usize>().map_err(|_| {
                pcd_header_error(path, format!("line {line_number}: bad {what} `{v}`"))
            })
        })
        .collect()
}

/// The kinds of a `TYPE` line: `F`, `U` or `I`.
fn parse_pcd_types(
    values: &[&str],
    line_number: usize,
    path: &Path,
) -> Result<Vec<char>, ScanError> {
    values
        .iter()
        .map(|v| match v.chars().collect::<Vec<_>>().as_slice() {
            [c @ ('F' | 'U' | 'I')] => Ok(*c),
            _ => Err(pcd_header_error(
                path,
                format!("line {line_number}: bad TYPE `{v}`"),
            )),
        })
        .collect()
}

impl PcdHeader {
    /// The record layout this header declares, checked: the keys agree on the number of
    /// fields, on the number of points, and no size overflows.
    fn layout(&self, path: &Path) -> Result<PcdLayout, ScanError> {
        let header_error = |message: String| pcd_header_error(path, message);
        let names = &self.names;
        let (sizes, kinds) = (&self.sizes, &self.kinds);
        let counts = if self.counts.is_empty() {
            vec![1; names.len()]
        } else {
            self.counts.clone()
        };
        if names.is_empty()
            || sizes.len() != names.len()
            || kinds.len() != names.len()
            || counts.len() != names.len()
        {
            return Err(header_error(format!(
                "FIELDS ({}), SIZE ({}), TYPE ({}) and COUNT ({}) disagree",
                names.len(),
                sizes.len(),
                kinds.len(),
                counts.len()
            )));
        }
        let height = self.height;
        let organised =
            match self.width {
                Some(w) => Some(w.checked_mul(height).ok_or_else(|| {
                    header_error(format!("WIDTH {w} x HEIGHT {height} overflows"))
                })?),
                None => None,
            };
        let expected = match (self.points, organised) {
            (Some(p), Some(wh)) if p != wh => {
                return Err(header_error(format!(
                    "POINTS {p} disagrees with WIDTH x HEIGHT = {wh}"
                )));
            }
            (Some(p), _) => p,
            (None, Some(wh)) => wh,
            (None, None) => return Err(header_error("neither POINTS nor WIDTH given".into())),
        };
        let mut fields = Vec::with_capacity(names.len());
        let (mut offset, mut column) = (0usize, 0usize);
        for i in 0..names.len() {
            fields.push(PcdField {
                name: names[i].clone(),
                kind: kinds[i],
                size: sizes[i],
                count: counts[i],
                offset,
                column,
            });
            let overflow = || {
                header_error(format!(
                    "field `{}`: SIZE {} x COUNT {} makes the record size overflow",
                    names[i], sizes[i], counts[i]
                ))
            };
            offset = sizes[i]
                .checked_mul(counts[i])
                .and_then(|len| offset.checked_add(len))
                .ok_or_else(overflow)?;
            column = column.checked_add(counts[i]).ok_or_else(overflow)?;
        }
        Ok(PcdLayout {
            fields,
            record_len: offset,
            column,
            expected,
        })
    }
}

impl PcdLayout {
    /// The field `name`, if its kind and size can be read (one element; x, y and z floats,
    /// intensity a float or an integer of 1, 2 or 4 bytes); `Ok(None)` when it is missing and
    /// not `required`.
    fn field(
        &self,
        name: &'static str,
        required: bool,
        path: &Path,
    ) -> Result<Option<PcdField>, ScanError> {
        let Some(field) = self.fields.iter().find(|f| f.name == name) else {
            return if required {
                Err(ScanError::MissingField {
                    path: path.to_path_buf(),
                    field: name,
                })
            } else {
                Ok(None)
            };
        };
        let coordinate = name != "intensity";
        let supported = field.count == 1
            && match field.kind {
                'F' => matches!(field.size, 4 | 8),
                'U' | 'I' => !coordinate && matches!(field.size, 1 | 2 | 4),
                _ => false,
            };
        if !supported {
            return Err(ScanError::UnsupportedField {
                path: path.to_path_buf(),
                field: field.name.clone(),
                kind: field.kind,
                size: field.size,
                count: field.count,
            });
        }
        Ok(Some(field.clone()))
    }
}

/// Reads the points of binary PCD `data` into `scan`.
fn decode_pcd_binary(
    data: &[u8],
    layout: &PcdLayout,
    fields: &PcdPointFields,
    scan: &mut Scan,
    path: &Path,
) -> Result<(), ScanError> {
    let (record_len, expected) = (layout.record_len, layout.expected);
    let [fx, fy, fz] = &fields.xyz;
    let found = data.len() / record_len.max(1);
    let needed = expected.checked_mul(record_len);
    if needed.is_none_or(|n| n > data.len()) || record_len == 0 {
        return Err(ScanError::Truncated {
            path: path.to_path_buf(),
            expected,
            found,
        });
    }
    for record in data.chunks_exact(record_len).take(expected) {
        scan.points_in_sensor
            .push([fx.decode(record), fy.decode(record), fz.decode(record)]);
        if let Some(fi) = &fields.intensity {
            scan.intensity.push(fi.decode(record));
        }
    }
    Ok(())
}

/// Reads the points of ascii PCD `data`, which starts after line `header_lines`, into `scan`.
fn decode_pcd_ascii(
    data: &[u8],
    header_lines: usize,
    layout: &PcdLayout,
    fields: &PcdPointFields,
    scan: &mut Scan,
    path: &Path,
) -> Result<(), ScanError> {
    let (column, expected) = (layout.column, layout.expected);
    let [fx, fy, fz] = &fields.xyz;
    let text = String::from_utf8_lossy(data);
    let mut values: Vec<f32> = Vec::with_capacity(column.min(64));
    for (i, line) in text.lines().enumerate() {
        if scan.points_in_sensor.len() == expected {
            break;
        }
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let number = header_lines + i + 1;
        values.clear();
        for word in line.split_whitespace() {
            // PCD writes non-finite values as `nan`; Rust parses `nan`/`inf` as such.
            let v: f64 = word.parse().map_err(|_| ScanError::AsciiData {
                path: path.to_path_buf(),
                line: number,
                message: format!("`{word}` is not a number"),
            })?;
            values.push(v as f32);
        }
        if values.len() < column {
            return Err(ScanError::AsciiData {
                path: path.to_path_buf(),
                line: number,
                message: format!("{} values, header declares {column}", values.len()),
            });
        }
        scan.points_in_sensor
            .push([values[fx.column], values[fy.column], values[fz.column]]);
        if let Some(fi) = &fields.intensity {
            scan.intensity.push(values[fi.column]);
        }
    }
    if scan.points_in_sensor.len() < expected {
        return Err(ScanError::Truncated {
            path: path.to_path_buf(),
            expected,
            found: scan.points_in_sensor.len(),
        });
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn shared_scans() -> Option<Vec<PathBuf>> {
        let dir = geodata::testdata::shared_file("data/lidar/kitti-city-22")?;
        let paths = list_scans(&dir).unwrap();
        assert!(!paths.is_empty(), "no scans in {}", dir.display());
        Some(paths)
    }

    #[test]
    fn ascii_pcd_with_fields_in_any_order_and_f8() {
        let text = "# .PCD v0.7\nVERSION 0.7\nFIELDS intensity z y x\nSIZE 4 8 4 4\nTYPE U F F F\n\
                    COUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n\
                    7 3.5 2 1\n9 nan -2 -1.5\n";
        let scan = parse_pcd(text.as_bytes(), Path::new("t.pcd")).unwrap();
        assert_eq!(scan.points_in_sensor[0], [1.0, 2.0, 3.5]);
        assert_eq!(scan.points_in_sensor[1][..2], [-1.5, -2.0]);
        assert!(scan.points_in_sensor[1][2].is_nan());
        assert_eq!(scan.intensity, vec![7.0, 9.0]);
    }

    #[test]
    fn binary_pcd_with_extra_field_and_f8() {
        let mut bytes =
            b"VERSION 0.7\nFIELDS x ring y z\nSIZE 8 2 4 4\nTYPE F U F F\nCOUNT 1 1 1 1\n\
                          WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n"
                .to_vec();
        bytes.extend_from_slice(&(-2.25f64).to_le_bytes());
        bytes.extend_from_slice(&5u16.to_le_bytes());
        bytes.extend_from_slice(&0.5f32.to_le_bytes());
        bytes.extend_from_slice(&(-1.75f32).to_le_bytes());
        let scan = parse_pcd(&bytes, Path::new("b.pcd")).unwrap();
        assert_eq!(scan.points_in_sensor, vec![[-2.25, 0.5, -1.75]]);
        assert!(scan.intensity.is_empty());
    }

    #[test]
    fn errors_name_the_file_and_the_problem() {
        let head = "VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2\n";
        let err = parse_pcd(head.as_bytes(), Path::new("scan7.pcd")).unwrap_err();
        assert!(matches!(err, ScanError::MissingField { field: "z", .. }));
        assert!(err.to_string().starts_with("scan7.pcd:"));

        let compressed = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary_compressed\n";
        assert!(matches!(
            parse_pcd(compressed.as_bytes(), Path::new("c.pcd")),
            Err(ScanError::UnsupportedEncoding { .. })
        ));
        let short = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 2\nDATA binary\n0123456789ab";
        assert!(matches!(
            parse_pcd(short.as_bytes(), Path::new("s.pcd")),
            Err(ScanError::Truncated {
                expected: 2,
                found: 1,
                ..
            })
        ));
        let int_x = "FIELDS x y z\nSIZE 4 4 4\nTYPE I F F\nPOINTS 0\nDATA ascii\n";
        assert!(matches!(
            parse_pcd(int_x.as_bytes(), Path::new("i.pcd")),
            Err(ScanError::UnsupportedField { kind: 'I', .. })
        ));
        assert!(matches!(
            parse_kitti_bin(&[0u8; 20], Path::new("k.bin")),
            Err(ScanError::KittiLength { len: 20, .. })
        ));
        assert!(matches!(
            read_scan(Path::new("x.las")),
            Err(ScanError::UnknownFormat { .. })
        ));
        assert!(matches!(
            read_scan(Path::new("/nonexistent/a.pcd")),
            Err(ScanError::Io { .. })
        ));
    }

    #[test]
    fn kitti_bin_records() {
        let mut bytes = Vec::new();
        for v in [1.0f32, 2.0, 3.0, 0.5, -4.0, 5.5, -1.0, 0.25] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        let scan = parse_kitti_bin(&bytes, Path::new("k.bin")).unwrap();
        assert_eq!(
            scan.points_in_sensor,
            vec![[1.0, 2.0, 3.0], [-4.0, 5.5, -1.0]]
        );
        assert_eq!(scan.intensity, vec![0.5, 0.25]);
    }

    /// A header with `x y z` F4 and the given extra lines, then the data.
    fn hostile(extra_header: &str, data: &str) -> Vec<u8> {
        format!("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n{extra_header}{data}")
            .into_bytes()
    }

    #[test]
    fn hostile_point_counts_are_refused_before_allocating() {
        let twelve_bytes = "0123456789ab";
        for points in ["4000000000", "18446744073709551615"] {
            for encoding in ["binary", "ascii"] {
                let bytes = hostile(&format!("POINTS {points}\nDATA {encoding}\n"), twelve_bytes);
                let err = parse_pcd(&bytes, Path::new("h.pcd")).unwrap_err();
                assert!(
                    matches!(
                        err,
                        ScanError::Truncated { .. } | ScanError::AsciiData { .. }
                    ),
                    "{points} {encoding}: {err}"
                );
                assert!(err.to_string().starts_with("h.pcd:"));
            }
        }
        // WIDTH x HEIGHT overflowing, and POINTS disagreeing with it.
        let bytes = hostile("WIDTH 4294967296\nHEIGHT 4294967296\nDATA binary\n", "");
        let err = parse_pcd(&bytes, Path::new("h.pcd"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("overflows"), "{err}");
        let bytes = hostile("WIDTH 2\nHEIGHT 3\nPOINTS 5\nDATA binary\n", "");
        let err = parse_pcd(&bytes, Path::new("h.pcd"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("POINTS 5 disagrees with WIDTH x HEIGHT = 6"),
            "{err}"
        );
    }

    #[test]
    fn hostile_field_sizes_and_counts_are_refused() {
        // SIZE near usize::MAX on an extra field: the record size overflows.
        let size = "VERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 18446744073709551612\nTYPE F F F U\n\
                    COUNT 1 1 1 2\nPOINTS 1\nDATA binary\n0123456789ab";
        let err = parse_pcd(size.as_bytes(), Path::new("h.pcd"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("record size overflow"), "{err}");
        // SIZE that fits but a record far longer than the file.
        let size = "VERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 18446744073709551500\nTYPE F F F U\n\
                    POINTS 1\nDATA binary\n0123456789ab";
        let err = parse_pcd(size.as_bytes(), Path::new("h.pcd")).unwrap_err();
        assert!(matches!(err, ScanError::Truncated { .. }), "{err}");
        // COUNT 10^12 on an ascii extra field: every line is short, nothing is allocated for it.
        let count = "VERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\n\
                     COUNT 1 1 1 1000000000000\nPOINTS 1\nDATA ascii\n1 2 3 4\n";
        let err = parse_pcd(count.as_bytes(), Path::new("h.pcd"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("line 8") && err.contains("header declares 1000000000003"),
            "{err}"
        );
        // COUNT near usize::MAX: the column count overflows.
        let count = "VERSION 0.7\nFIELDS x y z a b\nSIZE 4 4 4 1 1\nTYPE F F F U U\n\
                     COUNT 1 1 1 18446744073709551615 18446744073709551615\nPOINTS 1\nDATA ascii\n1 2 3\n";
        let err = parse_pcd(count.as_bytes(), Path::new("h.pcd"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("overflow"), "{err}");
        // COUNT on x itself is unsupported, however large.
        let count = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1000000000000 1 1\n\
                     POINTS 1\nDATA ascii\n1 2 3\n";
        assert!(matches!(
            parse_pcd(count.as_bytes(), Path::new("h.pcd")),
            Err(ScanError::UnsupportedField { .. })
        ));
    }

    #[test]
    fn files_above_the_bound_are_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["big.bin", "big.pcd"] {
            let path = dir.path().join(name);
            // Sparse: no disk space is used, and the reader must not read it.
            let file = std::fs::File::create(&path).unwrap();
            file.set_len(MAX_SCAN_BYTES + 1).unwrap();
            let err = read_scan(&path).unwrap_err();
            assert!(
                matches!(err, ScanError::TooLarge { len, .. } if len == MAX_SCAN_BYTES + 1),
                "{err}"
            );
            assert!(err.to_string().contains(name));
        }
    }

    #[test]
    fn reads_the_shared_kitti_scans() {
        let Some(paths) = shared_scans() else { return };
        assert_eq!(paths.len(), 22);
        let scan = read_scan(&paths[0]).unwrap();
        // Header of 0000000000.pcd announces 119 978 points with intensity.
        assert_eq!(scan.len(), 119_978);
        assert_eq!(scan.intensity.len(), scan.len());
        // An HDL-64E reaches about 120 m and sits about 1.73 m above the road: the bulk of the
        // points lie in a plausible box around the sensor.
        let plausible = scan
            .points_in_sensor
            .iter()
            .filter(|p| {
                p.iter().all(|v| v.is_finite())
                    && p[0].abs() < 130.0
                    && p[1].abs() < 130.0
                    && p[2] > -4.0
                    && p[2] < 10.0
            })
            .count();
        assert!(plausible as f64 > 0.99 * scan.len() as f64, "{plausible}");
        // The same scan written as a KITTI record stream reads back identically.
        let mut bin = Vec::new();
        for (p, i) in scan.points_in_sensor.iter().zip(&scan.intensity) {
            for v in [p[0], p[1], p[2], *i] {
                bin.extend_from_slice(&v.to_le_bytes());
            }
        }
        assert_eq!(parse_kitti_bin(&bin, Path::new("copy.bin")).unwrap(), scan);
    }
}
