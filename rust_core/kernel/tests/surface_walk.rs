//! The surface walker on meshes whose answers are known: flat grids (the walk is the straight
//! displacement), bent grids (the walk unfolds around the fold), spheres (the walk stays on the
//! surface and is reversible), holes and borders (the point is lifted where the path leaves the
//! mesh), degenerate triangles in the way, and inputs that must not loop.

mod common;

use common::{Rng, grid, uv_sphere};
use glam::Vec3;
use springwrap_kernel::surface::walk::MAX_CROSSINGS;
use springwrap_kernel::{
    FacePoint, KernelError, NO_TRIANGLE, TargetMesh, TargetMeshOptions, WalkEnd,
};

fn mesh(vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> TargetMesh {
    TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap()
}

/// The face-point at a position on the surface.
fn face_point_at(mesh: &TargetMesh, position: Vec3) -> FacePoint {
    let hit = mesh.closest_point(position, f32::INFINITY).unwrap();
    assert!(hit.distance < 1e-5, "{position} is not on the surface");
    hit.face_point
}

/// Every face-point sitting exactly on `vertex`: one per non-degenerate triangle around it.
fn face_points_on_vertex(mesh: &TargetMesh, vertex: u32) -> Vec<FacePoint> {
    let mut face_points = Vec::new();
    for (triangle, corners) in mesh.triangles().iter().enumerate() {
        if mesh.degenerate_triangles()[triangle] {
            continue;
        }
        if let Some(corner) = corners.iter().position(|&v| v == vertex) {
            let mut barycentric = Vec3::ZERO;
            barycentric[corner] = 1.0;
            face_points.push(FacePoint {
                triangle: triangle as u32,
                barycentric,
            });
        }
    }
    face_points
}

/// Barycentrics are non-negative and sum to one.
fn assert_valid(face_point: FacePoint) {
    let barycentric = face_point.barycentric;
    assert!(barycentric.min_element() >= 0.0, "{barycentric}");
    assert!(
        (barycentric.element_sum() - 1.0).abs() < 1e-6,
        "{barycentric}"
    );
}

/// The end position of a walk that must stay on the surface.
fn on_surface(mesh: &TargetMesh, end: WalkEnd) -> Vec3 {
    let WalkEnd::OnSurface(face_point) = end else {
        panic!("expected to stay on the surface, got {end:?}");
    };
    assert_valid(face_point);
    mesh.face_point_position(face_point).unwrap()
}

/// The lifted end of a walk that must leave the surface: `(position, exit point)`.
fn lifted(mesh: &TargetMesh, end: WalkEnd) -> (Vec3, Vec3) {
    let WalkEnd::Lifted {
        position,
        exit,
        edge,
    } = end
    else {
        panic!("expected to be lifted, got {end:?}");
    };
    assert_valid(exit);
    assert_eq!(exit.triangle, edge.triangle);
    assert_eq!(
        mesh.triangle_neighbors()[edge.triangle as usize][usize::from(edge.edge)],
        NO_TRIANGLE,
        "lifted at an edge that is not a boundary"
    );
    // The exit point is on the edge: the corner opposite it has no weight.
    assert_eq!(exit.barycentric[(usize::from(edge.edge) + 2) % 3], 0.0);
    (position, mesh.face_point_position(exit).unwrap())
}

fn assert_close(actual: Vec3, expected: Vec3, tolerance: f32) {
    assert!(
        actual.distance(expected) <= tolerance,
        "{actual} is not within {tolerance} of {expected}"
    );
}

#[test]
fn on_a_flat_grid_the_walk_is_the_displacement_projected_on_the_plane() {
    // A 16 x 16 grid in z = 0; random starts and displacements (with a z part that the walk
    // drops). Inside the square the end is start + (dx, dy); past its border the point is lifted
    // where the straight path leaves the square and goes on to start + (dx, dy).
    let size = 16.0;
    let (vertices, triangles) = grid(16);
    let mesh = mesh(vertices, triangles);
    let mut rng = Rng::new(7);
    let (mut inside, mut outside, mut most_crossings) = (0, 0, 0);
    for _ in 0..2000 {
        let start = Vec3::new(rng.range(0.0, size), rng.range(0.0, size), 0.0);
        let displacement = Vec3::new(
            rng.range(-9.0, 9.0),
            rng.range(-9.0, 9.0),
            rng.range(-3.0, 3.0),
        );
        let planar = displacement.with_z(0.0);
        let end = start + planar;
        let margin = end.x.min(end.y).min(size - end.x).min(size - end.y);
        if margin.abs() < 1e-3 {
            continue; // too close to the border to say which side
        }
        let outcome = mesh.walk_traced(face_point_at(&mesh, start), displacement);
        assert!(!outcome.truncated);
        assert_close(outcome.direction, planar.normalize(), 1e-5);
        most_crossings = most_crossings.max(outcome.edge_crossings);
        if margin > 0.0 {
            inside += 1;
            assert_close(on_surface(&mesh, outcome.end), end, 1e-5);
        } else {
            outside += 1;
            let (position, exit) = lifted(&mesh, outcome.end);
            assert_close(position, end, 1e-5);
            // The exit is where the segment leaves the square.
            let leave = [
                (-start.x / planar.x),
                ((size - start.x) / planar.x),
                (-start.y / planar.y),
                ((size - start.y) / planar.y),
            ]
            .into_iter()
            .filter(|&t| t > 0.0)
            .fold(f32::INFINITY, f32::min);
            assert_close(exit, start + planar * leave, 1e-5);
        }
    }
    assert!(
        inside > 500 && outside > 500,
        "{inside} inside, {outside} outside"
    );
    assert!(
        most_crossings > 30,
        "paths cross many triangles ({most_crossings})"
    );
}

#[test]
fn on_a_flat_grid_paths_through_vertices_and_along_edges_go_straight() {
    // The grid's triangles are split along (1, 1) diagonals. These paths start on vertices,
    // edges and cell interiors and run along edges, along diagonals, or hit vertex after vertex.
    let (vertices, triangles) = grid(12);
    let mesh = mesh(vertices, triangles);
    let vertex = |x: u32, y: u32| y * 13 + x;
    let cases = [
        (Vec3::new(3.0, 3.0, 0.0), Vec3::new(5.0, 5.0, 0.0)), // along diagonals, vertex to vertex
        (Vec3::new(2.5, 4.0, 0.0), Vec3::new(6.0, 0.0, 0.0)), // along a horizontal edge line
        (Vec3::new(4.0, 1.5, 0.0), Vec3::new(0.0, 7.0, 0.0)), // along a vertical edge line
        (Vec3::new(1.0, 1.0, 0.0), Vec3::new(4.0, 8.0, 0.0)), // through the lattice points (1+k, 1+2k)
        (Vec3::new(8.0, 8.0, 0.0), Vec3::new(-6.0, 3.0, 0.0)), // through (6, 9), (4, 10), (2, 11)
        (Vec3::new(2.0, 9.0, 0.0), Vec3::new(7.0, -7.0, 0.0)), // across every diagonal at its middle, cell corner to cell corner
        (Vec3::new(0.5, 0.5, 0.0), Vec3::new(10.0, 10.0, 0.0)), // inside the diagonals of the cells
        (Vec3::new(11.0, 0.0, 0.0), Vec3::new(-11.0, 0.0, 0.0)), // along the border
        (Vec3::new(0.0, 12.0, 0.0), Vec3::new(12.0, -12.0, 0.0)), // corner to corner across the grid
    ];
    for (start, displacement) in cases {
        let outcome = mesh.walk_traced(face_point_at(&mesh, start), displacement);
        assert_close(on_surface(&mesh, outcome.end), start + displacement, 1e-5);
        assert_close(outcome.direction, displacement.normalize(), 1e-5);
    }
    // From a vertex, whichever triangle around it the face-point names, in 24 directions.
    for face_point in face_points_on_vertex(&mesh, vertex(6, 6)) {
        for step in 0..24 {
            let angle = std::f32::consts::TAU * step as f32 / 24.0;
            let displacement = 3.7 * Vec3::new(angle.cos(), angle.sin(), 0.0);
            let end = on_surface(&mesh, mesh.walk(face_point, displacement));
            assert_close(end, Vec3::new(6.0, 6.0, 0.0) + displacement, 1e-5);
        }
    }
}

#[test]
fn walking_off_the_border_of_a_grid_lifts_at_the_border() {
    let (vertices, triangles) = grid(4);
    let mesh = mesh(vertices, triangles);
    let start = face_point_at(&mesh, Vec3::new(2.0, 2.5, 0.0));
    let outcome = mesh.walk_traced(start, Vec3::new(3.0, 0.5, 0.0));
    let (position, exit) = lifted(&mesh, outcome.end);
    // The path leaves x = 4 after 2/3 of the displacement, at y = 2.5 + 0.5 * 2/3.
    assert_close(exit, Vec3::new(4.0, 2.5 + 1.0 / 3.0, 0.0), 1e-6);
    assert_close(position, Vec3::new(5.0, 3.0, 0.0), 1e-6);
    assert_close(
        outcome.direction,
        Vec3::new(3.0, 0.5, 0.0).normalize(),
        1e-6,
    );
    // Out through a corner vertex of the grid.
    let (position, exit) = lifted(&mesh, mesh.walk(start, Vec3::new(-3.0, -3.0, 0.0)));
    assert_close(exit, Vec3::new(0.0, 0.5, 0.0), 1e-6);
    assert_close(position, Vec3::new(-1.0, -0.5, 0.0), 1e-6);
    let corner = face_point_at(&mesh, Vec3::new(1.0, 1.0, 0.0));
    let (position, exit) = lifted(&mesh, mesh.walk(corner, Vec3::new(-2.0, -2.0, 0.0)));
    assert_close(exit, Vec3::ZERO, 1e-6);
    assert_close(position, Vec3::new(-1.0, -1.0, 0.0), 1e-6);
}

#[test]
fn a_grid_with_a_hole_lifts_at_the_holes_edge() {
    // A 12 x 12 grid without the cells of [4, 8) x [4, 8).
    let (vertices, triangles) = grid(12);
    let triangles: Vec<[u32; 3]> = triangles
        .into_iter()
        .enumerate()
        .filter(|&(index, _)| {
            let cell = index / 2;
            let (x, y) = (cell % 12, cell / 12);
            !((4..8).contains(&x) && (4..8).contains(&y))
        })
        .map(|(_, triangle)| triangle)
        .collect();
    let mesh = mesh(vertices, triangles);
    let hole_edge = |end: WalkEnd| {
        let WalkEnd::Lifted { edge, .. } = end else {
            unreachable!()
        };
        let corners = mesh.triangles()[edge.triangle as usize];
        let (a, b) = (
            mesh.vertices()[corners[usize::from(edge.edge)] as usize],
            mesh.vertices()[corners[(usize::from(edge.edge) + 1) % 3] as usize],
        );
        let (low, high) = (a.min(b).truncate(), a.max(b).truncate());
        low.min_element() >= 4.0 && high.max_element() <= 8.0
    };
    // Into the hole across its left side.
    let end = mesh.walk(
        face_point_at(&mesh, Vec3::new(1.5, 5.5, 0.0)),
        Vec3::new(6.0, 0.0, 0.0),
    );
    let (position, exit) = lifted(&mesh, end);
    assert_close(exit, Vec3::new(4.0, 5.5, 0.0), 1e-6);
    assert_close(position, Vec3::new(7.5, 5.5, 0.0), 1e-6);
    assert!(hole_edge(end));
    // Into the hole through its corner (4, 4), along the diagonals.
    let end = mesh.walk(
        face_point_at(&mesh, Vec3::new(2.0, 2.0, 0.0)),
        Vec3::new(4.0, 4.0, 0.0),
    );
    let (position, exit) = lifted(&mesh, end);
    assert_close(exit, Vec3::new(4.0, 4.0, 0.0), 1e-6);
    assert_close(position, Vec3::new(6.0, 6.0, 0.0), 1e-6);
    assert!(hole_edge(end));
    // Across the hole diagonally from the top right: lifted on entering it, not on leaving.
    let end = mesh.walk(
        face_point_at(&mesh, Vec3::new(10.0, 9.0, 0.0)),
        Vec3::new(-8.0, -4.0, 0.0),
    );
    let (position, exit) = lifted(&mesh, end);
    assert_close(exit, Vec3::new(8.0, 8.0, 0.0), 1e-6);
    assert_close(position, Vec3::new(2.0, 5.0, 0.0), 1e-6);
    // Through the hole's corner (8, 8) from the right, on into the cells above the hole: the
    // path touches the hole only at that vertex and stays on the surface.
    for (start, displacement) in [
        (Vec3::new(10.0, 7.5, 0.0), Vec3::new(-4.0, 1.0, 0.0)),
        (Vec3::new(9.0, 7.0, 0.0), Vec3::new(-3.0, 3.0, 0.0)),
        (Vec3::new(8.5, 2.0, 0.0), Vec3::new(-1.0, 12.0, 0.0) * 0.8),
    ] {
        let end = mesh.walk(face_point_at(&mesh, start), displacement);
        assert_close(on_surface(&mesh, end), start + displacement, 1e-5);
    }
    // Sliding along the hole's bottom side (a boundary edge) stays on the surface.
    let end = mesh.walk(
        face_point_at(&mesh, Vec3::new(1.0, 4.0, 0.0)),
        Vec3::new(5.0, 0.0, 0.0),
    );
    assert_close(on_surface(&mesh, end), Vec3::new(6.0, 4.0, 0.0), 1e-6);
    // Passing beside the hole does not lift.
    let end = mesh.walk(
        face_point_at(&mesh, Vec3::new(1.0, 2.0, 0.0)),
        Vec3::new(10.0, 1.9, 0.0),
    );
    assert_close(on_surface(&mesh, end), Vec3::new(11.0, 3.9, 0.0), 1e-6);
}

/// A 6 x `rows` grid bent up along x = 3 by `angle` (0 is flat): the cells with x < 3 lie in
/// z = 0, the others on a plane through the line x = 3 tilted by `angle`. Maps a point of the
/// flat (unfolded) grid onto the bent one.
fn bent_grid(rows: u32, angle: f32) -> (TargetMesh, impl Fn(Vec3) -> Vec3) {
    let fold = move |flat: Vec3| {
        if flat.x <= 3.0 {
            flat
        } else {
            let along = flat.x - 3.0;
            Vec3::new(3.0 + along * angle.cos(), flat.y, along * angle.sin())
        }
    };
    let row = 7;
    let vertices = (0..row * (rows + 1))
        .map(|index| fold(Vec3::new((index % row) as f32, (index / row) as f32, 0.0)))
        .collect();
    let mut triangles = Vec::new();
    for y in 0..rows {
        for x in 0..6 {
            let a = y * row + x;
            triangles.push([a, a + 1, a + row + 1]);
            triangles.push([a, a + row + 1, a + row]);
        }
    }
    (mesh(vertices, triangles), fold)
}

#[test]
fn a_folded_strip_unfolds_the_displacement_around_the_fold() {
    // Walking across the fold of a bent grid equals walking on the flat grid and bending the
    // result: the displacement turns about the fold line and keeps its length.
    let degrees = [90.0f32, 45.0, 135.0, 170.0, -60.0];
    let cases = [
        (Vec3::new(0.5, 0.5, 0.0), Vec3::new(4.0, 2.0, 0.0)),
        (Vec3::new(1.0, 1.0, 0.0), Vec3::new(3.0, 3.0, 0.0)), // through the fold at vertex (3, 3)
        (Vec3::new(2.0, 4.0, 0.0), Vec3::new(3.0, 0.0, 0.0)), // along an edge line across the fold
        (Vec3::new(5.5, 1.2, 0.0), Vec3::new(-5.0, 4.1, 0.0)), // from the bent part back down
    ];
    for degrees in degrees {
        let angle = degrees.to_radians();
        let (mesh, fold) = bent_grid(6, angle);
        // A flat vector at a flat point, as seen on the bent grid.
        let bend = |at: Vec3, vector: Vec3| {
            if at.x < 3.0 {
                vector
            } else {
                Vec3::new(vector.x * angle.cos(), vector.y, vector.x * angle.sin())
            }
        };
        for (flat_start, flat_displacement) in cases {
            let start = face_point_at(&mesh, fold(flat_start));
            // The displacement as seen in the start's plane, plus a normal part that is dropped.
            let displacement =
                bend(flat_start, flat_displacement) + mesh.face_normals()[start.triangle as usize];
            let outcome = mesh.walk_traced(start, displacement);
            let flat_end = flat_start + flat_displacement;
            assert_close(on_surface(&mesh, outcome.end), fold(flat_end), 2e-5);
            // The direction at the end is the displacement carried over the fold.
            let expected_direction = bend(flat_end, flat_displacement.normalize());
            assert_close(outcome.direction, expected_direction, 1e-5);
            // Walking back along the reversed direction returns to the start.
            let back = mesh.walk(
                outcome.end.face_point().unwrap(),
                -outcome.direction * flat_displacement.length(),
            );
            assert_close(on_surface(&mesh, back), fold(flat_start), 2e-5);
        }
    }
}

#[test]
fn on_a_sphere_the_walk_stays_on_the_surface_and_is_reversible() {
    // A UV sphere of radius 2 (24 rings, 48 segments): its triangles lie between 0.99 r and r
    // from the centre. Short tangent walks from random starts must (1) end on the surface,
    // (2) cover an arc about as long as the displacement, (3) come back when walked in reverse.
    let radius = 2.0;
    let (vertices, triangles) = uv_sphere(radius, 24, 48);
    let mesh = mesh(vertices, triangles);
    let mut rng = Rng::new(11);
    let mut worst_arc_error = 0.0f32;
    let mut worst_return = 0.0f32;
    for _ in 0..2000 {
        let direction = rng.point_in_box(1.0).normalize_or(Vec3::Z);
        let start = face_point_at(
            &mesh,
            mesh.closest_point(direction * 3.0, f32::INFINITY)
                .unwrap()
                .position,
        );
        let start_position = mesh.face_point_position(start).unwrap();
        let normal = mesh.face_normals()[start.triangle as usize];
        let tangent = rng
            .point_in_box(1.0)
            .reject_from(normal)
            .normalize_or(normal.any_orthonormal_vector());
        let length = rng.range(0.05, 0.6);
        let outcome = mesh.walk_traced(start, tangent * length + normal * rng.range(-1.0, 1.0));
        let end = on_surface(&mesh, outcome.end);
        assert!(
            end.length() > 0.99 * radius && end.length() < radius + 1e-5,
            "{end}"
        );
        let arc = radius * start_position.angle_between(end);
        worst_arc_error = worst_arc_error.max((arc - length).abs() / length);
        let back = mesh.walk(
            outcome.end.face_point().unwrap(),
            -outcome.direction * length,
        );
        worst_return = worst_return.max(on_surface(&mesh, back).distance(start_position));
    }
    assert!(
        worst_arc_error < 0.01,
        "arc length off by {worst_arc_error}"
    );
    assert!(worst_return < 1e-5, "came back {worst_return} away");
}

#[test]
fn walking_along_the_equator_of_a_sphere_goes_round_it() {
    // The UV sphere's equator is a ring of vertices joined by edges; the mesh is symmetric about
    // it, so the straightest path from an equator vertex along the equator stays on it, through
    // every vertex, and three laps of its perimeter end where they started.
    let (vertices, triangles) = uv_sphere(1.0, 16, 32);
    let mesh = mesh(vertices, triangles);
    let start_vertex = 1 + 7 * 32; // ring 8, segment 0: (1, 0, 0)
    let start_position = mesh.vertices()[start_vertex as usize];
    assert_close(start_position, Vec3::X, 1e-6);
    let next_vertex = start_vertex + 1; // segment 1, towards +y
    let edge = mesh.vertices()[next_vertex as usize] - start_position;
    let perimeter = 32.0 * edge.length();
    // The two triangles that hold the first equator edge, each at the start vertex.
    let starts: Vec<FacePoint> = face_points_on_vertex(&mesh, start_vertex)
        .into_iter()
        .filter(|face_point| mesh.triangles()[face_point.triangle as usize].contains(&next_vertex))
        .collect();
    assert_eq!(starts.len(), 2);
    for start in starts {
        for (laps, expected) in [(0.25f32, Vec3::Y), (1.0, Vec3::X), (3.0, Vec3::X)] {
            let outcome = mesh.walk_traced(start, edge.normalize() * perimeter * laps);
            let end = on_surface(&mesh, outcome.end);
            assert!(end.z.abs() < 1e-5, "left the equator: {end}");
            assert_close(end, expected, 1e-4);
        }
    }
}

#[test]
fn degenerate_triangles_in_the_way_are_crossed_at_no_length() {
    // A 6 x 4 grid cut along x = 3 into two halves with their own vertices, zipped back by a
    // column of zero-area triangles (each has two corners at the same place). Walks across the
    // cut go straight as on an uncut grid.
    let rows = 4u32;
    let mut vertices = Vec::new();
    // Left half: columns 0..=3; right half: columns 3..=6 (column 3 twice).
    for y in 0..=rows {
        for x in 0..=3 {
            vertices.push(Vec3::new(x as f32, y as f32, 0.0));
        }
    }
    let right_start = vertices.len() as u32;
    for y in 0..=rows {
        for x in 3..=6 {
            vertices.push(Vec3::new(x as f32, y as f32, 0.0));
        }
    }
    let left = |x: u32, y: u32| y * 4 + x;
    let right = |x: u32, y: u32| right_start + y * 4 + (x - 3);
    let mut triangles = Vec::new();
    for y in 0..rows {
        for x in 0..3 {
            triangles.push([left(x, y), left(x + 1, y), left(x + 1, y + 1)]);
            triangles.push([left(x, y), left(x + 1, y + 1), left(x, y + 1)]);
        }
        for x in 3..6 {
            triangles.push([right(x, y), right(x + 1, y), right(x + 1, y + 1)]);
            triangles.push([right(x, y), right(x + 1, y + 1), right(x, y + 1)]);
        }
    }
    let first_degenerate = triangles.len();
    for y in 0..rows {
        triangles.push([left(3, y), right(3, y), right(3, y + 1)]);
        triangles.push([left(3, y), right(3, y + 1), left(3, y + 1)]);
    }
    let cut = mesh(vertices.clone(), triangles.clone());
    assert_eq!(cut.degenerate_triangle_count(), 2 * rows as usize);
    assert!(
        cut.boundary_edges().iter().all(|edge| {
            let corners = cut.triangles()[edge.triangle as usize];
            let (a, b) = (
                corners[usize::from(edge.edge)],
                corners[(usize::from(edge.edge) + 1) % 3],
            );
            let (a, b) = (cut.vertices()[a as usize], cut.vertices()[b as usize]);
            a.x == b.x && (a.x == 0.0 || a.x == 6.0)
                || a.y == b.y && (a.y == 0.0 || a.y == rows as f32)
        }),
        "the zipped grid is one surface"
    );

    let cases = [
        (Vec3::new(1.0, 0.5, 0.0), Vec3::new(4.0, 1.0, 0.0)),
        (Vec3::new(5.5, 3.5, 0.0), Vec3::new(-5.0, -2.5, 0.0)),
        (Vec3::new(0.5, 2.0, 0.0), Vec3::new(5.0, 0.0, 0.0)), // through the cut's vertex (3, 2)
        (Vec3::new(1.0, 1.0, 0.0), Vec3::new(4.0, 2.0, 0.0)), // through vertex (3, 2) diagonally
        (Vec3::new(2.0, 0.0, 0.0), Vec3::new(3.0, 3.0, 0.0)), // along diagonals through (3, 1)
        (Vec3::new(3.0, 0.5, 0.0), Vec3::new(0.0, 3.0, 0.0)), // along the cut itself
    ];
    for (start, displacement) in cases {
        let outcome = cut.walk_traced(face_point_at(&cut, start), displacement);
        assert_close(on_surface(&cut, outcome.end), start + displacement, 1e-5);
        assert_close(outcome.direction, displacement.normalize(), 1e-5);
    }
    // Starting on a degenerate triangle, the walk steps off on the side it points to.
    for (barycentric, displacement) in [
        (Vec3::new(0.0, 0.7, 0.3), Vec3::new(1.5, -0.2, 0.0)),
        (Vec3::new(0.0, 0.7, 0.3), Vec3::new(-1.5, -0.2, 0.0)),
        (Vec3::new(0.2, 0.3, 0.5), Vec3::new(-0.5, -0.2, 0.3)),
    ] {
        for triangle in first_degenerate..triangles.len() {
            let start = FacePoint {
                triangle: triangle as u32,
                barycentric,
            };
            let position = cut.face_point_position(start).unwrap();
            let end = on_surface(&cut, cut.walk(start, displacement));
            assert_close(end, position + displacement.with_z(0.0), 1e-5);
        }
    }

    // Without the right half, the strip of degenerate triangles leads to a hole: lifted there.
    let left_only: Vec<[u32; 3]> = triangles
        .iter()
        .copied()
        .filter(|corners| corners.iter().any(|&v| v < right_start))
        .collect();
    let open = mesh(vertices, left_only);
    let end = open.walk(
        face_point_at(&open, Vec3::new(1.0, 1.5, 0.0)),
        Vec3::new(4.0, 0.0, 0.0),
    );
    let (position, exit) = lifted(&open, end);
    assert_close(exit, Vec3::new(3.0, 1.5, 0.0), 1e-6);
    assert_close(position, Vec3::new(5.0, 1.5, 0.0), 1e-6);
}

#[test]
fn a_t_junction_capped_by_a_degenerate_triangle_is_crossed() {
    //  L1 ------ A2 ------ R1
    //  |  left   | cap  right
    //  L0 ------ A0 ------ R0      A1 = (1, 1) is the midpoint of A0 A2: the left triangle's
    //                              edge A0 A2 meets the right side's two edges A0 A1 and A1 A2
    //                              through the flat "cap" triangle (A0, A1, A2).
    let vertices = vec![
        Vec3::new(0.0, 0.0, 0.0), // L0
        Vec3::new(0.0, 2.0, 0.0), // L1
        Vec3::new(1.0, 0.0, 0.0), // A0
        Vec3::new(1.0, 1.0, 0.0), // A1
        Vec3::new(1.0, 2.0, 0.0), // A2
        Vec3::new(2.0, 0.0, 0.0), // R0
        Vec3::new(2.0, 2.0, 0.0), // R1
    ];
    let triangles = vec![
        [0, 2, 4],
        [0, 4, 1],
        [2, 3, 4], // the cap
        [2, 5, 3],
        [3, 5, 6],
        [3, 6, 4],
    ];
    let mesh = mesh(vertices, triangles);
    assert_eq!(
        mesh.degenerate_triangles(),
        [false, false, true, false, false, false]
    );
    let cases = [
        (Vec3::new(0.3, 0.5, 0.0), Vec3::new(1.4, 0.9, 0.0)), // crosses x = 1 below A1
        (Vec3::new(0.3, 1.5, 0.0), Vec3::new(1.4, 0.2, 0.0)), // crosses above A1
        (Vec3::new(0.5, 0.5, 0.0), Vec3::new(1.0, 1.0, 0.0)), // through A1 itself
        (Vec3::new(1.8, 0.3, 0.0), Vec3::new(-1.6, 1.2, 0.0)), // right to left
    ];
    for (start, displacement) in cases {
        for sign in [1.0, -1.0] {
            // There, then back from the end.
            let (from, by) = if sign > 0.0 {
                (start, displacement)
            } else {
                (start + displacement, -displacement)
            };
            let end = mesh.walk(face_point_at(&mesh, from), by);
            assert_close(on_surface(&mesh, end), from + by, 1e-5);
        }
    }
}

#[test]
fn zero_and_normal_displacements_leave_the_start_unchanged() {
    let (vertices, triangles) = uv_sphere(1.0, 8, 16);
    let mesh = mesh(vertices, triangles);
    let start = FacePoint {
        triangle: 5,
        barycentric: Vec3::new(0.2, 0.3, 0.5),
    };
    let outcome = mesh.walk_traced(start, Vec3::ZERO);
    assert_eq!(outcome.end, WalkEnd::OnSurface(start));
    assert_eq!(
        (outcome.direction, outcome.edge_crossings, outcome.truncated),
        (Vec3::ZERO, 0, false)
    );
    let normal = mesh.face_normals()[5];
    assert_eq!(mesh.walk(start, normal * 0.3), WalkEnd::OnSurface(start));
    // A tiny displacement moves a tiny bit and stays in the triangle.
    let tangent = normal.any_orthonormal_vector();
    let end = mesh.walk(start, tangent * 1e-6);
    assert_eq!(end.face_point().unwrap().triangle, 5);
    assert_close(
        on_surface(&mesh, end),
        mesh.face_point_position(start).unwrap() + tangent * 1e-6,
        1e-7,
    );
}

#[test]
fn a_huge_displacement_on_a_closed_sphere_stops_at_the_crossing_cap() {
    // On a closed surface nothing ends a walk but its length: 1e6 times round a unit sphere
    // would cross billions of edges. The cap stops it, on the surface.
    let (vertices, triangles) = uv_sphere(1.0, 16, 32);
    let mesh = mesh(vertices, triangles);
    let start = face_point_at(
        &mesh,
        mesh.closest_point(Vec3::new(1.0, 0.2, 0.3), f32::INFINITY)
            .unwrap()
            .position,
    );
    let normal = mesh.face_normals()[start.triangle as usize];
    let time = std::time::Instant::now();
    let outcome = mesh.walk_traced(start, normal.any_orthonormal_vector() * 1e6);
    assert!(outcome.truncated);
    assert!(outcome.edge_crossings <= MAX_CROSSINGS + 64);
    on_surface(&mesh, outcome.end);
    assert!(time.elapsed().as_secs_f32() < 5.0);
    // A walk of a few laps is not cut short.
    let outcome = mesh.walk_traced(start, normal.any_orthonormal_vector() * 20.0);
    assert!(!outcome.truncated);
    on_surface(&mesh, outcome.end);
}

#[test]
fn walk_many_checks_its_inputs_and_matches_single_walks() {
    let (vertices, triangles) = uv_sphere(1.0, 12, 24);
    let mesh = mesh(vertices, triangles);
    let mut rng = Rng::new(3);
    let starts: Vec<FacePoint> = (0..5000)
        .map(|_| {
            let point = rng.point_in_box(1.0);
            mesh.closest_point(point, f32::INFINITY).unwrap().face_point
        })
        .collect();
    let displacements: Vec<Vec3> = (0..5000).map(|_| rng.point_in_box(0.5)).collect();
    let ends = mesh.walk_many(&starts, &displacements).unwrap();
    for ((&start, &displacement), &end) in starts.iter().zip(&displacements).zip(&ends) {
        assert_eq!(end, mesh.walk(start, displacement));
    }

    assert_eq!(
        mesh.walk_many(&starts, &displacements[1..]).unwrap_err(),
        KernelError::LengthMismatch {
            what: "walk starts and displacements",
            first: 5000,
            second: 4999
        }
    );
    let mut bad_starts = starts.clone();
    bad_starts[7].triangle = mesh.triangles().len() as u32;
    assert_eq!(
        mesh.walk_many(&bad_starts, &displacements).unwrap_err(),
        KernelError::TriangleIndexOutOfRange {
            index: 7,
            triangle: mesh.triangles().len() as u32,
            triangle_count: mesh.triangles().len()
        }
    );
    let mut bad_starts = starts.clone();
    bad_starts[9].barycentric.y = f32::NAN;
    assert_eq!(
        mesh.walk_many(&bad_starts, &displacements).unwrap_err(),
        KernelError::NonFinite {
            what: "barycentric",
            index: 9
        }
    );
    let mut bad_displacements = displacements.clone();
    bad_displacements[11].x = f32::INFINITY;
    let error = mesh.walk_many(&starts, &bad_displacements).unwrap_err();
    assert_eq!(
        error,
        KernelError::NonFinite {
            what: "displacement",
            index: 11
        }
    );
    assert!(error.to_string().contains("displacement 11"));
    assert!(mesh.walk_many(&[], &[]).unwrap().is_empty());
}

#[test]
fn on_a_crumpled_grid_every_walk_ends_sound_and_walks_back() {
    // A 20 x 20 grid with random heights: every pair of triangles meets at an angle, and every
    // interior vertex is a cone or a saddle. Starts anywhere (inside, on edges, on vertices),
    // displacements of any direction (some exactly along an edge) up to 30 long. Every walk must
    // end on the surface with valid barycentrics or be lifted at a boundary edge, never be cut
    // short, never end farther from the start (straight-line) than the length walked, and walking
    // back from the end along the reversed direction must return to the start. (Not checked for
    // displacements along an edge: those slide along edges and leave through a vertex exactly,
    // while the reverse path, rounded to f32, may pass a hair beside the vertex, where a cone
    // or saddle vertex turns it by its angle defect; that is what geodesics do.)
    let (mut vertices, triangles) = grid(20);
    let mut rng = Rng::new(5);
    for vertex in &mut vertices {
        vertex.z = rng.range(-0.3, 0.3);
    }
    let mesh = mesh(vertices, triangles);
    let (mut lifted_count, mut returned, mut worst_return) = (0, 0, 0.0f32);
    for case in 0..4000 {
        let triangle = rng.below(mesh.triangles().len()) as u32;
        let mut barycentric = Vec3::new(rng.unit(), rng.unit(), rng.unit());
        let on_vertex = case % 7 == 0;
        match case % 5 {
            0 => barycentric[rng.below(3)] = 0.0,
            1 if on_vertex => barycentric = Vec3::ZERO.with_x(1.0),
            _ => {}
        }
        let start = FacePoint {
            triangle,
            barycentric: barycentric / barycentric.element_sum(),
        };
        let start_position = mesh.face_point_position(start).unwrap();
        let corners = mesh.triangles()[triangle as usize].map(|v| mesh.vertices()[v as usize]);
        let along_edge = case % 3 == 0;
        let displacement = if along_edge {
            // Exactly along one of the start triangle's edges.
            let corner = rng.below(3);
            (corners[(corner + 1) % 3] - corners[corner]) * rng.range(0.5, 12.0)
        } else {
            rng.point_in_box(1.0) * rng.range(0.1, 30.0)
        };
        let normal = mesh.face_normals()[triangle as usize];
        let length = displacement.reject_from(normal).length();
        let outcome = mesh.walk_traced(start, displacement);
        assert!(!outcome.truncated, "case {case} was cut short");
        match outcome.end {
            WalkEnd::OnSurface(end) => {
                let end_position = on_surface(&mesh, outcome.end);
                assert!(end_position.distance(start_position) <= length + 1e-4);
                if on_vertex || along_edge || outcome.direction == Vec3::ZERO {
                    continue;
                }
                let back = mesh.walk(end, -outcome.direction * length);
                if let WalkEnd::OnSurface(_) = back {
                    returned += 1;
                    let distance = on_surface(&mesh, back).distance(start_position);
                    worst_return = worst_return.max(distance);
                }
            }
            WalkEnd::Lifted { position, .. } => {
                lifted_count += 1;
                let (_, exit) = lifted(&mesh, outcome.end);
                assert!(exit.distance(start_position) <= length + 1e-4);
                assert!(
                    (position.distance(exit) + exit.distance(start_position))
                        <= length * 1.001 + 1e-4
                );
            }
        }
    }
    assert!(
        lifted_count > 500 && returned > 500,
        "{lifted_count} lifted, {returned} returned"
    );
    assert!(worst_return < 1e-4, "came back {worst_return} away");
}

#[test]
fn flipped_windings_do_not_change_the_walk() {
    // The same 10 x 10 grid with every other triangle wound the other way round (its normal
    // points down): the walker reads only edges and corners, so the walks are the same.
    let (vertices, triangles) = grid(10);
    let flipped: Vec<[u32; 3]> = triangles
        .iter()
        .enumerate()
        .map(|(index, &[a, b, c])| if index % 2 == 0 { [a, c, b] } else { [a, b, c] })
        .collect();
    let flipped = mesh(vertices, flipped);
    let mut rng = Rng::new(13);
    for _ in 0..500 {
        let start = Vec3::new(rng.range(0.0, 10.0), rng.range(0.0, 10.0), 0.0);
        let displacement = Vec3::new(rng.range(-6.0, 6.0), rng.range(-6.0, 6.0), 0.0);
        let end = start + displacement;
        if end.min_element() < 1e-3 || end.max_element() > 10.0 - 1e-3 {
            continue;
        }
        let walked = flipped.walk(face_point_at(&flipped, start), displacement);
        assert_close(on_surface(&flipped, walked), end, 1e-5);
    }
    // Through vertices, where the walk turns around each vertex's triangles.
    for (start, displacement) in [
        (Vec3::new(1.0, 1.0, 0.0), Vec3::new(3.0, 6.0, 0.0)),
        (Vec3::new(0.5, 0.5, 0.0), Vec3::new(8.0, 8.0, 0.0)),
        (Vec3::new(2.0, 8.0, 0.0), Vec3::new(6.0, -6.0, 0.0)),
        (Vec3::new(9.5, 3.0, 0.0), Vec3::new(-9.0, 0.0, 0.0)),
    ] {
        let walked = flipped.walk(face_point_at(&flipped, start), displacement);
        assert_close(on_surface(&flipped, walked), start + displacement, 1e-5);
    }
}

#[test]
fn a_non_manifold_edge_lifts_like_a_boundary() {
    // Three triangles on the edge from (0, 0, 0) to (0, 1, 0): one to the left, one to the right,
    // one standing up (a fin). No walk can tell which to go on to, so crossing it lifts.
    let vertices = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(-1.0, 0.5, 0.0),
        Vec3::new(1.0, 0.5, 0.0),
        Vec3::new(0.0, 0.5, 1.0),
    ];
    let mesh = mesh(vertices, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
    assert_eq!(mesh.non_manifold_edge_count(), 1);
    let end = mesh.walk(
        face_point_at(&mesh, Vec3::new(-0.5, 0.5, 0.0)),
        Vec3::new(1.0, 0.0, 0.0),
    );
    let (position, exit) = lifted(&mesh, end);
    assert_close(exit, Vec3::new(0.0, 0.5, 0.0), 1e-6);
    assert_close(position, Vec3::new(0.5, 0.5, 0.0), 1e-6);
}

#[test]
fn a_single_walk_with_a_non_finite_input_stays_put() {
    // `walk` does not check its inputs (`walk_many` does); it must still not loop or panic.
    let (vertices, triangles) = grid(2);
    let mesh = mesh(vertices, triangles);
    let start = FacePoint {
        triangle: 1,
        barycentric: Vec3::splat(1.0 / 3.0),
    };
    for displacement in [Vec3::NAN, Vec3::new(f32::INFINITY, 0.0, 0.0)] {
        assert_eq!(mesh.walk(start, displacement), WalkEnd::OnSurface(start));
    }
    // Barycentrics that are negative or do not sum to one are made valid first.
    let sloppy = FacePoint {
        triangle: 1,
        barycentric: Vec3::new(2.0, -0.5, 2.0),
    };
    let end = mesh.walk(sloppy, Vec3::new(0.1, 0.0, 0.0));
    let expected = mesh
        .face_point_position(FacePoint {
            triangle: 1,
            barycentric: Vec3::new(0.5, 0.0, 0.5),
        })
        .unwrap()
        + Vec3::new(0.1, 0.0, 0.0);
    assert_close(on_surface(&mesh, end), expected, 1e-6);
}

#[test]
fn walks_from_a_vertex_of_a_tilted_grid_go_straight() {
    // A flat grid tilted and moved off the axes: a walk that starts exactly on an interior vertex
    // must follow the displacement projected on the plane, in every direction.
    let (vertices, triangles) = common::grid(8);
    let rotation = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.4, -0.3, 0.7);
    let offset = Vec3::new(0.3, -1.2, 2.0);
    let vertices: Vec<Vec3> = vertices.iter().map(|&v| rotation * v + offset).collect();
    let normal = rotation * Vec3::Z;
    let mesh = TargetMesh::new(
        vertices.clone(),
        triangles.clone(),
        TargetMeshOptions::default(),
    )
    .unwrap();
    let centre_vertex = 4 * 9 + 4;
    let (triangle, corner) = triangles
        .iter()
        .enumerate()
        .find_map(|(t, c)| {
            c.iter()
                .position(|&v| v == centre_vertex)
                .map(|k| (t as u32, k))
        })
        .unwrap();
    let mut barycentric = Vec3::ZERO;
    barycentric[corner] = 1.0;
    let start = FacePoint {
        triangle,
        barycentric,
    };
    let start_position = vertices[centre_vertex as usize];
    // Along the grid's edges and diagonals exactly (multiples of 45°), and in generic directions.
    for step in 0..72 {
        let angle = (step / 2) as f32 * std::f32::consts::TAU / 36.0
            + if step % 2 == 0 { 0.0 } else { 0.01 };
        let in_plane = rotation * Vec3::new(angle.cos(), angle.sin(), 0.0) * 1.7;
        let displacement = in_plane + normal * 0.2; // a little off the plane, as forces are
        match mesh.walk(start, displacement) {
            WalkEnd::OnSurface(end) => {
                let position = mesh.face_point_position(end).unwrap();
                let expected = start_position + in_plane;
                assert!(
                    position.distance(expected) < 1e-4,
                    "direction {step}: {position} vs {expected}"
                );
            }
            other => panic!("direction {step}: {other:?}"),
        }
    }
}
