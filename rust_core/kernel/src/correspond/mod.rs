//! Correspondence proposals: from the anchors given and the current fit, further layout-vertex →
//! target-point pairs where both shapes say where a point goes.
//!
//! 1. **Distinct points** of each shape: vertices whose *protrusion* (how far a vertex stands out
//!    along its normal from the centroid of the surface within a radius, over the radius) is an
//!    extreme within that radius — tips (fingertips, toes, nose, ears, heels) stand out, pits and
//!    creases sink. The radius is a fraction of each shape's own bounding-box diagonal, and the
//!    measure a ratio to it, so it survives a change of size and, being local, of proportions.
//!    The layout is measured in its rest shape, the target only around where layout points are
//!    expected.
//! 2. **Where a layout point is expected**: its current position (after Align) moved by the
//!    anchors' residuals (anchor target − anchored vertex's current position), interpolated by
//!    inverse squared geodesic distance on the layout.
//! 3. **Descriptors** of each point: its protrusion at two radii and its geodesic distances to the
//!    anchors over the mean geodesic distance between anchors on its own shape (ratios, so a
//!    longer arm does not change them much).
//! 4. **Matching**: the cost of a pair adds how far apart (against the search radius), how
//!    different the protrusions and how different the geodesic ratios; pairs of a tip with a pit,
//!    or whose normals disagree, are impossible. Only reciprocal best matches are kept; their
//!    confidence falls with the cost and with the margin to the next candidate of either point.
//! 5. **Consistency**: a pair whose distances to its nearest anchors and other pairs stretch
//!    (median |log ratio| against the anchors' overall scale) by more than 35 % is rejected,
//!    worst first; the rest have their confidence lowered by their stretch.
//! 6. **Symmetry**: on a mirror-symmetric layout, a pair whose vertex has a partner across the
//!    mirror is kept only when the partner's feature is proposed too, at a consistent distance (a
//!    wrong match is more often one-sided). On `benchmarks/few_anchors.py`'s heavy-old body with 4
//!    anchors it drops the buttock (1.9 % of the diagonal off): mean error 0.453 % of the diagonal
//!    with the proposals accepted (0.627 % before, 0.506 % without proposals); but the heavy body
//!    with 4 anchors loses a shoulder and a toe, right ones: 0.331 % (0.257 % before, 0.262 %
//!    without).

mod matching;
mod shape;
mod symmetry;

use glam::Vec3;
use rayon::prelude::*;

use crate::error::KernelError;
use crate::face_point::FacePoint;
use crate::mesh::TargetMesh;
use crate::quality::LayoutFaces;
use crate::validate::{SettingRange, check_coordinate, check_coordinates, check_setting};
use matching::{Feature, consistent_pairs, reciprocal_matches};
use shape::Shape;

/// A pair the artist placed: a layout vertex and the point on (or near) the target it goes to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GivenPair {
    /// The layout vertex.
    pub vertex: u32,
    /// Where it goes, in the target's space.
    pub target: Vec3,
}

/// The layout as the proposals see it.
#[derive(Debug, Clone, Copy)]
pub struct ProposalLayout<'a> {
    /// Its rest shape (the template's own proportions).
    pub rest: &'a [Vec3],
    /// Where its vertices are now, in the target's space (after Align).
    pub current: &'a [Vec3],
    /// Its faces.
    pub faces: LayoutFaces<'a>,
}

/// How the proposals are made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProposalSettings {
    /// The most pairs proposed (the most confident kept), 1 to 10,000.
    pub max_count: u32,
    /// The least confidence of a proposed pair, 0 to 1.
    pub min_confidence: f32,
    /// How far from where the current fit expects it a layout point's partner is looked for, as
    /// a fraction of the target's bounding-box diagonal, (0, 0.5].
    pub search_radius: f32,
    /// The radius over which a point's protrusion is measured, as a fraction of each shape's
    /// bounding-box diagonal, (0, 0.1]; the larger descriptor radius is three times it. By
    /// default 0.03: on the benchmark bodies it also finds points below the knees, where few
    /// anchors let a leg slide (`benchmarks/few_anchors.py`, the wrap with all proposals
    /// accepted, mean error in % of the diagonal): heavy-old with 6 anchors 0.431 (0.472 at
    /// 0.015, 0.465 without proposals), old-male with 4 anchors 0.599 (0.909 without); but
    /// heavy-old with 4 anchors 0.627 (0.500 at 0.015, 0.506 without: 2 of its 5 proposals, the
    /// upper arms and a buttock, lie 1 % to 1.9 % off), measured before the symmetry rule (step 6).
    pub feature_scale: f32,
}

impl Default for ProposalSettings {
    fn default() -> Self {
        Self {
            max_count: 40,
            min_confidence: 0.7,
            search_radius: 0.06,
            feature_scale: 0.03,
        }
    }
}

