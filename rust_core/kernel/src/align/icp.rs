//! Point-to-plane ICP: refines a transform of source points so they land on a target surface.
//!
//! Each iteration pairs every transformed source point with its closest point on the target,
//! drops pairs that cannot be trusted (farther than `max_distance`, landing on a boundary edge of
//! a hole or border, or among the worst `trim_fraction`), then solves the linearised
//! small-angle update that minimises the squared distances to the pairs' tangent planes
//! (6x6 normal equations for a rigid update, 7x7 with a uniform scale), by Cholesky.
//!
//! [`icp_anchored`] also keeps anchor pairs (a source point and where it must go) in the fit, as
//! point-to-point terms with a chosen share of the weight, so that ICP refines an anchor fit
//! without sliding away from what the anchors say where the shapes differ.

use glam::{DQuat, DVec3, Vec3};

use super::linear_algebra::cholesky_solve;
use super::transform::Transform;
use crate::error::KernelError;
use crate::mesh::{NO_TRIANGLE, TargetMesh};
use crate::validate::{self, SettingRange, check_setting};

/// Which transforms one ICP step may apply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IcpUpdate {
    /// Rotation and translation.
    Rigid,
    /// Rotation, uniform scale and translation.
    Similarity,
}

/// How ICP runs. [`IcpSettings::default`] is a rigid update, 50 iterations, 10 % trimmed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpSettings {
    /// Rigid or similarity steps.
    pub update: IcpUpdate,
    /// The most iterations to run.
    pub max_iterations: u32,
    /// Fraction of the pairs, the farthest ones, ignored in each iteration; in `[0, 1)`.
    pub trim_fraction: f32,
    /// Pairs farther apart than this are ignored (`f32::INFINITY`: no limit).
    pub max_distance: f32,
    /// Converged when the RMS distance changes by less than this fraction of the target's
    /// bounding-box diagonal between two iterations.
    pub tolerance: f64,
    /// Ignore pairs whose closest point lies on a boundary edge (a hole or an open border): such
    /// points are usually over a hole, not near the surface they belong to.
    pub ignore_boundary: bool,
}

impl IcpSettings {
    /// The ranges of the settings (field, what it is, range): at most 100,000 iterations; a trim
    /// fraction in `[0, 1)`; a positive `max_distance` up to [`crate::MAX_COORDINATE`] or
    /// infinite (no limit); a tolerance in `[0, 1]`.
    pub const RANGES: [(&'static str, &'static str, SettingRange); 4] = [
        (
            "max_iterations",
            "number of ICP iterations",
            SettingRange::closed(0.0, 100_000.0),
        ),
        (
            "trim_fraction",
            "trim fraction",
            SettingRange::below(0.0, 1.0),
        ),
        (
            "max_distance",
            "maximum pair distance",
            SettingRange::above(0.0, validate::MAX_COORDINATE as f64).or_infinite(),
        ),
        ("tolerance", "tolerance", SettingRange::closed(0.0, 1.0)),
    ];

    /// The range of [`IcpAnchors::weight`]: 0 to a million.
    pub const ANCHOR_WEIGHT_RANGE: SettingRange = SettingRange::closed(0.0, 1e6);
}

impl Default for IcpSettings {
    fn default() -> Self {
        Self {
            update: IcpUpdate::Rigid,
            max_iterations: 50,
            trim_fraction: 0.1,
            max_distance: f32::INFINITY,
            tolerance: 1e-7,
            ignore_boundary: true,
        }
    }
}

/// What an ICP run did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpReport {
    /// The refined transform (source to target), the initial one composed with every step.
    pub transform: Transform,
    /// Iterations run (steps applied).
    pub iterations: u32,
    /// True when the RMS change fell below the tolerance before `max_iterations`.
    pub converged: bool,
    /// RMS distance of the pairs used, at the initial transform.
    pub rms_before: f64,
    /// RMS distance of the pairs used, at the returned transform.
    pub rms_after: f64,
    /// Pairs used in the last evaluation (after trimming and the distance and boundary checks).
    pub pairs_used: usize,
}

