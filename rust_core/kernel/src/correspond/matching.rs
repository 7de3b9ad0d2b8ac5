//! Matching distinct points of the layout to distinct points of the target: the cost of a pair,
//! reciprocal best matches with a confidence, and the rejection of pairs that disagree with the
//! given anchors and with each other about distances.

use glam::Vec3;

/// A distinct point of one shape as the matcher sees it.
#[derive(Debug, Clone)]
pub(crate) struct Feature {
    /// The vertex on its own shape.
    pub vertex: u32,
    /// Where it is expected on the target: for a layout point, its current position corrected by
    /// the anchors' residuals; for a target point, itself.
    pub position: Vec3,
    /// Its unit normal (the layout's at its current position).
    pub normal: Vec3,
    /// Its protrusion at the small and the large radius.
    pub protrusion: [f32; 2],
    /// Its geodesic distance to each given anchor, over its shape's mean distance between anchors.
    pub geodesic: Vec<f32>,
}

/// The least cosine between a layout point's normal and a target point's for them to pair.
const MIN_NORMAL_AGREEMENT: f32 = 0.3;
/// The spread of each term of the cost (a pair off by this much in it costs 1).
const POSITION_SPREAD: f32 = 0.5; // of the search radius
const PROTRUSION_SPREAD: f32 = 0.35;
const GEODESIC_SPREAD: f32 = 0.2; // relative
/// The floor of the relative geodesic difference's denominator, in mean anchor distances: a point
/// next to an anchor is compared in absolute terms.
const GEODESIC_FLOOR: f32 = 0.05;
/// The largest median |log| of distance ratios a pair may have to its nearest references
/// (anchors and other pairs) before it is rejected as an outlier: 0.3 is a 35 % stretch.
pub(crate) const MAX_INCONSISTENCY: f32 = 0.3;
/// The spread of the consistency factor of the confidence.
const INCONSISTENCY_SPREAD: f32 = 0.2;
/// The cost at which a match's agreement factor is 1/e (a right pair across a change of
/// proportions typically costs 1 to 4).
const CONFIDENCE_COST: f32 = 6.0;
/// How many nearest references the consistency of a pair is measured against.
const REFERENCES: usize = 6;

/// What pairing `layout` with `target` costs (0 for a perfect agreement; about 1 per term off by
/// its spread), or `None` when they cannot pair: farther apart than `radius`, of opposite kinds
/// (a tip and a pit), or facing different ways.
pub(crate) fn pair_cost(layout: &Feature, target: &Feature, radius: f32) -> Option<f32> {
    let distance = layout.position.distance(target.position);
    if distance > radius
        || layout.protrusion[0].signum() != target.protrusion[0].signum()
        || layout.normal.dot(target.normal) < MIN_NORMAL_AGREEMENT
    {
        return None;
    }
    let position = (distance / (POSITION_SPREAD * radius)).powi(2);
    let protrusion: f32 = layout
        .protrusion
        .iter()
        .zip(target.protrusion)
        .map(|(a, b)| ((a - b) / PROTRUSION_SPREAD).powi(2))
        .sum();
    let geodesic = if layout.geodesic.is_empty() {
        0.0
    } else {
        let sum: f32 = layout
            .geodesic
            .iter()
            .zip(&target.geodesic)
            .map(|(&a, &b)| {
                let relative = if a.is_finite() && b.is_finite() {
                    (a - b) / (0.5 * (a + b) + GEODESIC_FLOOR)
                } else {
                    1.0
                };
                (relative / GEODESIC_SPREAD).powi(2)
            })
            .sum();
        sum / layout.geodesic.len() as f32
    };
    Some(position + protrusion + geodesic)
}

/// A reciprocal match: layout feature `layout` (index into the layout list) and target feature
/// `target`, with its confidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Match {
    pub layout: usize,
    pub target: usize,
    pub confidence: f32,
}