impl ProposalSettings {
    /// Checks every setting against its documented range.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] naming the setting.
    pub fn validate(&self) -> Result<(), KernelError> {
        check_setting(
            "max_count",
            "most proposals",
            self.max_count,
            SettingRange::closed(1.0, 10_000.0),
        )?;
        check_setting(
            "min_confidence",
            "least confidence",
            self.min_confidence,
            SettingRange::closed(0.0, 1.0),
        )?;
        check_setting(
            "search_radius",
            "search radius (a fraction of the target's diagonal)",
            self.search_radius,
            SettingRange::above(0.0, 0.5),
        )?;
        check_setting(
            "feature_scale",
            "feature scale (a fraction of each shape's diagonal)",
            self.feature_scale,
            SettingRange::above(0.0, 0.1),
        )
    }
}

/// A proposed pair: a layout vertex, the target point it goes to, how sure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proposal {
    /// The layout vertex.
    pub vertex: u32,
    /// Where on the target, as a face-point.
    pub face_point: FacePoint,
    /// The same point in space.
    pub position: Vec3,
    /// In `[0, 1]`: how well the two points agree and how clearly they are each other's best.
    pub confidence: f32,
}

/// The fewest anchors the proposals start from (the geodesic ratios and the consistency need a
/// frame).
pub const MIN_GIVEN_PAIRS: usize = 3;
/// The least |protrusion| of a distinct point.
const PROTRUSION_THRESHOLD: f32 = 0.2;
/// The larger descriptor radius, in feature scales.
const LARGE_RADIUS: f32 = 3.0;
/// Points closer than this many feature radii to an anchor (on either shape) are not proposed: the
/// anchor already holds them, and a bump's rim beside an anchored tip is no feature of its own.
const ANCHOR_CLEARANCE: f32 = 3.0;

