//! The structure read from layouts whose grid lines, extraordinary vertices and curves are known.

use springwrap_kernel::{CurveKind, KernelError, LayoutStructure, LineTriple};

/// An `n` x `n` grid of quads: (n + 1)^2 vertices, row-major, faces counter-clockwise.
fn quad_grid(n: u32) -> (usize, Vec<u32>, Vec<u32>) {
    let row = n + 1;
    let mut corners = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let a = y * row + x;
            corners.extend([a, a + 1, a + row + 1, a + row]);
        }
    }
    ((row * row) as usize, corners, vec![4; (n * n) as usize])
}

fn triples_through(structure: &LayoutStructure, vertex: u32) -> Vec<(u32, u32)> {
    let mut pairs: Vec<(u32, u32)> = structure
        .line_triples
        .iter()
        .filter(|triple| triple.vertex == vertex)
        .map(|triple| {
            (
                triple.previous.min(triple.next),
                triple.previous.max(triple.next),
            )
        })
        .collect();
    pairs.sort_unstable();
    pairs
}

#[test]
fn a_quad_grid_has_two_lines_inside_one_along_the_border_and_corners_apart() {
    let (vertex_count, corners, sizes) = quad_grid(4);
    let structure = LayoutStructure::new(vertex_count, &corners, &sizes, &[], &[]).unwrap();
    // Interior vertex 6 = (1, 1): lines 5-7 (horizontal) and 1-11 (vertical).
    assert_eq!(triples_through(&structure, 6), vec![(1, 11), (5, 7)]);
    // Border vertex 2 = (2, 0): one line along the border, 1-3.
    assert_eq!(triples_through(&structure, 2), vec![(1, 3)]);
    // The 4 corners (border vertices of one face) are corners, nothing is extraordinary.
    assert_eq!(structure.corners, vec![0, 4, 20, 24]);
    assert!(structure.extraordinary.is_empty());
    assert_eq!(structure.line_triples.len(), 9 * 2 + 12);
    // The border comes out as the patch's four sides, each open, from corner to corner.
    assert_eq!(structure.curves.len(), 4);
    for side in &structure.curves {
        assert_eq!(
            (side.kind, side.closed, side.vertices.len()),
            (CurveKind::Border, false, 5)
        );
        let ends = [side.vertices[0], side.vertices[4]];
        assert!(
            ends.iter().all(|end| structure.corners.contains(end)),
            "{side:?}"
        );
    }
    assert_eq!(structure.neighbors_of(6), &[1, 5, 7, 11]);
}

#[test]
fn a_cube_is_all_extraordinary_and_closed() {
    // 8 corners of a cube, 6 quads: every vertex has valence 3 and no border.
    let corners = [
        0, 1, 2, 3, 4, 7, 6, 5, 0, 4, 5, 1, 1, 5, 6, 2, 2, 6, 7, 3, 4, 0, 3, 7,
    ];
    let structure = LayoutStructure::new(8, &corners, &[4; 6], &[], &[]).unwrap();
    assert!(structure.line_triples.is_empty());
    assert_eq!(structure.extraordinary, (0..8).collect::<Vec<u32>>());
    assert!(structure.curves.is_empty());
}

#[test]
fn triangles_make_their_vertices_extraordinary() {
    let (vertex_count, mut corners, mut sizes) = quad_grid(4);
    // Replace the quad of cell (1, 1) (corners 6, 7, 12, 11) by two triangles.
    let cell = (4 + 1) as usize * 4;
    corners.splice(cell..cell + 4, [6, 7, 12, 6, 12, 11]);
    sizes.splice(5..6, [3, 3]);
    let structure = LayoutStructure::new(vertex_count, &corners, &sizes, &[], &[]).unwrap();
    for vertex in [6, 7, 11, 12] {
        assert!(structure.extraordinary.contains(&vertex), "vertex {vertex}");
        assert!(triples_through(&structure, vertex).is_empty());
    }
    assert_eq!(triples_through(&structure, 8), vec![(3, 13), (7, 9)]);
}

#[test]
fn loose_chains_are_curves_with_lines_inside() {
    // A chain 10-11-12-13-14 of loose edges next to an unrelated quad 0-1-2-3.
    let edges = [[10, 11], [11, 12], [12, 13], [13, 14]];
    let structure = LayoutStructure::new(15, &[0, 1, 2, 3], &[4], &edges, &[]).unwrap();
    assert_eq!(
        structure
            .line_triples
            .iter()
            .filter(|t| t.vertex >= 10)
            .count(),
        3
    );
    assert!(structure.line_triples.contains(&LineTriple {
        previous: 11,
        vertex: 12,
        next: 13
    }));
    assert!(structure.extraordinary.contains(&10) && structure.extraordinary.contains(&14));
    let loose: Vec<_> = structure
        .curves
        .iter()
        .filter(|c| c.kind == CurveKind::Loose)
        .collect();
    assert_eq!(loose.len(), 1);
    assert_eq!(loose[0].vertices, vec![10, 11, 12, 13, 14]);
    assert!(!loose[0].closed);
    // Isolated vertices 4..=9 have no neighbours: neither lines nor fallback.
    assert!(!structure.extraordinary.contains(&5));
}

#[test]
fn seams_are_curves_that_keep_the_grid_lines() {
    let (vertex_count, corners, sizes) = quad_grid(4);
    // The vertical line x = 2: vertices 2, 7, 12, 17, 22.
    let seams = [[2, 7], [7, 12], [12, 17], [17, 22]];
    let structure = LayoutStructure::new(vertex_count, &corners, &sizes, &[], &seams).unwrap();
    assert_eq!(triples_through(&structure, 12), vec![(7, 17), (11, 13)]);
    // The border also breaks where the seam meets it: 4 sides, two of them cut in two.
    let border_count = structure
        .curves
        .iter()
        .filter(|c| c.kind == CurveKind::Border)
        .count();
    assert_eq!(border_count, 6);
    let seam: Vec<_> = structure
        .curves
        .iter()
        .filter(|c| c.kind == CurveKind::Seam)
        .collect();
    assert_eq!(seam.len(), 1);
    let mut vertices = seam[0].vertices.clone();
    if vertices[0] != 2 {
        vertices.reverse();
    }
    assert_eq!(vertices, vec![2, 7, 12, 17, 22]);
}

#[test]
fn bad_layouts_are_refused_with_the_reason() {
    let error = LayoutStructure::new(3, &[0, 1, 5], &[3], &[], &[]).unwrap_err();
    assert_eq!(
        error,
        KernelError::LayoutIndexOutOfRange {
            element: "face",
            index: 0,
            vertex: 5,
            vertex_count: 3
        }
    );
    assert!(
        error
            .to_string()
            .contains("layout face 0 refers to vertex 5")
    );
    let error = LayoutStructure::new(3, &[0, 1, 2], &[4], &[], &[]).unwrap_err();
    assert!(matches!(
        error,
        KernelError::InvalidArgument {
            name: "face_sizes",
            ..
        }
    ));
    let error = LayoutStructure::new(3, &[0, 1], &[2], &[], &[]).unwrap_err();
    assert!(error.to_string().contains("at least 3"));
    let error = LayoutStructure::new(3, &[], &[], &[[1, 1]], &[]).unwrap_err();
    assert!(error.to_string().contains("to itself"));
    let error = LayoutStructure::new(3, &[], &[], &[], &[[0, 9]]).unwrap_err();
    assert!(matches!(
        error,
        KernelError::LayoutIndexOutOfRange {
            element: "seam",
            ..
        }
    ));
}
