//! The OSM PBF file structure (wiki.openstreetmap.org/wiki/PBF_Format): length-prefixed
//! `BlobHeader`/`Blob` pairs, zlib-compressed blobs, the `HeaderBlock` with its bounding box, and
//! `PrimitiveBlock`s (string table, granularity and offsets; nodes, dense nodes with delta coding,
//! ways with delta-coded references, relations with delta-coded members) decoded into
//! [`Item`]s.
//!
//! Every length is checked against the bytes that are there and the format's own limits (a
//! `BlobHeader` under 64 KiB, a blob under 32 MiB before and after decompression) before
//! anything is reserved.

use std::io::Read;

use flate2::read::ZlibDecoder;

use super::wire::{WireError, fields, repeated, zigzag};

/// The largest `BlobHeader` the format allows.
const MAX_HEADER_BYTES: usize = 64 * 1024;
/// The largest blob the format allows, compressed or not.
const MAX_BLOB_BYTES: usize = 32 * 1024 * 1024;

/// Required features this reader understands (a file needing another is refused, as the
/// format asks). `LocationsOnWays` adds coordinates to ways, which are read by reference.
const KNOWN_FEATURES: [&str; 4] = [
    "OsmSchema-V0.6",
    "DenseNodes",
    "HistoricalInformation",
    "LocationsOnWays",
];

/// One thing read from a PBF file, borrowing from its (decompressed) block.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Item<'a> {
    /// The header's bounding box, degrees as written (`left`/`right` longitudes,
    /// `top`/`bottom` latitudes).
    Bounds {
        /// Western longitude.
        left: f64,
        /// Eastern longitude.
        right: f64,
        /// Northern latitude.
        top: f64,
        /// Southern latitude.
        bottom: f64,
    },
    /// A node, from a `Node` or `DenseNodes`.
    Node {
        /// OSM id.
        id: i64,
        /// Latitude, degrees.
        lat: f64,
        /// Longitude, degrees.
        lon: f64,
        /// Tags in file order.
        tags: Vec<(&'a str, &'a str)>,
    },
    /// A way.
    Way {
        /// OSM id.
        id: i64,
        /// Node ids in order.
        refs: Vec<i64>,
        /// Tags in file order.
        tags: Vec<(&'a str, &'a str)>,
    },
    /// A relation.
    Relation {
        /// OSM id.
        id: i64,
        /// Members in order: (kind, id, role).
        members: Vec<(MemberKind, i64, &'a str)>,
        /// Tags in file order.
        tags: Vec<(&'a str, &'a str)>,
    },
}

/// What a relation member is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MemberKind {
    /// A node (`MemberType` 0).
    Node,
    /// A way (1).
    Way,
    /// A relation (2).
    Relation,
}

/// Reads every blob of `bytes` in order and hands each item to `visit`, stopping at the first
/// error (of the file or of `visit`).
///
/// # Errors
/// The file's problem as a sentence naming the blob and its byte offset, or `visit`'s error.
pub(crate) fn read_items<E>(
    bytes: &[u8],
    mut visit: impl FnMut(Item<'_>) -> Result<(), E>,
) -> Result<(), ReadError<E>> {
    let mut position = 0;
    let mut index = 0;
    let mut buffer = Vec::new();
    while position < bytes.len() {
        let start = position;
        let at =
            |message: String| ReadError::File(format!("blob {index} at byte {start}: {message}"));
        let (kind, blob) = frame_blob(bytes, &mut position).map_err(at)?;
        let data = blob_data(blob, &mut buffer).map_err(at)?;
        let mut visited = Ok(());
        let mut visit_once = |item| {
            if visited.is_ok() {
                visited = visit(item);
            }
        };
        match kind {
            b"OSMHeader" => read_header(data, &mut visit_once),
            b"OSMData" => read_block(data, &mut visit_once),
            _ => Ok(()),
        }
        .map_err(at)?;
        visited.map_err(ReadError::Visit)?;
        index += 1;
    }
    if index == 0 {
        return Err(ReadError::File("no blob in the file".to_owned()));
    }
    Ok(())
}

/// An error of [`read_items`].
#[derive(Debug, PartialEq)]
pub(crate) enum ReadError<E> {
    /// The file is truncated, corrupt or needs what this reader does not do.
    File(String),
    /// The visitor's error.
    Visit(E),
}

fn wire(context: &'static str) -> impl Fn(WireError) -> String {
    move |error| format!("{context}: {}", error.0)
}

/// Splits off the next `[length][BlobHeader][Blob]` at `position`: the header's type and the
/// blob's bytes.
fn frame_blob<'a>(bytes: &'a [u8], position: &mut usize) -> Result<(&'a [u8], &'a [u8]), String> {
    let take = |position: &mut usize, length: usize, what: &str| {
        let end = position
            .checked_add(length)
            .filter(|&end| end <= bytes.len())
            .ok_or_else(|| {
                format!(
                    "truncated: the {what} needs {length} bytes, {} are left",
                    bytes.len() - *position
                )
            })?;
        let slice = &bytes[*position..end];
        *position = end;
        Ok::<_, String>(slice)
    };
    let length = take(position, 4, "header length")?;
    let header_length = u32::from_be_bytes([length[0], length[1], length[2], length[3]]) as usize;
    if header_length > MAX_HEADER_BYTES {
        return Err(format!(
            "BlobHeader of {header_length} bytes, over the format's {MAX_HEADER_BYTES}"
        ));
    }
    let header = take(position, header_length, "BlobHeader")?;
    let mut kind = None;
    let mut data_size = None;
    for field in fields(header) {
        match field.map_err(wire("BlobHeader"))? {
            (1, value) => kind = Some(value.bytes().map_err(wire("BlobHeader type"))?),
            (3, value) => data_size = Some(value.varint().map_err(wire("BlobHeader datasize"))?),
            _ => {}
        }
    }
    let kind = kind.ok_or("BlobHeader has no type")?;
    let data_size = data_size.ok_or("BlobHeader has no datasize")?;
    let data_size = usize::try_from(data_size)
        .ok()
        .filter(|&size| size <= MAX_BLOB_BYTES)
        .ok_or_else(|| format!("blob of {data_size} bytes, over the format's {MAX_BLOB_BYTES}"))?;
    let blob = take(position, data_size, "blob")?;
    Ok((kind, blob))
}