/// Proposes further pairs from the `given` ones, most confident first (see the module's
/// documentation for how).
///
/// # Errors
/// [`KernelError::InvalidArgument`] for a setting out of range or a layout without faces;
/// [`KernelError::LengthMismatch`] when the rest and current positions differ in count;
/// [`KernelError::LayoutIndexOutOfRange`] for a face or anchor naming a missing vertex;
/// [`KernelError::NonFinite`] / [`KernelError::CoordinateOutOfRange`] for a bad coordinate;
/// [`KernelError::TooFewPairs`] for fewer than [`MIN_GIVEN_PAIRS`] anchors on distinct vertices;
/// [`KernelError::CoincidentAnchors`] when the anchors of one side sit at one point.
pub fn propose_correspondences(
    target: &TargetMesh,
    layout: ProposalLayout<'_>,
    given: &[GivenPair],
    settings: &ProposalSettings,
) -> Result<Vec<Proposal>, KernelError> {
    settings.validate()?;
    let given = check_inputs(&layout, given)?;
    let triangles = fan_triangles(&layout)?;
    let rest = Shape::new(layout.rest, &triangles);
    let current_normals = Shape::new(layout.current, &triangles).normals;
    let surface = Shape::new(target.vertices(), target.triangles());
    let anchor_hits: Vec<_> = given
        .iter()
        .map(|pair| target.closest_point(pair.target, f32::INFINITY))
        .collect::<Option<_>>()
        .ok_or(KernelError::InvalidArgument {
            name: "anchors",
            reason: "an anchor's target point has no closest point on the target".into(),
        })?;
    // Geodesic distances from every anchor on both shapes, in parallel.
    let layout_geodesics: Vec<Vec<f32>> = given
        .par_iter()
        .map(|pair| rest.geodesic(&[(pair.vertex, 0.0)]))
        .collect();
    let target_geodesics: Vec<Vec<f32>> = anchor_hits
        .par_iter()
        .map(|hit| surface.geodesic(&corner_seeds(target, hit.face_point, hit.position)))
        .collect();
    let layout_unit = mean_between(&layout_geodesics, |distances, j| {
        distances[given[j].vertex as usize]
    })
    .ok_or(KernelError::CoincidentAnchors { side: "source" })?;
    let target_unit = mean_between(&target_geodesics, |distances, j| {
        at_point(
            target,
            distances,
            anchor_hits[j].face_point,
            anchor_hits[j].position,
        )
    })
    .ok_or(KernelError::CoincidentAnchors { side: "target" })?;

    // Distinct points of the layout at rest, away from the anchors.
    let layout_radius = settings.feature_scale * rest.diagonal;
    let layout_radii = [layout_radius, LARGE_RADIUS * layout_radius];
    let everyone: Vec<u32> = (0..layout.rest.len() as u32).collect();
    let layout_protrusion = rest.protrusions(&everyone, &layout_radii);
    let small: Vec<f32> = layout_protrusion.iter().map(|p| p[0]).collect();
    let clearance = ANCHOR_CLEARANCE * layout_radius;
    let layout_points: Vec<u32> = rest
        .extremes(&everyone, &small, layout_radius, PROTRUSION_THRESHOLD)
        .into_iter()
        .filter(|&v| {
            given.iter().all(|pair| {
                layout.rest[pair.vertex as usize].distance(layout.rest[v as usize]) > clearance
            })
        })
        .collect();
    let residuals: Vec<Vec3> = given
        .iter()
        .map(|pair| pair.target - layout.current[pair.vertex as usize])
        .collect();
    let layout_features: Vec<Feature> = layout_points
        .iter()
        .map(|&v| {
            let geodesic: Vec<f32> = layout_geodesics.iter().map(|d| d[v as usize]).collect();
            let softening = (LARGE_RADIUS * layout_radius).powi(2);
            let (mut moved, mut total) = (Vec3::ZERO, 0.0);
            for (&distance, &residual) in geodesic.iter().zip(&residuals) {
                if distance.is_finite() {
                    let weight = 1.0 / (distance * distance + softening);
                    moved += residual * weight;
                    total += weight;
                }
            }
            let shift = if total > 0.0 {
                moved / total
            } else {
                Vec3::ZERO
            };
            Feature {
                vertex: v,
                position: layout.current[v as usize] + shift,
                normal: current_normals[v as usize],
                protrusion: [
                    layout_protrusion[v as usize][0],
                    layout_protrusion[v as usize][1],
                ],
                geodesic: geodesic.iter().map(|d| d / layout_unit).collect(),
            }
        })
        .collect();

    // Distinct points of the target near where layout points are expected.
    let search = settings.search_radius * surface.diagonal;
    let expected: Vec<Vec3> = layout_features.iter().map(|f| f.position).collect();
    let nearby: Vec<u32> = (0..target.vertices().len() as u32)
        .into_par_iter()
        .filter(|&v| {
            let p = target.vertices()[v as usize];
            expected
                .iter()
                .any(|e| e.distance_squared(p) <= search * search)
        })
        .collect();
    let target_radius = settings.feature_scale * surface.diagonal;
    // The small radius everywhere near; the large one (costlier) only at the distinct points.
    let target_small = surface.protrusions(&nearby, &[target_radius]);
    let mut value_of = vec![f32::NAN; target.vertices().len()];
    for (&v, p) in nearby.iter().zip(&target_small) {
        value_of[v as usize] = p[0];
    }
    let target_clearance = ANCHOR_CLEARANCE * target_radius;
    let target_points: Vec<u32> = surface
        .extremes(&nearby, &value_of, target_radius, PROTRUSION_THRESHOLD)
        .into_iter()
        .filter(|&v| {
            let p = target.vertices()[v as usize];
            anchor_hits
                .iter()
                .all(|hit| hit.position.distance(p) > target_clearance)
        })
        .collect();
    let target_large = surface.protrusions(&target_points, &[LARGE_RADIUS * target_radius]);
    let target_features: Vec<Feature> = target_points
        .iter()
        .zip(&target_large)
        .map(|(&v, large)| Feature {
            vertex: v,
            position: target.vertices()[v as usize],
            normal: surface.normals[v as usize],
            protrusion: [value_of[v as usize], large[0]],
            geodesic: target_geodesics
                .iter()
                .map(|d| d[v as usize] / target_unit)
                .collect(),
        })
        .collect();

    let matches = reciprocal_matches(&layout_features, &target_features, search);
    let pairs_rest: Vec<Vec3> = matches
        .iter()
        .map(|m| layout.rest[layout_features[m.layout].vertex as usize])
        .collect();
    let pairs_target: Vec<Vec3> = matches
        .iter()
        .map(|m| target_features[m.target].position)
        .collect();
    let anchor_rest: Vec<Vec3> = given
        .iter()
        .map(|p| layout.rest[p.vertex as usize])
        .collect();
    let anchor_target: Vec<Vec3> = anchor_hits.iter().map(|h| h.position).collect();
    let scale = anchor_scale(&anchor_rest, &anchor_target);
    let kept = consistent_pairs(
        &pairs_rest,
        &pairs_target,
        &anchor_rest,
        &anchor_target,
        scale,
        LARGE_RADIUS * layout_radius,
    );
    let proposals: Vec<Proposal> = kept
        .into_iter()
        .filter_map(|(k, factor)| {
            let m = matches[k];
            let feature = &target_features[m.target];
            let hit = target.nearest_vertex(feature.position, f32::INFINITY)?;
            Some(Proposal {
                vertex: layout_features[m.layout].vertex,
                face_point: hit.face_point,
                position: hit.position,
                confidence: (m.confidence * factor).clamp(0.0, 1.0),
            })
        })
        .filter(|p| p.confidence >= settings.min_confidence)
        .collect();
    let mut proposals = symmetry::bilateral(
        proposals,
        layout.rest,
        rest.diagonal,
        layout_radius,
        &anchor_rest,
        clearance,
        scale,
    );
    proposals.sort_by(|a, b| {
        b.confidence
            .total_cmp(&a.confidence)
            .then(a.vertex.cmp(&b.vertex))
    });
    proposals.truncate(settings.max_count as usize);
    Ok(proposals)
}

