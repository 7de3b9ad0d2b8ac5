//! Closest point on a triangle, with barycentric coordinates, exact for degenerate triangles too.

use glam::Vec3A;

/// Relative threshold under which a triangle counts as degenerate: `|ab × ac|` at most this
/// times its longest squared edge (the sine of its widest-open angle is about that small).
pub const DEGENERATE_RELATIVE_AREA: f32 = 1e-6;

/// Whether the triangle `(a, b, c)` is degenerate (a point, a segment, or a sliver whose height
/// is below [`DEGENERATE_RELATIVE_AREA`] times its longest edge).
#[must_use]
#[inline]
pub fn is_degenerate(a: Vec3A, b: Vec3A, c: Vec3A) -> bool {
    let ab = b - a;
    let ac = c - a;
    let bc = c - b;
    let longest_squared = ab
        .length_squared()
        .max(ac.length_squared())
        .max(bc.length_squared());
    let twice_area = ab.cross(ac).length();
    twice_area <= DEGENERATE_RELATIVE_AREA * longest_squared
}

/// The point of triangle `(a, b, c)` closest to `point`, and its barycentric coordinates
/// (weights of `a`, `b`, `c`, summing to 1).
///
/// Voronoi-region method (Ericson, *Real-Time Collision Detection*, 5.1.5). Callers that know the
/// triangle is degenerate must use [`closest_point_on_degenerate_triangle`] instead.
#[must_use]
#[inline]
pub fn closest_point_on_triangle(point: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> (Vec3A, Vec3A) {
    let ab = b - a;
    let ac = c - a;
    let ap = point - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Vec3A::X);
    }
    let bp = point - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Vec3A::Y);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, Vec3A::new(1.0 - v, v, 0.0));
    }
    let cp = point - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Vec3A::Z);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, Vec3A::new(1.0 - w, 0.0, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Vec3A::new(0.0, 1.0 - w, w));
    }
    let denominator = 1.0 / (va + vb + vc);
    let v = vb * denominator;
    let w = vc * denominator;
    (a + ab * v + ac * w, Vec3A::new(1.0 - v - w, v, w))
}

/// Closest point on a degenerate triangle: the best of its three edges taken as segments.
#[must_use]
pub fn closest_point_on_degenerate_triangle(
    point: Vec3A,
    a: Vec3A,
    b: Vec3A,
    c: Vec3A,
) -> (Vec3A, Vec3A) {
    let corners = [a, b, c];
    let mut best = (a, Vec3A::X);
    let mut best_distance_squared = f32::INFINITY;
    for edge in 0..3 {
        let start = corners[edge];
        let end = corners[(edge + 1) % 3];
        let (closest, t) = closest_point_on_segment(point, start, end);
        let distance_squared = closest.distance_squared(point);
        if distance_squared < best_distance_squared {
            best_distance_squared = distance_squared;
            let mut barycentric = [0.0f32; 3];
            barycentric[edge] = 1.0 - t;
            barycentric[(edge + 1) % 3] += t;
            best = (closest, Vec3A::from_array(barycentric));
        }
    }
    best
}

/// Closest point of segment `start..end` to `point`, and its parameter `t` in `[0, 1]`.
#[must_use]
#[inline]
pub fn closest_point_on_segment(point: Vec3A, start: Vec3A, end: Vec3A) -> (Vec3A, f32) {
    let direction = end - start;
    let length_squared = direction.length_squared();
    if length_squared == 0.0 {
        return (start, 0.0);
    }
    let t = ((point - start).dot(direction) / length_squared).clamp(0.0, 1.0);
    (start + direction * t, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interior_point_projects_onto_plane() {
        let (a, b, c) = (Vec3A::ZERO, Vec3A::X, Vec3A::Y);
        let (closest, barycentric) =
            closest_point_on_triangle(Vec3A::new(0.25, 0.25, 2.0), a, b, c);
        assert!(closest.distance(Vec3A::new(0.25, 0.25, 0.0)) < 1e-7);
        assert!(barycentric.distance(Vec3A::new(0.5, 0.25, 0.25)) < 1e-7);
    }

    #[test]
    fn regions_of_corners_and_edges() {
        let (a, b, c) = (Vec3A::ZERO, Vec3A::X, Vec3A::Y);
        assert_eq!(
            closest_point_on_triangle(Vec3A::new(-1.0, -1.0, 0.0), a, b, c).1,
            Vec3A::X
        );
        assert_eq!(
            closest_point_on_triangle(Vec3A::new(3.0, -0.5, 1.0), a, b, c).1,
            Vec3A::Y
        );
        let (closest, barycentric) = closest_point_on_triangle(Vec3A::new(1.0, 1.0, 0.0), a, b, c);
        assert!(closest.distance(Vec3A::new(0.5, 0.5, 0.0)) < 1e-7);
        assert!(barycentric.distance(Vec3A::new(0.0, 0.5, 0.5)) < 1e-7);
    }

    #[test]
    fn degenerate_triangles_are_detected_and_handled() {
        let a = Vec3A::ZERO;
        let b = Vec3A::new(2.0, 0.0, 0.0);
        let collinear = Vec3A::new(1.0, 0.0, 0.0);
        assert!(is_degenerate(a, b, collinear));
        assert!(is_degenerate(a, a, a));
        assert!(!is_degenerate(a, b, Vec3A::Y));
        let (closest, barycentric) =
            closest_point_on_degenerate_triangle(Vec3A::new(1.5, 1.0, 0.0), a, b, collinear);
        assert!(closest.distance(Vec3A::new(1.5, 0.0, 0.0)) < 1e-6);
        let rebuilt = a * barycentric.x + b * barycentric.y + collinear * barycentric.z;
        assert!(rebuilt.distance(closest) < 1e-6);
        assert!((barycentric.element_sum() - 1.0).abs() < 1e-6);
        let (point_closest, _) =
            closest_point_on_degenerate_triangle(Vec3A::new(0.0, 3.0, 4.0), a, a, a);
        assert_eq!(point_closest, a);
    }
}
