//! The energy wrap's global-to-local schedule: stiff, nearly affine levels before the local fit.
//!
//! With few anchors on a large change of shape, the default schedule's first level already pulls
//! the layout onto the nearest surface with one scale for all: a heavier body's girth cannot be
//! expressed, and the data term drags the layout sideways into a wrong fit (an arm onto the
//! torso). This schedule gives every vertex a **stretch** `S_i` (a symmetric 3×3 in the rest
//! frame) besides its rotation, so that the shape terms ask `x_j − x_i ≈ R_i S_i (r_j − r_i)`:
//! local scale and shear are free, as in non-rigid ICP's per-vertex affine transforms (Amberg et
//! al. 2007). Stiffness is the smoothing of the stretches and rotations over many rings (one
//! factored solve each, `smoothing`), relaxed level by level (a near-affine deformation of whole regions first, local at the end), while the
//! data term tightens from weak and wide to strong and narrow; then the default schedule's local
//! levels follow, with the stretches kept.

mod choice;
mod smoothing;

use glam::{DVec3, Mat3, Quat, Vec3, Vec4};
use rayon::prelude::*;

use super::energy_solver::{LEVELS, Level};
use super::similarity::Similarity;
use crate::error::KernelError;
use crate::layout::LayoutStructure;
pub(crate) use choice::{choose_schedule, global_phase_fits};
use smoothing::Smoother;

/// The global-to-local schedule: three stiff levels whose stretches are smoothed as 16,384, 4,096
/// and 512 rounds of neighbour averaging would (about 128, 64 and 23 rings: rounds ≈ rings²) and
/// rotations as 4,096, 1,024 and 128, with a weak and wide data term (λ = 0.03, 0.1, 0.5; σ = 10,
/// 6, 3 mean edges), then the default schedule's local levels. Chosen by measurement on the
/// benchmark bodies with 6 anchors (`benchmarks/few_anchors.py`'s cases through the kernel alone):
/// 16 times stiffer than rounds of averaging could afford (1,024, 256, 64) with a three times
/// stronger data term lowered the mean error from 0.275 %, 0.489 %, 0.461 % of the diagonal (the
/// heavy, heavy-old and old-male bodies) to 0.244 %, 0.476 %, 0.438 % and the flipped quads from
/// 11, 21, 16 to 9, 14, 5; 64 times stiffer was better on one body and worse on another, a ten times stronger data
/// term worse, a fourth stiff level or fewer iterations worse. The last stiff level at 512 and 128
/// rounds instead of 1,024 and 256 (`benchmarks/few_anchors.py`, the wrap alone, one run each):
/// with 6 anchors the mean error on the heavy-old body from 0.465 % to 0.463 % (0.802 to 0.798 times
/// nricp's) and on the old-male body from 0.441 % to 0.433 %, on the heavy body 0.241 % to 0.243 %,
/// flipped quads as before; with 12 and 24 anchors no body worse (old-male 0.418 % to 0.416 % and
/// 0.309 % to 0.307 %); with 4 old-male 0.909 % to 0.895 %, heavy and young-female 0.002 % worse,
/// heavy-old one flipped quad more. At 256 and 64 heavy-old reached 0.461 % but the heavy
/// body 0.244 % with 8 flipped quads; a fourth level (λ = 1, 256 and 64 rounds) 0.461 % and 0.245 %
/// with 8 flipped; a least alignment of 0.8, reciprocity kept in two levels, other reciprocity
/// ratios or the facing weight squared or rooted were worse on heavy-old (0.473 % to 0.479 %).
pub(crate) const GLOBAL_TO_LOCAL_LEVELS: [Level; 6] = [
    STIFF_LEVELS[0],
    STIFF_LEVELS[1],
    STIFF_LEVELS[2],
    LEVELS[1],
    LEVELS[2],
    LEVELS[3],
];

/// The stiff levels of [`GLOBAL_TO_LOCAL_LEVELS`].
const STIFF_LEVELS: [Level; 3] = [
    Level {
        data_weight: 0.03,
        welsch_width: 10.0,
        scale_smoothing: Some(16_384),
        rotation_smoothing: 4096,
        max_iterations: 20,
    },
    Level {
        data_weight: 0.1,
        welsch_width: 6.0,
        scale_smoothing: Some(4096),
        rotation_smoothing: 1024,
        max_iterations: 12,
    },
    Level {
        data_weight: 0.5,
        welsch_width: 3.0,
        scale_smoothing: Some(512),
        rotation_smoothing: 128,
        max_iterations: 8,
    },
];

