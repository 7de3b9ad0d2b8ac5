//! The structure of a layout mesh that the wrap's forces act on: grid lines, curves and the
//! fallback neighbourhoods of extraordinary vertices.
//!
//! Krishnamurthy & Levoy's spring meshes are regular grids: every point has a predecessor and a
//! successor along two grid lines, and the fairness and arc-length forces act on those triples.
//! A real layout is a quad mesh with extraordinary vertices, triangles, open borders, seams and
//! loose edge chains (curves). This module reads all of that from plain faces and edges:
//!
//! - a **line triple** `(previous, vertex, next)` says `vertex` lies on a grid line between two
//!   neighbours: the two pairs of opposite neighbours of a regular interior vertex (valence 4, all
//!   faces quads), the two border neighbours of a regular border vertex (valence 3), the two
//!   neighbours of a vertex inside a curve chain, and the two border neighbours of any border
//!   vertex of two or more faces;
//! - a **corner** (a border vertex of a single face) has no line and no fairness: smoothing it
//!   would cut the corner and shrink the patch;
//! - a vertex with no line triple through it (valence other than 4, a triangle around it, a
//!   junction of curves) is **extraordinary**: it gets the umbrella fallback, the mean of its edge
//!   neighbours (no cotangent weights: the layout's own geometry is not to be trusted);
//! - **curves** are maximal chains of border, seam or loose edges between junctions.

use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};

use crate::error::KernelError;
use crate::mesh::MAX_ELEMENTS;

/// A layout point lies on a grid line between `previous` and `next` (its two opposite neighbours).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct LineTriple {
    /// The neighbour on one side.
    pub previous: u32,
    /// The point the triple's forces act on.
    pub vertex: u32,
    /// The neighbour on the other side.
    pub next: u32,
}

/// What a curve of the layout is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CurveKind {
    /// Edges used by one face: an open border of the layout.
    Border,
    /// Edges marked as seams: patch boundaries inside the layout.
    Seam,
    /// Edges used by no face: a free-standing face-point curve.
    Loose,
}

/// A chain of edges of one kind, from junction to junction (or a closed loop).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Curve {
    /// The kind of all its edges.
    pub kind: CurveKind,
    /// The vertices in order; a closed curve does not repeat its first vertex.
    pub vertices: Vec<u32>,
    /// Whether the last vertex connects back to the first.
    pub closed: bool,
}

/// The forces' view of a layout mesh.
#[derive(Debug, Clone, Default)]
pub struct LayoutStructure {
    /// Number of layout vertices.
    pub vertex_count: usize,
    /// The vertices any face or edge uses, in increasing order, when they are sparse (then the
    /// offset tables below are indexed by the position of a vertex in this list); empty when the
    /// tables are indexed by the vertex itself.
    pub vertex_ids: Vec<u32>,
    /// Edge neighbours of each vertex, CSR: the neighbours of `v` are
    /// `neighbors[neighbor_offsets[v]..neighbor_offsets[v + 1]]`, sorted. It stops after the last
    /// vertex any face or edge uses (the rest have no neighbours), and is indexed through
    /// `vertex_ids` when that is not empty: read it through [`LayoutStructure::neighbors_of`].
    pub neighbor_offsets: Vec<u32>,
    /// See `neighbor_offsets`.
    pub neighbors: Vec<u32>,
    /// Every grid-line triple.
    pub line_triples: Vec<LineTriple>,
    /// Vertices with no line triple and at least one neighbour, other than corners: they use the
    /// umbrella fallback.
    pub extraordinary: Vec<u32>,
    /// Patch corners: border vertices of a single face. No fairness acts on them (the umbrella
    /// would cut the corner and shrink the patch); anchors and the other forces still do.
    pub corners: Vec<u32>,
    /// Border, seam and loose-edge chains.
    pub curves: Vec<Curve>,
    /// For each vertex, CSR like `neighbor_offsets` (and, like it, stopping after the last vertex
    /// used): one `(previous, next)` pair per face around it, its neighbours before and after it
    /// in that face's winding (for oriented normals). Read through
    /// [`LayoutStructure::wedge_range`].
    pub wedge_offsets: Vec<u32>,
    /// See `wedge_offsets`.
    pub wedges: Vec<(u32, u32)>,
}

