//! The closest-point search (a four-wide BVH whose leaves are tested four triangles at a time
//! with a SIMD estimate before the exact test) answers exactly what testing every triangle with
//! the exact test answers: on random soups with degenerate triangles and slivers, on smooth
//! meshes far from the origin, for points far away, on the surface and just off it, with a
//! distance limit, and warm-started from a wrong triangle.

mod common;

use common::{Rng, lumpy_egg, random_soup, uv_sphere};
use glam::{Vec3, Vec3A};
use springwrap_kernel::query::point_triangle::{
    closest_point_on_degenerate_triangle, closest_point_on_triangle, is_degenerate,
};
use springwrap_kernel::{NO_TRIANGLE, SurfaceHit, TargetMesh, TargetMeshOptions};

/// The exact distance from `point` to the surface, testing every triangle.
fn brute_force_distance(mesh: &TargetMesh, point: Vec3) -> f32 {
    let point = Vec3A::from(point);
    mesh.triangles()
        .iter()
        .map(|corners| {
            let [a, b, c] = corners.map(|index| Vec3A::from(mesh.vertices()[index as usize]));
            let (closest, _) = if is_degenerate(a, b, c) {
                closest_point_on_degenerate_triangle(point, a, b, c)
            } else {
                closest_point_on_triangle(point, a, b, c)
            };
            closest.distance(point)
        })
        .fold(f32::INFINITY, f32::min)
}

/// A hit is the brute-force answer: the same distance, and a point on its triangle at that
/// distance.
fn check_hit(mesh: &TargetMesh, query: Vec3, hit: Option<SurfaceHit>, max_distance: f32) {
    let expected = brute_force_distance(mesh, query);
    if expected > max_distance * (1.0 + 1e-5) {
        assert!(
            hit.is_none(),
            "{query}: {expected} is beyond {max_distance}"
        );
        return;
    }
    if expected >= max_distance * (1.0 - 1e-5) {
        return; // on the limit: either answer is right
    }
    let hit = hit.unwrap_or_else(|| panic!("{query}: nothing found within {max_distance}"));
    assert_eq!(hit.distance, expected, "distance for query {query}");
    let rebuilt = mesh.face_point_position(hit.face_point).unwrap();
    let scale = 1.0 + hit.position.abs().max_element();
    assert!(rebuilt.distance(hit.position) <= 1e-5 * scale);
    assert!((hit.position.distance(query) - hit.distance).abs() <= 1e-5 * scale);
}

/// Checks `closest_points`, `closest_point`, and `closest_points_near` started from a wrong
/// triangle, from no triangle and from the right one.
fn check_queries(mesh: &TargetMesh, queries: &[Vec3], max_distance: f32, rng: &mut Rng) {
    let hits = mesh.closest_points(queries, max_distance).unwrap();
    for (query, hit) in queries.iter().zip(&hits) {
        check_hit(mesh, *query, *hit, max_distance);
    }
    for query in queries.iter().step_by(7) {
        check_hit(
            mesh,
            *query,
            mesh.closest_point(*query, max_distance),
            max_distance,
        );
    }
    let triangle_count = mesh.triangles().len();
    let wrong: Vec<u32> = (0..queries.len())
        .map(|index| match index % 5 {
            0 => NO_TRIANGLE,
            1 => triangle_count as u32 + 3, // not a triangle: no warm start
            _ => rng.below(triangle_count) as u32,
        })
        .collect();
    let right: Vec<u32> = hits
        .iter()
        .map(|hit| hit.map_or(NO_TRIANGLE, |hit| hit.face_point.triangle))
        .collect();
    for near in [&wrong, &right] {
        let warm = mesh
            .closest_points_near(queries, max_distance, near)
            .unwrap();
        for (query, hit) in queries.iter().zip(warm) {
            check_hit(mesh, *query, hit, max_distance);
        }
    }
}