/// In the stiff levels (the first [`RECIPROCAL_LEVELS`]), a correspondence farther than
/// [`RECIPROCAL_NEAR`] mean edges is kept only when no layout point outside its own
/// neighbourhood ([`RECIPROCAL_NEAR`] edges) lies nearer to the point it is pulled to than
/// [`RECIPROCAL_RATIO`] times its own distance: an arm is not pulled onto a torso that has its own
/// layout right there. (Measured with the first stiff levels tried: a ratio of 1 hurt with 4
/// anchors; no reciprocity at all hurt the heavy body with 6.)
pub(crate) const RECIPROCAL_LEVELS: usize = 3;
const RECIPROCAL_NEAR: f32 = 2.0;
const RECIPROCAL_RATIO: f32 = 0.5;

/// In the global-to-local schedule a layout corner may turn from its rest normal (turned by the
/// layout's frame) until this cosine, about 45 degrees, where the local schedule lets it reach 90:
/// the stretches let a region shear far, and a corner let through at 80 degrees from its rest
/// normal faces against the surface wherever the change of shape has turned the surface too
/// (armpits, hands at the hips, folds of a heavy body). Measured with 6 anchors
/// (`benchmarks/few_anchors.py`'s global-to-local wrap; flipped quads against the true layout and
/// mean error in % of the diagonal, on the heavy, heavy-old, old-male and young-female bodies):
/// at 0 (the local schedule's) 9, 17, 15, 1 flipped and 0.244, 0.480, 0.446, 0.373; at 0.3 9, 5,
/// 4 and 0.244, 0.474, 0.434; at 0.5 10, 4, 2 and 0.244, 0.468, 0.431; at 0.7 8, 3, 0, 3 and
/// 0.246, 0.469, 0.429, 0.348; at 0.85 6, 2, 0, 2 but 0.462 on the old-male body.
pub(crate) const GLOBAL_MIN_ALIGNMENT: f32 = 0.7;

/// A stretch's determinant may not fall below this fraction of its mean scale cubed (a region
/// squashed flat or turned inside out by averaging); such a stretch becomes its mean scale.
const MIN_STRETCH_VOLUME: f32 = 0.05;
/// Per-vertex stretches stay within this factor of the median scale.
const STRETCH_RANGE: f32 = 3.0;

/// The stretches of the global-to-local schedule, and what fitting them needs.
#[derive(Debug, Clone)]
pub(crate) struct Stretches {
    /// Per vertex, its rest position and unit rest normal.
    rest: Vec<Vec3>,
    rest_normals: Vec<Vec3>,
    /// Per vertex, `S_i` (the shape terms ask `R_i S_i` of its rest vectors).
    pub(crate) values: Vec<Mat3>,
    /// Smooths the stretches and the rotations (one factored solve each instead of rounds of
    /// averaging).
    stretch_smoother: Smoother,
    rotation_smoother: Smoother,
}

impl Stretches {
    /// Isotropic unit stretches for a layout resting at `rest`.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the smoothing's system cannot be built.
    pub(crate) fn new(structure: &LayoutStructure, rest: &[Vec3]) -> Result<Self, KernelError> {
        let rest_normals = (0..rest.len() as u32)
            .into_par_iter()
            .with_min_len(2048)
            .map(|vertex| structure.normal_at(rest, vertex).normalize_or_zero())
            .collect();
        let stretch_smoother = Smoother::new(structure)?;
        Ok(Self {
            rest: rest.to_vec(),
            rest_normals,
            values: vec![Mat3::IDENTITY; rest.len()],
            rotation_smoother: stretch_smoother.clone(),
            stretch_smoother,
        })
    }

    /// Replaces each rotation of `similarities` by its average over about `√rounds` rings (as
    /// quaternions, signs matched to `reference`, smoothed as `rounds` rounds of neighbour
    /// averaging would, then normalised; a vertex whose average vanishes keeps its own).
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the smoothing's solve fails.
    pub(crate) fn smooth_rotations(
        &mut self,
        similarities: &mut [Similarity],
        rounds: usize,
        reference: Quat,
    ) -> Result<(), KernelError> {
        if rounds == 0 {
            return Ok(());
        }
        let matched: Vec<Vec4> = similarities
            .iter()
            .map(|fit| {
                let rotation = Vec4::from(fit.rotation);
                if rotation.dot(Vec4::from(reference)) < 0.0 {
                    -rotation
                } else {
                    rotation
                }
            })
            .collect();
        let mut columns = vec![
            matched
                .iter()
                .map(|q| DVec3::new(q.x.into(), q.y.into(), q.z.into()))
                .collect(),
            matched
                .iter()
                .map(|q| DVec3::new(q.w.into(), 0.0, 0.0))
                .collect(),
        ];
        self.rotation_smoother.smooth(rounds, &mut columns)?;
        for (vertex, fit) in similarities.iter_mut().enumerate() {
            let (xyz, w) = (columns[0][vertex], columns[1][vertex].x);
            let sum = Vec4::new(xyz.x as f32, xyz.y as f32, xyz.z as f32, w as f32);
            let length = sum.length();
            if length > 1e-6 && length.is_finite() {
                fit.rotation = Quat::from_vec4(sum / length);
            }
        }
        Ok(())
    }

