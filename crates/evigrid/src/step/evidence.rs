//! The evidence a block is fused with: the map prior GG of each map context (SPEC §4) and the
//! sensor's evidence SG'_t = r(SG_t) ⊕ GG (SPEC §5 steps 1-2, eq 16-21), per cell in the compact
//! form the fusion needs, with the per-lane lookups by map context it is built with.

use super::lanes::any_lane;
use super::passes::{BLOCK, Lanes, Restrictions};
use crate::grids::{OMEGA, class};
use crate::map_prior::MAP_CONTEXTS;
use geodata::MapContext;

/// The number of map contexts, each with its prior (`MapContext` discriminants 0 to 4).
pub(super) const N_CONTEXTS: usize = MAP_CONTEXTS.len();

/// The GISGrid mass function of one map context, β on the focal set G and 1 − β on Ω (SPEC §4,
/// from [`prior_focal_set`](crate::map_prior::prior_focal_set) and
/// [`prior_beta`](crate::map_prior::prior_beta)), as the kernel applies it: its transfers, and
/// the indicators SG' needs as 0/1 factors. (Not [`MapPrior`](crate::map_prior::MapPrior),
/// which fills the GISGrid's contexts.)
#[derive(Clone, Copy, Debug)]
pub(super) struct ContextPrior {
    /// The focal set G.
    pub(super) g: usize,
    /// The transfers of m ∩ GG, for blocks on the reachable sets and for any block.
    pub(super) restriction: Restrictions,
    pub(super) beta: f32,
    /// [F ∈ G], [O ∩ G ≠ ∅], [G = {F}], [∅ ≠ G ⊆ O].
    pub(super) free_in_g: f32,
    pub(super) occupied_meets_g: f32,
    pub(super) g_is_free: f32,
    pub(super) g_within_occupied: f32,
}

impl ContextPrior {
    pub(super) fn new(g: usize, beta: f64) -> Self {
        let indicator = |condition: bool| if condition { 1.0 } else { 0.0 };
        ContextPrior {
            g,
            restriction: Restrictions::new(g),
            beta: beta as f32,
            free_in_g: indicator(g & class::F != 0),
            occupied_meets_g: indicator(g & class::O != 0),
            g_is_free: indicator(g == class::F),
            g_within_occupied: indicator(g != 0 && g & class::F == 0),
        }
    }

    /// Whether combining with this prior can change a mass function.
    pub(super) fn is_informative(&self) -> bool {
        self.g != OMEGA && self.beta > 0.0
    }
}

/// A Dempster conflict K between the sensor and the map at or above `1 − this` counts as total
/// (K = 1, SPEC §5 step 2): dividing by a smaller 1 − K would only amplify f32 rounding.
const TOTAL_CONFLICT_MARGIN: f32 = 1e-6;

/// SG'_t = r(SG_t) ⊕ GG of one cell: see [`SensorEvidence`].
#[derive(Clone, Copy, Debug)]
pub(super) struct CellEvidence {
    pub(super) free: f32,
    pub(super) occupied: f32,
    pub(super) omega: f32,
    pub(super) beta: f32,
    pub(super) conflict: f32,
    pub(super) inv_normaliser: f32,
    pub(super) sg_free: f32,
    pub(super) sg_occupied: f32,
    pub(super) observed: bool,
    pub(super) total_conflict: bool,
}

