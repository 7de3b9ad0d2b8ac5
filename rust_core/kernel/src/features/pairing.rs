//! Pairing the layout's feature lines with the target's feature curves, under the current fit.
//!
//! For each layout line (its vertices where the fit has them now) and each target curve of a kind
//! it may follow (a ridge for a convex crease, a valley for a concave one, a hole's border for a
//! border, any curve for a marked line across a smooth region), every line vertex is projected to
//! the nearest point of the curve. The curve is a candidate when
//!
//! - **close**: the mean projection distance is within the maximum distance, and at least
//!   [`MIN_NEAR_FRACTION`] of the vertices are within it;
//! - **parallel**: the mean `|cos|` between each line edge and the chord of the curve between the
//!   projections of the edge's ends is at least the cosine of the maximum angle;
//! - **the same length within reason**: the stretch of curve between the projections of the
//!   line's ends (unrolled along a closed curve) is at least [`MIN_LENGTH_RATIO`] of the line's
//!   length and at most its inverse.
//!
//! Its confidence is the product of the three measures, each from 0 to 1: `1 − mean distance /
//! maximum distance`, the mean `|cos|` rescaled so that the maximum angle gives 0, and the ratio
//! of the shorter of the two lengths to the longer. Each line takes its most confident candidate
//! at or above the minimum confidence; lines are then accepted from the most confident down, and
//! one whose stretch of curve overlaps (by more than [`MAX_OVERLAP`] of its length) a stretch
//! already taken stays free, as do lines without a candidate. A curve known only to within some
//! accuracy (a crest traced on a rounded crease) does not pair a line that already lies within
//! that accuracy of it: the curve would be no better a reference than the fit itself; an exact
//! curve (a sharp crease of the target's own edges, accuracy 0) pairs any line close enough. A
//! paired line's target is its stretch of curve in the line's direction (a closed line: the whole
//! loop from the projection of its first vertex, the chain then ending on its first vertex again). An open line's end that
//! another line shares (a junction, such as a box's corner where three creases meet) is left out
//! of its chain, so that no vertex follows two curves, and so are the vertices of a line beyond an
//! end of an open curve (projecting onto that end as the one before them does).

use std::collections::HashMap;

use glam::Vec3;

use crate::error::KernelError;
use crate::layout::{FeatureLine, LineKind};
use crate::validate::{self, SettingRange, check_setting};

/// The share of a line's vertices that must lie within the maximum distance of the curve.
pub const MIN_NEAR_FRACTION: f32 = 0.8;
/// The shortest stretch of curve a line may follow, as a fraction of the line's length.
pub const MIN_LENGTH_RATIO: f32 = 0.5;
/// The largest share of a line's stretch that may overlap a stretch another line took.
pub const MAX_OVERLAP: f32 = 0.25;

/// What a target feature curve is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TargetCurveKind {
    /// A ridge (the crest of a convex band).
    Ridge,
    /// A valley (the trough of a concave band).
    Valley,
    /// The border of a hole.
    Border,
}

/// A target curve to pair with: a polyline (a closed one does not repeat its first point).
#[derive(Debug, Clone, PartialEq)]
pub struct TargetCurve {
    /// What it is.
    pub kind: TargetCurveKind,
    /// Its points in order.
    pub points: Vec<Vec3>,
    /// Whether it is a loop.
    pub closed: bool,
    /// How far the curve may lie from the feature it marks (model units, ≥ 0): 0 for a curve of the
    /// target's own sharp edges, about the rounding for a crest traced on a rounded crease.
    pub accuracy: f32,
}

/// Settings of [`pair_lines`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairSettings {
    /// The farthest (mean) a line may lie from its curve, in model units (> 0).
    pub max_distance: f32,
    /// The largest angle (degrees) between a line and its curve (default 30).
    pub max_angle: f32,
    /// The lowest confidence a pair may have (default 0.5).
    pub min_confidence: f32,
}

impl PairSettings {
    /// The defaults with a given maximum distance.
    #[must_use]
    pub fn with_distance(max_distance: f32) -> Self {
        Self {
            max_distance,
            max_angle: 30.0,
            min_confidence: 0.5,
        }
    }
}