    /// Fits every vertex's stretch at `positions` given its rotation in `similarities`, then
    /// smooths them as `rounds` rounds of averaging over edge neighbours would (one factored
    /// solve, see [`Smoother`]), or (`None`) replaces them by the median scale.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the smoothing's solve fails.
    pub(crate) fn fit(
        &mut self,
        structure: &LayoutStructure,
        positions: &[Vec3],
        similarities: &[Similarity],
        rounds: Option<usize>,
    ) -> Result<(), KernelError> {
        let Some(median) = Similarity::median_scale(similarities) else {
            return Ok(());
        };
        let Some(rounds) = rounds else {
            self.values = vec![Mat3::from_diagonal(Vec3::splat(median)); positions.len()];
            return Ok(());
        };
        let bound = |stretch: Mat3| bounded(stretch, median);
        let stretches: Vec<Mat3> = (0..positions.len() as u32)
            .into_par_iter()
            .with_min_len(1024)
            .map(|vertex| {
                let fit = similarities[vertex as usize];
                self.fit_one(structure, positions, vertex, fit)
                    .map_or_else(|| Mat3::from_quat(fit.rotation) * median, bound)
            })
            .collect();
        let mut columns: Vec<Vec<DVec3>> = (0..3)
            .map(|axis| stretches.iter().map(|s| s.col(axis).as_dvec3()).collect())
            .collect();
        self.stretch_smoother.smooth(rounds, &mut columns)?;
        self.values = (0..stretches.len())
            .map(|vertex| {
                let column = |axis: usize| columns[axis][vertex].as_vec3();
                bound(Mat3::from_cols(column(0), column(1), column(2)))
            })
            .collect();
        Ok(())
    }

    /// The symmetric stretch `S` with `R S` the least-squares linear map of `vertex`'s rest edges
    /// (and its rest normal, as long as its edges) onto its current ones, `R` its fitted
    /// rotation; `None` when its neighbourhood is degenerate.
    fn fit_one(
        &self,
        structure: &LayoutStructure,
        positions: &[Vec3],
        vertex: u32,
        fit: Similarity,
    ) -> Option<Mat3> {
        let index = vertex as usize;
        let (here, rest_here) = (positions[index], self.rest[index]);
        let neighbors = structure.neighbors_of(vertex);
        if neighbors.is_empty() {
            return None;
        }
        let mut now_rest = Mat3::ZERO;
        let mut rest_rest = Mat3::ZERO;
        let (mut now_length, mut rest_length) = (0.0f32, 0.0f32);
        for &other in neighbors {
            let now = positions[other as usize] - here;
            let rest = self.rest[other as usize] - rest_here;
            now_rest += outer(now, rest);
            rest_rest += outer(rest, rest);
            now_length += now.length_squared();
            rest_length += rest.length_squared();
        }
        let count = neighbors.len() as f32;
        let (now_length, rest_length) = ((now_length / count).sqrt(), (rest_length / count).sqrt());
        let now_normal = structure.normal_at(positions, vertex).normalize_or_zero() * now_length;
        let rest_normal = self.rest_normals[index] * rest_length;
        now_rest += outer(now_normal, rest_normal);
        rest_rest += outer(rest_normal, rest_normal);
        if rest_rest.determinant().abs() <= f32::EPSILON * rest_length.powi(6) {
            return None;
        }
        let linear = now_rest * rest_rest.inverse();
        let unturned = glam::Mat3::from_quat(fit.rotation).transpose() * linear;
        let stretch = (unturned + unturned.transpose()) * 0.5;
        stretch.is_finite().then_some(stretch)
    }
}