impl CellEvidence {
    /// From the SensorGrid masses and the map prior's
    /// `[β, [F ∈ G], [O ∩ G ≠ ∅], [G = {F}], [∅ ≠ G ⊆ O]]`.
    #[inline(always)]
    fn new(m_free: f32, m_occupied: f32, prior: [f32; 5]) -> Self {
        let [beta, in_f, meets_o, is_f, within_o] = prior;
        // A valid mass function whatever the input: NaN → 0 (`max` ignores NaN), sum ≤ 1.
        #[allow(clippy::manual_clamp, reason = "clamp keeps NaN; this turns it into 0")]
        let free = m_free.max(0.0).min(1.0);
        let occupied = m_occupied.max(0.0).min(1.0 - free);
        let omega = 1.0 - free - occupied;
        let conflict = beta * (free * (1.0 - in_f) + occupied * (1.0 - meets_o));
        let total = conflict >= 1.0 - TOTAL_CONFLICT_MARGIN;
        let (beta, conflict) = if total { (0.0, 0.0) } else { (beta, conflict) };
        let inv = 1.0 / (1.0 - conflict);
        CellEvidence {
            free,
            occupied,
            omega,
            beta,
            conflict,
            inv_normaliser: inv,
            sg_free: (free * (1.0 - beta) + free * beta * in_f + omega * beta * is_f) * inv,
            sg_occupied: (occupied * (1.0 - beta)
                + occupied * beta * meets_o
                + omega * beta * within_o)
                * inv,
            observed: free + occupied > 0.0,
            total_conflict: total,
        }
    }

    /// A cell the scan did not reach, in map context `prior`.
    pub(super) fn unobserved(prior: &ContextPrior) -> Self {
        let ContextPrior {
            beta,
            free_in_g,
            occupied_meets_g,
            g_is_free,
            g_within_occupied,
            ..
        } = *prior;
        let prior = [
            beta,
            free_in_g,
            occupied_meets_g,
            g_is_free,
            g_within_occupied,
        ];
        CellEvidence::new(0.0, 0.0, prior)
    }
}

/// SG'_t = r(SG_t) ⊕ GG per cell, in the compact form the fusion needs.
///
/// r(SG) has mass m_F on {F}, m_O on O = {I,U,S,M}, m_Ω on Ω (eq 16-20). GG has β on G, 1 − β on
/// Ω. Their conjunctive combination has m_F·β on {F}∩G, m_F(1 − β) on {F}, m_O·β on O∩G,
/// m_O(1 − β) on O, m_Ω·β on G, m_Ω(1 − β) on Ω; the conflict K is the part of m_F·β and m_O·β
/// whose intersection is empty, and Dempster's rule divides the rest by 1 − K (eq 9-11, 21).
pub(super) struct SensorEvidence {
    /// r(SG): m_F, m_O, m_Ω, after clamping to a valid mass function.
    pub(super) free: Lanes,
    pub(super) occupied: Lanes,
    pub(super) omega: Lanes,
    /// β of the cell's context; 0 where the conflict is total (then SG' = r(SG)).
    pub(super) beta: Lanes,
    /// K and 1 / (1 − K).
    pub(super) conflict: Lanes,
    pub(super) inv_normaliser: Lanes,
    /// m_SG'({F}) and m_SG'(O), the masses eq 22-23 multiply.
    pub(super) sg_free: Lanes,
    pub(super) sg_occupied: Lanes,
    /// Non-vacuous sensor grid (1) or not (0); total conflict (1) or not (0).
    pub(super) observed: [u8; BLOCK],
    pub(super) total_conflict: [u8; BLOCK],
    /// Bit c set when a cell of the block has map context c.
    pub(super) contexts_present: u8,
    /// Whether K > 0 in any cell of the block (outside building cells it is 0).
    pub(super) any_sensor_map_conflict: bool,
    /// Whether m_SG'({F}) ≠ 0 in any cell of the block (never where the scan saw nothing, with
    /// the map contexts there are).
    pub(super) any_sensor_free: bool,
    /// Whether any cell, or every cell, of the block has a non-vacuous SensorGrid.
    pub(super) any_observed: bool,
    pub(super) all_observed: bool,
}

impl SensorEvidence {
    pub(super) fn zeroed() -> Self {
        SensorEvidence {
            free: [0.0; BLOCK],
            occupied: [0.0; BLOCK],
            omega: [0.0; BLOCK],
            beta: [0.0; BLOCK],
            conflict: [0.0; BLOCK],
            inv_normaliser: [0.0; BLOCK],
            sg_free: [0.0; BLOCK],
            sg_occupied: [0.0; BLOCK],
            observed: [0; BLOCK],
            total_conflict: [0; BLOCK],
            contexts_present: 0,
            any_sensor_map_conflict: false,
            any_sensor_free: false,
            any_observed: false,
            all_observed: false,
        }
    }

