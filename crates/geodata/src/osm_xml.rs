//! Reading OSM XML (`.osm`), the format of the OSM API and of JOSM.

use quick_xml::Reader;
use quick_xml::XmlVersion;
use quick_xml::events::{BytesStart, Event};

use crate::error::MapError;
use crate::osm::OsmData;
use crate::tags::Roles;

/// The element whose children are being read.
enum Parent {
    None,
    Way {
        id: i64,
        refs: Vec<i64>,
        tags: Vec<(String, String)>,
    },
    Relation {
        members: Vec<(i64, String)>,
        tags: Vec<(String, String)>,
    },
    Other,
}

/// Parses OSM XML into [`OsmData`].
///
/// # Errors
/// [`MapError::Xml`] for malformed XML (including a document cut short), a root element other
/// than `<osm>`, or a missing/unparsable `id`, `lat`, `lon` or `ref`;
/// [`MapError::CoordinateOutOfRange`] for a node outside WGS84 ranges.
pub(crate) fn read_osm_xml(bytes: &[u8]) -> Result<OsmData, MapError> {
    let mut reader = Reader::from_reader(bytes);
    let mut data = OsmData::default();
    let mut parent = Parent::None;
    let mut depth = 0usize;
    let mut seen_root = false;
    loop {
        let position = reader.buffer_position();
        let event = reader.read_event().map_err(|e| MapError::Xml {
            position: reader.buffer_position(),
            message: e.to_string(),
        })?;
        let xml_error = |message: String| MapError::Xml { position, message };
        match event {
            Event::Start(ref element) | Event::Empty(ref element) => {
                let is_empty = matches!(event, Event::Empty(_));
                if depth == 0 {
                    if seen_root || element.name().as_ref() != "osm" {
                        return Err(xml_error(format!(
                            "root element is <{}>, expected <osm>",
                            element.name().as_ref()
                        )));
                    }
                    seen_root = true;
                } else {
                    read_element(element, depth, &mut parent, &mut data).map_err(|e| match e {
                        ElementError::Map(error) => error,
                        ElementError::Message(message) => xml_error(message),
                    })?;
                    if is_empty && depth == 1 {
                        finish(std::mem::replace(&mut parent, Parent::None), &mut data);
                    }
                }
                if !is_empty {
                    depth += 1;
                }
            }
            Event::End(_) => {
                depth = depth.saturating_sub(1);
                if depth == 1 {
                    finish(std::mem::replace(&mut parent, Parent::None), &mut data);
                }
            }
            Event::Eof => {
                if !seen_root {
                    return Err(xml_error("no <osm> element".to_owned()));
                }
                if depth != 0 {
                    return Err(xml_error(
                        "document ends before </osm>: truncated file?".to_owned(),
                    ));
                }
                return Ok(data);
            }
            Event::Text(ref text) if depth == 0 && !text.trim().is_empty() => {
                return Err(xml_error("text outside the root element".to_owned()));
            }
            _ => {}
        }
    }
}

enum ElementError {
    Map(MapError),
    Message(String),
}

impl From<MapError> for ElementError {
    fn from(error: MapError) -> Self {
        Self::Map(error)
    }
}

/// Handles one start (or empty) element below the root.
fn read_element(
    element: &BytesStart<'_>,
    depth: usize,
    parent: &mut Parent,
    data: &mut OsmData,
) -> Result<(), ElementError> {
    let name = element.name();
    let name = name.as_ref();
    if depth == 1 {
        *parent = match name {
            "node" => {
                let id = number::<i64>(element, "id")?;
                data.add_node(id, number(element, "lat")?, number(element, "lon")?)?;
                Parent::Other
            }
            "way" => Parent::Way {
                id: number(element, "id")?,
                refs: Vec::new(),
                tags: Vec::new(),
            },
            "relation" => Parent::Relation {
                members: Vec::new(),
                tags: Vec::new(),
            },
            "bounds" => {
                data.set_bounds(
                    number(element, "minlat")?,
                    number(element, "minlon")?,
                    number(element, "maxlat")?,
                    number(element, "maxlon")?,
                )?;
                Parent::Other
            }
            _ => Parent::Other,
        };
        return Ok(());
    }
    match (name, parent) {
        ("nd", Parent::Way { refs, .. }) => refs.push(number(element, "ref")?),
        ("tag", Parent::Way { tags, .. } | Parent::Relation { tags, .. }) => {
            tags.push((text(element, "k")?, text(element, "v")?));
        }
        // Node and relation members play no part in a multipolygon's rings.
        ("member", Parent::Relation { members, .. })
            if text(element, "type").is_ok_and(|kind| kind == "way") =>
        {
            members.push((
                number(element, "ref")?,
                text(element, "role").unwrap_or_default(),
            ));
        }
        _ => {}
    }
    Ok(())
}

/// Stores a completed way or relation.
fn finish(parent: Parent, data: &mut OsmData) {
    match parent {
        Parent::Way { id, refs, tags } => {
            let roles = Roles::from_tags(|k| lookup(&tags, k));
            data.add_way(id, refs, roles);
        }
        Parent::Relation { members, tags } => {
            data.add_relation(
                |k| lookup(&tags, k),
                members.iter().map(|(way, role)| (*way, role.as_str())),
            );
        }
        Parent::None | Parent::Other => {}
    }
}

