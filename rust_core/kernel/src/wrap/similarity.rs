//! Per-vertex similarities: how each vertex's neighbourhood is turned and scaled from the
//! template (the rest shape) to now, fitted by Procrustes as in as-rigid-as-possible deformation.
//! The energy's shape terms aim at the template's edges and second differences under these.

use glam::{Mat3, Quat, Vec3};
use rayon::prelude::*;

use crate::layout::LayoutStructure;

/// How a vertex's neighbourhood is turned and scaled from rest to now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    /// The rotation from rest to now.
    pub rotation: Quat,
    /// The scale from rest to now.
    pub scale: f32,
}

impl Similarity {
    /// No turn, no scale.
    pub const IDENTITY: Self = Self {
        rotation: Quat::IDENTITY,
        scale: 1.0,
    };

    /// The median of the positive, finite scales of `fits`; `None` when there is none.
    #[must_use]
    pub fn median_scale(fits: &[Self]) -> Option<f32> {
        let mut scales: Vec<f32> = fits
            .iter()
            .map(|fit| fit.scale)
            .filter(|scale| *scale > 0.0 && scale.is_finite())
            .collect();
        if scales.is_empty() {
            return None;
        }
        let middle = scales.len() / 2;
        Some(*scales.select_nth_unstable_by(middle, f32::total_cmp).1)
    }
}

/// Rotation-fit refinements per iteration, warm-started from the last fit (Müller et al. 2016,
/// "A robust method to extract the rotational part of deformations").
const ROTATION_REFINEMENTS: usize = 1;
/// Refinements for the first fit, from the identity.
const FIRST_ROTATION_REFINEMENTS: usize = 40;

/// The template's shape, to fit each vertex's similarity against.
#[derive(Debug, Clone, Default)]
pub(crate) struct RestFit {
    /// Per vertex: its rest position.
    rest: Vec<Vec3>,
}

impl RestFit {
    /// Fits against `rest` (one position per layout vertex).
    pub(crate) fn new(rest: &[Vec3]) -> Self {
        Self {
            rest: rest.to_vec(),
        }
    }

    /// The similarity that best maps `vertex`'s rest edges onto its current ones, refined from
    /// `previous` (the last fit, or [`Similarity::IDENTITY`] with `first`).
    fn fit(
        &self,
        positions: &[Vec3],
        structure: &LayoutStructure,
        vertex: u32,
        previous: Similarity,
        first: bool,
    ) -> Similarity {
        let index = vertex as usize;
        let (here, rest_here) = (positions[index], self.rest[index]);
        // A = sum of now ⊗ rest over the edges: the rotation maximising tr(Rᵀ A) maps rest to now.
        let mut covariance = Mat3::ZERO;
        let mut rest_norm = 0.0f32;
        for &other in structure.neighbors_of(vertex) {
            let now = positions[other as usize] - here;
            let rest = self.rest[other as usize] - rest_here;
            covariance += Mat3::from_cols(now * rest.x, now * rest.y, now * rest.z);
            rest_norm += rest.length_squared();
        }
        if rest_norm <= 0.0 {
            return previous;
        }
        let refinements = if first {
            FIRST_ROTATION_REFINEMENTS
        } else {
            ROTATION_REFINEMENTS
        };
        let rotation = refine_rotation(covariance, previous.rotation, refinements);
        // The least-squares scale: tr(Rᵀ A) / Σ|rest|².
        let turned = Mat3::from_quat(rotation);
        let aligned = turned.x_axis.dot(covariance.x_axis)
            + turned.y_axis.dot(covariance.y_axis)
            + turned.z_axis.dot(covariance.z_axis);
        let scale = (aligned / rest_norm).max(0.0);
        Similarity { rotation, scale }
    }

    /// [`RestFit::fit`] for every vertex, in parallel, each refined from its `previous` fit.
    pub(crate) fn fit_all(
        &self,
        positions: &[Vec3],
        structure: &LayoutStructure,
        previous: &[Similarity],
        first: bool,
    ) -> Vec<Similarity> {
        (0..positions.len() as u32)
            .into_par_iter()
            .with_min_len(1024)
            .map(|vertex| {
                self.fit(
                    positions,
                    structure,
                    vertex,
                    previous[vertex as usize],
                    first,
                )
            })
            .collect()
    }
}

/// Refines `rotation` toward the rotation part of `matrix` (the rotation `R` maximising
/// `tr(Rᵀ matrix)`): Müller, Bender, Chentanez & Macklin 2016, robust where the matrix is
/// degenerate or reflected, warm-started.
fn refine_rotation(matrix: Mat3, rotation: Quat, iterations: usize) -> Quat {
    let mut rotation = rotation;
    for _ in 0..iterations {
        let turned = Mat3::from_quat(rotation);
        let torque = turned.x_axis.cross(matrix.x_axis)
            + turned.y_axis.cross(matrix.y_axis)
            + turned.z_axis.cross(matrix.z_axis);
        let alignment = turned.x_axis.dot(matrix.x_axis)
            + turned.y_axis.dot(matrix.y_axis)
            + turned.z_axis.dot(matrix.z_axis);
        let omega = torque / (alignment.abs() + 1e-9);
        let angle = omega.length();
        if angle.is_nan() || angle <= 1e-7 {
            break;
        }
        rotation = (Quat::from_axis_angle(omega / angle, angle) * rotation).normalize();
    }
    rotation
}
