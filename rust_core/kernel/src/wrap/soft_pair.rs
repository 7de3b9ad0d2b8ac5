//! Soft pairs: a layout vertex pulled toward a target point by a spring whose strength is the
//! pair's confidence, while the energy wrap is stiff, and let go before the local fit.
//!
//! They do not pull in the warm-up: there the data term is off and the anchors alone deform the
//! layout as rigidly as possible, so a pull acts as an anchor would and carries its whole region.
//! Measured on the heavy-old body with 4 anchors and its 3 proposals (both nipples, 0.5 % and
//! 0.8 % of the diagonal from their true points, and an ear; `benchmarks/few_anchors.py`): mean
//! error 0.506 % of the diagonal without them, 0.647 % with them pulling in the warm-up too,
//! 0.500 % in the stiff levels only.
//!
//! An anchor is met exactly. A pair found automatically (a tip of the layout matched to a tip of
//! the target) is only about as precise as the wrap itself, and sometimes wrong: held exactly it
//! would drag its neighbourhood off the surface. As a soft pair it helps where it is needed, in
//! the stiff levels that decide which part of the layout goes where, and the data term alone
//! places the vertex at the end.

use glam::Vec3;

/// A soft pair: a layout vertex, the point it is pulled toward and how firmly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SoftPair {
    /// The layout vertex.
    pub vertex: u32,
    /// The point it is pulled toward, in the target's space.
    pub target: Vec3,
    /// In `(0, 1]`: how sure the pair is; its pull is in proportion.
    pub confidence: f32,
}

/// The pull of a soft pair of confidence 1, against the shape terms' weight (1 per edge). Measured
/// on the benchmark bodies with 6 anchors and the proposals of confidence 0.7 or more
/// (`benchmarks/few_anchors.py`'s cases): 1, 3 and 10 gave mean errors within 0.02 % of the
/// diagonal of each other; with the proposals of confidence 0.5 or more, 10 was worse than 1 on
/// the heavy body (0.324 % against 0.261 %), whose proposals were 42 % wrong.
pub(crate) const SOFT_PAIR_WEIGHT: f64 = 3.0;
/// Soft pairs act in the levels whose data weight is below this (the stiff ones and the first
/// local one); from the first level at or above it, the data term alone pulls their
/// vertices. Letting go after the stiff levels alone (1) measured the same.
pub(crate) const SOFT_PAIR_RELEASE: f64 = 10.0;

/// Per vertex, its soft pair's target point and confidence (empty: none).
pub(crate) type SoftPairOfVertex = Vec<Option<(Vec3, f32)>>;

/// Replaces the correspondences of the vertices with a soft pair by their pair, at a weight such
/// that times `data_weight` it is [`SOFT_PAIR_WEIGHT`] × confidence; nothing when the level
/// releases them (`data_weight` at or above [`SOFT_PAIR_RELEASE`]).
pub(crate) fn pull_soft_pairs(
    soft_pairs: &[Option<(Vec3, f32)>],
    correspondences: &mut [Option<(f32, Vec3)>],
    data_weight: f64,
) {
    if data_weight >= SOFT_PAIR_RELEASE || data_weight <= 0.0 {
        return;
    }
    for (correspondence, pair) in correspondences.iter_mut().zip(soft_pairs) {
        if let Some((target, confidence)) = *pair {
            let weight = SOFT_PAIR_WEIGHT * f64::from(confidence) / data_weight;
            *correspondence = Some((weight as f32, target));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn soft_pairs_replace_correspondences_in_stiff_levels_only() {
        let pairs = vec![None, Some((Vec3::X, 0.5))];
        let mut correspondences = vec![Some((1.0, Vec3::Y)), Some((1.0, Vec3::Y))];
        pull_soft_pairs(&pairs, &mut correspondences, 0.1);
        assert_eq!(correspondences[0], Some((1.0, Vec3::Y)));
        let (weight, point) = correspondences[1].unwrap();
        assert_eq!(point, Vec3::X);
        assert!((f64::from(weight) * 0.1 - SOFT_PAIR_WEIGHT * 0.5).abs() < 1e-4);
        // Released: the data term alone.
        let mut released = vec![Some((1.0, Vec3::Y)), Some((1.0, Vec3::Y))];
        pull_soft_pairs(&pairs, &mut released, SOFT_PAIR_RELEASE);
        assert_eq!(released[1], Some((1.0, Vec3::Y)));
    }
}
