//! The mirror plane as a constraint: the seam of a mirrored layout stays on the plane (paper,
//! section 3, "Mirroring example").

use glam::Vec3;

use crate::error::KernelError;
use crate::validate;

/// Layout vertices held on a plane during the wrap: the seam where a mirrored layout's two halves
/// meet.
///
/// A held face-point slides only along the target's cross-section with the plane (the line where
/// the surface's tangent plane meets the mirror plane) and is walked back onto the plane after
/// every move; a held space-point moves only within the plane. So the seam follows the target's
/// cross-section whatever shape it has (a closed loop around a body, several pieces, a curve over
/// a hole), which a curve constraint matched by arc length cannot do.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneConstraint {
    /// The held layout vertices, in any order (anchored ones keep their anchors instead).
    pub vertices: Vec<u32>,
    /// A point of the plane (world space).
    pub point: Vec3,
    /// The plane's normal (any length but zero).
    pub normal: Vec3,
    /// Whether held points slide along the cross-section, moved by the springs (the seam settles
    /// between both halves), or only move onto the cross-section, the shortest way, and stay
    /// there (the seam stays as the surfaced half has it).
    pub slide: bool,
}

/// A checked plane: a point and a unit normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Plane {
    pub(crate) point: Vec3,
    pub(crate) normal: Vec3,
}

impl Plane {
    /// Checks `point` and `normal` (finite, normal not zero) and normalises the normal.
    pub(crate) fn new(point: Vec3, normal: Vec3) -> Result<Self, KernelError> {
        let invalid = |reason: &str| KernelError::InvalidArgument {
            name: "plane constraint",
            reason: reason.to_owned(),
        };
        validate::check_coordinate("plane point", 0, point)?;
        validate::check_coordinate("plane normal", 0, normal)?;
        let normal = normal
            .try_normalize()
            .ok_or_else(|| invalid("the plane's normal has zero length"))?;
        Ok(Self { point, normal })
    }

    /// Signed distance of `position` from the plane (positive on the normal's side).
    #[must_use]
    pub(crate) fn distance(&self, position: Vec3) -> f32 {
        (position - self.point).dot(self.normal)
    }

    /// `position` moved straight onto the plane.
    #[must_use]
    pub(crate) fn project(&self, position: Vec3) -> Vec3 {
        position - self.normal * self.distance(position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_and_projections() {
        let plane = Plane::new(Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)).unwrap();
        assert_eq!(plane.normal, Vec3::X);
        assert_eq!(plane.distance(Vec3::new(3.0, 5.0, 1.0)), 2.0);
        assert_eq!(
            plane.project(Vec3::new(3.0, 5.0, 1.0)),
            Vec3::new(1.0, 5.0, 1.0)
        );
        assert!(Plane::new(Vec3::ZERO, Vec3::ZERO).is_err());
        assert!(Plane::new(Vec3::NAN, Vec3::X).is_err());
    }
}