/// The reciprocal best matches: pairs each of which is the other's cheapest partner. The
/// confidence is `exp(−cost / 2)` (how well they agree) times `1 − exp(−margin)` (how much better
/// they are than the next candidate of either: ambiguity lowers it; no competitor leaves it 1).
pub(crate) fn reciprocal_matches(
    layout: &[Feature],
    target: &[Feature],
    radius: f32,
) -> Vec<Match> {
    use rayon::prelude::*;
    let costs: Vec<Vec<(usize, f32)>> = layout
        .par_iter()
        .map(|l| {
            target
                .iter()
                .enumerate()
                .filter_map(|(t, feature)| pair_cost(l, feature, radius).map(|c| (t, c)))
                .collect()
        })
        .collect();
    // Each target feature's cheapest and second cheapest layout partner.
    let mut by_target = vec![(usize::MAX, f32::INFINITY, f32::INFINITY); target.len()];
    for (l, row) in costs.iter().enumerate() {
        for &(t, cost) in row {
            let entry = &mut by_target[t];
            if cost < entry.1 {
                *entry = (l, cost, entry.1);
            } else if cost < entry.2 {
                entry.2 = cost;
            }
        }
    }
    let mut matches = Vec::new();
    for (l, row) in costs.iter().enumerate() {
        let mut best = (usize::MAX, f32::INFINITY);
        let mut second = f32::INFINITY;
        for &(t, cost) in row {
            if cost < best.1 {
                second = best.1;
                best = (t, cost);
            } else if cost < second {
                second = cost;
            }
        }
        let (t, cost) = best;
        if t == usize::MAX || by_target[t].0 != l {
            continue;
        }
        let competitor = second.min(by_target[t].2);
        let margin = if competitor.is_finite() {
            1.0 - (-(competitor - cost)).exp()
        } else {
            1.0
        };
        matches.push(Match {
            layout: l,
            target: t,
            confidence: (-cost / CONFIDENCE_COST).exp() * margin,
        });
    }
    matches
}