impl LayoutStructure {
    /// Reads the structure of a layout given as polygons and edges.
    ///
    /// `face_sizes[f]` corner indices of face `f` follow one another in `face_corners`. `edges` are
    /// all edges of the mesh (those of the faces may be listed or not; edges used by no face are
    /// loose curve edges); `seams` are the edges marked as patch boundaries.
    ///
    /// # Errors
    /// [`KernelError::TooLarge`] for a vertex count or a number of face corners above
    /// [`MAX_ELEMENTS`], [`KernelError::LayoutIndexOutOfRange`] for an index `>= vertex_count`,
    /// [`KernelError::InvalidArgument`] for a face with fewer
    /// than 3 corners, corner counts that do not add up, or an edge from a vertex to itself.
    pub fn new(
        vertex_count: usize,
        face_corners: &[u32],
        face_sizes: &[u32],
        edges: &[[u32; 2]],
        seams: &[[u32; 2]],
    ) -> Result<Self, KernelError> {
        validate(vertex_count, face_corners, face_sizes, edges, seams)?;
        // Vertices past the last one a face or an edge uses have no neighbours, lines or curves:
        // nothing is stored for them. When the vertices used are sparse (a few faces on vertices
        // 2^31 apart), they are numbered densely first: the memory used follows the arrays
        // given, never a count or an index alone.
        let used = face_corners
            .iter()
            .chain(edges.iter().chain(seams).flatten())
            .max()
            .map_or(0, |&vertex| vertex as usize + 1);
        let entries = face_corners.len() + 2 * (edges.len() + seams.len());
        if used > 2 * entries + DENSE_SLACK {
            return Self::new_sparse(vertex_count, face_corners, face_sizes, edges, seams);
        }

        // Undirected edges with how many faces use them, and for each vertex the pairs of its
        // neighbours that are consecutive around it within one face.
        let mut face_count_of_edge: FastMap<(u32, u32), u32> =
            FastMap::with_capacity_and_hasher(face_corners.len(), Default::default());
        let mut consecutive: Vec<Vec<(u32, u32)>> = vec![Vec::new(); used];
        let mut only_quads = vec![true; used];
        let mut face_count = vec![0u32; used];
        let mut offset = 0usize;
        for &size in face_sizes {
            let face = &face_corners[offset..offset + size as usize];
            offset += size as usize;
            for corner in 0..face.len() {
                let vertex = face[corner];
                let next = face[(corner + 1) % face.len()];
                let previous = face[(corner + face.len() - 1) % face.len()];
                *face_count_of_edge
                    .entry(edge_key(vertex, next))
                    .or_insert(0) += 1;
                consecutive[vertex as usize].push((previous, next));
                face_count[vertex as usize] += 1;
                if face.len() != 4 {
                    only_quads[vertex as usize] = false;
                }
            }
        }
        for edge in edges.iter().chain(seams) {
            face_count_of_edge
                .entry(edge_key(edge[0], edge[1]))
                .or_insert(0);
        }
        let seam_keys: FastSet<(u32, u32)> = seams
            .iter()
            .map(|edge| edge_key(edge[0], edge[1]))
            .collect();

        let mut adjacency: Vec<Vec<u32>> = vec![Vec::new(); used];
        for &(a, b) in face_count_of_edge.keys() {
            adjacency[a as usize].push(b);
            adjacency[b as usize].push(a);
        }
        let mut neighbor_offsets = Vec::with_capacity(used + 1);
        let mut neighbors = Vec::new();
        neighbor_offsets.push(0);
        for list in &mut adjacency {
            list.sort_unstable();
            neighbors.extend_from_slice(list);
            neighbor_offsets.push(neighbors.len() as u32);
        }

        let kind_lookup = |a: u32, b: u32| -> Option<CurveKind> {
            let key = edge_key(a, b);
            match face_count_of_edge.get(&key).copied() {
                Some(0) => Some(CurveKind::Loose),
                Some(1) => Some(CurveKind::Border),
                _ if seam_keys.contains(&key) => Some(CurveKind::Seam),
                _ => None,
            }
        };
        // Each neighbour's edge kind, looked up once (tracing curves asks many times).
        let kinds: Vec<Vec<Option<CurveKind>>> = adjacency
            .iter()
            .enumerate()
            .map(|(vertex, around)| {
                around
                    .iter()
                    .map(|&other| kind_lookup(vertex as u32, other))
                    .collect()
            })
            .collect();
        let kind_of = |a: u32, b: u32| -> Option<CurveKind> {
            let around = &adjacency[a as usize];
            around
                .binary_search(&b)
                .ok()
                .and_then(|index| kinds[a as usize][index])
        };

        let mut line_triples = Vec::new();
        let mut extraordinary = Vec::new();
        let mut corners = Vec::new();
        for vertex in 0..used as u32 {
            let around = &adjacency[vertex as usize];
            if around.is_empty() {
                continue;
            }
            let before = line_triples.len();
            let curve_neighbors: Vec<(u32, CurveKind)> = around
                .iter()
                .filter_map(|&other| kind_of(vertex, other).map(|kind| (other, kind)))
                .collect();
            let face_edges = around.len()
                - curve_neighbors
                    .iter()
                    .filter(|c| c.1 == CurveKind::Loose)
                    .count();
            if only_quads[vertex as usize] && !consecutive[vertex as usize].is_empty() {
                let border_count = curve_neighbors
                    .iter()
                    .filter(|(_, kind)| *kind == CurveKind::Border)
                    .count();
                if border_count == 0 && face_edges == 4 && around.len() == 4 {
                    // A regular interior vertex: two grid lines through opposite neighbours.
                    for &neighbor in around {
                        if let Some(opposite) =
                            opposite_neighbor(neighbor, around, &consecutive[vertex as usize])
                            && neighbor < opposite
                        {
                            line_triples.push(LineTriple {
                                previous: neighbor,
                                vertex,
                                next: opposite,
                            });
                        }
                    }
                }
            }
            let border: Vec<u32> = curve_neighbors
                .iter()
                .filter(|(_, kind)| *kind == CurveKind::Border)
                .map(|(other, _)| *other)
                .collect();
            if line_triples.len() == before && border.len() == 2 && face_count[vertex as usize] >= 2
            {
                // On an open border, away from a patch corner: the line runs along the border.
                line_triples.push(LineTriple {
                    previous: border[0],
                    vertex,
                    next: border[1],
                });
            }
            if line_triples.len() == before {
                // A vertex inside a loose curve chain (and nothing else) still lies on a line.
                let loose: Vec<u32> = curve_neighbors
                    .iter()
                    .filter(|(_, kind)| *kind == CurveKind::Loose)
                    .map(|(other, _)| *other)
                    .collect();
                if loose.len() == 2 && around.len() == 2 {
                    line_triples.push(LineTriple {
                        previous: loose[0],
                        vertex,
                        next: loose[1],
                    });
                }
            }
            if line_triples.len() == before {
                if border.len() == 2 && face_count[vertex as usize] == 1 {
                    corners.push(vertex);
                } else {
                    extraordinary.push(vertex);
                }
            }
        }

        let mut is_corner = vec![false; used];
        for &corner in &corners {
            is_corner[corner as usize] = true;
        }
        let curves = trace_curves(used, &adjacency, &kind_of, &is_corner);
        let mut wedge_offsets = Vec::with_capacity(used + 1);
        let mut wedges = Vec::new();
        wedge_offsets.push(0);
        for around in &consecutive {
            wedges.extend_from_slice(around);
            wedge_offsets.push(wedges.len() as u32);
        }
        Ok(Self {
            wedge_offsets,
            wedges,
            vertex_count,
            vertex_ids: Vec::new(),
            neighbor_offsets,
            neighbors,
            line_triples,
            extraordinary,
            corners,
            curves,
        })
    }

