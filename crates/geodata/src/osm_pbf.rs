//! Reading OSM PBF (`.osm.pbf`), the compact binary format of planet extracts, with an in-house
//! decoder: the file structure in `block`, the protocol-buffer wire format in `wire`.
//!
//! Why not a crate: `osmpbf` generates its protobuf code at build time (protobuf, its parser and
//! code generator), which was about 9 % of the CPU of the tool's first build, to read five message
//! types whose wire format fits in a page. `osmpbf` stays a dev-dependency: the tests below check
//! that both readers give the same nodes, ways, relations and tags, and the same grids, on every
//! shared `.osm.pbf`.

mod block;
mod wire;

use block::{Item, MemberKind, ReadError, read_items};

use crate::error::MapError;
use crate::osm::OsmData;
use crate::tags::Roles;

/// Parses OSM PBF bytes into [`OsmData`].
///
/// # Errors
/// [`MapError::Pbf`] when a blob is truncated, corrupt or uses what the reader does not support
/// (LZMA, LZ4 or zstd blobs, an unknown required feature); [`MapError::CoordinateOutOfRange`]
/// for a node or bounding box outside WGS84 ranges.
pub(crate) fn read_osm_pbf(bytes: &[u8]) -> Result<OsmData, MapError> {
    let mut data = OsmData::default();
    read_items(bytes, |item| add_item(item, &mut data)).map_err(|error| match error {
        ReadError::File(message) => MapError::Pbf { message },
        ReadError::Visit(error) => error,
    })?;
    Ok(data)
}

fn add_item(item: Item<'_>, data: &mut OsmData) -> Result<(), MapError> {
    match item {
        Item::Bounds {
            left,
            right,
            top,
            bottom,
        } => data.set_bounds(
            bottom.min(top),
            left.min(right),
            bottom.max(top),
            left.max(right),
        ),
        Item::Node { id, lat, lon, .. } => data.add_node(id, lat, lon),
        Item::Way { id, refs, tags } => {
            data.add_way(id, refs, Roles::from_tags(|k| tag(&tags, k)));
            Ok(())
        }
        Item::Relation { members, tags, .. } => {
            let ways = members
                .into_iter()
                .filter(|(kind, _, _)| *kind == MemberKind::Way)
                .map(|(_, id, role)| (id, role));
            data.add_relation(|k| tag(&tags, k), ways);
            Ok(())
        }
    }
}