/// The uncompressed content of a `Blob`, in place or decompressed into `buffer`.
fn blob_data<'a>(blob: &'a [u8], buffer: &'a mut Vec<u8>) -> Result<&'a [u8], String> {
    let mut raw = None;
    let mut raw_size = None;
    let mut zlib = None;
    for field in fields(blob) {
        match field.map_err(wire("Blob"))? {
            (1, value) => raw = Some(value.bytes().map_err(wire("Blob raw"))?),
            (2, value) => raw_size = Some(value.varint().map_err(wire("Blob raw_size"))?),
            (3, value) => zlib = Some(value.bytes().map_err(wire("Blob zlib_data"))?),
            (4, _) => return Err("LZMA-compressed blobs are not supported".to_owned()),
            (5, _) => return Err("bzip2-compressed blobs are not supported".to_owned()),
            (6, _) => return Err("LZ4-compressed blobs are not supported".to_owned()),
            (7, _) => return Err("zstd-compressed blobs are not supported".to_owned()),
            _ => {}
        }
    }
    if let Some(raw) = raw {
        return Ok(raw);
    }
    let zlib = zlib.ok_or("blob has no data")?;
    let expected = raw_size
        .and_then(|size| usize::try_from(size).ok())
        .filter(|&size| size <= MAX_BLOB_BYTES)
        .ok_or_else(|| format!("zlib blob without a raw_size up to {MAX_BLOB_BYTES} bytes"))?;
    buffer.clear();
    buffer.reserve(expected);
    ZlibDecoder::new(zlib)
        .take(expected as u64 + 1)
        .read_to_end(buffer)
        .map_err(|error| format!("zlib data: {error}"))?;
    if buffer.len() != expected {
        return Err(format!(
            "zlib data gives {}{} bytes, raw_size says {expected}",
            buffer.len().min(expected),
            if buffer.len() > expected { "+" } else { "" }
        ));
    }
    Ok(buffer)
}