/// Why a line stayed free.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FreeReason {
    /// No curve of its kind lies close enough.
    NoneNearby,
    /// The close curves run across it.
    NotParallel,
    /// The close parallel curves are much shorter or longer where it would follow them.
    LengthDiffers,
    /// The best candidate's confidence is below the minimum.
    LowConfidence,
    /// A more confident line already follows that stretch of its curve.
    Taken,
    /// The line already lies within the accuracy of the curve it would follow.
    WithinAccuracy,
}

/// The outcome for one line.
#[derive(Debug, Clone, PartialEq)]
pub struct LinePairing {
    /// The curve it follows, or why it stays free.
    pub result: Result<usize, FreeReason>,
    /// The pair's confidence (0 for a free line).
    pub confidence: f32,
    /// The layout chain to constrain (a closed line ends on its first vertex again); empty when
    /// free.
    pub chain: Vec<u32>,
    /// The target polyline, in the chain's direction; empty when free.
    pub target: Vec<Vec3>,
}

/// A curve prepared for projections: points (a loop's first repeated at the end) and lengths.
struct Prepared {
    points: Vec<Vec3>,
    cumulative: Vec<f32>,
    closed: bool,
    accuracy: f32,
    lower: Vec3,
    upper: Vec3,
}

impl Prepared {
    fn new(curve: &TargetCurve) -> Self {
        let mut points = curve.points.clone();
        if curve.closed {
            points.push(curve.points[0]);
        }
        let mut cumulative = vec![0.0f32];
        for pair in points.windows(2) {
            cumulative.push(cumulative[cumulative.len() - 1] + pair[0].distance(pair[1]));
        }
        let lower = points.iter().fold(Vec3::MAX, |a, &b| a.min(b));
        let upper = points.iter().fold(Vec3::MIN, |a, &b| a.max(b));
        Self {
            points,
            cumulative,
            closed: curve.closed,
            accuracy: curve.accuracy,
            lower,
            upper,
        }
    }

    fn length(&self) -> f32 {
        self.cumulative[self.cumulative.len() - 1]
    }