/// The value of the first tag named `key`.
fn tag<'a>(tags: &[(&'a str, &'a str)], key: &str) -> Option<&'a str> {
    tags.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tiny protobuf writer for hand-made files.
    fn varint(out: &mut Vec<u8>, mut value: u64) {
        while value >= 0x80 {
            out.push((value as u8) | 0x80);
            value >>= 7;
        }
        out.push(value as u8);
    }

    fn zz(value: i64) -> u64 {
        ((value << 1) ^ (value >> 63)) as u64
    }

    fn number(out: &mut Vec<u8>, field: u64, value: u64) {
        varint(out, field << 3);
        varint(out, value);
    }

    fn bytes(out: &mut Vec<u8>, field: u64, content: &[u8]) {
        varint(out, (field << 3) | 2);
        varint(out, content.len() as u64);
        out.extend_from_slice(content);
    }

    fn packed(out: &mut Vec<u8>, field: u64, values: &[u64]) {
        let mut run = Vec::new();
        for &v in values {
            varint(&mut run, v);
        }
        bytes(out, field, &run);
    }

    /// `[length][BlobHeader][Blob]` with the data zlib-compressed (or raw).
    fn blob(kind: &str, data: &[u8], zlib: bool) -> Vec<u8> {
        let mut blob = Vec::new();
        if zlib {
            use std::io::Write;
            let mut encoder =
                flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            encoder.write_all(data).expect("in-memory write");
            number(&mut blob, 2, data.len() as u64);
            bytes(&mut blob, 3, &encoder.finish().expect("in-memory write"));
        } else {
            bytes(&mut blob, 1, data);
        }
        let mut header = Vec::new();
        bytes(&mut header, 1, kind.as_bytes());
        number(&mut header, 3, blob.len() as u64);
        let mut out = (header.len() as u32).to_be_bytes().to_vec();
        out.extend(header);
        out.extend(blob);
        out
    }

    fn header_block(features: &[&str]) -> Vec<u8> {
        let mut bbox = Vec::new();
        // left 24.9°, right 25.0°, top 60.2°, bottom 60.1°, in nanodegrees.
        for (field, nano) in [
            (1, 24_900_000_000i64),
            (2, 25_000_000_000),
            (3, 60_200_000_000),
            (4, 60_100_000_000),
        ] {
            number(&mut bbox, field, zz(nano));
        }
        let mut block = Vec::new();
        bytes(&mut block, 1, &bbox);
        for feature in features {
            bytes(&mut block, 4, feature.as_bytes());
        }
        block
    }

    /// String table ["", "building", "yes", "type", "multipolygon", "outer", "name", "x"];
    /// granularity 100, lat offset 1000; three dense nodes (one tagged name=x), a way of them
    /// tagged building=yes, a relation type=multipolygon, building=yes with the way (outer) and
    /// node 11 as members.
    fn data_block() -> Vec<u8> {
        let mut table = Vec::new();
        for s in [
            "",
            "building",
            "yes",
            "type",
            "multipolygon",
            "outer",
            "name",
            "x",
        ] {
            bytes(&mut table, 1, s.as_bytes());
        }
        let mut dense = Vec::new();
        // ids 10, 11, 13; lat (units of 100 nd) 601_000_000, +1_000, -500; lon 249_000_000, +0, +2.
        packed(&mut dense, 1, &[zz(10), zz(1), zz(2)]);
        packed(&mut dense, 8, &[zz(601_000_000), zz(1_000), zz(-500)]);
        packed(&mut dense, 9, &[zz(249_000_000), zz(0), zz(2)]);
        packed(&mut dense, 10, &[0, 6, 7, 0, 0]);
        let mut way = Vec::new();
        number(&mut way, 1, 100);
        packed(&mut way, 2, &[1]);
        packed(&mut way, 3, &[2]);
        packed(&mut way, 8, &[zz(10), zz(1), zz(2), zz(-3)]);
        let mut relation = Vec::new();
        number(&mut relation, 1, 7);
        packed(&mut relation, 2, &[3, 1]);
        packed(&mut relation, 3, &[4, 2]);
        packed(&mut relation, 8, &[5, 0]);
        packed(&mut relation, 9, &[zz(100), zz(-89)]);
        packed(&mut relation, 10, &[1, 0]);
        let mut group = Vec::new();
        bytes(&mut group, 2, &dense);
        bytes(&mut group, 3, &way);
        bytes(&mut group, 4, &relation);
        let mut block = Vec::new();
        bytes(&mut block, 1, &table);
        bytes(&mut block, 2, &group);
        number(&mut block, 17, 100);
        number(&mut block, 19, 1_000);
        block
    }

    fn file(zlib: bool) -> Vec<u8> {
        let mut file = blob(
            "OSMHeader",
            &header_block(&["OsmSchema-V0.6", "DenseNodes"]),
            zlib,
        );
        file.extend(blob("OSMData", &data_block(), zlib));
        file
    }

    fn items(bytes: &[u8]) -> Result<Vec<String>, String> {
        let mut seen = Vec::new();
        read_items(bytes, |item| {
            seen.push(format!("{item:?}"));
            Ok::<_, ()>(())
        })
        .map_err(|e| format!("{e:?}"))?;
        Ok(seen)
    }

    #[test]
    fn a_hand_made_file_decodes_to_hand_computed_elements() -> Result<(), String> {
        for zlib in [false, true] {
            let mut elements = Vec::new();
            read_items(&file(zlib), |item| {
                elements.push(match item {
                    Item::Bounds { .. } => "bounds".to_owned(),
                    Item::Node { id, lat, lon, tags } => {
                        format!("node {id} {lat:.7} {lon:.7} {tags:?}")
                    }
                    Item::Way { id, refs, tags } => format!("way {id} {refs:?} {tags:?}"),
                    Item::Relation { id, members, tags } => {
                        format!("relation {id} {members:?} {tags:?}")
                    }
                });
                Ok::<_, ()>(())
            })
            .map_err(|e| format!("{e:?}"))?;
            // lat = 1e-9 (1000 + 100 · 601_000_000) = 60.1000010°; + 100 000 nd per 1000 units.
            assert_eq!(
                elements,
                vec![
                    "bounds",
                    "node 10 60.1000010 24.9000000 []",
                    "node 11 60.1001010 24.9000000 [(\"name\", \"x\")]",
                    "node 13 60.1000510 24.9000002 []",
                    "way 100 [10, 11, 13, 10] [(\"building\", \"yes\")]",
                    "relation 7 [(Way, 100, \"outer\"), (Node, 11, \"\")] \
                     [(\"type\", \"multipolygon\"), (\"building\", \"yes\")]",
                ],
                "zlib {zlib}"
            );
        }
        Ok(())
    }

    #[test]
    fn the_hand_made_file_becomes_osm_data() -> Result<(), MapError> {
        let data = read_osm_pbf(&file(true))?;
        assert_eq!(data.nodes.len(), 3);
        assert_eq!(data.way_order, vec![100]);
        assert_eq!(data.multipolygons.len(), 1);
        assert_eq!(
            data.multipolygons[0].members.len(),
            1,
            "the node member is dropped"
        );
        let bounds = data.bounds.ok_or(MapError::Empty)?;
        assert_eq!((bounds.min().y, bounds.max().y), (60.1, 60.2));
        Ok(())
    }

    #[test]
    fn damaged_files_are_one_line_errors() {
        let good = file(true);
        let first_blob = blob(
            "OSMHeader",
            &header_block(&["OsmSchema-V0.6", "DenseNodes"]),
            true,
        );
        // Every truncation of the file but the one between its two blobs is an error, never a
        // panic.
        for end in (0..good.len()).filter(|&end| end != first_blob.len()) {
            let error = items(&good[..end]).expect_err("a truncated file is an error");
            assert!(!error.contains('\n'), "{error}");
        }
        // Every single-byte change either decodes or is an error, never a panic.
        for at in 0..good.len() {
            for byte in [0x00, 0x7f, 0x80, 0xff] {
                let mut bad = good.clone();
                bad[at] = byte;
                let _ = items(&bad);
            }
        }
    }

    #[test]
    fn hostile_lengths_are_refused_before_allocating() {
        // A BlobHeader of 1 GiB; a blob that claims 1 GiB; a zlib blob that claims 1 GiB raw.
        let mut huge_header = (1u32 << 30).to_be_bytes().to_vec();
        huge_header.extend_from_slice(b"\x0a\x07OSMData");
        assert!(items(&huge_header).is_err_and(|e| e.contains("over the format's 65536")));
        let mut header = Vec::new();
        bytes(&mut header, 1, b"OSMData");
        number(&mut header, 3, 1 << 30);
        let mut huge_blob = (header.len() as u32).to_be_bytes().to_vec();
        huge_blob.extend(header);
        assert!(items(&huge_blob).is_err_and(|e| e.contains("over the format's 33554432")));
        let mut claim = Vec::new();
        number(&mut claim, 2, 1 << 30);
        bytes(
            &mut claim,
            3,
            &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
        );
        let mut blob_header = Vec::new();
        bytes(&mut blob_header, 1, b"OSMData");
        number(&mut blob_header, 3, claim.len() as u64);
        let mut lying = (blob_header.len() as u32).to_be_bytes().to_vec();
        lying.extend(blob_header);
        lying.extend(claim);
        assert!(items(&lying).is_err_and(|e| e.contains("raw_size")));
    }

    #[test]
    fn a_zlib_blob_longer_than_its_raw_size_is_refused() {
        let mut file = blob("OSMData", &data_block(), true);
        // raw_size is the first field of the blob: make it one byte short. The blob's header
        // and the raw_size varint keep their lengths as long as the varint does.
        let size = data_block().len() as u64;
        let mut old = Vec::new();
        number(&mut old, 2, size);
        let mut new = Vec::new();
        number(&mut new, 2, size - 1);
        assert_eq!(old.len(), new.len());
        let at = file
            .windows(old.len())
            .position(|w| w == old.as_slice())
            .expect("raw_size field present");
        file[at..at + new.len()].copy_from_slice(&new);
        assert!(items(&file).is_err_and(|e| e.contains("raw_size says")));
    }

    #[test]
    fn unknown_required_features_and_other_compressions_are_named() {
        let needs = blob("OSMHeader", &header_block(&["Sort.Type_then_ID_x"]), false);
        assert!(items(&needs).is_err_and(|e| e.contains("Sort.Type_then_ID_x")));
        let mut zstd = Vec::new();
        bytes(&mut zstd, 7, b"....");
        let mut header = Vec::new();
        bytes(&mut header, 1, b"OSMData");
        number(&mut header, 3, zstd.len() as u64);
        let mut file = (header.len() as u32).to_be_bytes().to_vec();
        file.extend(header);
        file.extend(zstd);
        assert!(items(&file).is_err_and(|e| e.contains("zstd-compressed blobs")));
        assert!(items(b"").is_err_and(|e| e.contains("no blob")));
    }

    #[test]
    fn unknown_blob_types_are_skipped() -> Result<(), String> {
        let mut file = blob("OSMIndex", b"\xff\xff", false);
        file.extend(blob("OSMData", &data_block(), false));
        assert_eq!(items(&file)?.len(), 5);
        Ok(())
    }

    #[test]
    fn out_of_table_strings_and_unequal_runs_are_errors() {
        let mut table = Vec::new();
        bytes(&mut table, 1, b"");
        let mut way = Vec::new();
        number(&mut way, 1, 1);
        packed(&mut way, 2, &[5]);
        packed(&mut way, 3, &[0]);
        let mut dense = Vec::new();
        packed(&mut dense, 1, &[zz(1), zz(1)]);
        packed(&mut dense, 8, &[0]);
        packed(&mut dense, 9, &[0, 0]);
        for (field, element, expected) in [
            (
                3,
                way,
                "string index 5 outside the string table of 1 entries",
            ),
            (2, dense, "unequal numbers of ids, lats and lons"),
        ] {
            let mut group = Vec::new();
            bytes(&mut group, field, &element);
            let mut block = Vec::new();
            bytes(&mut block, 1, &table);
            bytes(&mut block, 2, &group);
            let result = items(&blob("OSMData", &block, false));
            assert!(
                result.as_ref().is_err_and(|e| e.contains(expected)),
                "{result:?}"
            );
        }
    }

    /// The same file read by `osmpbf` into the same [`OsmData`], the way the reader before this
    /// one did.
    fn read_with_osmpbf(bytes: &[u8]) -> OsmData {
        use osmpbf::{BlobDecode, BlobReader, Element, RelMemberType};
        let mut data = OsmData::default();
        for blob in BlobReader::new(std::io::Cursor::new(bytes)) {
            match blob
                .expect("osmpbf reads the blob")
                .decode()
                .expect("osmpbf decodes it")
            {
                BlobDecode::OsmHeader(header) => {
                    if let Some(b) = header.bbox() {
                        let bounds = data.set_bounds(
                            b.bottom.min(b.top),
                            b.left.min(b.right),
                            b.bottom.max(b.top),
                            b.left.max(b.right),
                        );
                        bounds.expect("valid bounds");
                    }
                }
                BlobDecode::OsmData(block) => block.for_each_element(|element| match element {
                    Element::Node(n) => data.add_node(n.id(), n.lat(), n.lon()).expect("node"),
                    Element::DenseNode(n) => data.add_node(n.id(), n.lat(), n.lon()).expect("node"),
                    Element::Way(way) => {
                        let tags: Vec<(&str, &str)> = way.tags().collect();
                        data.add_way(
                            way.id(),
                            way.refs().collect(),
                            Roles::from_tags(|k| tag(&tags, k)),
                        );
                    }
                    Element::Relation(relation) => {
                        let tags: Vec<(&str, &str)> = relation.tags().collect();
                        let members: Vec<(i64, &str)> = relation
                            .members()
                            .filter(|m| m.member_type == RelMemberType::Way)
                            .map(|m| (m.member_id, m.role().unwrap_or("")))
                            .collect();
                        data.add_relation(|k| tag(&tags, k), members.into_iter());
                    }
                }),
                BlobDecode::Unknown(_) => {}
            }
        }
        data
    }

    /// Every element as text (kind, id, coordinates to the bit, references, members, tags), in
    /// file order, from `osmpbf`.
    fn osmpbf_elements(bytes: &[u8]) -> Vec<String> {
        use osmpbf::{BlobDecode, BlobReader, Element, RelMemberType};
        let mut out = Vec::new();
        for blob in BlobReader::new(std::io::Cursor::new(bytes)) {
            let blob = blob.expect("osmpbf reads the blob");
            if let BlobDecode::OsmData(block) = blob.decode().expect("osmpbf decodes it") {
                block.for_each_element(|element| {
                    out.push(match element {
                        Element::Node(n) => node_text(n.id(), n.lat(), n.lon(), n.tags().collect()),
                        Element::DenseNode(n) => {
                            node_text(n.id(), n.lat(), n.lon(), n.tags().collect())
                        }
                        Element::Way(w) => {
                            let refs: Vec<i64> = w.refs().collect();
                            let tags: Vec<(&str, &str)> = w.tags().collect();
                            format!("way {} {refs:?} {tags:?}", w.id())
                        }
                        Element::Relation(r) => {
                            let members: Vec<(MemberKind, i64, &str)> = r
                                .members()
                                .map(|m| {
                                    let kind = match m.member_type {
                                        RelMemberType::Node => MemberKind::Node,
                                        RelMemberType::Way => MemberKind::Way,
                                        RelMemberType::Relation => MemberKind::Relation,
                                    };
                                    (kind, m.member_id, m.role().expect("role in the table"))
                                })
                                .collect();
                            let tags: Vec<(&str, &str)> = r.tags().collect();
                            format!("relation {} {members:?} {tags:?}", r.id())
                        }
                    });
                });
            }
        }
        out
    }

    fn node_text(id: i64, lat: f64, lon: f64, tags: Vec<(&str, &str)>) -> String {
        format!("node {id} {:x} {:x} {tags:?}", lat.to_bits(), lon.to_bits())
    }

    fn our_elements(bytes: &[u8]) -> Result<Vec<String>, String> {
        let mut out = Vec::new();
        read_items(bytes, |item| {
            match item {
                Item::Bounds { .. } => {}
                Item::Node { id, lat, lon, tags } => out.push(node_text(id, lat, lon, tags)),
                Item::Way { id, refs, tags } => out.push(format!("way {id} {refs:?} {tags:?}")),
                Item::Relation { id, members, tags } => {
                    out.push(format!("relation {id} {members:?} {tags:?}"));
                }
            }
            Ok::<_, ()>(())
        })
        .map_err(|e| format!("{e:?}"))?;
        Ok(out)
    }

    /// The shared `.osm.pbf` files, or none when the shared data is absent.
    fn shared_pbf_files() -> Vec<std::path::PathBuf> {
        let Some(dir) = crate::testdata::shared_dir() else {
            return Vec::new();
        };
        let mut files: Vec<_> = std::fs::read_dir(dir.join("data/osm"))
            .expect("the shared osm folder lists")
            .filter_map(|entry| entry.ok().map(|e| e.path()))
            .filter(|path| path.to_string_lossy().ends_with(".osm.pbf"))
            .collect();
        files.sort();
        assert!(!files.is_empty(), "no .osm.pbf in the shared data");
        files
    }

    #[test]
    fn every_shared_pbf_reads_as_osmpbf_reads_it() -> Result<(), String> {
        for path in shared_pbf_files() {
            let bytes = std::fs::read(&path).map_err(|e| e.to_string())?;
            let ours = our_elements(&bytes)?;
            let theirs = osmpbf_elements(&bytes);
            assert!(
                ours.len() > 1000,
                "{}: {} elements",
                path.display(),
                ours.len()
            );
            assert_eq!(ours.len(), theirs.len(), "{}", path.display());
            for (a, b) in ours.iter().zip(&theirs) {
                assert_eq!(a, b, "{}", path.display());
            }
        }
        Ok(())
    }

    #[test]
    fn every_shared_pbf_gives_the_grid_osmpbf_gives() -> Result<(), MapError> {
        use crate::load::{LoadOptions, MapFormat, project};
        use crate::raster::ContextRaster;
        for path in shared_pbf_files() {
            let bytes = std::fs::read(&path).map_err(|e| MapError::Pbf {
                message: e.to_string(),
            })?;
            let ours = read_osm_pbf(&bytes)?;
            let theirs = read_with_osmpbf(&bytes);
            assert!(ours == theirs, "{}: the OSM data differ", path.display());
            let grid = |data: OsmData| -> Result<_, MapError> {
                let loaded = project(
                    data.into_features(),
                    MapFormat::OsmPbf,
                    &LoadOptions::default(),
                )?;
                let (window, cells) = ContextRaster::new(&loaded.map).rasterise_extent(1.0);
                Ok((format!("{:?}", loaded.stats), format!("{window:?}"), cells))
            };
            let (our_stats, our_window, our_cells) = grid(ours)?;
            let (their_stats, their_window, their_cells) = grid(theirs)?;
            assert_eq!(our_stats, their_stats, "{}", path.display());
            assert_eq!(our_window, their_window, "{}", path.display());
            assert!(our_cells.len() > 100_000, "{}", path.display());
            assert!(
                our_cells == their_cells,
                "{}: the grids differ",
                path.display()
            );
        }
        Ok(())
    }
}