/// Anchor pairs ICP keeps in its fit: `source[i]` (mapped by the transform) is pulled to
/// `target[i]`, point to point.
#[derive(Debug, Clone, Copy, Default)]
pub struct IcpAnchors<'a> {
    /// Anchor points on the source side (the same space as ICP's source points).
    pub source: &'a [Vec3],
    /// Where each anchor point must go.
    pub target: &'a [Vec3],
    /// The anchors' share of the fit: all anchors together weigh `weight` times all the surface
    /// pairs together (0: the anchors are ignored; 1: as much as the surface).
    pub weight: f64,
}

/// One trusted pair: the transformed source point, its closest target point and that face's
/// normal (an anchor gives three pairs, one per axis), and its weight in the fit.
#[derive(Clone, Copy)]
struct Pair {
    point: DVec3,
    closest: DVec3,
    normal: DVec3,
    distance: f64,
    weight: f64,
}

/// Refines `initial` so that `source` mapped by it lies on `target`, by trimmed point-to-plane ICP.
///
/// # Errors
/// [`KernelError::NonFinite`] for a NaN or infinite source point;
/// [`KernelError::InvalidArgument`] for a non-finite `initial`, or settings out of range;
/// [`KernelError::TooFewPairs`] when fewer trusted pairs remain than the update has unknowns.
pub fn icp(
    target: &TargetMesh,
    source: &[Vec3],
    initial: Transform,
    settings: IcpSettings,
) -> Result<IcpReport, KernelError> {
    icp_anchored(target, source, IcpAnchors::default(), initial, settings)
}

/// [`icp`] that also keeps `anchors` in the fit (see [`IcpAnchors`]). The report's RMS values are
/// the surface pairs' alone; convergence is judged on the whole weighted fit.
///
/// # Errors
/// Those of [`icp`]; [`KernelError::LengthMismatch`] when the anchors' two sides differ in
/// length; [`KernelError::NonFinite`] for a NaN or infinite anchor point;
/// [`KernelError::InvalidArgument`] for a negative or non-finite anchor weight.
pub fn icp_anchored(
    target: &TargetMesh,
    source: &[Vec3],
    anchors: IcpAnchors<'_>,
    initial: Transform,
    settings: IcpSettings,
) -> Result<IcpReport, KernelError> {
    check_settings(&settings)?;
    check_anchors(&anchors)?;
    validate::check_coordinates("source point", source)?;
    if !initial.is_finite() {
        return Err(KernelError::InvalidArgument {
            name: "initial",
            reason: "the initial transform has a NaN or infinite entry".to_owned(),
        });
    }
    // The source where `initial` puts it is what the queries see: it must be within bounds too.
    for (index, point) in source.iter().enumerate() {
        let moved = initial.apply_f64(point.as_dvec3());
        let largest = moved.abs().max_element();
        if largest.is_nan() || largest > f64::from(validate::MAX_COORDINATE) {
            return Err(KernelError::InvalidArgument {
                name: "initial",
                reason: format!(
                    "it moves source point {index} to {moved}, beyond the kernel's bound of ±{:e}",
                    validate::MAX_COORDINATE
                ),
            });
        }
    }
    let (low, high) = target.bounding_box();
    let diagonal = f64::from((high - low).length()).max(f64::MIN_POSITIVE);
    let tolerance = settings.tolerance * diagonal;
    let unknowns = match settings.update {
        IcpUpdate::Rigid => 6,
        IcpUpdate::Similarity => 7,
    };

    let mut transform = initial;
    let mut pairs = trusted_pairs(target, source, &transform, &settings)?;
    if pairs.len() < unknowns {
        return Err(KernelError::TooFewPairs {
            what: "ICP",
            given: pairs.len(),
            needed: unknowns,
        });
    }
    let rms_before = rms(&pairs);
    let mut current_rms = rms_before;
    let mut current_fit = fit_rms(&pairs, &anchors, &transform);
    let mut iterations = 0;
    let mut converged = false;
    while iterations < settings.max_iterations {
        let mut all_pairs = anchor_pairs(&anchors, &transform, pairs.len());
        all_pairs.extend_from_slice(&pairs);
        let Some(step) = solve_step(&all_pairs, settings.update) else {
            break;
        };
        let candidate = step.after(&transform);
        let candidate_pairs = trusted_pairs(target, source, &candidate, &settings)?;
        if candidate_pairs.len() < unknowns {
            break;
        }
        transform = candidate;
        pairs = candidate_pairs;
        iterations += 1;
        current_rms = rms(&pairs);
        let new_fit = fit_rms(&pairs, &anchors, &transform);
        let change = (new_fit - current_fit).abs();
        current_fit = new_fit;
        if change <= tolerance {
            converged = true;
            break;
        }
    }
    Ok(IcpReport {
        transform,
        iterations,
        converged,
        rms_before,
        rms_after: current_rms,
        pairs_used: pairs.len(),
    })
}