    /// (distance, arc parameter, unit tangent) of the nearest point to `point`.
    fn project(&self, point: Vec3) -> (f32, f32, Vec3) {
        let mut best = (f32::MAX, 0.0, Vec3::X);
        for (index, pair) in self.points.windows(2).enumerate() {
            let direction = pair[1] - pair[0];
            let squared = direction.length_squared();
            let t = if squared > 0.0 {
                ((point - pair[0]).dot(direction) / squared).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let distance = point.distance(pair[0] + direction * t);
            if distance < best.0 {
                let span = self.cumulative[index + 1] - self.cumulative[index];
                best = (
                    distance,
                    self.cumulative[index] + t * span,
                    direction.normalize_or_zero(),
                );
            }
        }
        best
    }

    /// The point at arc parameter `s` (wrapped round a loop, clamped on an open curve).
    fn point_at(&self, s: f32) -> Vec3 {
        let length = self.length();
        let s = if self.closed && length > 0.0 {
            s.rem_euclid(length)
        } else {
            s.clamp(0.0, length)
        };
        let segment = self
            .cumulative
            .partition_point(|&value| value <= s)
            .clamp(1, self.points.len() - 1);
        let start = self.cumulative[segment - 1];
        let span = self.cumulative[segment] - start;
        let t = if span > 0.0 { (s - start) / span } else { 0.0 };
        self.points[segment - 1].lerp(self.points[segment], t)
    }

    /// The curve from parameter `begin` over the signed length `span`, with its own points in
    /// between.
    fn stretch(&self, begin: f32, span: f32) -> Vec<Vec3> {
        let steps = self.points.len().max(2) * 2;
        let count = ((span.abs() / self.length().max(f32::MIN_POSITIVE)) * steps as f32)
            .ceil()
            .max(1.0) as usize;
        (0..=count)
            .map(|index| self.point_at(begin + span * index as f32 / count as f32))
            .collect()
    }
}

/// Whether a line of `kind` may follow a curve of `curve`.
fn kinds_agree(kind: LineKind, curve: TargetCurveKind) -> bool {
    matches!(
        (kind, curve),
        (LineKind::Any, _)
            | (LineKind::Ridge, TargetCurveKind::Ridge)
            | (LineKind::Valley, TargetCurveKind::Valley)
            | (LineKind::Border, TargetCurveKind::Border)
    )
}

/// A candidate: (confidence, curve, arc parameter of the first vertex, signed span, vertices
/// trimmed off the chain's start and end).
type Candidate = (f32, usize, f32, f32, usize, usize);

/// How many vertices at each end of a chain to leave out when pairing with open `curve`: those
/// beyond one of its ends (projecting onto that end, as the one before them does), so that a line
/// longer than its feature follows it only where it runs beside it.
fn overshoot(curve: &Prepared, projections: &[(f32, f32, Vec3)]) -> (usize, usize) {
    if curve.closed {
        return (0, 0);
    }
    let length = curve.length();
    let at_end = |s: f32| s <= 1e-6 * length || s >= (1.0 - 1e-6) * length;
    let count = projections.len();
    let mut front = 0;
    while front + 2 < count
        && at_end(projections[front].1)
        && projections[front + 1].1 == projections[front].1
    {
        front += 1;
    }
    let mut back = 0;
    while back + front + 2 < count
        && at_end(projections[count - 1 - back].1)
        && projections[count - 2 - back].1 == projections[count - 1 - back].1
    {
        back += 1;
    }
    (front, back)
}

/// The best candidate curve for one line, or why there is none.
fn best_candidate(
    chain: &[Vec3],
    kind: LineKind,
    curves: &[(TargetCurveKind, Prepared)],
    settings: &PairSettings,
) -> Result<Candidate, FreeReason> {
    let full_length: f32 = chain.windows(2).map(|pair| pair[0].distance(pair[1])).sum();
    let lower = chain.iter().fold(Vec3::MAX, |a, &b| a.min(b)) - settings.max_distance;
    let upper = chain.iter().fold(Vec3::MIN, |a, &b| a.max(b)) + settings.max_distance;
    let whole = chain;
    let min_cos = settings.max_angle.to_radians().cos();
    let mut reason = FreeReason::NoneNearby;
    let mut best: Option<Candidate> = None;
    for (index, (curve_kind, curve)) in curves.iter().enumerate() {
        if !kinds_agree(kind, *curve_kind)
            || curve.lower.cmpgt(upper).any()
            || curve.upper.cmplt(lower).any()
            || full_length <= 0.0
        {
            continue;
        }
        let all: Vec<(f32, f32, Vec3)> = whole.iter().map(|&point| curve.project(point)).collect();
        let (front, back) = overshoot(curve, &all);
        let projections = &all[front..all.len() - back];
        let chain = &whole[front..whole.len() - back];
        // The length agreement is the whole line's: a short curve beside a long line is no partner.
        let line_length = full_length;
        let mean_distance = projections.iter().map(|p| p.0).sum::<f32>() / projections.len() as f32;
        let near = projections
            .iter()
            .filter(|p| p.0 <= settings.max_distance)
            .count();
        if mean_distance > settings.max_distance
            || (near as f32) < MIN_NEAR_FRACTION * projections.len() as f32
        {
            continue;
        }
        if mean_distance <= curve.accuracy {
            reason = reason_after(reason, FreeReason::WithinAccuracy);
            continue;
        }
        let mut cosine_sum = 0.0f32;
        for (pair, projected) in chain.windows(2).zip(projections.windows(2)) {
            // The curve's direction over the stretch the edge projects onto (its chord: a polyline
            // that zig-zags at the scale of the target's triangles is judged at the edge's scale),
            // or its tangent where the edge's ends project to one point.
            let chord = curve.point_at(projected[1].1) - curve.point_at(projected[0].1);
            let tangent = if chord.length() > 1e-3 * pair[0].distance(pair[1]) {
                chord.normalize()
            } else {
                curve.project((pair[0] + pair[1]) * 0.5).2
            };
            cosine_sum += (pair[1] - pair[0]).normalize_or_zero().dot(tangent).abs();
        }
        let cosine = cosine_sum / (chain.len() - 1) as f32;
        if cosine < min_cos {
            reason = reason_after(reason, FreeReason::NotParallel);
            continue;
        }
        let total = curve.length();
        let mut span = 0.0f32;
        for pair in projections.windows(2) {
            let mut step = pair[1].1 - pair[0].1;
            if curve.closed && total > 0.0 {
                step = (step + total * 0.5).rem_euclid(total) - total * 0.5;
            }
            span += step;
        }
        let ratio = span.abs().min(line_length) / span.abs().max(line_length);
        if span.abs() < MIN_LENGTH_RATIO * line_length
            || span.abs() * MIN_LENGTH_RATIO > line_length
        {
            reason = reason_after(reason, FreeReason::LengthDiffers);
            continue;
        }
        let closeness = 1.0 - mean_distance / settings.max_distance;
        let parallel = ((cosine - min_cos) / (1.0 - min_cos).max(1e-6)).clamp(0.0, 1.0);
        let confidence = closeness * parallel * ratio;
        if confidence < settings.min_confidence {
            reason = reason_after(reason, FreeReason::LowConfidence);
            continue;
        }
        if best.is_none_or(|b| confidence > b.0) {
            best = Some((confidence, index, projections[0].1, span, front, back));
        }
    }
    best.ok_or(reason)
}

/// The more telling of two reasons (the one that got further through the tests).
fn reason_after(old: FreeReason, new: FreeReason) -> FreeReason {
    let rank = |reason| match reason {
        FreeReason::NoneNearby => 0,
        FreeReason::NotParallel => 1,
        FreeReason::LengthDiffers => 2,
        FreeReason::WithinAccuracy => 3,
        _ => 4,
    };
    if rank(new) > rank(old) { new } else { old }
}

/// The error of a curve or line (`what` `index`, in the argument `name`) of fewer than 2 points.
fn too_few(name: &'static str, what: &str, index: usize, count: usize) -> KernelError {
    KernelError::InvalidArgument {
        name,
        reason: format!("{what} {index} has {count} points, it needs 2"),
    }
}

/// Pairs each of `lines` (their vertices at `positions`, the current fit) with at most one of
/// `curves` (see the module docs). One outcome per line, in order.
///
/// # Errors
/// [`KernelError::InvalidArgument`] for a maximum distance that is not positive and finite, an
/// angle outside 0 to 90 degrees, a confidence outside 0 to 1, a curve's accuracy that is negative
/// or not finite, a curve of fewer than two points
/// or a line of fewer than two vertices; [`KernelError::LayoutIndexOutOfRange`] for a line vertex
/// beyond `positions`; the coordinate errors of [`validate::check_coordinates`].
pub fn pair_lines(
    positions: &[Vec3],
    lines: &[FeatureLine],
    curves: &[TargetCurve],
    settings: &PairSettings,
) -> Result<Vec<LinePairing>, KernelError> {
    validate::check_coordinates("vertex", positions)?;
    check_setting(
        "max_distance",
        "maximum distance",
        settings.max_distance,
        SettingRange::above(0.0, f64::from(validate::MAX_COORDINATE)),
    )?;
    check_setting(
        "max_angle",
        "maximum angle",
        settings.max_angle,
        SettingRange::closed(0.0, 90.0),
    )?;
    check_setting(
        "min_confidence",
        "minimum confidence",
        settings.min_confidence,
        SettingRange::closed(0.0, 1.0),
    )?;
    let mut prepared = Vec::with_capacity(curves.len());
    for (index, curve) in curves.iter().enumerate() {
        if curve.points.len() < 2 {
            return Err(too_few("target curves", "curve", index, curve.points.len()));
        }
        validate::check_coordinates("curve point", &curve.points)?;
        check_setting(
            "curves",
            "a curve's accuracy",
            curve.accuracy,
            SettingRange::closed(0.0, f64::from(validate::MAX_COORDINATE)),
        )?;
        prepared.push((curve.kind, Prepared::new(curve)));
    }
    let mut uses: HashMap<u32, usize> = HashMap::new();
    for line in lines {
        for &vertex in &line.vertices {
            *uses.entry(vertex).or_default() += 1;
        }
    }
    let mut candidates = Vec::with_capacity(lines.len());
    for (index, line) in lines.iter().enumerate() {
        if line.vertices.len() < 2 {
            return Err(too_few("feature lines", "line", index, line.vertices.len()));
        }
        let mut chain = line.vertices.clone();
        if line.closed {
            chain.push(chain[0]);
        } else {
            // An end shared with another line (a junction: a box's corner) is left out: a vertex
            // follows one curve only.
            if chain.len() > 2 && uses[&chain[0]] > 1 {
                chain.remove(0);
            }
            if chain.len() > 2 && uses[&chain[chain.len() - 1]] > 1 {
                chain.pop();
            }
        }
        let mut points = Vec::with_capacity(chain.len());
        for &vertex in &chain {
            let Some(&point) = positions.get(vertex as usize) else {
                return Err(KernelError::LayoutIndexOutOfRange {
                    element: "feature line",
                    index,
                    vertex,
                    vertex_count: positions.len(),
                });
            };
            points.push(point);
        }
        candidates.push((
            chain,
            best_candidate(&points, line.kind, &prepared, settings),
        ));
    }
    let mut order: Vec<usize> = (0..lines.len()).collect();
    order.sort_by(|&a, &b| {
        let confidence = |index: usize| candidates[index].1.map_or(-1.0, |c| c.0);
        confidence(b).total_cmp(&confidence(a))
    });
    let mut taken: Vec<(usize, f32, f32)> = Vec::new();
    let mut outcomes: Vec<Option<LinePairing>> = vec![None; lines.len()];
    for index in order {
        let (chain, candidate) = &candidates[index];
        let free = |reason| LinePairing {
            result: Err(reason),
            confidence: 0.0,
            chain: Vec::new(),
            target: Vec::new(),
        };
        let outcome = match *candidate {
            Err(reason) => free(reason),
            Ok((confidence, curve, begin, span, front, back)) => {
                let (low, high) = (begin.min(begin + span), begin.max(begin + span));
                let overlaps = taken.iter().any(|&(other, other_low, other_high)| {
                    other == curve
                        && (high.min(other_high) - low.max(other_low)) > MAX_OVERLAP * (high - low)
                });
                if overlaps {
                    free(FreeReason::Taken)
                } else {
                    taken.push((curve, low, high));
                    LinePairing {
                        result: Ok(curve),
                        confidence,
                        chain: chain[front..chain.len() - back].to_vec(),
                        target: prepared[curve].1.stretch(begin, span),
                    }
                }
            }
        };
        outcomes[index] = Some(outcome);
    }
    Ok(outcomes.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::LineSource;

    /// `pair_lines` with the default settings at `distance`, which must succeed.
    fn pair(
        positions: &[Vec3],
        lines: &[FeatureLine],
        curves: &[TargetCurve],
        distance: f32,
    ) -> Vec<LinePairing> {
        pair_lines(
            positions,
            lines,
            curves,
            &PairSettings::with_distance(distance),
        )
        .unwrap()
    }

    fn line(vertices: Vec<u32>, kind: LineKind) -> FeatureLine {
        FeatureLine {
            vertices,
            closed: false,
            kind,
            source: LineSource::Crease,
            dihedral: 0.0,
        }
    }

    fn straight(kind: TargetCurveKind, from: Vec3, to: Vec3, count: usize) -> TargetCurve {
        TargetCurve {
            kind,
            points: (0..count)
                .map(|i| from.lerp(to, i as f32 / (count - 1) as f32))
                .collect(),
            closed: false,
            accuracy: 0.0,
        }
    }

    #[test]
    fn a_line_pairs_with_the_close_parallel_curve_of_its_kind() {
        // A layout line along x at y = 0.1, a ridge at y = 0, a valley at y = 0.05 and a ridge
        // across it.
        let positions: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f32, 0.1, 0.0)).collect();
        let lines = [line(vec![0, 1, 2, 3, 4], LineKind::Ridge)];
        let curves = [
            straight(
                TargetCurveKind::Valley,
                Vec3::new(0.0, 0.05, 0.0),
                Vec3::new(4.0, 0.05, 0.0),
                9,
            ),
            straight(
                TargetCurveKind::Ridge,
                Vec3::new(2.0, -3.0, 0.0),
                Vec3::new(2.0, 3.0, 0.0),
                9,
            ),
            straight(
                TargetCurveKind::Ridge,
                Vec3::new(4.2, 0.0, 0.0),
                Vec3::new(-0.2, 0.0, 0.0),
                9,
            ),
        ];
        let outcome = pair(&positions, &lines, &curves, 0.5);
        assert_eq!(outcome[0].result, Ok(2));
        assert!(outcome[0].confidence > 0.7 && outcome[0].confidence < 1.0);
        assert_eq!(outcome[0].chain, vec![0, 1, 2, 3, 4]);
        // The stretch runs in the line's direction, from near its first vertex to near its last.
        let target = &outcome[0].target;
        assert!(target[0].distance(Vec3::new(0.0, 0.0, 0.0)) < 1e-4);
        assert!(target[target.len() - 1].distance(Vec3::new(4.0, 0.0, 0.0)) < 1e-4);
    }

