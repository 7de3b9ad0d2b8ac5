//! `LayoutStructure::new`: hostile vertex counts (up to `usize::MAX`), face sizes and indices.

use proptest::prelude::*;
use proptest::sample::select;
use springwrap_kernel::mesh::MAX_ELEMENTS;
use springwrap_kernel::{KernelError, LayoutStructure};

use crate::hostile::{config, index};

fn vertex_count() -> impl Strategy<Value = usize> {
    prop_oneof![
        8 => 0usize..14,
        1 => select(vec![
            MAX_ELEMENTS,
            MAX_ELEMENTS + 1,
            1 << 31,
            1 << 40,
            usize::MAX,
            u32::MAX as usize,
        ]),
    ]
}

fn face_size() -> impl Strategy<Value = u32> {
    prop_oneof![
        8 => 3u32..5,
        2 => 0u32..8,
        1 => select(vec![u32::MAX, i32::MAX as u32, (i32::MAX as u32) + 1]),
    ]
}

proptest! {
    #![proptest_config(config("tests/fuzz/proptest-regressions/layout.txt", 3000))]

    #[test]
    fn a_layout_structure_is_read_or_refused(
        vertex_count in vertex_count(),
        face_sizes in prop::collection::vec(face_size(), 0..6),
        face_corners in prop::collection::vec(index(12), 0..26),
        edges in prop::collection::vec([index(12), index(12)], 0..6),
        seams in prop::collection::vec([index(12), index(12)], 0..4),
        consistent in any::<bool>(),
    ) {
        // Half of the cases get corner counts that add up, so that the work past the checks runs.
        let face_sizes = if consistent {
            let mut sizes = Vec::new();
            let mut left = face_corners.len();
            for size in face_sizes.iter().map(|&size| (size as usize).clamp(3, 5)) {
                if left >= size {
                    sizes.push(size as u32);
                    left -= size;
                }
            }
            if left > 0 {
                sizes.push(left as u32);
            }
            sizes
        } else {
            face_sizes
        };
        match LayoutStructure::new(vertex_count, &face_corners, &face_sizes, &edges, &seams) {
            Ok(structure) => {
                prop_assert_eq!(structure.vertex_count, vertex_count);
                let in_range = |vertex: u32| (vertex as usize) < vertex_count;
                for triple in &structure.line_triples {
                    prop_assert!(in_range(triple.previous) && in_range(triple.vertex) && in_range(triple.next));
                }
                prop_assert!(structure.corners.iter().all(|&v| in_range(v)));
                prop_assert!(structure.extraordinary.iter().all(|&v| in_range(v)));
                for curve in &structure.curves {
                    prop_assert!(curve.vertices.iter().all(|&v| in_range(v)));
                }
                if vertex_count <= 14 {
                    // The same layout on vertex numbers 2^30 higher is read sparsely: the same
                    // structure, numbered 2^30 higher.
                    let shift = 1u32 << 30;
                    let moved = |pairs: &[[u32; 2]]| -> Vec<[u32; 2]> {
                        pairs.iter().map(|pair| pair.map(|v| v + shift)).collect()
                    };
                    let corners: Vec<u32> = face_corners.iter().map(|v| v + shift).collect();
                    let sparse = LayoutStructure::new(
                        vertex_count + shift as usize,
                        &corners,
                        &face_sizes,
                        &moved(&edges),
                        &moved(&seams),
                    );
                    prop_assert!(sparse.is_ok(), "{sparse:?}");
                    let sparse = sparse.unwrap();
                    let back = |v: u32| v - shift;
                    let triples: Vec<_> = sparse
                        .line_triples
                        .iter()
                        .map(|t| (back(t.previous), back(t.vertex), back(t.next)))
                        .collect();
                    let dense: Vec<_> = structure
                        .line_triples
                        .iter()
                        .map(|t| (t.previous, t.vertex, t.next))
                        .collect();
                    prop_assert_eq!(triples, dense);
                    prop_assert_eq!(
                        sparse.corners.iter().map(|&v| back(v)).collect::<Vec<_>>(),
                        structure.corners.clone()
                    );
                    prop_assert_eq!(
                        sparse.extraordinary.iter().map(|&v| back(v)).collect::<Vec<_>>(),
                        structure.extraordinary.clone()
                    );
                    prop_assert_eq!(sparse.curves.len(), structure.curves.len());
                    for vertex in 0..vertex_count as u32 {
                        let neighbors: Vec<u32> =
                            sparse.neighbors_of(vertex + shift).iter().map(|&v| back(v)).collect();
                        prop_assert_eq!(neighbors, structure.neighbors_of(vertex).to_vec());
                        let wedges: Vec<_> = sparse.wedges[sparse.wedge_range(vertex + shift)]
                            .iter()
                            .map(|&(a, b)| (back(a), back(b)))
                            .collect();
                        prop_assert_eq!(wedges, structure.wedges[structure.wedge_range(vertex)].to_vec());
                    }
                }
                for vertex in [0, vertex_count.saturating_sub(1), vertex_count / 2] {
                    let vertex = vertex.min(u32::MAX as usize) as u32;
                    prop_assert!(structure.neighbors_of(vertex).iter().all(|&v| in_range(v)));
                    let _ = structure.wedge_range(vertex);
                }
            }
            Err(
                KernelError::TooLarge { .. }
                | KernelError::LayoutIndexOutOfRange { .. }
                | KernelError::InvalidArgument { .. },
            ) => {}
            Err(other) => prop_assert!(false, "undocumented error: {other:?}"),
        }
    }
}
