//! Ridge and valley curves: the crests of high-curvature bands (the centre-lines of blends).
//!
//! Method (Ohtake, Belyaev and Seidel 2004, on curvatures fitted over a scale): a ridge is where
//! the largest curvature `k1` is extremal along its own direction `d1`, i.e. where the
//! *extremality* `e = ∇k1 · d1` crosses zero from positive to negative along `d1`, on a surface
//! that bends more across than along (`k1 > |k2|`) and clearly (`k1 × scale` and `(k1 − k2) ×
//! scale` at least the ridge threshold; the second keeps umbilic spots such as a box's spherical
//! corners out, where `d1` means nothing). Valleys are the ridges of the surface seen from inside
//! (`−k2` along `d2`). `∇k1` is the weighted least-squares gradient over half the scale in the
//! fitted tangent plane; `d1` is a line field, so on each edge the far end's direction is flipped to
//! agree with the near end's before the two are compared.
//!
//! Each edge with a zero crossing that is a maximum gets a point (linear interpolation of `e`);
//! each triangle with exactly two such edges gives a segment; segments sharing an edge point are
//! chained into polylines. Chains whose ends are within the join distance and roughly continue
//! each other are joined (through a spot where the test failed, such as noise); a chain whose two
//! ends meet is closed. Chains shorter than the minimum length are dropped, and two passes of
//! Laplacian smoothing take the zig-zag of triangle crossings off the rest.
//!
//! On a constant-radius blend the curvature across the band is flat-topped at scales below its
//! half-width: the fit over a scale about the blend radius turns that plateau into a peak at the
//! centre-line, which is why the scale should be about the radius of the blends sought.

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;

use super::curvature::PrincipalCurvatures;
use super::extend::{CreaseField, extend_end};
use super::join::{end_tangent, join_chains, polyline_length};
use super::neighborhood::{Scratch, VertexAdjacency, gather};
use crate::mesh::TargetMesh;

/// Whether a feature curve follows a convex crest or a concave trough.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FeatureCurveKind {
    /// The crest of a convex band: an outer edge's blend, a ridge.
    Ridge,
    /// The trough of a concave band: an inner edge's fillet, a valley.
    Valley,
}

/// A ridge or valley polyline on the surface.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureCurve {
    /// Ridge or valley.
    pub kind: FeatureCurveKind,
    /// The points in order (a closed curve does not repeat its first point).
    pub points: Vec<Vec3>,
    /// Whether the curve is a loop.
    pub closed: bool,
}

impl FeatureCurve {
    /// Length of the polyline (with the closing segment of a loop).
    #[must_use]
    pub fn length(&self) -> f32 {
        polyline_length(&self.points, self.closed)
    }
}

/// Settings of the curve extraction (the scale is that of the curvatures).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveSettings {
    /// `k × scale` a crest must reach somewhere on a curve (see the module docs).
    pub ridge_threshold: f32,
    /// The fraction of `ridge_threshold` a curve keeps along the rest of its length, and while its
    /// ends are extended along the crease (hysteresis; 1 = none).
    pub hysteresis: f32,
    /// Curves shorter than this are dropped (model units).
    pub min_length: f32,
    /// Chain ends closer than this that continue each other are joined (model units).
    pub join_distance: f32,
}

/// Ridge and valley curves of `mesh` from its curvatures (computed over `curvatures.scale`).
///
/// Hysteresis, as Canny's edge detector has it: crest segments are traced wherever the crest test
/// passes at the low threshold (`hysteresis × ridge_threshold`), and a chain of them is kept when
/// at least one of its segments passes at the full threshold. Chains that continue each other are
/// joined, their open ends are walked on along the crease while it stays a crest at the low
/// threshold ([`super::extend`]), ends that now meet are joined again, short curves are dropped.
#[must_use]
pub fn feature_curves(
    mesh: &TargetMesh,
    curvatures: &PrincipalCurvatures,
    settings: &CurveSettings,
) -> Vec<FeatureCurve> {
    let adjacency = VertexAdjacency::new(mesh.vertices().len(), mesh.triangles());
    let mut curves = Vec::new();
    for kind in [FeatureCurveKind::Ridge, FeatureCurveKind::Valley] {
        let field = CrestField::new(
            mesh,
            curvatures,
            &adjacency,
            kind,
            settings.ridge_threshold,
            settings.hysteresis,
        );
        let segments = crest_segments(mesh, &field);
        let chains = chain_segments(&segments)
            .into_iter()
            .filter(|chain| chain.2)
            .map(|(points, closed, _)| (points, closed))
            .collect();
        let joined = join_chains(chains, settings.join_distance);
        let crease = CreaseField {
            strength: &field.strength,
            other: &field.other,
            along: &field.along,
            low: settings.hysteresis * settings.ridge_threshold / curvatures.scale,
            scale: curvatures.scale,
        };
        let extended: Vec<(Vec<Vec3>, bool)> = joined
            .into_par_iter()
            .map(|(points, closed)| {
                // Only curves at least a scale long are extended: a crumb near a junction (a
                // box's corner) has no direction to extend along.
                if closed || polyline_length(&points, false) < curvatures.scale {
                    (points, closed)
                } else {
                    (extend_both_ends(mesh, &crease, points), false)
                }
            })
            .collect();
        for (mut points, closed) in join_chains(extended, settings.join_distance) {
            smooth(&mut points, closed, 2);
            if polyline_length(&points, closed) >= settings.min_length {
                curves.push(FeatureCurve {
                    kind,
                    points,
                    closed,
                });
            }
        }
    }
    curves
}

