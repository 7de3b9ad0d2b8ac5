//! Least-squares fits of a transform to point pairs (anchors): rigid, similarity and affine.
//!
//! Rigid and similarity use Horn's quaternion method, which gives the same optimum as Umeyama
//! (1991) with its determinant correction: the rotation is always proper, never a reflection,
//! even when the pairs are mirrored. The affine fit is plain weighted least squares.

use glam::{DMat3, DQuat, DVec3, Vec3};

use super::linear_algebra::{cholesky_solve, symmetric_eigen};
use super::transform::Transform;
use crate::error::KernelError;

/// Which family of transforms a fit chooses from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlignMethod {
    /// Rotation and translation (6 degrees of freedom); needs 3 anchors not on one line.
    Rigid,
    /// Rotation, uniform scale and translation (7); needs 3 anchors not on one line.
    Similarity,
    /// Any affine map (12): shears and non-uniform scales too; needs 4 anchors not in one plane.
    Affine,
}

impl AlignMethod {
    /// The name used in error messages, e.g. `"rigid fit"`.
    #[must_use]
    pub fn fit_name(self) -> &'static str {
        match self {
            Self::Rigid => "rigid fit",
            Self::Similarity => "similarity fit",
            Self::Affine => "affine fit",
        }
    }

    /// The least number of anchor pairs that determine the transform.
    #[must_use]
    pub fn minimum_pairs(self) -> usize {
        match self {
            Self::Rigid | Self::Similarity => 3,
            Self::Affine => 4,
        }
    }
}

/// Spreads at or below this fraction of the points' extent count as zero (f32 inputs carry
/// about 1e-7 relative precision).
const DEGENERATE_SPREAD: f64 = 1e-6;

/// Fits the transform of family `method` that best maps `source[i]` onto `target[i]` in the
/// weighted least-squares sense (weights default to 1; pairs of weight 0 are ignored).
///
/// # Errors
/// [`KernelError::LengthMismatch`] when `source`, `target` (and `weights`) differ in length;
/// [`KernelError::NonFinite`] for a NaN or infinite coordinate or weight;
/// [`KernelError::CoordinateOutOfRange`] for a coordinate beyond [`crate::MAX_COORDINATE`];
/// [`KernelError::InvalidArgument`] for a negative weight;
/// [`KernelError::TooFewPairs`] with fewer pairs of positive weight than
/// [`AlignMethod::minimum_pairs`]; [`KernelError::CoincidentAnchors`] when one side's anchors all
/// sit at one point; [`KernelError::CollinearAnchors`] (rigid, similarity) when either side's
/// anchors lie on one line; [`KernelError::CoplanarAnchors`] (affine) when the source anchors
/// cannot fix every axis.
pub fn fit_transform(
    source: &[Vec3],
    target: &[Vec3],
    method: AlignMethod,
    weights: Option<&[f32]>,
) -> Result<Transform, KernelError> {
    if source.len() != target.len() {
        return Err(KernelError::LengthMismatch {
            what: "source and target anchors",
            first: source.len(),
            second: target.len(),
        });
    }
    check_finite_points("source anchor", source)?;
    check_finite_points("target anchor", target)?;
    let weights = check_weights(weights, source.len())?;
    let usable = weights.iter().filter(|&&weight| weight > 0.0).count();
    if usable < method.minimum_pairs() {
        return Err(KernelError::TooFewPairs {
            what: method.fit_name(),
            given: usable,
            needed: method.minimum_pairs(),
        });
    }

    let source: Vec<DVec3> = source.iter().map(|point| point.as_dvec3()).collect();
    let target: Vec<DVec3> = target.iter().map(|point| point.as_dvec3()).collect();
    let total: f64 = weights.iter().sum();
    let weighted_mean = |points: &[DVec3]| {
        points
            .iter()
            .zip(&weights)
            .map(|(&point, &weight)| point * weight)
            .sum::<DVec3>()
            / total
    };
    let source_centroid = weighted_mean(&source);
    let target_centroid = weighted_mean(&target);

    // Spread of each side: eigenvalues of the weighted covariance, largest first.
    let spread = |points: &[DVec3], centroid: DVec3| {
        let covariance = weighted_outer_sum(points, centroid, points, centroid, &weights);
        let (values, _) = symmetric_eigen(covariance);
        let extent = points
            .iter()
            .zip(&weights)
            .filter(|(_, weight)| **weight > 0.0)
            .map(|(point, _)| point.abs().max_element())
            .fold(f64::MIN_POSITIVE, f64::max);
        let deviations = values.map(|value| (value.max(0.0) / total).sqrt());
        (deviations, extent)
    };
    let (source_deviation, source_extent) = spread(&source, source_centroid);
    let (target_deviation, target_extent) = spread(&target, target_centroid);
    if source_deviation[0] <= DEGENERATE_SPREAD * source_extent {
        return Err(KernelError::CoincidentAnchors { side: "source" });
    }
    if target_deviation[0] <= DEGENERATE_SPREAD * target_extent {
        return Err(KernelError::CoincidentAnchors { side: "target" });
    }

    match method {
        AlignMethod::Rigid | AlignMethod::Similarity => {
            if source_deviation[1] <= DEGENERATE_SPREAD * source_deviation[0] {
                return Err(KernelError::CollinearAnchors {
                    side: "source",
                    count: usable,
                });
            }
            if target_deviation[1] <= DEGENERATE_SPREAD * target_deviation[0] {
                return Err(KernelError::CollinearAnchors {
                    side: "target",
                    count: usable,
                });
            }
            // cross[a][b] = Σ w (p - p̄)_a (q - q̄)_b.
            let cross =
                weighted_outer_sum(&source, source_centroid, &target, target_centroid, &weights);
            let rotation = horn_rotation(&cross);
            let scale = if method == AlignMethod::Similarity {
                let numerator: f64 = source
                    .iter()
                    .zip(&target)
                    .zip(&weights)
                    .map(|((&p, &q), &w)| {
                        w * (q - target_centroid).dot(rotation * (p - source_centroid))
                    })
                    .sum();
                let denominator: f64 = source
                    .iter()
                    .zip(&weights)
                    .map(|(&p, &w)| w * (p - source_centroid).length_squared())
                    .sum();
                numerator / denominator
            } else {
                1.0
            };
            let linear = DMat3::from_quat(rotation) * scale;
            let translation = target_centroid - linear * source_centroid;
            Ok(Transform::from_linear_translation(
                rows_of(&linear),
                translation,
            ))
        }
        AlignMethod::Affine => {
            if source_deviation[2] <= DEGENERATE_SPREAD * source_deviation[0] {
                return Err(KernelError::CoplanarAnchors { count: usable });
            }
            // A C = B with C = Σ w p̃ p̃ᵀ and B = Σ w q̃ p̃ᵀ; C is symmetric, so row r of A
            // solves C a_r = B[r].
            let covariance =
                weighted_outer_sum(&source, source_centroid, &source, source_centroid, &weights);
            let target_by_source =
                weighted_outer_sum(&target, target_centroid, &source, source_centroid, &weights);
            let mut linear = [[0.0; 3]; 3];
            for (row, out) in linear.iter_mut().enumerate() {
                *out = cholesky_solve(&covariance, &target_by_source[row])
                    .ok_or(KernelError::CoplanarAnchors { count: usable })?;
            }
            let matrix = DMat3::from_cols_array_2d(&linear).transpose();
            let translation = target_centroid - matrix * source_centroid;
            Ok(Transform::from_linear_translation(linear, translation))
        }
    }
}

