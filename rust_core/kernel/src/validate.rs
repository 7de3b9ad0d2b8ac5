//! The kernel's input policy, in one place: what every public entry point checks before it
//! computes or allocates anything.
//!
//! - **Coordinates** (mesh vertices, query points, ray origins and directions, layout positions,
//!   rest shapes, anchor targets, curve points, the mirror plane, alignment anchors and
//!   displacements) must be finite and within [`MAX_COORDINATE`] of the origin, each component.
//!   A NaN or infinity is [`KernelError::NonFinite`]; a finite value beyond the bound is
//!   [`KernelError::CoordinateOutOfRange`], naming the array, the row and the value. The bound
//!   keeps the squared distances and the products inside the closest-point, ray and degeneracy
//!   tests well below `f32::MAX` (3.4e38): at `1e8` they stay under about `1e35`.
//! - **Barycentric weights** of face-points must be finite and each within
//!   [`BARYCENTRIC_RANGE`]: they describe a point of the triangle (0 to 1, up to rounding).
//! - **Constraints of a wrap** (anchor targets, target curves, the mirror plane) must lie within
//!   the region the wrap can reach (the one whose exit is [`KernelError::Diverged`]: ten times the
//!   size of the target and the layout's start, about the target's centre):
//!   [`KernelError::BeyondReach`]. An anchor `1e7` away from a target 2 units wide is absurd.
//! - **Counts** (vertices, triangles, layout vertices) are at most [`crate::mesh::MAX_ELEMENTS`]
//!   ([`KernelError::TooLarge`]), and no count drives an allocation on its own: what the kernel
//!   allocates follows the arrays it is given (a layout's vertex count does not, see
//!   [`crate::LayoutStructure::new`]).
//! - **Settings** (weights, tolerances, distances, iteration counts) are checked by
//!   [`check_setting`] against the range their owner documents: the wrap's in
//!   [`crate::WrapSettings::validate`], ICP's and feature detection's beside their settings.

use glam::Vec3;
use rayon::prelude::*;

use crate::error::KernelError;

/// The largest coordinate magnitude the kernel accepts, in model units.
///
/// At `1e8` an f32 still resolves 8 units; the squares and products of the queries' tests stay
/// four orders of magnitude below f32's overflow. Real models (millimetres, metres, UTM
/// coordinates of a scan) are far inside it.
pub const MAX_COORDINATE: f32 = 1e8;

/// The range each barycentric weight of a face-point must lie in (inclusive): weights of a point
/// of the triangle are within `[0, 1]`; rounding and the walk's edge tolerance leave them a hair
/// outside, nothing else does.
pub const BARYCENTRIC_RANGE: (f32, f32) = (-1.0, 2.0);

/// Checks one coordinate triple: finite, and each component within [`MAX_COORDINATE`].
///
/// # Errors
/// [`KernelError::NonFinite`] or [`KernelError::CoordinateOutOfRange`] naming `what` and `index`.
#[inline]
pub fn check_coordinate(what: &'static str, index: usize, point: Vec3) -> Result<(), KernelError> {
    if !point.is_finite() {
        return Err(KernelError::NonFinite { what, index });
    }
    if point.abs().max_element() > MAX_COORDINATE {
        let value = point
            .to_array()
            .into_iter()
            .find(|value| value.abs() > MAX_COORDINATE)
            .unwrap_or(f32::INFINITY);
        return Err(KernelError::CoordinateOutOfRange {
            what,
            index,
            value,
            limit: MAX_COORDINATE,
        });
    }
    Ok(())
}

/// [`check_coordinate`] for every row of `points`; the first bad row is named.
///
/// # Errors
/// As [`check_coordinate`].
pub fn check_coordinates(what: &'static str, points: &[Vec3]) -> Result<(), KernelError> {
    // Searched in parallel (a dense target has millions of vertices); the first bad row is named.
    let refused = |point: &Vec3| !point.is_finite() || point.abs().max_element() > MAX_COORDINATE;
    match points
        .par_iter()
        .with_min_len(1 << 14)
        .position_first(refused)
    {
        Some(index) => check_coordinate(what, index, points[index]),
        None => Ok(()),
    }
}

/// Checks the barycentric weights of a face-point: finite, each within [`BARYCENTRIC_RANGE`].
///
/// # Errors
/// [`KernelError::NonFinite`] (what: `what`) or [`KernelError::InvalidArgument`] naming the row
/// and the weight.
pub fn check_barycentric(
    what: &'static str,
    index: usize,
    barycentric: Vec3,
) -> Result<(), KernelError> {
    if !barycentric.is_finite() {
        return Err(KernelError::NonFinite { what, index });
    }
    let (low, high) = BARYCENTRIC_RANGE;
    if let Some(value) = barycentric
        .to_array()
        .into_iter()
        .find(|value| !(low..=high).contains(value))
    {
        return Err(KernelError::InvalidArgument {
            name: what,
            reason: format!(
                "{what} {index} has a weight of {value}; each weight must be within [{low}, {high}] \
                 (0 to 1 for a point of the triangle)"
            ),
        });
    }
    Ok(())
}

