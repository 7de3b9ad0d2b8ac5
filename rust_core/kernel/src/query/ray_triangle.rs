//! Ray against triangle (Möller–Trumbore, two-sided), with barycentric coordinates.

use glam::Vec3A;

/// Tolerance on barycentric coordinates so that rays through a shared edge hit one of its two
/// triangles instead of slipping between them.
const EDGE_TOLERANCE: f32 = 1e-6;

/// Intersection of the ray `origin + t * direction` with triangle `(a, b, c)`, either side.
///
/// Returns `(t, barycentric)` for `t` in `[t_min, t_max]`, or `None`. Degenerate triangles are
/// never hit (their determinant vanishes).
#[must_use]
#[inline]
pub fn intersect_ray_triangle(
    origin: Vec3A,
    direction: Vec3A,
    t_min: f32,
    t_max: f32,
    a: Vec3A,
    b: Vec3A,
    c: Vec3A,
) -> Option<(f32, Vec3A)> {
    let edge1 = b - a;
    let edge2 = c - a;
    let p = direction.cross(edge2);
    let determinant = edge1.dot(p);
    if determinant.abs() <= f32::MIN_POSITIVE || !determinant.is_finite() {
        return None;
    }
    let inverse = 1.0 / determinant;
    let s = origin - a;
    let u = s.dot(p) * inverse;
    if !(-EDGE_TOLERANCE..=1.0 + EDGE_TOLERANCE).contains(&u) {
        return None;
    }
    let q = s.cross(edge1);
    let v = direction.dot(q) * inverse;
    if v < -EDGE_TOLERANCE || u + v > 1.0 + EDGE_TOLERANCE {
        return None;
    }
    let t = edge2.dot(q) * inverse;
    if !(t_min..=t_max).contains(&t) {
        return None;
    }
    let u = u.clamp(0.0, 1.0);
    let v = v.clamp(0.0, 1.0 - u);
    Some((t, Vec3A::new(1.0 - u - v, u, v)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_from_both_sides_and_reports_barycentrics() {
        let (a, b, c) = (Vec3A::ZERO, Vec3A::X, Vec3A::Y);
        let origin = Vec3A::new(0.2, 0.3, 1.0);
        let (t, barycentric) =
            intersect_ray_triangle(origin, -Vec3A::Z, 0.0, f32::INFINITY, a, b, c).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        assert!(barycentric.distance(Vec3A::new(0.5, 0.2, 0.3)) < 1e-6);
        let below = Vec3A::new(0.2, 0.3, -1.0);
        assert!(intersect_ray_triangle(below, Vec3A::Z, 0.0, f32::INFINITY, a, b, c).is_some());
    }

    #[test]
    fn misses_outside_behind_and_beyond() {
        let (a, b, c) = (Vec3A::ZERO, Vec3A::X, Vec3A::Y);
        let outside = Vec3A::new(0.8, 0.8, 1.0);
        assert!(intersect_ray_triangle(outside, -Vec3A::Z, 0.0, f32::INFINITY, a, b, c).is_none());
        let origin = Vec3A::new(0.2, 0.2, 1.0);
        assert!(intersect_ray_triangle(origin, Vec3A::Z, 0.0, f32::INFINITY, a, b, c).is_none());
        assert!(intersect_ray_triangle(origin, -Vec3A::Z, 0.0, 0.5, a, b, c).is_none());
        let flat = Vec3A::new(2.0, 0.0, 0.0);
        assert!(intersect_ray_triangle(origin, -Vec3A::Z, 0.0, 9.0, a, b, flat).is_none());
    }
}