    /// [`LayoutStructure::new`] for a layout whose used vertices are sparse: they are numbered
    /// densely (in increasing order, so every list keeps its order), the structure is read on
    /// those numbers, and the results are numbered back.
    fn new_sparse(
        vertex_count: usize,
        face_corners: &[u32],
        face_sizes: &[u32],
        edges: &[[u32; 2]],
        seams: &[[u32; 2]],
    ) -> Result<Self, KernelError> {
        let mut ids: Vec<u32> = face_corners
            .iter()
            .chain(edges.iter().chain(seams).flatten())
            .copied()
            .collect();
        ids.sort_unstable();
        ids.dedup();
        let local = |vertex: u32| ids.binary_search(&vertex).unwrap_or(0) as u32;
        let local_corners: Vec<u32> = face_corners.iter().map(|&vertex| local(vertex)).collect();
        let local_pairs = |pairs: &[[u32; 2]]| -> Vec<[u32; 2]> {
            pairs.iter().map(|pair| pair.map(local)).collect()
        };
        let mut structure = Self::new(
            ids.len(),
            &local_corners,
            face_sizes,
            &local_pairs(edges),
            &local_pairs(seams),
        )?;
        let global = |vertex: &mut u32| *vertex = ids[*vertex as usize];
        for triple in &mut structure.line_triples {
            global(&mut triple.previous);
            global(&mut triple.vertex);
            global(&mut triple.next);
        }
        structure.extraordinary.iter_mut().for_each(global);
        structure.corners.iter_mut().for_each(global);
        for curve in &mut structure.curves {
            curve.vertices.iter_mut().for_each(global);
        }
        structure.neighbors.iter_mut().for_each(global);
        for (previous, next) in &mut structure.wedges {
            global(previous);
            global(next);
        }
        structure.vertex_count = vertex_count;
        structure.vertex_ids = ids;
        Ok(structure)
    }

