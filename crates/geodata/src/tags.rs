//! Which OSM tags make a building, a road surface or a parking area (SPEC §4), road widths, and
//! whether an element lies at street level.
//!
//! The same rules read OSM elements and GeoJSON feature properties, so a map cropped to GeoJSON
//! reads back with the same result.

/// Width of one traffic lane, metres (SPEC §4: `lanes` × 3.25 m).
pub const LANE_WIDTH_M: f64 = 3.25;

/// Widest `width` tag taken at face value, metres; larger values are treated as tagging errors
/// and the class default is used instead (the widest real carriageways are about 50 m).
const MAX_PLAUSIBLE_WIDTH_M: f64 = 60.0;

/// Most lanes taken at face value; more is a tagging error.
const MAX_PLAUSIBLE_LANES: u32 = 16;

/// Default carriageway width of a vehicle road class when neither `width` nor `lanes` is tagged,
/// metres; `None` for a class that does not carry vehicles (footway, cycleway, path, steps,
/// pedestrian, track, …).
///
/// # Sources
/// The paper gives none (SPEC §4 asks for "a default per class"). These are typical European
/// carriageway widths (kerb to kerb), chosen as whole lanes of [`LANE_WIDTH_M`] plus margins:
///
/// | class | width | reasoning |
/// | --- | --- | --- |
/// | motorway, trunk | 7.5 m | one OSM way per carriageway: 2 lanes + hard strip |
/// | primary, secondary | 7.0 m | 2 lanes + kerb margins |
/// | tertiary | 6.5 m | 2 lanes |
/// | residential, unclassified | 5.5 m | narrow 2-lane street |
/// | living_street | 4.5 m | shared space, 1 wide lane |
/// | service | 3.5 m | 1 lane (driveway, parking aisle) |
/// | `*_link` | 4.0 m | 1 lane + margin |
///
/// By default these values are used; tag `width` or `lanes` in the map to override them.
pub fn default_road_width_m(highway: &str) -> Option<f64> {
    let width = match highway {
        "motorway" | "trunk" => 7.5,
        "primary" | "secondary" => 7.0,
        "tertiary" => 6.5,
        "residential" | "unclassified" => 5.5,
        "living_street" => 4.5,
        "service" => 3.5,
        "motorway_link" | "trunk_link" | "primary_link" | "secondary_link" | "tertiary_link" => 4.0,
        _ => return None,
    };
    Some(width)
}

/// True for `highway` values that carry vehicles (SPEC §4): motorway, trunk, primary, secondary,
/// tertiary, unclassified, residential, service, living_street and the `*_link` types.
pub fn is_vehicle_road(highway: &str) -> bool {
    default_road_width_m(highway).is_some()
}

/// Width of a vehicle road, metres: the `width` tag, else `lanes` × [`LANE_WIDTH_M`], else
/// [`default_road_width_m`]. Unparsable or implausible tags fall through to the next rule.
/// `None` when `highway` is not a vehicle road.
///
/// ```
/// use geodata::tags::road_width_m;
/// assert_eq!(road_width_m("residential", Some("8 m"), Some("4")), Some(8.0));
/// assert_eq!(road_width_m("residential", None, Some("4")), Some(13.0));
/// assert_eq!(road_width_m("residential", Some("wide"), None), Some(5.5));
/// assert_eq!(road_width_m("footway", Some("3"), None), None);
/// ```
pub fn road_width_m(
    highway: &str,
    width_tag: Option<&str>,
    lanes_tag: Option<&str>,
) -> Option<f64> {
    let default = default_road_width_m(highway)?;
    if let Some(width) = width_tag.and_then(parse_width_m) {
        return Some(width);
    }
    if let Some(lanes) = lanes_tag.and_then(parse_lanes) {
        return Some(f64::from(lanes) * LANE_WIDTH_M);
    }
    Some(default)
}