/// An open chain with both its ends walked on along the crease.
fn extend_both_ends(mesh: &TargetMesh, crease: &CreaseField<'_>, points: Vec<Vec3>) -> Vec<Vec3> {
    if points.len() < 2 {
        return points;
    }
    let reach = crease.scale.min(0.5 * polyline_length(&points, false));
    let before = extend_end(mesh, crease, points[0], end_tangent(&points, true, reach));
    let after = extend_end(
        mesh,
        crease,
        points[points.len() - 1],
        end_tangent(&points, false, reach),
    );
    let mut result = Vec::with_capacity(before.len() + points.len() + after.len());
    result.extend(before.into_iter().rev());
    result.extend(points);
    result.extend(after);
    result
}

/// The crest test's inputs per vertex for one kind: eligibility at the low and the full
/// threshold, extremality, the direction across the crest and along it, and the curvatures.
struct CrestField {
    eligible: Vec<bool>,
    strong: Vec<bool>,
    extremality: Vec<f32>,
    direction: Vec<Vec3>,
    along: Vec<Vec3>,
    strength: Vec<f32>,
    other: Vec<f32>,
}

impl CrestField {
    fn new(
        mesh: &TargetMesh,
        curvatures: &PrincipalCurvatures,
        adjacency: &VertexAdjacency,
        kind: FeatureCurveKind,
        ridge_threshold: f32,
        hysteresis: f32,
    ) -> Self {
        let (strength, other, direction, along): (Vec<f32>, Vec<f32>, &[Vec3], &[Vec3]) = match kind
        {
            FeatureCurveKind::Ridge => (
                curvatures.k1.clone(),
                curvatures.k2.clone(),
                &curvatures.d1,
                &curvatures.d2,
            ),
            FeatureCurveKind::Valley => (
                curvatures.k2.iter().map(|k| -k).collect(),
                curvatures.k1.iter().map(|k| -k).collect(),
                &curvatures.d2,
                &curvatures.d1,
            ),
        };
        let passes = |vertex: usize, threshold: f32| {
            let (k, other) = (strength[vertex], other[vertex]);
            direction[vertex] != Vec3::ZERO
                && k >= threshold
                && k > other.abs()
                && k - other >= threshold
        };
        let threshold = ridge_threshold / curvatures.scale;
        let low = hysteresis * threshold;
        let eligible: Vec<bool> = (0..strength.len()).map(|v| passes(v, low)).collect();
        let strong: Vec<bool> = (0..strength.len()).map(|v| passes(v, threshold)).collect();
        let positions = mesh.vertices();
        let normals = &curvatures.normals;
        // The gradient is fitted over half the scale: over the one-ring alone, noise of the
        // order of the edges would scatter the zero crossings.
        let radius = 0.5 * curvatures.scale;
        // Per vertex: the extremality, and whether the surface really bends the crest's way.
        let tested: Vec<(f32, bool)> = (0..strength.len() as u32)
            .into_par_iter()
            .with_min_len(512)
            .map_init(
                || (Scratch::new(positions.len()), Vec::new()),
                |(scratch, neighborhood), vertex| {
                    if !eligible[vertex as usize] {
                        return (0.0, false);
                    }
                    gather(
                        positions,
                        adjacency,
                        vertex,
                        curvatures.scale,
                        7,
                        scratch,
                        neighborhood,
                    );
                    let height = mean_height(
                        positions,
                        normals[vertex as usize],
                        neighborhood,
                        vertex as usize,
                        curvatures.scale,
                    );
                    // Convex: the neighbourhood lies below the tangent plane on average.
                    let bends = match kind {
                        FeatureCurveKind::Ridge => height < 0.0,
                        FeatureCurveKind::Valley => height > 0.0,
                    };
                    gather(
                        positions,
                        adjacency,
                        vertex,
                        radius,
                        7,
                        scratch,
                        neighborhood,
                    );
                    let gradient = tangent_gradient(
                        positions,
                        normals[vertex as usize],
                        &strength,
                        neighborhood,
                        vertex as usize,
                        radius,
                    );
                    (gradient.dot(direction[vertex as usize]), bends)
                },
            )
            .collect();
        let extremality = tested.iter().map(|&(value, _)| value).collect();
        let eligible: Vec<bool> = tested.iter().map(|&(_, bends)| bends).collect();
        let strong = strong
            .iter()
            .zip(&eligible)
            .map(|(&strong, &eligible)| strong && eligible)
            .collect();
        Self {
            eligible,
            strong,
            extremality,
            direction: direction.to_vec(),
            along: along.to_vec(),
            strength,
            other,
        }
    }

