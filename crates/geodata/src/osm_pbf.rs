//! Reading OSM PBF (`.osm.pbf`), the compact binary format of planet extracts.

use std::io::Cursor;

use osmpbf::{BlobDecode, BlobReader, Element, RelMemberType};

use crate::error::MapError;
use crate::osm::OsmData;
use crate::tags::Roles;

/// Parses OSM PBF bytes into [`OsmData`].
///
/// # Errors
/// [`MapError::Pbf`] when a blob is truncated or corrupt; [`MapError::CoordinateOutOfRange`] for
/// a node outside WGS84 ranges.
pub(crate) fn read_osm_pbf(bytes: &[u8]) -> Result<OsmData, MapError> {
    let pbf_error = |e: osmpbf::Error| MapError::Pbf {
        message: e.to_string(),
    };
    let mut data = OsmData::default();
    let mut blobs = 0usize;
    for blob in BlobReader::new(Cursor::new(bytes)) {
        let blob = blob.map_err(pbf_error)?;
        blobs += 1;
        match blob.decode().map_err(pbf_error)? {
            BlobDecode::OsmHeader(header) => {
                if let Some(bbox) = header.bbox() {
                    // osmpbf's field docs swap top and bottom; order them by value instead.
                    data.set_bounds(
                        bbox.bottom.min(bbox.top),
                        bbox.left.min(bbox.right),
                        bbox.bottom.max(bbox.top),
                        bbox.left.max(bbox.right),
                    )?;
                }
            }
            BlobDecode::OsmData(block) => {
                let mut failure = None;
                block.for_each_element(|element| {
                    if failure.is_none()
                        && let Err(error) = read_element(element, &mut data)
                    {
                        failure = Some(error);
                    }
                });
                if let Some(error) = failure {
                    return Err(error);
                }
            }
            BlobDecode::Unknown(_) => {}
        }
    }
    if blobs == 0 {
        return Err(MapError::Pbf {
            message: "no blob in the file".to_owned(),
        });
    }
    Ok(data)
}

fn read_element(element: Element<'_>, data: &mut OsmData) -> Result<(), MapError> {
    match element {
        Element::Node(node) => data.add_node(node.id(), node.lat(), node.lon()),
        Element::DenseNode(node) => data.add_node(node.id(), node.lat(), node.lon()),
        Element::Way(way) => {
            let tags: Vec<(&str, &str)> = way.tags().collect();
            let roles =
                Roles::from_tags(|k| tags.iter().find(|(key, _)| *key == k).map(|(_, v)| *v));
            data.add_way(way.id(), way.refs().collect(), roles);
            Ok(())
        }
        Element::Relation(relation) => {
            let tags: Vec<(&str, &str)> = relation.tags().collect();
            let members: Vec<(i64, &str)> = relation
                .members()
                .filter(|m| m.member_type == RelMemberType::Way)
                .map(|m| (m.member_id, m.role().unwrap_or("")))
                .collect();
            data.add_relation(
                |k| tags.iter().find(|(key, _)| *key == k).map(|(_, v)| *v),
                members.into_iter(),
            );
            Ok(())
        }
    }
}