/// Reads a `HeaderBlock`: refuses unknown required features, reports the bounding box.
fn read_header<'a>(data: &'a [u8], visit: &mut impl FnMut(Item<'a>)) -> Result<(), String> {
    for field in fields(data) {
        match field.map_err(wire("HeaderBlock"))? {
            (1, value) => {
                let bbox = value.bytes().map_err(wire("HeaderBBox"))?;
                let mut sides = [None; 4];
                for side in fields(bbox) {
                    let (number, value) = side.map_err(wire("HeaderBBox"))?;
                    if let Some(slot) = sides.get_mut((number as usize).wrapping_sub(1)) {
                        *slot = Some(value.sint().map_err(wire("HeaderBBox"))? as f64 * 1e-9);
                    }
                }
                let [Some(left), Some(right), Some(top), Some(bottom)] = sides else {
                    return Err("HeaderBBox lacks a side".to_owned());
                };
                visit(Item::Bounds {
                    left,
                    right,
                    top,
                    bottom,
                });
            }
            (4, value) => {
                let feature = value
                    .bytes()
                    .map_err(wire("HeaderBlock required_features"))?;
                if !KNOWN_FEATURES
                    .iter()
                    .any(|known| known.as_bytes() == feature)
                {
                    return Err(format!(
                        "the file requires the feature {:?}, which this reader does not support",
                        String::from_utf8_lossy(feature)
                    ));
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// What every element of a `PrimitiveBlock` is read against.
struct Block<'a> {
    strings: Vec<&'a [u8]>,
    granularity: i64,
    lat_offset: i64,
    lon_offset: i64,
}

impl<'a> Block<'a> {
    fn string(&self, index: u64) -> Result<&'a str, String> {
        let bytes = usize::try_from(index)
            .ok()
            .and_then(|i| self.strings.get(i))
            .ok_or_else(|| {
                format!(
                    "string index {index} outside the string table of {} entries",
                    self.strings.len()
                )
            })?;
        std::str::from_utf8(bytes).map_err(|_| format!("string {index} is not UTF-8"))
    }

    /// Degrees from a stored coordinate: 1e-9 · (offset + granularity · value).
    fn degrees(&self, offset: i64, value: i64) -> Result<f64, String> {
        let nano = self
            .granularity
            .checked_mul(value)
            .and_then(|scaled| scaled.checked_add(offset))
            .ok_or_else(|| {
                format!(
                    "coordinate {value} overflows at granularity {}",
                    self.granularity
                )
            })?;
        Ok(1e-9 * nano as f64)
    }

    /// Tags from parallel `keys` and `vals` fields (2 and 3) of `message`.
    fn tags(
        &self,
        message: &'a [u8],
        what: &'static str,
    ) -> Result<Vec<(&'a str, &'a str)>, String> {
        let mut keys = repeated(message, 2);
        let mut vals = repeated(message, 3);
        let mut tags = Vec::new();
        loop {
            match (keys.next(), vals.next()) {
                (None, None) => return Ok(tags),
                (Some(key), Some(val)) => {
                    let key = self.string(key.map_err(wire(what))?)?;
                    let val = self.string(val.map_err(wire(what))?)?;
                    tags.push((key, val));
                }
                _ => return Err(format!("{what} has unequal numbers of keys and values")),
            }
        }
    }
}

/// Reads a `PrimitiveBlock` and visits its elements in order.
fn read_block<'a>(data: &'a [u8], visit: &mut impl FnMut(Item<'a>)) -> Result<(), String> {
    let mut block = Block {
        strings: Vec::new(),
        granularity: 100,
        lat_offset: 0,
        lon_offset: 0,
    };
    let mut groups = Vec::new();
    for field in fields(data) {
        match field.map_err(wire("PrimitiveBlock"))? {
            (1, value) => {
                for string in fields(value.bytes().map_err(wire("StringTable"))?) {
                    if let (1, value) = string.map_err(wire("StringTable"))? {
                        block
                            .strings
                            .push(value.bytes().map_err(wire("StringTable"))?);
                    }
                }
            }
            (2, value) => groups.push(value.bytes().map_err(wire("PrimitiveGroup"))?),
            (17, value) => {
                // int32: the low 32 bits, two's complement.
                block.granularity = i64::from(value.varint().map_err(wire("granularity"))? as i32);
                if block.granularity <= 0 {
                    return Err(format!("granularity {} is not positive", block.granularity));
                }
            }
            (19, value) => block.lat_offset = value.varint().map_err(wire("lat_offset"))? as i64,
            (20, value) => block.lon_offset = value.varint().map_err(wire("lon_offset"))? as i64,
            _ => {}
        }
    }
    for group in groups {
        for field in fields(group) {
            match field.map_err(wire("PrimitiveGroup"))? {
                (1, value) => visit(read_node(&block, value.bytes().map_err(wire("Node"))?)?),
                (2, value) => {
                    read_dense(&block, value.bytes().map_err(wire("DenseNodes"))?, visit)?
                }
                (3, value) => visit(read_way(&block, value.bytes().map_err(wire("Way"))?)?),
                (4, value) => {
                    visit(read_relation(
                        &block,
                        value.bytes().map_err(wire("Relation"))?,
                    )?);
                }
                _ => {}
            }
        }
    }
    Ok(())
}

fn read_node<'a>(block: &Block<'a>, message: &'a [u8]) -> Result<Item<'a>, String> {
    let (mut id, mut lat, mut lon) = (None, None, None);
    for field in fields(message) {
        match field.map_err(wire("Node"))? {
            (1, value) => id = Some(value.sint().map_err(wire("Node id"))?),
            (8, value) => lat = Some(value.sint().map_err(wire("Node lat"))?),
            (9, value) => lon = Some(value.sint().map_err(wire("Node lon"))?),
            _ => {}
        }
    }
    let (Some(id), Some(lat), Some(lon)) = (id, lat, lon) else {
        return Err("a Node lacks its id, lat or lon".to_owned());
    };
    Ok(Item::Node {
        id,
        lat: block.degrees(block.lat_offset, lat)?,
        lon: block.degrees(block.lon_offset, lon)?,
        tags: block.tags(message, "Node")?,
    })
}

/// Visits the nodes of a `DenseNodes`: ids, latitudes and longitudes delta-coded in parallel
/// runs; tags in one run of `key, value, …, 0` per node (absent when no node has tags).
fn read_dense<'a>(
    block: &Block<'a>,
    message: &'a [u8],
    visit: &mut impl FnMut(Item<'a>),
) -> Result<(), String> {
    let mut ids = repeated(message, 1);
    let mut lats = repeated(message, 8);
    let mut lons = repeated(message, 9);
    let mut keys_vals = repeated(message, 10).peekable();
    let has_tags = keys_vals.peek().is_some();
    let (mut id, mut lat, mut lon) = (0i64, 0i64, 0i64);
    let delta = |sum: &mut i64, raw: Result<u64, WireError>| -> Result<(), String> {
        *sum = sum.wrapping_add(zigzag(raw.map_err(wire("DenseNodes"))?));
        Ok(())
    };
    loop {
        let (id_delta, lat_delta, lon_delta) = match (ids.next(), lats.next(), lons.next()) {
            (None, None, None) => break,
            (Some(a), Some(b), Some(c)) => (a, b, c),
            _ => return Err("DenseNodes has unequal numbers of ids, lats and lons".to_owned()),
        };
        delta(&mut id, id_delta)?;
        delta(&mut lat, lat_delta)?;
        delta(&mut lon, lon_delta)?;
        let mut tags = Vec::new();
        if has_tags {
            loop {
                let key = keys_vals
                    .next()
                    .ok_or("DenseNodes keys_vals ends before its last node")?
                    .map_err(wire("DenseNodes keys_vals"))?;
                if key == 0 {
                    break;
                }
                let val = keys_vals
                    .next()
                    .ok_or("DenseNodes keys_vals ends inside a tag")?
                    .map_err(wire("DenseNodes keys_vals"))?;
                tags.push((block.string(key)?, block.string(val)?));
            }
        }
        visit(Item::Node {
            id,
            lat: block.degrees(block.lat_offset, lat)?,
            lon: block.degrees(block.lon_offset, lon)?,
            tags,
        });
    }
    Ok(())
}

fn read_way<'a>(block: &Block<'a>, message: &'a [u8]) -> Result<Item<'a>, String> {
    let mut id = None;
    for field in fields(message) {
        if let (1, value) = field.map_err(wire("Way"))? {
            id = Some(value.varint().map_err(wire("Way id"))? as i64);
        }
    }
    let id = id.ok_or("a Way has no id")?;
    let mut node = 0i64;
    let refs = repeated(message, 8)
        .map(|raw| {
            node = node.wrapping_add(zigzag(raw.map_err(wire("Way refs"))?));
            Ok(node)
        })
        .collect::<Result<_, String>>()?;
    Ok(Item::Way {
        id,
        refs,
        tags: block.tags(message, "Way")?,
    })
}

fn read_relation<'a>(block: &Block<'a>, message: &'a [u8]) -> Result<Item<'a>, String> {
    let mut id = None;
    for field in fields(message) {
        if let (1, value) = field.map_err(wire("Relation"))? {
            id = Some(value.varint().map_err(wire("Relation id"))? as i64);
        }
    }
    let id = id.ok_or("a Relation has no id")?;
    let mut roles = repeated(message, 8);
    let mut member_ids = repeated(message, 9);
    let mut kinds = repeated(message, 10);
    let mut member = 0i64;
    let mut members = Vec::new();
    loop {
        let (role, member_id, kind) = match (roles.next(), member_ids.next(), kinds.next()) {
            (None, None, None) => break,
            (Some(a), Some(b), Some(c)) => (a, b, c),
            _ => {
                return Err(
                    "a Relation has unequal numbers of roles, member ids and types".to_owned(),
                );
            }
        };
        member = member.wrapping_add(zigzag(member_id.map_err(wire("Relation memids"))?));
        let kind = match kind.map_err(wire("Relation types"))? {
            0 => MemberKind::Node,
            1 => MemberKind::Way,
            2 => MemberKind::Relation,
            other => return Err(format!("relation member type {other} is not 0, 1 or 2")),
        };
        // roles_sid is int32: the low 32 bits; a negative index is outside the table.
        let role = role.map_err(wire("Relation roles_sid"))? as u32;
        members.push((kind, member, block.string(u64::from(role))?));
    }
    Ok(Item::Relation {
        id,
        members,
        tags: block.tags(message, "Relation")?,
    })
}
