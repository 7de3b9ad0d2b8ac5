//! Every query answers exactly what testing each triangle / vertex in turn answers.

mod common;

use common::{Rng, random_soup, uv_sphere};
use glam::{Vec3, Vec3A};
use springwrap_kernel::query::point_triangle::{
    closest_point_on_degenerate_triangle, closest_point_on_triangle, is_degenerate,
};
use springwrap_kernel::query::ray_triangle::intersect_ray_triangle;
use springwrap_kernel::{TargetMesh, TargetMeshOptions};

fn brute_force_closest_distance(mesh: &TargetMesh, point: Vec3) -> f32 {
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

fn check_closest_points(mesh: &TargetMesh, queries: &[Vec3]) {
    let hits = mesh.closest_points(queries, f32::INFINITY).unwrap();
    for (query, hit) in queries.iter().zip(&hits) {
        let hit = hit.expect("an unlimited search always finds the surface");
        let expected = brute_force_closest_distance(mesh, *query);
        assert_eq!(hit.distance, expected, "distance for query {query}");
        // The point, its face-point and its distance agree with one another.
        let rebuilt = mesh.face_point_position(hit.face_point).unwrap();
        assert!(rebuilt.distance(hit.position) <= 1e-5 * (1.0 + hit.position.length()));
        assert!(
            (hit.position.distance(*query) - hit.distance).abs() <= 1e-5 * (1.0 + hit.distance)
        );
        let barycentric = hit.face_point.barycentric;
        assert!(barycentric.min_element() >= 0.0 && (barycentric.element_sum() - 1.0).abs() < 1e-5);
    }
}

#[test]
fn closest_point_on_random_soups_with_degenerate_triangles() {
    let mut rng = Rng::new(7);
    for triangle_count in [1, 2, 17, 300, 2000] {
        let (vertices, triangles) = random_soup(&mut rng, triangle_count);
        let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default());
        let Ok(mesh) = mesh else {
            continue; // a one-triangle soup may be all degenerate: covered by the error tests
        };
        let queries: Vec<Vec3> = (0..400).map(|_| rng.point_in_box(8.0)).collect();
        check_closest_points(&mesh, &queries);
    }
}

#[test]
fn closest_point_on_a_sphere_near_and_far() {
    let (vertices, triangles) = uv_sphere(2.0, 40, 64);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let mut rng = Rng::new(11);
    let queries: Vec<Vec3> = (0..1000)
        .map(|index| {
            let direction = rng.point_in_box(1.0).normalize_or(Vec3::X);
            let radius = if index % 2 == 0 {
                rng.range(1.9, 2.1)
            } else {
                rng.range(0.0, 20.0)
            };
            direction * radius
        })
        .collect();
    check_closest_points(&mesh, &queries);
}

#[test]
fn max_distance_limits_the_search() {
    let (vertices, triangles) = uv_sphere(1.0, 10, 16);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let far = Vec3::new(0.0, 0.0, 3.0);
    assert!(mesh.closest_point(far, 1.9).is_none());
    let hit = mesh.closest_point(far, 2.1).unwrap();
    assert!((hit.distance - 2.0).abs() < 1e-5);
    let vertex = mesh.nearest_vertex(far, 2.1).unwrap();
    assert_eq!(vertex.position, Vec3::new(0.0, 0.0, 1.0));
    assert!(mesh.nearest_vertex(far, 1.5).is_none());
}