/// The correspondences (Welsch weight, point pulled to) with those dropped whose point has another
/// part of the layout nearer to it (see [`RECIPROCAL_RATIO`]).
pub(crate) fn keep_reciprocal<T: Copy + Send + Sync>(
    positions: &[Vec3],
    correspondences: &mut [Option<(T, Vec3)>],
    mean_edge_length: f32,
) {
    if mean_edge_length <= 0.0 {
        return;
    }
    let (ratio, near) = (RECIPROCAL_RATIO, RECIPROCAL_NEAR * mean_edge_length);
    let cell = mean_edge_length * 4.0;
    let key = |point: Vec3| (point / cell).floor().as_ivec3();
    let mut grid: std::collections::HashMap<glam::IVec3, Vec<u32>> =
        std::collections::HashMap::new();
    for (vertex, &position) in positions.iter().enumerate() {
        if position.is_finite() {
            grid.entry(key(position)).or_default().push(vertex as u32);
        }
    }
    let rejected: Vec<bool> = correspondences
        .par_iter()
        .enumerate()
        .with_min_len(256)
        .map(|(vertex, correspondence)| {
            let Some((_, point)) = *correspondence else {
                return false;
            };
            let here = positions[vertex];
            let distance = here.distance(point);
            if distance <= near {
                return false;
            }
            let radius = distance * ratio;
            let reach = (radius / cell).ceil() as i32;
            let centre = key(point);
            for dz in -reach..=reach {
                for dy in -reach..=reach {
                    for dx in -reach..=reach {
                        let Some(vertices) = grid.get(&(centre + glam::IVec3::new(dx, dy, dz)))
                        else {
                            continue;
                        };
                        for &other in vertices {
                            let there = positions[other as usize];
                            if there.distance(point) < radius && there.distance(here) > near {
                                return true;
                            }
                        }
                    }
                }
            }
            false
        })
        .collect();
    for (correspondence, rejected) in correspondences.iter_mut().zip(rejected) {
        if rejected {
            *correspondence = None;
        }
    }
}

/// `a bᵀ`.
fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// `stretch` with its mean scale within [`STRETCH_RANGE`] of `median`, or that mean scale alone
/// when it is nearly flat or inverted.
fn bounded(stretch: Mat3, median: f32) -> Mat3 {
    let mean = (stretch.x_axis.x + stretch.y_axis.y + stretch.z_axis.z) / 3.0;
    let clamped = mean.clamp(median / STRETCH_RANGE, median * STRETCH_RANGE);
    if mean.is_nan() || mean <= 0.0 || stretch.determinant() < MIN_STRETCH_VOLUME * mean.powi(3) {
        return Mat3::from_diagonal(Vec3::splat(clamped));
    }
    stretch * (clamped / mean)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    /// A 4 x 4 grid of unit cells in the xy plane and its structure.
    fn grid() -> (LayoutStructure, Vec<Vec3>) {
        let row = 5u32;
        let rest: Vec<Vec3> = (0..row * row)
            .map(|index| Vec3::new((index % row) as f32, (index / row) as f32, 0.0))
            .collect();
        let mut corners = Vec::new();
        for y in 0..4 {
            for x in 0..4 {
                let a = y * row + x;
                corners.extend([a, a + 1, a + row + 1, a + row]);
            }
        }
        let structure = LayoutStructure::new(rest.len(), &corners, &[4; 16], &[], &[]).unwrap();
        (structure, rest)
    }

    #[test]
    fn an_affine_deformation_is_fitted_as_its_rotation_and_stretch() {
        let (structure, rest) = grid();
        let stretch = Mat3::from_cols(
            Vec3::new(2.0, 0.3, 0.0),
            Vec3::new(0.3, 0.5, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        );
        let rotation = Quat::from_rotation_z(0.4);
        let positions: Vec<Vec3> = rest
            .iter()
            .map(|&p| rotation * (stretch * p) + Vec3::new(3.0, -1.0, 2.0))
            .collect();
        let similarities = vec![
            Similarity {
                rotation,
                scale: 1.0,
            };
            rest.len()
        ];
        let mut stretches = Stretches::new(&structure, &rest).unwrap();
        stretches
            .fit(&structure, &positions, &similarities, Some(0))
            .unwrap();
        // The normal's stretch is the edges' mean length ratio, not 1: only the in-plane part
        // is the deformation's own. Averaging equal in-plane stretches keeps them.
        let in_plane = |stretches: &Stretches| {
            for fitted in &stretches.values {
                for (row, column) in [(0, 0), (0, 1), (1, 1)] {
                    let (got, wanted) = (fitted.col(column)[row], stretch.col(column)[row]);
                    assert!((got - wanted).abs() < 1e-4, "{fitted} against {stretch}");
                }
            }
        };
        in_plane(&stretches);
        stretches
            .fit(&structure, &positions, &similarities, Some(8))
            .unwrap();
        in_plane(&stretches);
        // The median replaces them by one scale.
        stretches
            .fit(&structure, &positions, &similarities, None)
            .unwrap();
        assert!(
            stretches.values[12].abs_diff_eq(Mat3::IDENTITY, 1e-6),
            "{}",
            stretches.values[12]
        );
    }

    #[test]
    fn an_inverted_or_extreme_stretch_is_bounded() {
        let flat = Mat3::from_diagonal(Vec3::new(1.0, 1.0, -0.5));
        assert_eq!(bounded(flat, 1.0), Mat3::from_diagonal(Vec3::splat(0.5)));
        let huge = Mat3::from_diagonal(Vec3::splat(10.0));
        assert_eq!(bounded(huge, 1.0), Mat3::from_diagonal(Vec3::splat(3.0)));
    }
}