    /// The position of `vertex` in the offset tables (`neighbor_offsets`, `wedge_offsets`):
    /// itself, or its place among the used vertices of a sparse layout; `None` for a vertex of
    /// no face or edge there.
    fn slot(&self, vertex: u32) -> Option<usize> {
        if self.vertex_ids.is_empty() {
            Some(vertex as usize)
        } else {
            self.vertex_ids.binary_search(&vertex).ok()
        }
    }

    /// The layout's oriented normal at `vertex` for `positions` (the faces' winding, area
    /// weighted, not normalised); zero on a vertex of no face.
    #[must_use]
    pub fn normal_at(&self, positions: &[glam::Vec3], vertex: u32) -> glam::Vec3 {
        let range = self.wedge_range(vertex);
        if range.is_empty() {
            return glam::Vec3::ZERO;
        }
        let (start, end) = (range.start, range.end);
        let here = positions[vertex as usize];
        self.wedges[start..end]
            .iter()
            .map(|&(previous, next)| {
                (positions[next as usize] - here).cross(positions[previous as usize] - here)
            })
            .sum()
    }

    /// The positions in `wedges` of the faces around `vertex` (its corners); empty for a vertex
    /// of no face.
    #[must_use]
    pub fn wedge_range(&self, vertex: u32) -> std::ops::Range<usize> {
        let Some(slot) = self.slot(vertex) else {
            return 0..0;
        };
        match (
            self.wedge_offsets.get(slot),
            self.wedge_offsets.get(slot + 1),
        ) {
            (Some(&start), Some(&end)) => start as usize..end as usize,
            _ => 0..0,
        }
    }

    /// The edge neighbours of `vertex`, sorted; empty for a vertex of no edge.
    #[must_use]
    pub fn neighbors_of(&self, vertex: u32) -> &[u32] {
        let Some(slot) = self.slot(vertex) else {
            return &[];
        };
        match (
            self.neighbor_offsets.get(slot),
            self.neighbor_offsets.get(slot + 1),
        ) {
            (Some(&start), Some(&end)) => &self.neighbors[start as usize..end as usize],
            _ => &[],
        }
    }
}

/// Unused vertex numbers below the last used one that a layout may have and still be read
/// densely (indexed by vertex); past twice its face corners and edge ends plus this, it is read
/// sparsely.
const DENSE_SLACK: usize = 1 << 16;

/// A multiply-rotate hasher (as rustc's FxHash) for the edge maps: the keys are vertex index
/// pairs, not attacker-chosen, and SipHash made tracing curves the cost of a 4 M-point layout.
#[derive(Default, Clone, Copy)]
struct FastHasher(u64);

impl Hasher for FastHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.add(u64::from(byte));
        }
    }

    fn write_u32(&mut self, value: u32) {
        self.add(u64::from(value));
    }

    fn write_u64(&mut self, value: u64) {
        self.add(value);
    }

    fn write_usize(&mut self, value: usize) {
        self.add(value as u64);
    }
}

