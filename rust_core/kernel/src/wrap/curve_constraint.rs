//! Curve constraints: a chain of layout vertices paired with a target curve (paper, section 2.4).

use glam::Vec3;

use crate::error::KernelError;
use crate::validate;

/// A layout curve held to a target curve, matched by arc length.
///
/// The target curve is a polyline in space: a chain of target mesh edges, a Blender curve, a
/// feature curve, or a curve floating off the surface (a blend's limit curve). Each layout vertex
/// of the chain is pulled to the target point at the same fraction of the curve's length as the
/// vertex sits along the layout chain when the wrap starts, or at the fraction `fractions` gives it.
#[derive(Debug, Clone, PartialEq)]
pub struct CurveConstraint {
    /// The layout chain, in order (at least 2 vertices).
    pub layout_vertices: Vec<u32>,
    /// The target polyline, in the same direction (at least 2 points, not all equal).
    pub target: Vec<Vec3>,
    /// Where along the target polyline each chain vertex goes, as a fraction (0 to 1) of its
    /// length, one per chain vertex; empty: at the fraction the vertex has along the chain.
    pub fractions: Vec<f32>,
}

/// A target polyline prepared for arc-length lookups.
#[derive(Debug, Clone)]
pub(crate) struct ArcLengthCurve {
    points: Vec<Vec3>,
    /// Cumulative length at each point, from 0 to `length`.
    cumulative: Vec<f32>,
    length: f32,
}

impl ArcLengthCurve {
    /// Checks and prepares constraint `index`'s target curve, whose first point is curve point
    /// `first_point` of all the constraints' curves; every point within `reach` (the region the
    /// wrap can reach).
    pub(crate) fn new(
        index: usize,
        first_point: usize,
        points: &[Vec3],
        reach: (Vec3, f32),
    ) -> Result<Self, KernelError> {
        let invalid = |reason: String| KernelError::InvalidArgument {
            name: "curve constraints",
            reason: format!("curve constraint {index}: {reason}"),
        };
        if points.len() < 2 {
            return Err(invalid(format!(
                "the target curve needs at least 2 points, it has {}",
                points.len()
            )));
        }
        for (offset, &point) in points.iter().enumerate() {
            validate::check_coordinate("curve point", first_point + offset, point)?;
            validate::check_within_reach("curve point", first_point + offset, point, reach)?;
        }
        let mut cumulative = Vec::with_capacity(points.len());
        let mut length = 0.0f32;
        cumulative.push(0.0);
        for pair in points.windows(2) {
            length += pair[0].distance(pair[1]);
            cumulative.push(length);
        }
        if length <= 0.0 {
            return Err(invalid("the target curve has zero length".to_owned()));
        }
        Ok(Self {
            points: points.to_vec(),
            cumulative,
            length,
        })
    }

    /// The point at `fraction` (0 to 1) of the curve's length.
    pub(crate) fn point_at(&self, fraction: f32) -> Vec3 {
        let along = fraction.clamp(0.0, 1.0) * self.length;
        let segment = self
            .cumulative
            .partition_point(|&cumulative| cumulative <= along)
            .clamp(1, self.points.len() - 1);
        let start = self.cumulative[segment - 1];
        let span = self.cumulative[segment] - start;
        let t = if span > 0.0 {
            (along - start) / span
        } else {
            0.0
        };
        self.points[segment - 1].lerp(self.points[segment], t)
    }
}

/// Where each chain vertex goes along constraint `index`'s target curve, as a fraction of its
/// length: the constraint's own `fractions`, or the fraction of the chain's length at each
/// vertex (from `positions`).
///
/// # Errors
/// [`KernelError::InvalidArgument`] when `fractions` is neither empty nor one per chain vertex,
/// or one lies outside 0 to 1 (or is not finite).
pub(crate) fn vertex_fractions(
    index: usize,
    constraint: &CurveConstraint,
    positions: &[Vec3],
) -> Result<Vec<f32>, KernelError> {
    let chain = &constraint.layout_vertices;
    if constraint.fractions.is_empty() {
        return Ok(chain_fractions(positions, chain));
    }
    let invalid = |reason: String| KernelError::InvalidArgument {
        name: "curve constraints",
        reason: format!("curve constraint {index}: {reason}"),
    };
    if constraint.fractions.len() != chain.len() {
        return Err(invalid(format!(
            "{} fractions for a chain of {} vertices: give one per vertex or none",
            constraint.fractions.len(),
            chain.len()
        )));
    }
    if let Some((row, value)) = constraint
        .fractions
        .iter()
        .enumerate()
        .find(|(_, value)| !(0.0..=1.0).contains(*value))
    {
        return Err(invalid(format!(
            "fraction {row} is {value}: fractions lie from 0 to 1"
        )));
    }
    Ok(constraint.fractions.clone())
}