fn check_anchors(anchors: &IcpAnchors<'_>) -> Result<(), KernelError> {
    if anchors.source.len() != anchors.target.len() {
        return Err(KernelError::LengthMismatch {
            what: "anchor sources and targets",
            first: anchors.source.len(),
            second: anchors.target.len(),
        });
    }
    validate::check_coordinates("anchor source", anchors.source)?;
    validate::check_coordinates("anchor target", anchors.target)?;
    check_setting(
        "anchor_weight",
        "anchor weight",
        anchors.weight,
        IcpSettings::ANCHOR_WEIGHT_RANGE,
    )
}

/// The weight of one anchor: all anchors together weigh `weight` times the `surface_count` pairs.
fn anchor_weight(anchors: &IcpAnchors<'_>, surface_count: usize) -> f64 {
    if anchors.source.is_empty() {
        return 0.0;
    }
    anchors.weight * surface_count as f64 / anchors.source.len() as f64
}

/// Three point-to-point pairs per anchor (one per axis), at `transform`; none when the weight is 0.
fn anchor_pairs(
    anchors: &IcpAnchors<'_>,
    transform: &Transform,
    surface_count: usize,
) -> Vec<Pair> {
    let weight = anchor_weight(anchors, surface_count);
    if weight <= 0.0 {
        return Vec::new();
    }
    let mut pairs = Vec::with_capacity(anchors.source.len() * 3);
    for (source, target) in anchors.source.iter().zip(anchors.target) {
        let point = transform.apply_f64(source.as_dvec3());
        for normal in [DVec3::X, DVec3::Y, DVec3::Z] {
            pairs.push(Pair {
                point,
                closest: target.as_dvec3(),
                normal,
                distance: 0.0, // unused: the RMS values are the surface pairs' alone
                weight,
            });
        }
    }
    pairs
}

/// The whole fit's error as an RMS over the surface pairs: `sqrt((Σ d² + Σ w |p − q|²) / n)`.
fn fit_rms(pairs: &[Pair], anchors: &IcpAnchors<'_>, transform: &Transform) -> f64 {
    let surface: f64 = pairs.iter().map(|pair| pair.distance * pair.distance).sum();
    let weight = anchor_weight(anchors, pairs.len());
    let anchored: f64 = if weight > 0.0 {
        anchors
            .source
            .iter()
            .zip(anchors.target)
            .map(|(source, target)| {
                weight
                    * transform
                        .apply_f64(source.as_dvec3())
                        .distance_squared(target.as_dvec3())
            })
            .sum()
    } else {
        0.0
    };
    ((surface + anchored) / pairs.len().max(1) as f64).sqrt()
}

fn check_settings(settings: &IcpSettings) -> Result<(), KernelError> {
    let [iterations, trim, distance, tolerance] = IcpSettings::RANGES;
    check_setting(
        iterations.0,
        iterations.1,
        settings.max_iterations,
        iterations.2,
    )?;
    check_setting(trim.0, trim.1, settings.trim_fraction, trim.2)?;
    check_setting(distance.0, distance.1, settings.max_distance, distance.2)?;
    check_setting(tolerance.0, tolerance.1, settings.tolerance, tolerance.2)
}