/// Parses an OSM `width` value in metres: `"7"`, `"7.5"`, `"7,5"`, `"7 m"`, `"7.5m"`.
///
/// Imperial values (`7'6"`, `"20 ft"`) and anything else return `None`, as do widths that are not
/// in (0, 60] m.
pub fn parse_width_m(value: &str) -> Option<f64> {
    let trimmed = value.trim();
    let number = trimmed
        .strip_suffix('m')
        .map(str::trim_end)
        .unwrap_or(trimmed)
        .replace(',', ".");
    let width: f64 = number.parse().ok()?;
    (width.is_finite() && width > 0.0 && width <= MAX_PLAUSIBLE_WIDTH_M).then_some(width)
}

/// Parses an OSM `lanes` value: a positive whole number up to 16.
pub fn parse_lanes(value: &str) -> Option<u32> {
    let lanes: u32 = value.trim().parse().ok()?;
    (1..=MAX_PLAUSIBLE_LANES).contains(&lanes).then_some(lanes)
}

/// Where an element lies against the street a scanner on it sees (OSM's `layer`, `location`,
/// `tunnel`, `covered`). The map is what a street-level scanner meets: what lies below the street
/// is not in it, and a road under a roof at street level is open road.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Level {
    /// At street level in the open: no tag says otherwise (a bridge, `layer` > 0, is open road to
    /// a scanner on it).
    #[default]
    Open,
    /// At street level under a roof: `tunnel=building_passage` (an archway through a building) or
    /// `avalanche_protector`, `covered=*` other than `no`, or a `tunnel` whose explicit `layer` is
    /// 0 or above. Drivable, and the building over it has no wall there at a scanner's height.
    Covered,
    /// Below the street: `layer` < 0, `location=underground`, or `tunnel=*` other than `no`,
    /// `building_passage` and `avalanche_protector` without an explicit `layer` ≥ 0 (OSM places
    /// a tunnel below the ground unless its layer says otherwise).
    Underground,
}

impl Level {
    /// The level its tags give an element.
    ///
    /// ```
    /// use geodata::tags::Level;
    /// let level = |tags: &[(&str, &str)]| {
    ///     Level::from_tags(|k| tags.iter().find(|(key, _)| *key == k).map(|(_, v)| *v))
    /// };
    /// assert_eq!(level(&[("tunnel", "yes")]), Level::Underground);
    /// assert_eq!(level(&[("tunnel", "building_passage")]), Level::Covered);
    /// assert_eq!(level(&[("tunnel", "yes"), ("layer", "0")]), Level::Covered);
    /// assert_eq!(level(&[("layer", "-1")]), Level::Underground);
    /// assert_eq!(level(&[("layer", "1"), ("bridge", "yes")]), Level::Open);
    /// ```
    pub fn from_tags<'a>(tag: impl Fn(&str) -> Option<&'a str>) -> Self {
        let layer = tag("layer").and_then(parse_layer);
        if layer.is_some_and(|l| l < 0) || tag("location") == Some("underground") {
            return Self::Underground;
        }
        match tag("tunnel") {
            None | Some("no") => {}
            Some("building_passage" | "avalanche_protector") => return Self::Covered,
            Some(_) if layer.is_some() => return Self::Covered,
            Some(_) => return Self::Underground,
        }
        if tag("covered").is_some_and(|v| v != "no") {
            return Self::Covered;
        }
        Self::Open
    }
}

/// Parses an OSM `layer` value: a whole number, `"-1"`, `"+1"`, `" 0 "`; anything else (a list
/// `"-1;0"`, `"ground"`) is `None`, as if untagged.
pub fn parse_layer(value: &str) -> Option<i32> {
    value.trim().parse().ok()
}

/// What an OSM element (or GeoJSON feature) contributes to the map, judged by its tags alone.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Roles {
    /// `building=*` other than `building=no`.
    pub building: bool,
    /// `highway=*` with a vehicle class: the class.
    pub vehicle_road: Option<String>,
    /// Any `highway=*` (for counting).
    pub highway: bool,
    /// `area:highway=*` with a vehicle class (footway, pedestrian … areas are not road): the class.
    pub road_area: Option<String>,
    /// `area=yes`: a closed `highway` way is a surface, not a loop of centreline.
    pub area_yes: bool,
    /// `amenity=parking` that is not underground.
    pub parking: bool,
    /// The `width` tag, if any.
    pub width: Option<String>,
    /// The `lanes` tag, if any.
    pub lanes: Option<String>,
    /// Where it lies against the street (below it, the element contributes nothing).
    pub level: Level,
}

