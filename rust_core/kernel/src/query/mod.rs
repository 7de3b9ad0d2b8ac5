//! Queries against a [`crate::TargetMesh`]: single and batched (parallel with rayon).

pub mod closest_point;
pub mod nearest_vertex;
pub mod point_triangle;
pub mod ray_cast;
pub mod ray_triangle;

use glam::Vec3;

use crate::error::KernelError;

/// Checks that every query position is finite.
pub(crate) fn check_finite(what: &'static str, points: &[Vec3]) -> Result<(), KernelError> {
    match points.iter().position(|point| !point.is_finite()) {
        Some(index) => Err(KernelError::NonFinite { what, index }),
        None => Ok(()),
    }
}

/// Checks a search radius: zero or more, or infinite; never NaN.
pub(crate) fn check_max_distance(max_distance: f32) -> Result<(), KernelError> {
    if max_distance >= 0.0 {
        Ok(())
    } else {
        Err(KernelError::InvalidArgument {
            name: "max_distance",
            reason: format!("must be zero or more (infinity for no limit), got {max_distance}"),
        })
    }
}

/// Queries per rayon task: large enough to amortise scheduling, small enough to balance 2+ cores.
pub(crate) const QUERIES_PER_TASK: usize = 512;