fn lookup<'a>(tags: &'a [(String, String)], key: &str) -> Option<&'a str> {
    tags.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

/// An attribute's value, unescaped.
fn text(element: &BytesStart<'_>, key: &str) -> Result<String, ElementError> {
    for attribute in element.attributes() {
        let attribute = attribute.map_err(|e| ElementError::Message(e.to_string()))?;
        if attribute.key.as_ref() == key {
            return attribute
                .normalized_value(XmlVersion::Implicit1_0)
                .map(|v| v.into_owned())
                .map_err(|e| ElementError::Message(e.to_string()));
        }
    }
    Err(ElementError::Message(format!(
        "<{}> has no {} attribute",
        element.name().as_ref(),
        key
    )))
}

/// An attribute's value parsed as a number.
fn number<T: std::str::FromStr>(element: &BytesStart<'_>, key: &str) -> Result<T, ElementError> {
    let value = text(element, key)?;
    value.trim().parse().map_err(|_| {
        ElementError::Message(format!(
            "<{}> {}=\"{value}\" is not a number",
            element.name().as_ref(),
            key
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::SkipReason;

    const SMALL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6">
  <bounds minlat="60.0" minlon="24.0" maxlat="60.01" maxlon="24.02"/>
  <node id="1" lat="60.001" lon="24.001"/>
  <node id="2" lat="60.001" lon="24.002"/>
  <node id="3" lat="60.002" lon="24.002"/>
  <node id="4" lat="60.002" lon="24.001"/>
  <node id="5" lat="60.005" lon="24.005"/>
  <way id="10"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
    <tag k="building" v="yes"/></way>
  <way id="11"><nd ref="1"/><nd ref="99"/><nd ref="3"/><nd ref="5"/>
    <tag k="highway" v="residential"/><tag k="name" v="A &amp; B"/></way>
  <way id="12"><nd ref="2"/><nd ref="5"/><tag k="highway" v="footway"/></way>
  <way id="13"><nd ref="1"/><nd ref="98"/><nd ref="3"/><nd ref="1"/><tag k="building" v="yes"/></way>
  <way id="20"><nd ref="1"/><nd ref="2"/><nd ref="3"/></way>
  <way id="21"><nd ref="3"/><nd ref="4"/><nd ref="1"/></way>
  <relation id="30"><member type="way" ref="20" role="outer"/><member type="way" ref="21" role="outer"/>
    <tag k="type" v="multipolygon"/><tag k="building" v="yes"/></relation>
  <relation id="31"><member type="way" ref="77" role="outer"/>
    <tag k="type" v="multipolygon"/><tag k="building" v="yes"/></relation>
</osm>"#;

    #[test]
    fn reads_ways_relations_and_counts_what_is_missing() -> Result<(), MapError> {
        let features = read_osm_xml(SMALL.as_bytes())?.into_features();
        assert_eq!(features.source_counts.building_ways, 2);
        assert_eq!(features.source_counts.building_relations, 2);
        assert_eq!(features.source_counts.highway_ways, 2);
        assert_eq!(features.source_counts.vehicle_road_ways, 1);
        assert_eq!(features.buildings.len(), 2, "way 10 and relation 30");
        // Road 11 loses node 99: the run 3-5 survives.
        assert_eq!(features.roads.len(), 1);
        assert_eq!(features.roads[0].line.0.len(), 2);
        assert_eq!(
            features.skipped.get(&SkipReason::RoadWayPartlyMissing),
            Some(&1)
        );
        assert_eq!(
            features.skipped.get(&SkipReason::AreaWayMissingNodes),
            Some(&1)
        );
        assert_eq!(
            features.skipped.get(&SkipReason::RelationMissingMembers),
            Some(&1)
        );
        assert!(features.declared_bounds.is_some());
        Ok(())
    }

    #[test]
    fn malformed_xml_is_an_error() {
        let truncated = &SMALL[..SMALL.len() / 2];
        assert!(matches!(
            read_osm_xml(truncated.as_bytes()),
            Err(MapError::Xml { .. })
        ));
        let mismatched = "<osm><node id=\"1\" lat=\"0\" lon=\"0\"></way></osm>";
        assert!(matches!(
            read_osm_xml(mismatched.as_bytes()),
            Err(MapError::Xml { .. })
        ));
        let not_osm = "<gpx></gpx>";
        assert!(matches!(
            read_osm_xml(not_osm.as_bytes()),
            Err(MapError::Xml { .. })
        ));
        let bad_number = "<osm><node id=\"1\" lat=\"north\" lon=\"0\"/></osm>";
        assert!(matches!(
            read_osm_xml(bad_number.as_bytes()),
            Err(MapError::Xml { .. })
        ));
        let out_of_range = "<osm><node id=\"1\" lat=\"91\" lon=\"0\"/></osm>";
        assert!(matches!(
            read_osm_xml(out_of_range.as_bytes()),
            Err(MapError::CoordinateOutOfRange { lat, .. }) if lat == 91.0
        ));
    }
}