impl Roles {
    /// Reads the roles from a tag lookup.
    pub fn from_tags<'a>(tag: impl Fn(&str) -> Option<&'a str>) -> Self {
        let highway = tag("highway");
        Self {
            building: tag("building").is_some_and(|v| v != "no"),
            vehicle_road: highway
                .filter(|class| is_vehicle_road(class))
                .map(str::to_owned),
            highway: highway.is_some(),
            road_area: tag("area:highway")
                .filter(|class| is_vehicle_road(class))
                .map(str::to_owned),
            area_yes: tag("area") == Some("yes"),
            // Underground parking is not surface a vehicle on the street can see or drive on.
            parking: tag("amenity") == Some("parking") && tag("parking") != Some("underground"),
            width: tag("width").map(str::to_owned),
            lanes: tag("lanes").map(str::to_owned),
            level: Level::from_tags(&tag),
        }
    }

    /// True when the element lies below the street, where no street-level scanner sees it: it is
    /// neither building nor road surface in the map.
    pub fn is_underground(&self) -> bool {
        self.level == Level::Underground
    }

    /// True when the element is an area of road surface (area:highway, parking, or a vehicle
    /// `highway` explicitly tagged `area=yes`).
    pub fn is_road_surface_area(&self) -> bool {
        self.road_area_class().is_some() || self.parking
    }

    /// The vehicle class of a road-surface area: the `area:highway` value, else the `highway`
    /// value of a way tagged `area=yes`.
    pub fn road_area_class(&self) -> Option<&str> {
        self.road_area
            .as_deref()
            .or(self.vehicle_road.as_deref().filter(|_| self.area_yes))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn width_rules_in_order() {
        // width tag wins, then lanes × 3.25 m (3 × 3.25 = 9.75), then the class default.
        assert_eq!(road_width_m("primary", Some("12.5"), Some("3")), Some(12.5));
        assert_eq!(road_width_m("primary", None, Some("3")), Some(9.75));
        assert_eq!(road_width_m("primary", None, None), Some(7.0));
        assert_eq!(road_width_m("primary_link", None, None), Some(4.0));
        assert_eq!(road_width_m("service", Some("0"), Some("x")), Some(3.5));
    }

    #[test]
    fn width_parsing() {
        assert_eq!(parse_width_m("7,5"), Some(7.5));
        assert_eq!(parse_width_m(" 6 m "), Some(6.0));
        assert_eq!(parse_width_m("6m"), Some(6.0));
        assert_eq!(parse_width_m("20'"), None);
        assert_eq!(parse_width_m("NaN"), None);
        assert_eq!(parse_width_m("500"), None);
        assert_eq!(parse_lanes("2"), Some(2));
        assert_eq!(parse_lanes("0"), None);
        assert_eq!(parse_lanes("2;3"), None);
    }

    #[test]
    fn non_vehicle_ways_are_not_road() {
        for class in [
            "footway",
            "cycleway",
            "path",
            "steps",
            "pedestrian",
            "track",
            "bridleway",
        ] {
            assert!(!is_vehicle_road(class), "{class}");
        }
        for class in [
            "motorway",
            "trunk_link",
            "living_street",
            "unclassified",
            "service",
        ] {
            assert!(is_vehicle_road(class), "{class}");
        }
    }

    #[test]
    fn roles_from_tags() {
        let tags = [
            ("building", "no"),
            ("amenity", "parking"),
            ("parking", "underground"),
        ];
        let roles = Roles::from_tags(|k| tags.iter().find(|(key, _)| *key == k).map(|(_, v)| *v));
        assert!(!roles.building);
        assert!(!roles.parking);
        let tags = [
            ("area:highway", "footway"),
            ("highway", "pedestrian"),
            ("area", "yes"),
        ];
        let roles = Roles::from_tags(|k| tags.iter().find(|(key, _)| *key == k).map(|(_, v)| *v));
        assert!(!roles.is_road_surface_area());
        assert!(roles.highway);
    }
}