    /// The crest point on edge `(first, second)`, if the extremality crosses zero there as a
    /// maximum along the direction field. Symmetric in its two vertices.
    fn crossing(&self, positions: &[Vec3], first: u32, second: u32) -> Option<Vec3> {
        let (i, j) = (first.min(second) as usize, first.max(second) as usize);
        let (di, dj) = (self.direction[i], self.direction[j]);
        let agreement = di.dot(dj);
        if agreement.abs() < std::f32::consts::FRAC_1_SQRT_2 {
            return None;
        }
        let ei = self.extremality[i];
        let ej = self.extremality[j] * agreement.signum();
        if (ei >= 0.0) == (ej >= 0.0) {
            return None;
        }
        // A maximum: e falls while moving along the direction.
        let along = (positions[j] - positions[i]).dot(di);
        if (ej - ei) * along >= 0.0 {
            return None;
        }
        let t = ei / (ei - ej);
        Some(positions[i].lerp(positions[j], t))
    }
}

/// The weighted mean height of the neighbourhood over the tangent plane at `vertex` (along
/// `normal`; weights fall to zero at `radius`): negative where the surface bends away from its
/// normal (convex) over that radius. The fitted quadric alone can say "concave" beside a sharp
/// convex edge (the fit rings there); this says which way the surface really goes.
fn mean_height(
    positions: &[Vec3],
    normal: Vec3,
    neighbors: &[u32],
    vertex: usize,
    radius: f32,
) -> f32 {
    let origin = positions[vertex];
    let (mut sum, mut total) = (0.0f32, 0.0f32);
    for &neighbor in neighbors {
        let offset = positions[neighbor as usize] - origin;
        let t = (offset.length() / radius).min(1.0);
        let weight = (1.0 - t * t) * (1.0 - t * t);
        sum += weight * offset.dot(normal);
        total += weight;
    }
    if total > 0.0 { sum / total } else { 0.0 }
}

/// Weighted least-squares gradient of `field` at `vertex` in the plane normal to `normal`, from
/// the differences to the vertices of its neighbourhood (weights fall to zero at `radius`).
fn tangent_gradient(
    positions: &[Vec3],
    normal: Vec3,
    field: &[f32],
    neighbors: &[u32],
    vertex: usize,
    radius: f32,
) -> Vec3 {
    let (u_axis, w_axis) = normal.any_orthonormal_pair();
    let origin = positions[vertex];
    let (mut uu, mut uw, mut ww, mut fu, mut fw) = (0.0f32, 0.0, 0.0, 0.0, 0.0);
    for &neighbor in neighbors {
        let offset = positions[neighbor as usize] - origin;
        let (u, w) = (offset.dot(u_axis), offset.dot(w_axis));
        let difference = field[neighbor as usize] - field[vertex];
        let t = (offset.length() / (radius * 1.5)).min(1.0);
        let weight = (1.0 - t * t) * (1.0 - t * t);
        uu += weight * u * u;
        uw += weight * u * w;
        ww += weight * w * w;
        fu += weight * u * difference;
        fw += weight * w * difference;
    }
    let determinant = uu * ww - uw * uw;
    if determinant.abs() <= f32::EPSILON * (uu * ww).max(f32::MIN_POSITIVE) {
        return Vec3::ZERO;
    }
    let gu = (ww * fu - uw * fw) / determinant;
    let gw = (uu * fw - uw * fu) / determinant;
    u_axis * gu + w_axis * gw
}

