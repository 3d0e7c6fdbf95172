//! The variants an evaluation compares, by name: evigrid's methods and the baselines.

use serde::{Deserialize, Serialize};

use crate::EvalError;

/// A method to evaluate. Adding one: a variant here, its name in [`Variant::name`], its place
/// in [`Variant::ALL`], its method in the runner, and [`Variant::uses_map`] if it fuses the map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Variant {
    /// The paper's method (Kurdej et al. 2013), equation for equation SPEC §5, with the map
    /// prior. Named `full` before the name said whose method it is (`full` is still read).
    #[serde(rename = "kurdej2013", alias = "full")]
    Kurdej2013,
    /// evigrid without a map.
    #[serde(rename = "no-map")]
    NoMap,
    /// evigrid with the map prior and the motion stage ([`evigrid::Method::Evigrid`]).
    #[serde(rename = "evigrid")]
    Evigrid,
    /// Moras et al. 2011 two-class evidential grid.
    #[serde(rename = "moras2011")]
    Moras2011,
    /// OctoMap-style log-odds grid.
    #[serde(rename = "log-odds")]
    LogOdds,
}

impl Variant {
    /// All variants, in report order.
    pub const ALL: [Variant; 5] = [
        Variant::Evigrid,
        Variant::Kurdej2013,
        Variant::NoMap,
        Variant::Moras2011,
        Variant::LogOdds,
    ];
    /// The name used on command lines and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Kurdej2013 => "kurdej2013",
            Variant::NoMap => "no-map",
            Variant::Evigrid => "evigrid",
            Variant::Moras2011 => "moras2011",
            Variant::LogOdds => "log-odds",
        }
    }
    /// Former names still accepted by [`Variant::parse`], with what they now mean.
    pub const DEPRECATED_NAMES: [(&'static str, Variant); 1] = [("full", Variant::Kurdej2013)];
    /// Parses a name, or a deprecated name ([`Variant::DEPRECATED_NAMES`]).
    ///
    /// # Errors
    /// [`EvalError::UnknownVariant`] for any other name.
    pub fn parse(name: &str) -> Result<Self, EvalError> {
        Self::ALL
            .into_iter()
            .find(|v| v.name() == name)
            .or_else(|| {
                Self::DEPRECATED_NAMES
                    .iter()
                    .find(|(old, _)| *old == name)
                    .map(|&(_, v)| v)
            })
            .ok_or_else(|| EvalError::UnknownVariant {
                name: name.to_string(),
                expected: Self::ALL.map(Variant::name).join(", "),
            })
    }
    /// True if the variant fuses the map prior (only those need the front end's GISGrid).
    pub fn uses_map(self) -> bool {
        matches!(self, Variant::Kurdej2013 | Variant::Evigrid)
    }
}