/// Points on random triangles (random barycentric coordinates), and the same pushed off by
/// `offset` in a random direction.
fn surface_points(mesh: &TargetMesh, rng: &mut Rng, count: usize, offset: f32) -> Vec<Vec3> {
    (0..count)
        .map(|_| {
            let triangle = mesh.triangles()[rng.below(mesh.triangles().len())];
            let (u, v) = (rng.unit(), rng.unit());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let [a, b, c] = triangle.map(|index| mesh.vertices()[index as usize]);
            let on_surface = a + (b - a) * u + (c - a) * v;
            on_surface + rng.point_in_box(1.0).normalize_or(Vec3::Z) * offset
        })
        .collect()
}

#[test]
fn random_soups_near_far_and_on_the_surface() {
    let mut rng = Rng::new(2024);
    for triangle_count in [3, 5, 40, 700, 3000] {
        let (vertices, triangles) = random_soup(&mut rng, triangle_count);
        let Ok(mesh) = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()) else {
            continue;
        };
        let mut queries: Vec<Vec3> = (0..300).map(|_| rng.point_in_box(8.0)).collect();
        queries.extend((0..60).map(|_| rng.point_in_box(1.0) * 1e4));
        for offset in [0.0, 1e-6, 1e-3, 0.1] {
            queries.extend(surface_points(&mesh, &mut rng, 80, offset));
        }
        for max_distance in [f32::INFINITY, 0.5, 0.0] {
            check_queries(&mesh, &queries, max_distance, &mut rng);
        }
    }
}

#[test]
fn slivers_and_caps_are_never_skipped() {
    // Thin triangles just above the degenerate threshold, in every orientation, with their
    // widest angle at each corner in turn, beside ordinary ones.
    let mut rng = Rng::new(99);
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for index in 0..600 {
        let a = rng.point_in_box(3.0);
        let along = rng.point_in_box(1.0).normalize_or(Vec3::X) * rng.range(0.1, 2.0);
        let across = along.any_orthonormal_vector() * along.length();
        let thinness = [1e-5, 1e-4, 1e-3, 1e-2, 0.3][index % 5];
        let (b, c) = if index % 2 == 0 {
            // A cap: the third corner near the middle of the long edge.
            (
                a + along,
                a + along * rng.range(0.2, 0.8) + across * thinness,
            )
        } else {
            // A needle: one short edge.
            (a + along, a + across * thinness)
        };
        let base = vertices.len() as u32;
        vertices.extend([a, b, c]);
        let rotation = index % 3;
        let mut corners = [base, base + 1, base + 2];
        corners.rotate_left(rotation);
        triangles.push(corners);
    }
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let mut queries: Vec<Vec3> = (0..400).map(|_| rng.point_in_box(4.0)).collect();
    for offset in [0.0, 1e-5, 1e-2] {
        queries.extend(surface_points(&mesh, &mut rng, 300, offset));
    }
    check_queries(&mesh, &queries, f32::INFINITY, &mut rng);
    check_queries(&mesh, &queries, 0.05, &mut rng);
}

#[test]
fn smooth_meshes_far_from_the_origin() {
    // Rounding grows with the coordinates: small triangles a thousand units away.
    let mut rng = Rng::new(4);
    for offset in [Vec3::ZERO, Vec3::new(1000.0, -250.0, 40.0)] {
        for (vertices, triangles) in [uv_sphere(0.5, 30, 48), lumpy_egg(0.8, 40, 64)] {
            let vertices: Vec<Vec3> = vertices.into_iter().map(|v| v + offset).collect();
            let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
            let mut queries: Vec<Vec3> = (0..300).map(|_| offset + rng.point_in_box(1.2)).collect();
            for surface_offset in [0.0, 1e-4, 0.02] {
                queries.extend(surface_points(&mesh, &mut rng, 200, surface_offset));
            }
            check_queries(&mesh, &queries, f32::INFINITY, &mut rng);
            check_queries(&mesh, &queries, 0.03, &mut rng);
        }
    }
}

#[test]
fn warm_start_length_must_match() {
    let (vertices, triangles) = uv_sphere(1.0, 8, 12);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    assert!(
        mesh.closest_points_near(&[Vec3::ZERO, Vec3::X], f32::INFINITY, &[0])
            .is_err()
    );
}