/// The pairs left after rejecting those whose distances to their nearest references disagree
/// between the shapes, worst first, one at a time, until none exceeds [`MAX_INCONSISTENCY`].
/// References are the anchors (`anchor_rest[i]` on the layout at rest, `anchor_target[i]`) and
/// the other pairs still kept; distances on the target are compared with those at rest times
/// `scale` (the anchors' median ratio). Only references at least `min_separation` away at rest
/// count (nearby points' ratios are noise). Returns, for each kept pair, its index in `pairs` and
/// its confidence factor `exp(−(e / 0.2)²)` for its median |log ratio| `e`.
pub(crate) fn consistent_pairs(
    pairs_rest: &[Vec3],
    pairs_target: &[Vec3],
    anchor_rest: &[Vec3],
    anchor_target: &[Vec3],
    scale: f32,
    min_separation: f32,
) -> Vec<(usize, f32)> {
    let mut kept: Vec<usize> = (0..pairs_rest.len()).collect();
    loop {
        let errors: Vec<f32> = kept
            .iter()
            .map(|&k| {
                let mut references: Vec<(f32, f32)> = anchor_rest
                    .iter()
                    .zip(anchor_target)
                    .map(|(&r, &t)| (r, t))
                    .chain(
                        kept.iter()
                            .filter(|&&j| j != k)
                            .map(|&j| (pairs_rest[j], pairs_target[j])),
                    )
                    .filter_map(|(rest, target)| {
                        let at_rest = rest.distance(pairs_rest[k]);
                        (at_rest >= min_separation).then(|| {
                            let ratio = target.distance(pairs_target[k]) / (scale * at_rest);
                            (at_rest, ratio.max(1e-6).ln().abs())
                        })
                    })
                    .collect();
                if references.is_empty() {
                    return 0.0;
                }
                references.sort_by(|a, b| a.0.total_cmp(&b.0));
                references.truncate(REFERENCES);
                let mut logs: Vec<f32> = references.iter().map(|r| r.1).collect();
                logs.sort_by(f32::total_cmp);
                logs[logs.len() / 2]
            })
            .collect();
        let worst = errors
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(index, &error)| (index, error));
        match worst {
            Some((index, error)) if error > MAX_INCONSISTENCY => {
                kept.remove(index);
            }
            _ => {
                return kept
                    .into_iter()
                    .zip(errors)
                    .map(|(k, e)| (k, (-(e / INCONSISTENCY_SPREAD).powi(2)).exp()))
                    .collect();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feature(vertex: u32, position: Vec3, protrusion: f32, geodesic: Vec<f32>) -> Feature {
        Feature {
            vertex,
            position,
            normal: Vec3::Z,
            protrusion: [protrusion, protrusion * 0.5],
            geodesic,
        }
    }

    #[test]
    fn identical_features_cost_nothing_and_incompatible_ones_cannot_pair() {
        let a = feature(0, Vec3::ZERO, 0.6, vec![1.0, 2.0]);
        assert_eq!(pair_cost(&a, &a, 1.0), Some(0.0));
        let far = feature(1, Vec3::new(2.0, 0.0, 0.0), 0.6, vec![1.0, 2.0]);
        assert_eq!(pair_cost(&a, &far, 1.0), None);
        let pit = feature(2, Vec3::ZERO, -0.6, vec![1.0, 2.0]);
        assert_eq!(pair_cost(&a, &pit, 1.0), None);
        let mut facing_away = a.clone();
        facing_away.normal = -Vec3::Z;
        assert_eq!(pair_cost(&a, &facing_away, 1.0), None);
        let elsewhere = feature(3, Vec3::ZERO, 0.6, vec![1.5, 2.0]);
        assert!(pair_cost(&a, &elsewhere, 1.0).unwrap() > 1.0);
    }

    #[test]
    fn matches_are_reciprocal_and_ambiguity_lowers_confidence() {
        let layout = vec![
            feature(0, Vec3::ZERO, 0.6, vec![1.0]),
            feature(1, Vec3::new(0.5, 0.0, 0.0), 0.6, vec![1.3]),
        ];
        let target = vec![
            feature(10, Vec3::new(0.02, 0.0, 0.0), 0.6, vec![1.0]),
            feature(11, Vec3::new(0.5, 0.0, 0.0), 0.6, vec![1.3]),
        ];
        let matches = reciprocal_matches(&layout, &target, 1.0);
        assert_eq!(matches.len(), 2);
        assert!(matches.iter().all(|m| m.layout == m.target));
        // Two equally good targets for one layout point: the margin is zero.
        let twins = vec![
            feature(10, Vec3::new(0.1, 0.0, 0.0), 0.6, vec![1.0]),
            feature(11, Vec3::new(-0.1, 0.0, 0.0), 0.6, vec![1.0]),
        ];
        let matches = reciprocal_matches(&layout[..1], &twins, 1.0);
        assert_eq!(matches.len(), 1);
        assert!(matches[0].confidence < 1e-3, "{:?}", matches);
    }

    #[test]
    fn a_pair_that_breaks_the_distances_is_rejected() {
        let anchors_rest = [Vec3::ZERO, Vec3::X * 10.0, Vec3::Y * 10.0, Vec3::Z * 10.0];
        let anchors_target = anchors_rest.map(|p| p * 2.0);
        let pairs_rest = [Vec3::splat(3.0), Vec3::new(6.0, 1.0, 2.0)];
        // The first pair lands where the doubling puts it; the second far off.
        let pairs_target = [Vec3::splat(6.0), Vec3::new(-5.0, 9.0, 1.0)];
        let kept = consistent_pairs(
            &pairs_rest,
            &pairs_target,
            &anchors_rest,
            &anchors_target,
            2.0,
            1.0,
        );
        assert_eq!(kept.len(), 1);
        assert_eq!(kept[0].0, 0);
        assert!(kept[0].1 > 0.99);
    }
}