/// Checks the layout and the anchors; the anchors with one per vertex (the first kept).
fn check_inputs(
    layout: &ProposalLayout<'_>,
    given: &[GivenPair],
) -> Result<Vec<GivenPair>, KernelError> {
    if layout.rest.len() != layout.current.len() {
        return Err(KernelError::LengthMismatch {
            what: "layout rest and current positions",
            first: layout.rest.len(),
            second: layout.current.len(),
        });
    }
    check_coordinates("layout rest position", layout.rest)?;
    check_coordinates("layout position", layout.current)?;
    if layout.faces.sizes.is_empty() {
        return Err(KernelError::InvalidArgument {
            name: "faces",
            reason: "the layout has no faces".into(),
        });
    }
    let vertex_count = layout.rest.len();
    let mut seen = std::collections::HashSet::new();
    let mut unique = Vec::with_capacity(given.len());
    for (index, pair) in given.iter().enumerate() {
        if pair.vertex as usize >= vertex_count {
            return Err(KernelError::LayoutIndexOutOfRange {
                element: "anchor",
                index,
                vertex: pair.vertex,
                vertex_count,
            });
        }
        check_coordinate("anchor target", index, pair.target)?;
        if seen.insert(pair.vertex) {
            unique.push(*pair);
        }
    }
    if unique.len() < MIN_GIVEN_PAIRS {
        return Err(KernelError::TooFewPairs {
            what: "correspondence proposals (anchors on distinct vertices)",
            given: unique.len(),
            needed: MIN_GIVEN_PAIRS,
        });
    }
    Ok(unique)
}

/// The layout's faces as a triangle fan each (faces checked against the vertex count).
fn fan_triangles(layout: &ProposalLayout<'_>) -> Result<Vec<[u32; 3]>, KernelError> {
    let starts = layout.faces.starts(layout.rest.len())?;
    let mut triangles = Vec::with_capacity(layout.faces.corners.len());
    for (&start, &size) in starts.iter().zip(layout.faces.sizes) {
        let corners = &layout.faces.corners[start..start + size as usize];
        for i in 1..corners.len().saturating_sub(1) {
            triangles.push([corners[0], corners[i], corners[i + 1]]);
        }
    }
    Ok(triangles)
}

/// A face-point's triangle corners with their distances to it: a geodesic's seeds.
fn corner_seeds(target: &TargetMesh, face_point: FacePoint, position: Vec3) -> Vec<(u32, f32)> {
    target.triangles()[face_point.triangle as usize]
        .iter()
        .map(|&corner| {
            (
                corner,
                target.vertices()[corner as usize].distance(position),
            )
        })
        .collect()
}

/// A geodesic distance field read at a face-point (through the nearest of its corners).
fn at_point(target: &TargetMesh, distances: &[f32], face_point: FacePoint, position: Vec3) -> f32 {
    corner_seeds(target, face_point, position)
        .into_iter()
        .map(|(corner, offset)| distances[corner as usize] + offset)
        .fold(f32::INFINITY, f32::min)
}

/// The mean over pairs of anchors of their distance `read(field of i, j)`, finite ones only;
/// `None` when there is none or it is zero.
fn mean_between(fields: &[Vec<f32>], read: impl Fn(&[f32], usize) -> f32) -> Option<f32> {
    let (mut sum, mut count) = (0.0f64, 0usize);
    for (i, field) in fields.iter().enumerate() {
        for j in (i + 1)..fields.len() {
            let distance = read(field, j);
            if distance.is_finite() {
                sum += f64::from(distance);
                count += 1;
            }
        }
    }
    let mean = (count > 0).then(|| (sum / count as f64) as f32)?;
    (mean > 0.0).then_some(mean)
}

/// The median ratio of the anchors' distances on the target to their distances at rest.
fn anchor_scale(rest: &[Vec3], target: &[Vec3]) -> f32 {
    let mut ratios = Vec::new();
    for i in 0..rest.len() {
        for j in (i + 1)..rest.len() {
            let at_rest = rest[i].distance(rest[j]);
            if at_rest > 0.0 {
                ratios.push(target[i].distance(target[j]) / at_rest);
            }
        }
    }
    if ratios.is_empty() {
        return 1.0;
    }
    ratios.sort_by(f32::total_cmp);
    ratios[ratios.len() / 2]
}
