//! Face normals and angle-weighted vertex normals.

use glam::Vec3;

/// Unit normal of each triangle (right-handed winding), zero for degenerate triangles.
#[must_use]
pub fn face_normals(vertices: &[Vec3], triangles: &[[u32; 3]], degenerate: &[bool]) -> Vec<Vec3> {
    triangles
        .iter()
        .zip(degenerate)
        .map(|(corners, &is_degenerate)| {
            if is_degenerate {
                return Vec3::ZERO;
            }
            let [a, b, c] = corners.map(|index| vertices[index as usize]);
            (b - a).cross(c - a).normalize_or_zero()
        })
        .collect()
}

/// Unit vertex normals, each the face normals around the vertex weighted by the corner angle
/// (Thürmer & Wüthrich), zero for vertices that no non-degenerate triangle uses.
#[must_use]
pub fn vertex_normals(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    face_normals: &[Vec3],
) -> Vec<Vec3> {
    let mut sums = vec![Vec3::ZERO; vertices.len()];
    for (corners, &normal) in triangles.iter().zip(face_normals) {
        if normal == Vec3::ZERO {
            continue;
        }
        for corner in 0..3 {
            let here = vertices[corners[corner] as usize];
            let next = vertices[corners[(corner + 1) % 3] as usize];
            let previous = vertices[corners[(corner + 2) % 3] as usize];
            let angle = (next - here).angle_between(previous - here);
            if angle.is_finite() {
                sums[corners[corner] as usize] += normal * angle;
            }
        }
    }
    sums.into_iter().map(Vec3::normalize_or_zero).collect()
}