/// The pairs to trust at `transform`: within `max_distance`, not on a boundary edge (when asked),
/// on a triangle with a normal, and not among the worst `trim_fraction`; nearest first.
fn trusted_pairs(
    target: &TargetMesh,
    source: &[Vec3],
    transform: &Transform,
    settings: &IcpSettings,
) -> Result<Vec<Pair>, KernelError> {
    let points: Vec<DVec3> = source
        .iter()
        .map(|point| transform.apply_f64(point.as_dvec3()))
        .collect();
    let queries: Vec<Vec3> = points.iter().map(|point| point.as_vec3()).collect();
    let hits = target.closest_points(&queries, settings.max_distance)?;
    let neighbors = target.triangle_neighbors();
    let normals = target.face_normals();
    let mut pairs: Vec<Pair> = points
        .iter()
        .zip(hits)
        .filter_map(|(&point, hit)| {
            let hit = hit?;
            let triangle = hit.face_point.triangle as usize;
            let normal = normals[triangle].as_dvec3();
            if normal.length_squared() < 0.5 {
                return None;
            }
            if settings.ignore_boundary {
                let barycentric = hit.face_point.barycentric.to_array();
                // Edge e runs from corner e to corner e + 1: on it, the weight of corner e + 2 is 0.
                let on_boundary = (0..3).any(|edge| {
                    neighbors[triangle][edge] == NO_TRIANGLE && barycentric[(edge + 2) % 3] <= 1e-5
                });
                if on_boundary {
                    return None;
                }
            }
            let closest = hit.position.as_dvec3();
            Some(Pair {
                point,
                closest,
                normal,
                distance: point.distance(closest),
                weight: 1.0,
            })
        })
        .collect();
    pairs.sort_by(|a, b| a.distance.total_cmp(&b.distance));
    let trimmed = (f64::from(settings.trim_fraction) * pairs.len() as f64).floor() as usize;
    pairs.truncate(pairs.len() - trimmed);
    Ok(pairs)
}

/// Root mean square of the pairs' distances.
fn rms(pairs: &[Pair]) -> f64 {
    let sum: f64 = pairs.iter().map(|pair| pair.distance * pair.distance).sum();
    (sum / pairs.len().max(1) as f64).sqrt()
}

/// The step `x -> c + s R (x - c) + t` (about the pairs' centroid `c`) that minimises
/// `Σ (n · (step(x) - y))²` to first order in the rotation vector and `s - 1`, or `None` when
/// the normal equations are singular.
fn solve_step(pairs: &[Pair], update: IcpUpdate) -> Option<Transform> {
    let total_weight: f64 = pairs.iter().map(|pair| pair.weight).sum();
    let centroid = pairs
        .iter()
        .map(|pair| pair.point * pair.weight)
        .sum::<DVec3>()
        / total_weight;
    let mut normal_matrix = [[0.0; 7]; 7];
    let mut rhs = [0.0; 7];
    let unknowns = if update == IcpUpdate::Similarity {
        7
    } else {
        6
    };
    for pair in pairs {
        let offset = pair.point - centroid;
        let residual = pair.normal.dot(pair.point - pair.closest);
        let rotation_part = offset.cross(pair.normal);
        let row = [
            rotation_part.x,
            rotation_part.y,
            rotation_part.z,
            pair.normal.x,
            pair.normal.y,
            pair.normal.z,
            pair.normal.dot(offset),
        ];
        for i in 0..unknowns {
            for j in 0..unknowns {
                normal_matrix[i][j] += pair.weight * row[i] * row[j];
            }
            rhs[i] -= pair.weight * row[i] * residual;
        }
    }
    // A light Levenberg damping keeps directions the surface does not constrain (turning a
    // sphere about its centre, sliding along a plane) at zero instead of letting them drift.
    let trace: f64 = (0..unknowns).map(|i| normal_matrix[i][i]).sum();
    let damping = 1e-9 * trace / unknowns as f64 + f64::MIN_POSITIVE;
    let delta = if update == IcpUpdate::Similarity {
        for (i, row) in normal_matrix.iter_mut().enumerate() {
            row[i] += damping;
        }
        cholesky_solve(&normal_matrix, &rhs)?
    } else {
        let mut rigid = [[0.0; 6]; 6];
        for i in 0..6 {
            rigid[i].copy_from_slice(&normal_matrix[i][..6]);
            rigid[i][i] += damping;
        }
        let solution = cholesky_solve(&rigid, &std::array::from_fn(|i| rhs[i]))?;
        std::array::from_fn(|i| if i < 6 { solution[i] } else { 0.0 })
    };
    if delta.iter().any(|value| !value.is_finite()) {
        return None;
    }
    let rotation = DQuat::from_scaled_axis(DVec3::new(delta[0], delta[1], delta[2]));
    let translation = DVec3::new(delta[3], delta[4], delta[5]);
    let scale = (1.0 + delta[6]).max(0.5);
    let linear = glam::DMat3::from_quat(rotation) * scale;
    let columns = linear.to_cols_array_2d();
    let rows = std::array::from_fn(|row| std::array::from_fn(|column| columns[column][row]));
    Some(Transform::from_linear_translation(
        rows,
        centroid + translation - linear * centroid,
    ))
}