/// Fraction of the chain's length at each of its vertices, from `positions` (uniform when the
/// chain has collapsed to a point).
pub(crate) fn chain_fractions(positions: &[Vec3], chain: &[u32]) -> Vec<f32> {
    let mut cumulative = Vec::with_capacity(chain.len());
    let mut length = 0.0f32;
    cumulative.push(0.0);
    for pair in chain.windows(2) {
        length += positions[pair[0] as usize].distance(positions[pair[1] as usize]);
        cumulative.push(length);
    }
    if length > 0.0 {
        cumulative.iter().map(|&value| value / length).collect()
    } else {
        let last = (chain.len() - 1).max(1) as f32;
        (0..chain.len()).map(|index| index as f32 / last).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reach that holds every test curve.
    const ANYWHERE: (Vec3, f32) = (Vec3::ZERO, f32::MAX);

    #[test]
    fn arc_length_lookup_and_chain_fractions() {
        let curve = ArcLengthCurve::new(
            0,
            0,
            &[Vec3::ZERO, Vec3::X, Vec3::new(1.0, 3.0, 0.0)],
            ANYWHERE,
        )
        .unwrap();
        assert_eq!(curve.point_at(0.0), Vec3::ZERO);
        assert_eq!(curve.point_at(0.25), Vec3::X);
        assert!(curve.point_at(0.5).distance(Vec3::new(1.0, 1.0, 0.0)) < 1e-6);
        assert_eq!(curve.point_at(1.0), Vec3::new(1.0, 3.0, 0.0));
        assert_eq!(curve.point_at(7.0), Vec3::new(1.0, 3.0, 0.0));
        let positions = [Vec3::ZERO, Vec3::X, Vec3::new(4.0, 0.0, 0.0)];
        assert_eq!(
            chain_fractions(&positions, &[0, 1, 2]),
            vec![0.0, 0.25, 1.0]
        );
        assert_eq!(
            chain_fractions(&[Vec3::ZERO; 3], &[0, 1, 2]),
            vec![0.0, 0.5, 1.0]
        );
    }

    #[test]
    fn given_fractions_replace_the_chain_spacing() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::new(4.0, 0.0, 0.0)];
        let mut constraint = CurveConstraint {
            layout_vertices: vec![0, 1, 2],
            target: vec![Vec3::ZERO, Vec3::Y],
            fractions: Vec::new(),
        };
        assert_eq!(
            vertex_fractions(0, &constraint, &positions).unwrap(),
            vec![0.0, 0.25, 1.0]
        );
        constraint.fractions = vec![0.0, 0.5, 1.0];
        assert_eq!(
            vertex_fractions(0, &constraint, &positions).unwrap(),
            vec![0.0, 0.5, 1.0]
        );
        for bad in [
            vec![0.0, 1.0],
            vec![0.0, 1.5, 1.0],
            vec![0.0, f32::NAN, 1.0],
        ] {
            constraint.fractions = bad;
            assert!(matches!(
                vertex_fractions(2, &constraint, &positions),
                Err(KernelError::InvalidArgument { reason, .. }) if reason.contains("curve constraint 2")
            ));
        }
    }

    #[test]
    fn bad_target_curves_are_refused() {
        assert!(
            ArcLengthCurve::new(3, 0, &[Vec3::ZERO], ANYWHERE)
                .unwrap_err()
                .to_string()
                .contains("curve constraint 3")
        );
        assert!(
            ArcLengthCurve::new(0, 0, &[Vec3::ZERO, Vec3::ZERO], ANYWHERE)
                .unwrap_err()
                .to_string()
                .contains("zero length")
        );
        // Points are numbered through all the curves (the binding's `curve_points` rows).
        assert_eq!(
            ArcLengthCurve::new(0, 5, &[Vec3::ZERO, Vec3::NAN], ANYWHERE).unwrap_err(),
            KernelError::NonFinite {
                what: "curve point",
                index: 6
            }
        );
        assert!(matches!(
            ArcLengthCurve::new(0, 0, &[Vec3::ZERO, Vec3::new(0.0, 3.4e38, 0.0)], ANYWHERE),
            Err(KernelError::CoordinateOutOfRange { index: 1, .. })
        ));
        assert!(matches!(
            ArcLengthCurve::new(
                0,
                0,
                &[Vec3::ZERO, Vec3::new(0.0, 50.0, 0.0)],
                (Vec3::ZERO, 10.0)
            ),
            Err(KernelError::BeyondReach {
                what: "curve point",
                index: 1,
                ..
            })
        ));
    }
}
