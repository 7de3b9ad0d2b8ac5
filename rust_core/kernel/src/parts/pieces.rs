//! The layout's separate pieces: connected components of its edges (union–find).

use crate::error::KernelError;
use crate::quality::check_edges;
use crate::validate::check_count;

/// One piece number per layout vertex: the connected components of `edges` over `vertex_count`
/// vertices, numbered 0, 1, … in the order of each piece's lowest vertex. A vertex on no edge is
/// a piece of its own.
///
/// # Errors
/// [`KernelError::TooLarge`] for more than [`crate::mesh::MAX_ELEMENTS`] vertices;
/// [`KernelError::LayoutIndexOutOfRange`] for an edge naming a vertex beyond `vertex_count`.
pub fn connected_pieces(vertex_count: usize, edges: &[[u32; 2]]) -> Result<Vec<u32>, KernelError> {
    check_count("layout vertices", vertex_count, crate::mesh::MAX_ELEMENTS)?;
    check_edges(edges, vertex_count)?;
    let mut parent: Vec<u32> = (0..vertex_count as u32).collect();
    for &[a, b] in edges {
        let (root_a, root_b) = (find(&mut parent, a), find(&mut parent, b));
        if root_a != root_b {
            // The lower root wins: a piece's root is its lowest vertex.
            let (low, high) = (root_a.min(root_b), root_a.max(root_b));
            parent[high as usize] = low;
        }
    }
    let mut number = vec![u32::MAX; vertex_count];
    let mut pieces = vec![0u32; vertex_count];
    let mut next = 0u32;
    for vertex in 0..vertex_count as u32 {
        let root = find(&mut parent, vertex) as usize;
        if number[root] == u32::MAX {
            number[root] = next;
            next += 1;
        }
        pieces[vertex as usize] = number[root];
    }
    Ok(pieces)
}

/// The root of `vertex`, halving the path on the way.
fn find(parent: &mut [u32], mut vertex: u32) -> u32 {
    while parent[vertex as usize] != vertex {
        let grand = parent[parent[vertex as usize] as usize];
        parent[vertex as usize] = grand;
        vertex = grand;
    }
    vertex
}