#[test]
fn nearest_vertex_matches_brute_force_and_skips_degenerate_only_vertices() {
    let mut rng = Rng::new(3);
    let (vertices, triangles) = random_soup(&mut rng, 1500);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let used: Vec<u32> = mesh
        .triangles()
        .iter()
        .zip(mesh.degenerate_triangles())
        .filter(|&(_, &degenerate)| !degenerate)
        .flat_map(|(corners, _)| *corners)
        .collect();
    let queries: Vec<Vec3> = (0..500).map(|_| rng.point_in_box(7.0)).collect();
    let hits = mesh.nearest_vertices(&queries, f32::INFINITY).unwrap();
    for (query, hit) in queries.iter().zip(hits) {
        let hit = hit.unwrap();
        let expected = used
            .iter()
            .map(|&vertex| mesh.vertices()[vertex as usize].distance(*query))
            .fold(f32::INFINITY, f32::min);
        assert_eq!(hit.distance, expected);
        assert!(!mesh.degenerate_triangles()[hit.face_point.triangle as usize]);
        let corner = mesh.triangles()[hit.face_point.triangle as usize];
        let weight_index = corner
            .iter()
            .position(|&vertex| vertex == hit.vertex)
            .unwrap();
        assert_eq!(hit.face_point.barycentric[weight_index], 1.0);
        assert_eq!(
            mesh.face_point_position(hit.face_point).unwrap(),
            hit.position
        );
    }
}

fn brute_force_ray(mesh: &TargetMesh, origin: Vec3, direction: Vec3, max: f32) -> Option<f32> {
    let direction = Vec3A::from(direction.normalize());
    mesh.triangles()
        .iter()
        .zip(mesh.degenerate_triangles())
        .filter(|&(_, &degenerate)| !degenerate)
        .filter_map(|(corners, _)| {
            let [a, b, c] = corners.map(|index| Vec3A::from(mesh.vertices()[index as usize]));
            intersect_ray_triangle(origin.into(), direction, 0.0, max, a, b, c).map(|(t, _)| t)
        })
        .reduce(f32::min)
}

#[test]
fn ray_casts_match_brute_force_in_both_directions() {
    let mut rng = Rng::new(5);
    let (vertices, triangles) = random_soup(&mut rng, 1500);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let origins: Vec<Vec3> = (0..600).map(|_| rng.point_in_box(6.0)).collect();
    let directions: Vec<Vec3> = (0..600)
        .map(|_| rng.point_in_box(1.0) + Vec3::splat(1e-3))
        .collect();
    for max_distance in [f32::INFINITY, 2.0] {
        let forward = mesh
            .ray_casts(&origins, &directions, max_distance, false)
            .unwrap();
        let both = mesh
            .ray_casts(&origins, &directions, max_distance, true)
            .unwrap();
        let mut hit_count = 0;
        for index in 0..origins.len() {
            let ahead = brute_force_ray(&mesh, origins[index], directions[index], max_distance);
            let behind = brute_force_ray(&mesh, origins[index], -directions[index], max_distance);
            match (ahead, forward[index]) {
                (None, None) => {}
                (Some(t), Some(hit)) => {
                    hit_count += 1;
                    assert!(
                        (hit.distance - t).abs() <= 1e-4,
                        "ray {index}: {} vs {t}",
                        hit.distance
                    );
                    let expected = origins[index] + directions[index].normalize() * hit.distance;
                    assert!(hit.position.distance(expected) < 1e-3);
                }
                (expected, found) => panic!("ray {index}: expected {expected:?}, found {found:?}"),
            }
            let nearest = match (ahead, behind) {
                (Some(a), Some(b)) => Some(if b < a { -b } else { a }),
                (a, b) => a.or(b.map(|t| -t)),
            };
            match (nearest, both[index]) {
                (None, None) => {}
                (Some(t), Some(hit)) => assert!((hit.distance - t).abs() <= 1e-4),
                (expected, found) => panic!("ray {index} both ways: {expected:?} vs {found:?}"),
            }
        }
        assert!(
            hit_count > 50,
            "the test must exercise hits, got {hit_count}"
        );
    }
}

#[test]
fn rays_through_shared_edges_do_not_slip_through() {
    let (vertices, triangles) = common::grid(8);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    // Straight down through every vertex and every edge midpoint of the grid interior.
    for x2 in 2..16 {
        for y2 in 2..16 {
            let origin = Vec3::new(x2 as f32 * 0.5, y2 as f32 * 0.5, 1.0);
            let hit = mesh.ray_cast(origin, -Vec3::Z, f32::INFINITY, false);
            assert!(hit.is_some(), "ray at {origin} slipped through");
        }
    }
}