/// An undirected mesh edge as one key.
fn edge_key(first: u32, second: u32) -> u64 {
    (u64::from(first.min(second)) << 32) | u64::from(first.max(second))
}

/// A crest segment across one triangle: its two end points, each keyed by the edge it lies on.
type Segment = [(u64, Vec3); 2];

/// The crest segments of every triangle, each with whether its triangle's corners all pass the
/// full threshold.
fn crest_segments(mesh: &TargetMesh, field: &CrestField) -> Vec<(Segment, bool)> {
    let positions = mesh.vertices();
    mesh.triangles()
        .par_iter()
        .zip(mesh.degenerate_triangles())
        .with_min_len(1024)
        .filter_map(|(corners, &degenerate)| {
            if degenerate || corners.iter().any(|&v| !field.eligible[v as usize]) {
                return None;
            }
            let mut found = [(0u64, Vec3::ZERO); 3];
            let mut count = 0;
            for edge in 0..3 {
                let (first, second) = (corners[edge], corners[(edge + 1) % 3]);
                if let Some(point) = field.crossing(positions, first, second) {
                    found[count] = (edge_key(first, second), point);
                    count += 1;
                }
            }
            let strong = corners.iter().all(|&v| field.strong[v as usize]);
            (count == 2).then_some(([found[0], found[1]], strong))
        })
        .collect()
}

/// Chains of segments joined at their shared edge points: `(points, closed, strong)`, `strong`
/// when one of its segments is.
fn chain_segments(flagged: &[(Segment, bool)]) -> Vec<(Vec<Vec3>, bool, bool)> {
    let segments: Vec<Segment> = flagged.iter().map(|(segment, _)| *segment).collect();
    let mut at_point: HashMap<u64, Vec<usize>> = HashMap::new();
    for (index, segment) in segments.iter().enumerate() {
        for (key, _) in segment {
            at_point.entry(*key).or_default().push(index);
        }
    }
    let mut used = vec![false; segments.len()];
    let mut chains = Vec::new();
    // Walk from `start` (a point key) through `first` segment while points join exactly two.
    let walk = |start: u64, first: usize, used: &mut Vec<bool>| {
        let mut points = vec![point_of(&segments[first], start)];
        let mut key = start;
        let mut segment = first;
        let mut strong = false;
        loop {
            used[segment] = true;
            strong |= flagged[segment].1;
            let next = other_end(&segments[segment], key);
            points.push(next.1);
            key = next.0;
            let here = &at_point[&key];
            if here.len() != 2 {
                return (points, false, strong);
            }
            let following = if here[0] == segment { here[1] } else { here[0] };
            if used[following] {
                let closed = key == start;
                if closed {
                    points.pop();
                }
                return (points, closed, strong);
            }
            segment = following;
        }
    };
    let mut keys: Vec<u64> = at_point.keys().copied().collect();
    keys.sort_unstable();
    for &key in &keys {
        if at_point[&key].len() == 2 {
            continue;
        }
        for &segment in &at_point[&key] {
            if !used[segment] {
                chains.push(walk(key, segment, &mut used));
            }
        }
    }
    for segment in 0..segments.len() {
        if !used[segment] {
            chains.push(walk(segments[segment][0].0, segment, &mut used));
        }
    }
    chains
}

fn point_of(segment: &Segment, key: u64) -> Vec3 {
    if segment[0].0 == key {
        segment[0].1
    } else {
        segment[1].1
    }
}

fn other_end(segment: &Segment, key: u64) -> (u64, Vec3) {
    if segment[0].0 == key {
        segment[1]
    } else {
        segment[0]
    }
}

/// `passes` rounds of moving each inner point halfway to the mean of its two neighbours.
fn smooth(points: &mut [Vec3], closed: bool, passes: usize) {
    let count = points.len();
    if count < 3 {
        return;
    }
    for _ in 0..passes {
        let previous = points.to_vec();
        for index in 0..count {
            let (before, after) = if closed {
                ((index + count - 1) % count, (index + 1) % count)
            } else if index == 0 || index == count - 1 {
                continue;
            } else {
                (index - 1, index + 1)
            };
            let mean = (previous[before] + previous[after]) * 0.5;
            points[index] = previous[index].lerp(mean, 0.5);
        }
    }
}