impl FastHasher {
    fn add(&mut self, value: u64) {
        self.0 = (self.0.rotate_left(5) ^ value).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<FastHasher>>;
type FastSet<K> = HashSet<K, BuildHasherDefault<FastHasher>>;

/// An undirected edge as a sorted pair.
fn edge_key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// The neighbour across `vertex` from `neighbor`: the one that shares no face corner with it.
fn opposite_neighbor(neighbor: u32, around: &[u32], consecutive: &[(u32, u32)]) -> Option<u32> {
    let mut candidates = around.iter().copied().filter(|&other| {
        other != neighbor
            && !consecutive.iter().any(|&(previous, next)| {
                (previous == neighbor && next == other) || (previous == other && next == neighbor)
            })
    });
    let opposite = candidates.next()?;
    candidates.next().is_none().then_some(opposite)
}

/// Chains of curve edges (border, seam, loose), from end to end of the layout's curve network:
/// a chain ends where it branches, where another curve meets it (a seam reaching the border), and
/// at patch corners, so that a patch's sides come out as separate curves (anchors at both ends of
/// a side then pair it with a target curve).
fn trace_curves(
    vertex_count: usize,
    adjacency: &[Vec<u32>],
    kind_of: &dyn Fn(u32, u32) -> Option<CurveKind>,
    is_corner: &[bool],
) -> Vec<Curve> {
    let kind_degree = |vertex: u32, kind: CurveKind| {
        adjacency[vertex as usize]
            .iter()
            .filter(|&&other| kind_of(vertex, other) == Some(kind))
            .count()
    };
    let any_degree = |vertex: u32| {
        adjacency[vertex as usize]
            .iter()
            .filter(|&&other| kind_of(vertex, other).is_some())
            .count()
    };
    // A vertex a chain of `kind` passes through: two edges of that kind and no other curve there.
    let curve_degree = |vertex: u32, kind: CurveKind| {
        let degree = kind_degree(vertex, kind);
        if degree == 2 && (any_degree(vertex) > 2 || is_corner[vertex as usize]) {
            usize::MAX // an end, like a junction
        } else {
            degree
        }
    };
    let mut visited: FastSet<(u32, u32)> = FastSet::default();
    let mut curves = Vec::new();
    for kind in [CurveKind::Border, CurveKind::Seam, CurveKind::Loose] {
        // Open chains first (from every end or junction), then what is left are closed loops.
        for pass_open in [true, false] {
            for start in 0..vertex_count as u32 {
                let degree = curve_degree(start, kind);
                if degree == 0 || (pass_open && degree == 2) {
                    continue;
                }
                for &first in &adjacency[start as usize] {
                    if kind_of(start, first) != Some(kind)
                        || visited.contains(&edge_key(start, first))
                    {
                        continue;
                    }
                    let mut vertices = vec![start];
                    let mut previous = start;
                    let mut current = first;
                    visited.insert(edge_key(start, first));
                    let mut closed = false;
                    loop {
                        if current == start {
                            closed = true;
                            break;
                        }
                        vertices.push(current);
                        if curve_degree(current, kind) != 2 {
                            break;
                        }
                        let next = adjacency[current as usize].iter().copied().find(|&other| {
                            other != previous
                                && kind_of(current, other) == Some(kind)
                                && !visited.contains(&edge_key(current, other))
                        });
                        let Some(next) = next else { break };
                        visited.insert(edge_key(current, next));
                        previous = current;
                        current = next;
                    }
                    curves.push(Curve {
                        kind,
                        vertices,
                        closed,
                    });
                }
            }
        }
    }
    curves
}

fn validate(
    vertex_count: usize,
    face_corners: &[u32],
    face_sizes: &[u32],
    edges: &[[u32; 2]],
    seams: &[[u32; 2]],
) -> Result<(), KernelError> {
    crate::validate::check_count("layout vertices", vertex_count, MAX_ELEMENTS)?;
    crate::validate::check_count("layout face corners", face_corners.len(), MAX_ELEMENTS)?;
    let corner_total = face_sizes
        .iter()
        .try_fold(0usize, |total, &size| total.checked_add(size as usize))
        .unwrap_or(usize::MAX);
    if corner_total != face_corners.len() {
        return Err(KernelError::InvalidArgument {
            name: "face_sizes",
            reason: format!(
                "the face sizes add up to {corner_total} corners, but {} corners were given",
                face_corners.len()
            ),
        });
    }
    if let Some(face) = face_sizes.iter().position(|&size| size < 3) {
        return Err(KernelError::InvalidArgument {
            name: "face_sizes",
            reason: format!(
                "face {face} has {} corners (at least 3 needed)",
                face_sizes[face]
            ),
        });
    }
    let mut offset = 0usize;
    for (face, &size) in face_sizes.iter().enumerate() {
        for &vertex in &face_corners[offset..offset + size as usize] {
            if vertex as usize >= vertex_count {
                return Err(KernelError::LayoutIndexOutOfRange {
                    element: "face",
                    index: face,
                    vertex,
                    vertex_count,
                });
            }
        }
        offset += size as usize;
    }
    for (element, list) in [("edge", edges), ("seam", seams)] {
        for (index, edge) in list.iter().enumerate() {
            if let Some(&vertex) = edge.iter().find(|&&vertex| vertex as usize >= vertex_count) {
                return Err(KernelError::LayoutIndexOutOfRange {
                    element,
                    index,
                    vertex,
                    vertex_count,
                });
            }
            if edge[0] == edge[1] {
                return Err(KernelError::InvalidArgument {
                    name: "edges",
                    reason: format!("{element} {index} joins vertex {} to itself", edge[0]),
                });
            }
        }
    }
    Ok(())
}