    #[inline(always)]
    pub(super) fn fill(
        &mut self,
        m_free: &Lanes,
        m_occupied: &Lanes,
        context: &[MapContext; BLOCK],
        priors: &[ContextPrior; N_CONTEXTS],
        unobserved_evidence: &[CellEvidence; N_CONTEXTS],
    ) {
        let e = self;
        let mut present = 0u8;
        for &c in context {
            present |= 1 << (c as u8);
        }
        e.contexts_present = present;
        let one_context = present
            .is_power_of_two()
            .then(|| present.trailing_zeros() as usize);
        // (NaN and negative masses count as 0, as in `CellEvidence::new`.)
        let unobserved = !any_lane(m_free, |free| free > 0.0) && !any_lane(m_occupied, |o| o > 0.0);
        if unobserved {
            // A block the scan did not reach (most blocks of a large window): every cell has
            // SG' = GG of its context, computed once per step. A block inside one context takes
            // it as a broadcast; one across contexts (half the blocks in a city centre) takes each
            // context's in its cells, a vectorised select.
            match one_context {
                Some(c) => e.broadcast(&unobserved_evidence[c]),
                None => e.select_unobserved(context, present, unobserved_evidence),
            }
        } else {
            // The map prior of each cell, selected the same way.
            // The map prior of each cell: a broadcast inside one context, else a lookup in the
            // contexts' values by the three bits of the context (seven selects a value).
            let table = |field: fn(&ContextPrior) -> f32| priors.map(|prior| field(&prior));
            let bits = match one_context {
                Some(_) => [[0; BLOCK]; CONTEXT_BITS],
                None => context_bits(context),
            };
            let lanes = |values: [f32; N_CONTEXTS]| match one_context {
                Some(c) => [values[c]; BLOCK],
                None => lookup_by_context(&bits, values),
            };
            let beta = lanes(table(|p| p.beta));
            let in_f = lanes(table(|p| p.free_in_g));
            let meets_o = lanes(table(|p| p.occupied_meets_g));
            let is_f = lanes(table(|p| p.g_is_free));
            let within_o = lanes(table(|p| p.g_within_occupied));
            for i in 0..BLOCK {
                let v = CellEvidence::new(
                    m_free[i],
                    m_occupied[i],
                    [beta[i], in_f[i], meets_o[i], is_f[i], within_o[i]],
                );
                e.free[i] = v.free;
                e.occupied[i] = v.occupied;
                e.omega[i] = v.omega;
                e.beta[i] = v.beta;
                e.conflict[i] = v.conflict;
                e.inv_normaliser[i] = v.inv_normaliser;
                e.sg_free[i] = v.sg_free;
                e.sg_occupied[i] = v.sg_occupied;
                e.observed[i] = u8::from(v.observed);
                e.total_conflict[i] = u8::from(v.total_conflict);
            }
        }
        // Boolean reductions, kept out of the loop above: an in-order float sum there would
        // stop the compiler from vectorising it.
        e.any_sensor_map_conflict = any_lane(&e.conflict, |conflict| conflict > 0.0);
        e.any_sensor_free = any_lane(&e.sg_free, |free| free != 0.0);
        e.any_observed = any_lane(&e.observed, |observed| observed != 0);
        e.all_observed = !any_lane(&e.observed, |observed| observed == 0);
    }
}

