//! Colour vision deficiency: simulated dichromat vision and a perceptual colour distance, to
//! check that a palette's classes stay apart for the 1 in 12 men who see colour differently.
//!
//! Simulation after Machado, Oliveira & Fernandes (2009), severity 1 (full dichromacy): a 3 × 3
//! matrix applied to linear RGB. Distance is CIE76 ΔE in CIELAB (D65): about 2.3 is a just
//! noticeable difference, and colours more than about 20 apart are told apart at a glance.

/// A kind of dichromacy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Deficiency {
    /// Normal colour vision (the identity).
    None,
    /// No M cones (green-blind), the commonest.
    Deuteranopia,
    /// No L cones (red-blind).
    Protanopia,
    /// No S cones (blue-blind), rare.
    Tritanopia,
}

impl Deficiency {
    /// Every kind, normal vision first.
    pub const ALL: [Self; 4] = [
        Self::None,
        Self::Deuteranopia,
        Self::Protanopia,
        Self::Tritanopia,
    ];

    /// Machado et al. (2009), Table 1, severity 1.0, rows acting on linear (R, G, B).
    fn matrix(self) -> [[f64; 3]; 3] {
        match self {
            Self::None => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            Self::Deuteranopia => [
                [0.367_322, 0.860_646, -0.227_968],
                [0.280_085, 0.672_501, 0.047_413],
                [-0.011_820, 0.042_940, 0.968_881],
            ],
            Self::Protanopia => [
                [0.152_286, 1.052_583, -0.204_868],
                [0.114_503, 0.786_281, 0.099_216],
                [-0.003_882, -0.048_116, 1.051_998],
            ],
            Self::Tritanopia => [
                [1.255_528, -0.076_749, -0.178_779],
                [-0.078_411, 0.930_809, 0.147_602],
                [0.004_733, 0.691_367, 0.303_900],
            ],
        }
    }
}