/// `Σ w (a - ā)(b - b̄)ᵀ` as a row-major 3x3: entry `[r][c]` is `Σ w (a - ā)_r (b - b̄)_c`.
fn weighted_outer_sum(
    first: &[DVec3],
    first_centroid: DVec3,
    second: &[DVec3],
    second_centroid: DVec3,
    weights: &[f64],
) -> [[f64; 3]; 3] {
    let mut sum = [[0.0; 3]; 3];
    for ((&a, &b), &weight) in first.iter().zip(second).zip(weights) {
        let a = (a - first_centroid).to_array();
        let b = (b - second_centroid).to_array();
        for (row, out) in sum.iter_mut().enumerate() {
            for (column, value) in out.iter_mut().enumerate() {
                *value += weight * a[row] * b[column];
            }
        }
    }
    sum
}

/// The proper rotation `R` maximising `Σ w (q - q̄)·R (p - p̄)`, from `cross` (see
/// [`weighted_outer_sum`]): the eigenvector of the largest eigenvalue of Horn's symmetric 4x4.
pub(crate) fn horn_rotation(cross: &[[f64; 3]; 3]) -> DQuat {
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = *cross;
    let horn = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let (_, vectors) = symmetric_eigen(horn);
    let [w, x, y, z] = vectors[0];
    DQuat::from_xyzw(x, y, z, w).normalize()
}

/// The rows of `matrix` (glam stores columns).
fn rows_of(matrix: &DMat3) -> [[f64; 3]; 3] {
    let columns = matrix.to_cols_array_2d();
    std::array::from_fn(|row| std::array::from_fn(|column| columns[column][row]))
}

fn check_finite_points(what: &'static str, points: &[Vec3]) -> Result<(), KernelError> {
    crate::validate::check_coordinates(what, points)
}

/// The weights as f64 (all 1 when absent), checked for length, finiteness and sign.
fn check_weights(weights: Option<&[f32]>, count: usize) -> Result<Vec<f64>, KernelError> {
    let Some(weights) = weights else {
        return Ok(vec![1.0; count]);
    };
    if weights.len() != count {
        return Err(KernelError::LengthMismatch {
            what: "anchors and weights",
            first: count,
            second: weights.len(),
        });
    }
    if let Some(index) = weights.iter().position(|weight| !weight.is_finite()) {
        return Err(KernelError::NonFinite {
            what: "weight",
            index,
        });
    }
    if let Some(index) = weights.iter().position(|&weight| weight < 0.0) {
        return Err(KernelError::InvalidArgument {
            name: "weights",
            reason: format!("weight {index} is negative ({})", weights[index]),
        });
    }
    Ok(weights.iter().map(|&weight| f64::from(weight)).collect())
}