impl SensorEvidence {
    /// Every lane set to the evidence `v`.
    #[inline(always)]
    fn broadcast(&mut self, v: &CellEvidence) {
        let e = self;
        e.free = [v.free; BLOCK];
        e.occupied = [v.occupied; BLOCK];
        e.omega = [v.omega; BLOCK];
        e.beta = [v.beta; BLOCK];
        e.conflict = [v.conflict; BLOCK];
        e.inv_normaliser = [v.inv_normaliser; BLOCK];
        e.sg_free = [v.sg_free; BLOCK];
        e.sg_occupied = [v.sg_occupied; BLOCK];
        e.observed = [u8::from(v.observed); BLOCK];
        e.total_conflict = [u8::from(v.total_conflict); BLOCK];
    }

    /// Each lane set to the evidence of a cell the scan did not reach in its map context, for
    /// a block whose cells are in the contexts of `present`.
    ///
    /// Without sensor mass, SG' = GG: m_F = m_O = K = 0, m_Ω = 1 and 1/(1 − K) = 1 in every
    /// context ([`CellEvidence::unobserved`] computes exactly these), so only β, m_SG'({F}) and
    /// m_SG'(O) can differ from cell to cell, and each is selected per context only where the
    /// contexts present disagree on it.
    #[inline(always)]
    fn select_unobserved(
        &mut self,
        context: &[MapContext; BLOCK],
        present: u8,
        evidence: &[CellEvidence; N_CONTEXTS],
    ) {
        let e = self;
        let any = &evidence[present.trailing_zeros() as usize];
        e.broadcast(any);
        let contexts = || (0..N_CONTEXTS).filter(move |&c| present & (1 << c) != 0);
        let bits = context_bits(context);
        // Each value that can vary, looked up by context where the contexts present disagree.
        let values = |v: &CellEvidence| [v.beta, v.sg_free, v.sg_occupied];
        for field in 0..3 {
            let differs = contexts()
                .any(|c| values(&evidence[c])[field].to_bits() != values(any)[field].to_bits());
            if differs {
                let lanes = lookup_by_context(&bits, evidence.each_ref().map(|v| values(v)[field]));
                match field {
                    0 => e.beta = lanes,
                    1 => e.sg_free = lanes,
                    _ => e.sg_occupied = lanes,
                }
            }
        }
    }
}

/// All bits set in the lanes chosen, none in the others.
type Mask = [u32; BLOCK];

/// Bits of a map context's discriminant the lookup reads.
const CONTEXT_BITS: usize = 3;
const _: () = assert!(N_CONTEXTS <= 1 << CONTEXT_BITS);

/// The three bits of each lane's map context (`MapContext` discriminants are 0 to 4), as masks.
#[inline(always)]
fn context_bits(context: &[MapContext; BLOCK]) -> [Mask; CONTEXT_BITS] {
    let mut bits = [[0; BLOCK]; CONTEXT_BITS];
    for i in 0..BLOCK {
        let c = context[i] as u8;
        for (bit, mask) in bits.iter_mut().enumerate() {
            mask[i] = if c & (1 << bit) != 0 { u32::MAX } else { 0 };
        }
    }
    bits
}

/// `values[context]` in each lane, with `bits` from [`context_bits`]: seven bit selects over
/// the eight values the bits can name (those past the last context repeat the first, never
/// picked).
#[inline(always)]
fn lookup_by_context(bits: &[Mask; CONTEXT_BITS], values: [f32; N_CONTEXTS]) -> Lanes {
    let v: [u32; 1 << CONTEXT_BITS] =
        std::array::from_fn(|c| values.get(c).unwrap_or(&values[0]).to_bits());
    let pick = |mask: u32, set: u32, clear: u32| (set & mask) | (clear & !mask);
    let mut lanes = [0.0; BLOCK];
    for i in 0..BLOCK {
        let [b0, b1, b2] = [bits[0][i], bits[1][i], bits[2][i]];
        let low = pick(b1, pick(b0, v[3], v[2]), pick(b0, v[1], v[0]));
        let high = pick(b1, pick(b0, v[7], v[6]), pick(b0, v[5], v[4]));
        lanes[i] = f32::from_bits(pick(b2, high, low));
    }
    lanes
}