    #[test]
    fn a_line_without_a_partner_stays_free_and_says_why() {
        let positions: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let lines = [line(vec![0, 1, 2, 3, 4], LineKind::Valley)];
        let far = [straight(
            TargetCurveKind::Valley,
            Vec3::new(0.0, 5.0, 0.0),
            Vec3::new(4.0, 5.0, 0.0),
            5,
        )];
        let across = [straight(
            TargetCurveKind::Valley,
            Vec3::new(2.0, -2.0, 0.0),
            Vec3::new(2.0, 2.0, 0.0),
            50,
        )];
        let short = [straight(
            TargetCurveKind::Valley,
            Vec3::new(1.5, 0.0, 0.0),
            Vec3::new(2.5, 0.0, 0.0),
            5,
        )];
        let settings = PairSettings::with_distance(3.0);
        for (curves, reason) in [
            (&far[..], FreeReason::NoneNearby),
            (&across[..], FreeReason::NotParallel),
            (&short[..], FreeReason::LengthDiffers),
        ] {
            let outcome = pair_lines(&positions, &lines, curves, &settings).unwrap();
            assert_eq!(outcome[0].result, Err(reason));
            assert!(outcome[0].chain.is_empty() && outcome[0].target.is_empty());
        }
    }

    #[test]
    fn two_lines_on_one_stretch_the_more_confident_wins_and_loops_close() {
        let mut positions: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f32, 0.1, 0.0)).collect();
        positions.extend((0..5).map(|i| Vec3::new(i as f32, 0.4, 0.0)));
        let lines = [
            line(vec![5, 6, 7, 8, 9], LineKind::Any),
            line(vec![0, 1, 2, 3, 4], LineKind::Any),
        ];
        let curves = [straight(
            TargetCurveKind::Border,
            Vec3::ZERO,
            Vec3::new(4.0, 0.0, 0.0),
            5,
        )];
        let outcome = pair(&positions, &lines, &curves, 1.0);
        assert_eq!(outcome[0].result, Err(FreeReason::Taken));
        assert_eq!(outcome[1].result, Ok(0));
        // A closed line round a closed curve: the chain comes back to its first vertex.
        let square = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let ring = FeatureLine {
            closed: true,
            ..line(vec![0, 1, 2, 3], LineKind::Border)
        };
        let loop_curve = TargetCurve {
            kind: TargetCurveKind::Border,
            points: square.iter().map(|p| *p * 1.02).collect(),
            closed: true,
            accuracy: 0.0,
        };
        let outcome = pair(&square, &[ring], &[loop_curve], 0.2);
        assert_eq!(outcome[0].chain, vec![0, 1, 2, 3, 0]);
        let target = &outcome[0].target;
        assert!(target[0].distance(target[target.len() - 1]) < 1e-4);
    }

    #[test]
    fn a_junction_shared_by_two_lines_is_left_out_of_both() {
        // Two lines meeting at vertex 4 at a right angle, each beside a curve.
        let mut positions: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f32, 0.1, 0.0)).collect();
        positions.extend((1..5).map(|i| Vec3::new(4.1, -(i as f32), 0.0)));
        let lines = [
            line(vec![0, 1, 2, 3, 4], LineKind::Ridge),
            line(vec![4, 5, 6, 7, 8], LineKind::Ridge),
        ];
        let curves = [
            straight(
                TargetCurveKind::Ridge,
                Vec3::ZERO,
                Vec3::new(4.0, 0.0, 0.0),
                5,
            ),
            straight(
                TargetCurveKind::Ridge,
                Vec3::new(4.0, 0.0, 0.0),
                Vec3::new(4.0, -4.0, 0.0),
                5,
            ),
        ];
        let outcome = pair(&positions, &lines, &curves, 0.5);
        assert_eq!(outcome[0].chain, vec![0, 1, 2, 3]);
        assert_eq!(outcome[1].chain, vec![5, 6, 7, 8]);
    }

    #[test]
    fn a_line_within_the_curves_accuracy_stays_free_an_exact_curve_pairs_it() {
        let positions: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f32, 0.1, 0.0)).collect();
        let lines = [line(vec![0, 1, 2, 3, 4], LineKind::Ridge)];
        let rounded = TargetCurve {
            accuracy: 0.2,
            ..straight(
                TargetCurveKind::Ridge,
                Vec3::ZERO,
                Vec3::new(4.0, 0.0, 0.0),
                9,
            )
        };
        let outcome = pair(&positions, &lines, std::slice::from_ref(&rounded), 0.5);
        assert_eq!(outcome[0].result, Err(FreeReason::WithinAccuracy));
        // Farther off than the curve's accuracy, or an exact curve: paired.
        let far: Vec<Vec3> = positions.iter().map(|p| *p + Vec3::Y * 0.2).collect();
        assert_eq!(
            pair(&far, &lines, std::slice::from_ref(&rounded), 1.0)[0].result,
            Ok(0)
        );
        let exact = TargetCurve {
            accuracy: 0.0,
            ..rounded
        };
        assert_eq!(pair(&positions, &lines, &[exact], 0.5)[0].result, Ok(0));
    }

    #[test]
    fn a_line_longer_than_its_curve_follows_it_only_beside_it() {
        // A line from x = 0 to 6 beside a ridge from 0 to 4: its last two vertices are beyond the
        // ridge's end and stay out of the chain.
        let positions: Vec<Vec3> = (0..7).map(|i| Vec3::new(i as f32, 0.1, 0.0)).collect();
        let lines = [line((0..7).collect(), LineKind::Ridge)];
        let curves = [straight(
            TargetCurveKind::Ridge,
            Vec3::ZERO,
            Vec3::new(4.0, 0.0, 0.0),
            5,
        )];
        let outcome = pair(&positions, &lines, &curves, 2.0);
        assert_eq!(outcome[0].result, Ok(0));
        assert_eq!(outcome[0].chain, vec![0, 1, 2, 3, 4]);
        let target = &outcome[0].target;
        assert!(target[target.len() - 1].distance(Vec3::new(4.0, 0.0, 0.0)) < 1e-4);
    }

    #[test]
    fn bad_settings_and_inputs_are_refused() {
        let positions = [Vec3::ZERO, Vec3::X];
        let lines = [line(vec![0, 1], LineKind::Any)];
        let curve = straight(TargetCurveKind::Ridge, Vec3::ZERO, Vec3::X, 2);
        let bad_distance = PairSettings::with_distance(0.0);
        assert!(
            pair_lines(
                &positions,
                &lines,
                std::slice::from_ref(&curve),
                &bad_distance
            )
            .is_err()
        );
        let beyond = [line(vec![0, 7], LineKind::Any)];
        assert!(matches!(
            pair_lines(&positions, &beyond, &[], &PairSettings::with_distance(1.0)),
            Err(KernelError::LayoutIndexOutOfRange { vertex: 7, .. })
        ));
        let inexact = TargetCurve {
            accuracy: -1.0,
            ..curve.clone()
        };
        assert!(
            pair_lines(
                &positions,
                &lines,
                &[inexact],
                &PairSettings::with_distance(1.0)
            )
            .is_err()
        );
        let one_point = TargetCurve {
            points: vec![Vec3::ZERO],
            ..curve
        };
        assert!(
            pair_lines(
                &positions,
                &lines,
                &[one_point],
                &PairSettings::with_distance(1.0)
            )
            .is_err()
        );
    }
}
