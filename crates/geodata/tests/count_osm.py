#!/usr/bin/env python3
"""Counts tagged OSM elements in an OSM XML file (.osm or .osm.gz), independently of geodata.

Usage: python3 count_osm.py FILE [FILE ...]   (prints one JSON object per file)

Standard library only (xml.etree). Counts, like the table in shared/README.md (pyosmium):
  building_ways       ways with a `building` tag whose value is not `no`
  building_relations  relations type=multipolygon with a `building` tag whose value is not `no`
  highway_ways        ways with any `highway` tag
  vehicle_road_ways   ways whose `highway` is a vehicle class of SPEC section 4
It also reports `building_ways_any_value` (building=* including `no`), what lies below the street
(`layer` < 0, `location=underground`, or a `tunnel` other than no/building_passage/
avalanche_protector without an explicit `layer` >= 0), which no street-level scanner sees:
  underground_road_ways       vehicle-road ways below the street
  underground_building_ways   building ways below the street
and what an extract cut at its border leaves usable, of what lies at street level:
  building_ways_complete      building ways that are closed, have >= 4 refs and all nodes present
  vehicle_road_ways_usable    vehicle-road ways with two consecutive present nodes somewhere
"""
import gzip
import json
import sys
import xml.etree.ElementTree as ET

VEHICLE = {
    "motorway", "trunk", "primary", "secondary", "tertiary", "unclassified", "residential",
    "service", "living_street", "motorway_link", "trunk_link", "primary_link", "secondary_link",
    "tertiary_link",
}


def underground(tags):
    """Whether the element lies below the street (geodata's `Level::Underground`)."""
    try:
        layer = int(tags.get("layer", "").strip())
    except ValueError:
        layer = None
    if (layer is not None and layer < 0) or tags.get("location") == "underground":
        return True
    tunnel = tags.get("tunnel", "no")
    return tunnel not in ("no", "building_passage", "avalanche_protector") and layer is None


def count(path):
    opener = gzip.open if path.endswith(".gz") else open
    counts = dict(building_ways=0, building_ways_any_value=0, building_relations=0,
                  highway_ways=0, vehicle_road_ways=0, building_ways_complete=0,
                  vehicle_road_ways_usable=0, underground_road_ways=0,
                  underground_building_ways=0)
    nodes = set()
    with opener(path, "rb") as stream:
        for _, element in ET.iterparse(stream, events=("end",)):
            if element.tag == "node":
                nodes.add(element.get("id"))
            if element.tag not in ("way", "relation"):
                continue
            refs = [nd.get("ref") for nd in element.findall("nd")]
            tags = {t.get("k"): t.get("v") for t in element.findall("tag")}
            building = tags.get("building")
            if element.tag == "way":
                if building is not None:
                    counts["building_ways_any_value"] += 1
                    if building != "no":
                        counts["building_ways"] += 1
                        if underground(tags):
                            counts["underground_building_ways"] += 1
                        elif len(refs) >= 4 and refs[0] == refs[-1] and all(r in nodes for r in refs):
                            counts["building_ways_complete"] += 1
                if "highway" in tags:
                    counts["highway_ways"] += 1
                    if tags["highway"] in VEHICLE:
                        counts["vehicle_road_ways"] += 1
                        present = [r in nodes for r in refs]
                        if underground(tags):
                            counts["underground_road_ways"] += 1
                        elif any(a and b for a, b in zip(present, present[1:])):
                            counts["vehicle_road_ways_usable"] += 1
            elif tags.get("type") == "multipolygon" and building not in (None, "no"):
                counts["building_relations"] += 1
            if element.tag in ("way", "relation"):
                element.clear()
    return counts


if __name__ == "__main__":
    for name in sys.argv[1:]:
        print(json.dumps({"file": name.rsplit("/", 1)[-1], **count(name)}))