/// Checks that `point` lies within `reach` of `centre` (the region a wrap can reach).
///
/// # Errors
/// [`KernelError::BeyondReach`] naming `what`, `index` and the distance.
pub fn check_within_reach(
    what: &'static str,
    index: usize,
    point: Vec3,
    (centre, reach): (Vec3, f32),
) -> Result<(), KernelError> {
    let distance = point.distance(centre);
    if distance > reach {
        return Err(KernelError::BeyondReach {
            what,
            index,
            distance,
            reach,
        });
    }
    Ok(())
}

/// A setting's range: `low` and `high` inclusive unless marked open.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettingRange {
    /// The lower end.
    pub low: f64,
    /// Whether `low` itself is refused.
    pub low_open: bool,
    /// The upper end (may be infinite: then any finite value above `low`, or infinity itself when
    /// `infinity_allowed`).
    pub high: f64,
    /// Whether `high` itself is refused.
    pub high_open: bool,
    /// Whether `+inf` is accepted (a distance meaning "no limit").
    pub infinity_allowed: bool,
}

impl SettingRange {
    /// `[low, high]`.
    #[must_use]
    pub const fn closed(low: f64, high: f64) -> Self {
        Self {
            low,
            low_open: false,
            high,
            high_open: false,
            infinity_allowed: false,
        }
    }

    /// `(low, high]`.
    #[must_use]
    pub const fn above(low: f64, high: f64) -> Self {
        Self {
            low_open: true,
            ..Self::closed(low, high)
        }
    }

    /// `[low, high)`.
    #[must_use]
    pub const fn below(low: f64, high: f64) -> Self {
        Self {
            high_open: true,
            ..Self::closed(low, high)
        }
    }

    /// The same range, with `+inf` also accepted ("no limit").
    #[must_use]
    pub const fn or_infinite(self) -> Self {
        Self {
            infinity_allowed: true,
            ..self
        }
    }

    /// Whether `value` is in the range (NaN never is).
    #[must_use]
    pub fn contains(&self, value: f64) -> bool {
        if value == f64::INFINITY && self.infinity_allowed {
            return true;
        }
        let above_low = if self.low_open {
            value > self.low
        } else {
            value >= self.low
        };
        let below_high = if self.high_open {
            value < self.high
        } else {
            value <= self.high
        };
        above_low && below_high && value.is_finite()
    }
}

impl std::fmt::Display for SettingRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let opening = if self.low_open { '(' } else { '[' };
        let closing = if self.high_open { ')' } else { ']' };
        write!(f, "{opening}{}, {}{closing}", self.low, self.high)?;
        if self.infinity_allowed {
            write!(f, " or infinity")?;
        }
        Ok(())
    }
}

/// Checks a setting against its documented range.
///
/// # Errors
/// [`KernelError::InvalidArgument`] named `name` (the field and keyword), saying `label`, the
/// range and the value: `invalid thin_plate: the thin plate weight must be within [0, 0.5], not 0.7`.
pub fn check_setting<T: Into<f64> + std::fmt::Display + Copy>(
    name: &'static str,
    label: &str,
    value: T,
    range: SettingRange,
) -> Result<(), KernelError> {
    if range.contains(value.into()) {
        Ok(())
    } else {
        Err(KernelError::InvalidArgument {
            name,
            reason: format!("the {label} must be within {range}, not {value}"),
        })
    }
}

/// Checks a count against the largest supported one.
///
/// # Errors
/// [`KernelError::TooLarge`].
pub fn check_count(what: &'static str, count: usize, max: usize) -> Result<(), KernelError> {
    if count > max {
        return Err(KernelError::TooLarge { what, count, max });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coordinates_are_refused_by_kind_with_row_and_value() {
        assert_eq!(
            check_coordinate("vertex", 3, Vec3::new(1.0, -1e8, 2.0)),
            Ok(())
        );
        assert_eq!(
            check_coordinate("vertex", 3, Vec3::new(1.0, f32::NAN, 2.0)),
            Err(KernelError::NonFinite {
                what: "vertex",
                index: 3
            })
        );
        assert_eq!(
            check_coordinate("vertex", 4, Vec3::new(1.0, -3e38, 2.0)),
            Err(KernelError::CoordinateOutOfRange {
                what: "vertex",
                index: 4,
                value: -3e38,
                limit: MAX_COORDINATE
            })
        );
        let message = check_coordinates("anchor target", &[Vec3::ZERO, Vec3::new(1e30, 0.0, 0.0)])
            .unwrap_err()
            .to_string();
        assert_eq!(
            message,
            "anchor target 1 has a coordinate of 1e30, beyond the kernel's bound of ±1e8 model units"
        );
    }

    #[test]
    fn ranges_say_what_they_accept() {
        let range = SettingRange::above(0.0, 1.0);
        assert!(!range.contains(0.0) && range.contains(1.0) && !range.contains(f64::NAN));
        assert_eq!(range.to_string(), "(0, 1]");
        let distance = SettingRange::closed(0.0, f64::from(MAX_COORDINATE)).or_infinite();
        assert!(distance.contains(f64::INFINITY) && !distance.contains(1e30));
        assert!(!SettingRange::below(0.0, 1.0).contains(1.0));
        assert_eq!(
            check_setting("momentum", "momentum", 1.5, SettingRange::closed(0.0, 0.99))
                .unwrap_err()
                .to_string(),
            "invalid momentum: the momentum must be within [0, 0.99], not 1.5"
        );
    }
}