/// sRGB component (0–255) to linear light (0–1).
fn to_linear(c: u8) -> f64 {
    let c = f64::from(c) / 255.0;
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The colour as seen with `deficiency`, in CIELAB (D65 white).
pub fn simulated_lab(rgb: [u8; 3], deficiency: Deficiency) -> [f64; 3] {
    let lin = rgb.map(to_linear);
    let m = deficiency.matrix();
    let [r, g, b] =
        m.map(|row| (row[0] * lin[0] + row[1] * lin[1] + row[2] * lin[2]).clamp(0.0, 1.0));
    // Linear sRGB to XYZ (D65), then to L*a*b*.
    let x = 0.412_456_4 * r + 0.357_576_1 * g + 0.180_437_5 * b;
    let y = 0.212_672_9 * r + 0.715_152_2 * g + 0.072_175_0 * b;
    let z = 0.019_333_9 * r + 0.119_192_0 * g + 0.950_304_1 * b;
    let f = |t: f64| {
        if t > 0.008_856 {
            t.cbrt()
        } else {
            7.787 * t + 16.0 / 116.0
        }
    };
    let (fx, fy, fz) = (f(x / 0.950_47), f(y), f(z / 1.088_83));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// CIE76 ΔE between two colours as seen with `deficiency`.
pub fn delta_e(a: [u8; 3], b: [u8; 3], deficiency: Deficiency) -> f64 {
    let (la, lb) = (simulated_lab(a, deficiency), simulated_lab(b, deficiency));
    la.iter()
        .zip(&lb)
        .map(|(p, q)| (p - q) * (p - q))
        .sum::<f64>()
        .sqrt()
}

/// The smallest ΔE between any two of `colours` as seen with `deficiency` (infinite for fewer
/// than two colours).
pub fn min_pairwise_delta_e(colours: &[[u8; 3]], deficiency: Deficiency) -> f64 {
    let mut min = f64::INFINITY;
    for (i, a) in colours.iter().enumerate() {
        for b in &colours[i + 1..] {
            min = min.min(delta_e(*a, *b, deficiency));
        }
    }
    min
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::views::ClassColours;

    /// Unknown and the five classes F, I, U, S, M: the colours a decision map shows.
    fn decided(c: &ClassColours) -> Vec<[u8; 3]> {
        let mut v = vec![c.unknown];
        v.extend(c.classes);
        v
    }

    /// Base64 (RFC 4648, padded) back to bytes.
    fn unbase64(text: &str) -> Vec<u8> {
        let value = |c: u8| match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            _ => 63,
        };
        let mut out = Vec::new();
        for chunk in text.as_bytes().chunks(4) {
            let n = chunk
                .iter()
                .take_while(|&&c| c != b'=')
                .fold((0u32, 0), |(n, k), &c| {
                    (n | u32::from(value(c)) << (18 - 6 * k), k + 1)
                });
            out.extend_from_slice(&n.0.to_be_bytes()[1..n.1]);
        }
        out
    }

    #[test]
    fn every_code_of_every_output_has_a_legend_entry_in_the_one_colour() {
        use crate::figure::{Legend, class_name};
        use crate::frame::{STRIP_LABELS, strip_entries, strip_name};
        use crate::georef::{GIS_COLOURS, gis_colour};
        use crate::views::COLOURS;
        use evigrid::{Label, PerceptionGrid, Window};

        assert_eq!(unbase64("Zm9vYg=="), b"foob");
        let decided: Vec<Label> = Label::ALL
            .into_iter()
            .filter(|&l| l != Label::Edge)
            .collect();
        // Figures: every decided class and O (the baselines' unresolved occupied).
        let figure = Legend::classes(&COLOURS, true, "");
        let pignistic = Legend::pignistic(&COLOURS, "");
        for &label in &decided {
            let entry = (COLOURS.of(label), class_name(label).to_owned());
            assert!(figure.entries.contains(&entry), "figure legend: {label:?}");
            if label != Label::O {
                assert!(pignistic.entries.contains(&entry), "pignistic: {label:?}");
            }
        }
        // The pignistic view's mixtures have a key: F and M half each is their mean colour.
        let f_m = crate::figure::mixed_colour(&COLOURS, &[Label::F, Label::M]);
        assert_eq!(f_m, [107, 126, 58]);
        assert!(pignistic.entries.iter().any(|(c, _)| *c == f_m));
        // Per-frame pictures: the strip names every code a decision map holds.
        let strip = strip_entries(&COLOURS);
        assert_eq!(STRIP_LABELS.len(), decided.len());
        for &label in &decided {
            assert!(
                strip.contains(&(COLOURS.of(label), strip_name(label))),
                "{label:?}"
            );
        }
        // GeoTIFF and georeferenced PNG: every code in the palette, in the same colour (free
        // a little see-through, unknown the transparent no-data).
        for label in Label::ALL {
            let [r, g, b, _] = gis_colour(label);
            assert_eq!([r, g, b], COLOURS.of(label), "GIS {label:?}");
            assert!(GIS_COLOURS.iter().any(|(l, _)| *l == label));
        }
        // The Foxglove grid: every cell carries its class's colour in red, green, blue.
        let window = Window::new(decided.len(), 1, 0.5).unwrap();
        let pg = PerceptionGrid::new(decided.len(), 1);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let mut recorder = crate::mcap::McapRecorder::create(&path, None).unwrap();
        recorder
            .write_frame(&crate::mcap::McapFrame {
                time_s: 1.0,
                window: &window,
                decisions: &decided,
                perception: &pg,
                world_from_sensor: &evigrid::IsometryMatrix3::identity(),
                points_in_sensor: &[],
                intensity: &[],
                sensor_height_m: 0.0,
                fix: None,
            })
            .unwrap();
        recorder.finish(None).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let grid: serde_json::Value = ::mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .find(|m| m.channel.topic == crate::mcap::TOPIC_DECISION)
            .map(|m| serde_json::from_slice(&m.data).unwrap())
            .unwrap();
        let offset = |name: &str| {
            grid["fields"]
                .as_array()
                .unwrap()
                .iter()
                .find(|f| f["name"] == name)
                .and_then(|f| f["offset"].as_u64())
                .unwrap() as usize
        };
        let stride = grid["cell_stride"].as_u64().unwrap() as usize;
        let data = unbase64(grid["data"].as_str().unwrap());
        for (k, &label) in decided.iter().enumerate() {
            let cell = &data[k * stride..(k + 1) * stride];
            assert_eq!(cell[offset("class")], label as u8);
            let rgb = [
                cell[offset("red")],
                cell[offset("green")],
                cell[offset("blue")],
            ];
            assert_eq!(rgb, COLOURS.of(label), "Foxglove {label:?}");
        }
    }

    #[test]
    fn lab_of_white_black_and_a_known_colour() {
        let white = simulated_lab([255, 255, 255], Deficiency::None);
        assert!((white[0] - 100.0).abs() < 0.01 && white[1].abs() < 0.05 && white[2].abs() < 0.05);
        assert_eq!(simulated_lab([0, 0, 0], Deficiency::None), [0.0, 0.0, 0.0]);
        // sRGB red is L* 53.24, a* 80.09, b* 67.20 (CIE76 references).
        let red = simulated_lab([255, 0, 0], Deficiency::None);
        assert!((red[0] - 53.24).abs() < 0.1, "{red:?}");
        assert!((red[1] - 80.09).abs() < 0.3, "{red:?}");
        assert!((red[2] - 67.20).abs() < 0.3, "{red:?}");
        // Greys are the same for every dichromat (each matrix row sums to 1).
        for d in Deficiency::ALL {
            assert!(delta_e([128, 128, 128], [128, 128, 128], d) < 1e-9);
            assert!(delta_e([90, 90, 90], [128, 128, 128], Deficiency::None) > 10.0);
        }
    }

    #[test]
    fn red_and_green_merge_for_a_deuteranope() {
        // The classic confusion pair: clearly apart for normal vision, close without M cones.
        let (red, green) = ([200, 60, 40], [90, 120, 30]);
        assert!(delta_e(red, green, Deficiency::None) > 40.0);
        assert!(delta_e(red, green, Deficiency::Deuteranopia) < 20.0);
    }

    #[test]
    fn okabe_ito_classes_stay_apart_for_dichromats_and_the_old_blues_did_not() {
        // 20 ΔE: told apart at a glance. The Okabe–Ito assignment keeps every pair of unknown
        // F I U S M above it for normal, deutan and protan vision (min 24.8 by this code), and
        // above 15 even for tritanopes.
        let readable = decided(&ClassColours::OKABE_ITO);
        for d in [
            Deficiency::None,
            Deficiency::Deuteranopia,
            Deficiency::Protanopia,
        ] {
            let min = min_pairwise_delta_e(&readable, d);
            println!("Okabe-Ito, {d:?}: smallest ΔE {min:.1}");
            assert!(min > 20.0, "{d:?}: {min}");
        }
        let tritan = min_pairwise_delta_e(&readable, Deficiency::Tritanopia);
        println!("Okabe-Ito, Tritanopia: smallest ΔE {tritan:.1}");
        assert!(tritan > 15.0, "{tritan}");
        // The three blues of FIVE_CLASSES fall below it for a deuteranope (issue 16).
        let old = decided(&ClassColours::FIVE_CLASSES);
        for d in Deficiency::ALL {
            let min = min_pairwise_delta_e(&old, d);
            println!("FIVE_CLASSES, {d:?}: smallest ΔE {min:.1}");
        }
        assert!(min_pairwise_delta_e(&old, Deficiency::Deuteranopia) < 20.0);
        assert_eq!(
            min_pairwise_delta_e(&old[..1], Deficiency::None),
            f64::INFINITY
        );
    }
}
