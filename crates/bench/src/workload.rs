//! Deterministic random grids for timing and for checking the kernel against the naive step.

use crate::naive::NaiveGrid;
use evigrid::{GisGrid, Params, PerceptionGrid, SensorGrid};
use geodata::MapContext;

/// SplitMix64: a tiny deterministic generator, so a bench run is the same on every machine.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform f32 in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A SensorGrid like a scan's: a third of the cells free (μ_F), a tenth occupied (μ_O), a tenth
/// with an arbitrary {F, O} pair, the rest unobserved.
pub fn random_sensor_grid(width: usize, height: usize, rng: &mut SplitMix64) -> SensorGrid {
    let mut sg = SensorGrid::new(width, height);
    for idx in 0..sg.len() {
        let (free, occupied) = match rng.next_u64() % 30 {
            0..=9 => (0.7, 0.0),
            10..=12 => (0.0, 0.8),
            13..=15 => {
                let free = rng.next_f32();
                (free, rng.next_f32() * (1.0 - free))
            }
            _ => (0.0, 0.0),
        };
        sg.m_free_mut()[idx] = free;
        sg.m_occupied_mut()[idx] = occupied;
    }
    sg
}

/// A GisGrid with every context, in runs of a few cells as a real map gives.
pub fn random_gis_grid(width: usize, height: usize, rng: &mut SplitMix64) -> GisGrid {
    let mut gg = GisGrid::new(width, height);
    let contexts = [
        MapContext::Unknown,
        MapContext::Other,
        MapContext::Road,
        MapContext::Building,
    ];
    let mut current = MapContext::Other;
    for context in gg.context.iter_mut() {
        if rng.next_u64().is_multiple_of(8) {
            current = contexts[(rng.next_u64() % 4) as usize];
        }
        *context = current;
    }
    gg
}

/// Runs `steps` steps of both the library kernel and the naive step on the same random
/// `cells`-cell grid, with a fresh random scan each step, and returns the largest absolute
/// difference of any mass, ζ or conflict mass seen along the way.
pub fn max_difference_after_steps(params: &Params, cells: usize, steps: usize, seed: u64) -> f32 {
    let mut rng = SplitMix64::new(seed);
    let gg = random_gis_grid(cells, 1, &mut rng);
    let mut pg = PerceptionGrid::new(cells, 1);
    let mut naive = NaiveGrid::from_perception(&pg);
    let mut worst: f32 = 0.0;
    for _ in 0..steps {
        let sg = random_sensor_grid(cells, 1, &mut rng);
        evigrid::step(&mut pg, &sg, &gg, params, 0.1);
        naive.step(&sg, &gg, params, 0.1);
        for (idx, cell) in naive.cells.iter().enumerate() {
            let library = pg.cell_masses(idx);
            for (a, b) in library.iter().zip(&cell.m) {
                worst = worst.max((a - b).abs());
            }
            worst = worst
                .max((pg.zeta()[idx] - cell.zeta).abs())
                .max((pg.conflict_fo()[idx] - cell.conflict_fo).abs())
                .max((pg.conflict_of()[idx] - cell.conflict_of).abs());
        }
    }
    worst
}
