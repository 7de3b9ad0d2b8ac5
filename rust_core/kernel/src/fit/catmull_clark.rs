//! Catmull–Clark subdivision as a sparse matrix: the stencils of every fine point of a cage
//! subdivided `levels` times, pushed to the limit surface.
//!
//! The rules are OpenSubdiv's (what Blender's Subdivision Surface modifier runs) for a manifold
//! cage of any polygons without creases:
//!
//! - face point: the mean of the face's corners;
//! - edge point: inside, the mean of the edge's ends and its two face points; on a border, the
//!   edge's midpoint (a border is an infinitely sharp crease);
//! - vertex point: inside, `(n − 2)/n · v + Σ neighbours / n² + Σ face points / n` over its `n`
//!   edges and faces; on a border `(u₀ + 6 v + u₁) / 8` with its two border neighbours `u`, or
//!   `v` itself for a corner (a border vertex of one face) under [`BoundaryRule::KeepCorners`].
//!
//! Every face of level ≥ 1 is a quad, so the limit position of each vertex of the last level is
//! the quad rule `(n² v + 4 Σ edge neighbours + Σ diagonal corners) / (n (n + 5))` inside,
//! `(u₀ + 4 v + u₁) / 6` on a border (the border's cubic B-spline), `v` at a kept corner. These
//! are the points where OpenSubdiv's patches pass through the fine vertices; Blender evaluates its
//! patches there when the modifier's *Use Limit Surface* is on (the default). Near an irregular
//! corner of a border (a border vertex of one face, smooth) Blender's patches approximate the limit
//! surface, and there its points differ from these by a small fraction of the fine edge length.
//!
//! Fine vertices are numbered level by level as vertex points (the parent's vertex order), edge
//! points, face points: the cage's vertices come first, as in Blender's subdivided mesh.

use std::collections::HashMap;

use glam::{DVec3, Vec3};

use crate::error::KernelError;
use crate::wrap::linear_system::Stencils;

/// The deepest subdivision level accepted (Blender's modifier goes to 6; each level has four
/// times the faces of the one before).
pub const MAX_LEVELS: u32 = 6;

/// How a border vertex with a single face (a corner) is subdivided: Blender's *Boundary Smooth*.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BoundaryRule {
    /// Corners are smoothed like any border vertex (Blender's "All", the default).
    #[default]
    SmoothCorners,
    /// Corners stay where they are (Blender's "Keep Corners").
    KeepCorners,
}

/// A polygon mesh: faces as runs of corners.
#[derive(Debug, Clone)]
struct PolygonMesh {
    vertex_count: usize,
    /// Start of each face's corners; one more than there are faces.
    face_offsets: Vec<usize>,
    corners: Vec<u32>,
}

impl PolygonMesh {
    fn face_count(&self) -> usize {
        self.face_offsets.len() - 1
    }

    fn face(&self, face: usize) -> &[u32] {
        &self.corners[self.face_offsets[face]..self.face_offsets[face + 1]]
    }
}

/// The edges of a mesh, the faces on each side and, per vertex, its edges and faces.
struct Adjacency {
    /// Each edge's two ends.
    edges: Vec<[u32; 2]>,
    /// Each edge's faces; the second is `u32::MAX` on a border.
    edge_faces: Vec<[u32; 2]>,
    /// Per face corner, the edge from it to the next corner.
    corner_edges: Vec<u32>,
    /// Per vertex, its edges.
    vertex_edges: Vec<Vec<u32>>,
    /// Per vertex, its faces.
    vertex_faces: Vec<Vec<u32>>,
}

const NO_FACE: u32 = u32::MAX;

fn non_manifold(reason: String) -> KernelError {
    KernelError::InvalidArgument {
        name: "subdivision cage",
        reason,
    }
}

impl Adjacency {
    /// The adjacency of `mesh`, refusing what Catmull–Clark cannot subdivide as Blender does: a
    /// face with fewer than three corners or a repeated corner, an edge of three or more faces,
    /// two faces of opposite winding across an edge, a vertex whose faces do not form one fan.
    fn new(mesh: &PolygonMesh) -> Result<Self, KernelError> {
        let mut edge_of_pair: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.corners.len());
        let mut edges: Vec<[u32; 2]> = Vec::new();
        let mut edge_faces: Vec<[u32; 2]> = Vec::new();
        let mut corner_edges = vec![0u32; mesh.corners.len()];
        for face in 0..mesh.face_count() {
            let corners = mesh.face(face);
            if corners.len() < 3 {
                return Err(non_manifold(format!(
                    "face {face} has {} corners (at least 3 needed)",
                    corners.len()
                )));
            }
            for (index, &corner) in corners.iter().enumerate() {
                if (corner as usize) >= mesh.vertex_count {
                    return Err(KernelError::LayoutIndexOutOfRange {
                        element: "face",
                        index: face,
                        vertex: corner,
                        vertex_count: mesh.vertex_count,
                    });
                }
                if corners[..index].contains(&corner) {
                    return Err(non_manifold(format!(
                        "face {face} uses vertex {corner} twice"
                    )));
                }
            }
            for (index, &from) in corners.iter().enumerate() {
                let to = corners[(index + 1) % corners.len()];
                let key = (from.min(to), from.max(to));
                let edge = *edge_of_pair.entry(key).or_insert_with(|| {
                    edges.push([from, to]);
                    edge_faces.push([NO_FACE, NO_FACE]);
                    (edges.len() - 1) as u32
                });
                let sides = &mut edge_faces[edge as usize];
                if sides[0] == NO_FACE {
                    sides[0] = face as u32;
                } else if sides[1] == NO_FACE {
                    if edges[edge as usize] == [from, to] {
                        return Err(non_manifold(format!(
                            "faces {} and {face} have opposite windings across the edge {from}-{to} \
                             (recalculate the normals)",
                            sides[0]
                        )));
                    }
                    sides[1] = face as u32;
                } else {
                    return Err(non_manifold(format!(
                        "the edge {from}-{to} has three or more faces (non-manifold)"
                    )));
                }
                corner_edges[mesh.face_offsets[face] + index] = edge;
            }
        }
        let mut vertex_edges = vec![Vec::new(); mesh.vertex_count];
        for (edge, ends) in edges.iter().enumerate() {
            vertex_edges[ends[0] as usize].push(edge as u32);
            vertex_edges[ends[1] as usize].push(edge as u32);
        }
        let mut vertex_faces = vec![Vec::new(); mesh.vertex_count];
        for face in 0..mesh.face_count() {
            for &corner in mesh.face(face) {
                vertex_faces[corner as usize].push(face as u32);
            }
        }
        let adjacency = Self {
            edges,
            edge_faces,
            corner_edges,
            vertex_edges,
            vertex_faces,
        };
        adjacency.check_fans()?;
        Ok(adjacency)
    }

    fn is_border(&self, edge: u32) -> bool {
        self.edge_faces[edge as usize][1] == NO_FACE
    }

    fn other_end(&self, edge: u32, vertex: u32) -> u32 {
        let [a, b] = self.edges[edge as usize];
        if a == vertex { b } else { a }
    }

    /// Each vertex's faces form one fan: connected through its edges, with no or two border edges.
    fn check_fans(&self) -> Result<(), KernelError> {
        let mut reached: Vec<u32> = Vec::new();
        for (vertex, faces) in self.vertex_faces.iter().enumerate() {
            if faces.is_empty() {
                continue;
            }
            let edges = &self.vertex_edges[vertex];
            let borders = edges.iter().filter(|&&edge| self.is_border(edge)).count();
            let fan = if borders == 0 {
                edges.len() == faces.len()
            } else {
                borders == 2 && edges.len() == faces.len() + 1
            };
            // Connected: walk face to face across the vertex's inner edges.
            reached.clear();
            reached.push(faces[0]);
            let mut cursor = 0;
            while cursor < reached.len() {
                let face = reached[cursor];
                cursor += 1;
                for &edge in edges {
                    let [a, b] = self.edge_faces[edge as usize];
                    let next = if a == face {
                        b
                    } else if b == face {
                        a
                    } else {
                        continue;
                    };
                    if next != NO_FACE && !reached.contains(&next) {
                        reached.push(next);
                    }
                }
            }
            if !fan || reached.len() != faces.len() {
                return Err(non_manifold(format!(
                    "vertex {vertex} is non-manifold (its faces do not form one fan)"
                )));
            }
        }
        Ok(())
    }
}

/// One sparse row: `(parent vertex, weight)` pairs.
type Row = Vec<(u32, f64)>;

/// One level of refinement: the child mesh and each child vertex as a row over the parent's.
fn refine(
    mesh: &PolygonMesh,
    adjacency: &Adjacency,
    rule: BoundaryRule,
) -> (PolygonMesh, Vec<Row>) {
    let vertex_count = mesh.vertex_count;
    let edge_count = adjacency.edges.len();
    let face_count = mesh.face_count();
    let face_row = |face: usize| -> Row {
        let corners = mesh.face(face);
        let weight = 1.0 / corners.len() as f64;
        corners.iter().map(|&corner| (corner, weight)).collect()
    };
    let mut rows: Vec<Row> = Vec::with_capacity(vertex_count + edge_count + face_count);
    for vertex in 0..vertex_count {
        let edges = &adjacency.vertex_edges[vertex];
        let faces = &adjacency.vertex_faces[vertex];
        let vertex_id = vertex as u32;
        if faces.is_empty() {
            rows.push(vec![(vertex_id, 1.0)]);
            continue;
        }
        let borders: Vec<u32> = edges
            .iter()
            .copied()
            .filter(|&edge| adjacency.is_border(edge))
            .collect();
        if borders.is_empty() {
            let n = edges.len() as f64;
            let mut row = vec![(vertex_id, (n - 2.0) / n)];
            for &edge in edges {
                row.push((adjacency.other_end(edge, vertex_id), 1.0 / (n * n)));
            }
            for &face in faces {
                let corners = mesh.face(face as usize);
                let weight = 1.0 / (n * n * corners.len() as f64);
                row.extend(corners.iter().map(|&corner| (corner, weight)));
            }
            rows.push(row);
        } else if rule == BoundaryRule::KeepCorners && faces.len() == 1 {
            rows.push(vec![(vertex_id, 1.0)]);
        } else {
            rows.push(vec![
                (vertex_id, 0.75),
                (adjacency.other_end(borders[0], vertex_id), 0.125),
                (adjacency.other_end(borders[1], vertex_id), 0.125),
            ]);
        }
    }
    for (edge, &[a, b]) in adjacency.edges.iter().enumerate() {
        let [left, right] = adjacency.edge_faces[edge];
        if right == NO_FACE {
            rows.push(vec![(a, 0.5), (b, 0.5)]);
        } else {
            let mut row = vec![(a, 0.25), (b, 0.25)];
            for face in [left, right] {
                row.extend(
                    face_row(face as usize)
                        .into_iter()
                        .map(|(corner, weight)| (corner, 0.25 * weight)),
                );
            }
            rows.push(row);
        }
    }
    for face in 0..face_count {
        rows.push(face_row(face));
    }
    let edge_point = |edge: u32| (vertex_count + edge as usize) as u32;
    let mut face_offsets = Vec::with_capacity(mesh.corners.len() + 1);
    let mut corners = Vec::with_capacity(mesh.corners.len() * 4);
    face_offsets.push(0);
    for face in 0..face_count {
        let start = mesh.face_offsets[face];
        let parent = mesh.face(face);
        let size = parent.len();
        let face_point = (vertex_count + edge_count + face) as u32;
        for (index, &corner) in parent.iter().enumerate() {
            let previous = (index + size - 1) % size;
            corners.extend_from_slice(&[
                corner,
                edge_point(adjacency.corner_edges[start + index]),
                face_point,
                edge_point(adjacency.corner_edges[start + previous]),
            ]);
            face_offsets.push(corners.len());
        }
    }
    let child = PolygonMesh {
        vertex_count: vertex_count + edge_count + face_count,
        face_offsets,
        corners,
    };
    (child, rows)
}

/// The limit position of every vertex of an all-quad mesh, as rows over its vertices.
fn limit_rows(mesh: &PolygonMesh, adjacency: &Adjacency, rule: BoundaryRule) -> Vec<Row> {
    (0..mesh.vertex_count)
        .map(|vertex| {
            let vertex_id = vertex as u32;
            let edges = &adjacency.vertex_edges[vertex];
            let faces = &adjacency.vertex_faces[vertex];
            if faces.is_empty() {
                return vec![(vertex_id, 1.0)];
            }
            let borders: Vec<u32> = edges
                .iter()
                .copied()
                .filter(|&edge| adjacency.is_border(edge))
                .collect();
            if borders.is_empty() {
                let n = edges.len() as f64;
                let scale = 1.0 / (n * (n + 5.0));
                let mut row = vec![(vertex_id, n * n * scale)];
                for &edge in edges {
                    row.push((adjacency.other_end(edge, vertex_id), 4.0 * scale));
                }
                for &face in faces {
                    let corners = mesh.face(face as usize);
                    let at = corners
                        .iter()
                        .position(|&corner| corner == vertex_id)
                        .unwrap_or(0);
                    row.push((corners[(at + 2) % 4], scale));
                }
                row
            } else if rule == BoundaryRule::KeepCorners && faces.len() == 1 {
                vec![(vertex_id, 1.0)]
            } else {
                vec![
                    (vertex_id, 4.0 / 6.0),
                    (adjacency.other_end(borders[0], vertex_id), 1.0 / 6.0),
                    (adjacency.other_end(borders[1], vertex_id), 1.0 / 6.0),
                ]
            }
        })
        .collect()
}

/// `rows ∘ previous`: each row over the previous level's vertices re-expressed over the cage's,
/// with a dense scratch of the cage's size (`weights`, zero outside the call).
fn compose(rows: &[Row], previous: &Stencils, weights: &mut [f64]) -> Stencils {
    let mut composed = Stencils::new();
    let mut touched: Vec<u32> = Vec::new();
    for row in rows {
        touched.clear();
        for &(parent, weight) in row {
            for (cage_vertex, coefficient) in previous.entries(parent as usize) {
                let slot = &mut weights[cage_vertex as usize];
                if *slot == 0.0 {
                    touched.push(cage_vertex);
                }
                *slot += weight * coefficient;
                if *slot == 0.0 {
                    // Cancelled exactly: keep it listed once, with a tiny mark.
                    *slot = f64::MIN_POSITIVE;
                }
            }
        }
        touched.sort_unstable();
        composed.push(
            touched.iter().map(|&cage_vertex| {
                let value = std::mem::take(&mut weights[cage_vertex as usize]);
                (cage_vertex, value)
            }),
            1.0,
        );
    }
    composed
}

/// The limit points of a cage subdivided `levels` times, as stencils over the cage's vertices,
/// and the fine quads they form.
#[derive(Debug, Clone)]
pub struct SubdivisionStencils {
    cage_vertex_count: usize,
    levels: u32,
    rule: BoundaryRule,
    /// One term per fine vertex (weight 1): its limit position over the cage's vertices.
    stencils: Stencils,
    /// The faces of the last level, all quads, wound as the cage's faces.
    fine_quads: Vec<[u32; 4]>,
    /// Per fine vertex, whether it lies on the subdivided surface (not a cage vertex on no face).
    on_surface: Vec<bool>,
    /// The cage's edges (between face corners), each once.
    cage_edges: Vec<[u32; 2]>,
}

impl SubdivisionStencils {
    /// The stencils of the cage `(vertex_count, faces)` subdivided `levels` times
    /// (`face_sizes[f]` corners of face `f` in `face_corners`, in order).
    ///
    /// Cage vertices on no face are carried over as themselves and are not on the surface.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] for `levels` outside 1..=[`MAX_LEVELS`], a cage with no
    /// face, a face of fewer than three corners or with a repeated corner, an edge of three or more
    /// faces, faces of opposite winding across an edge, a vertex whose faces are not one fan;
    /// [`KernelError::LengthMismatch`] when the face sizes do not add up to the corners;
    /// [`KernelError::LayoutIndexOutOfRange`] for a corner that is not a vertex;
    /// [`KernelError::TooLarge`] when the fine mesh would pass 2³¹ vertices.
    pub fn new(
        vertex_count: usize,
        face_corners: &[u32],
        face_sizes: &[u32],
        levels: u32,
        rule: BoundaryRule,
    ) -> Result<Self, KernelError> {
        if !(1..=MAX_LEVELS).contains(&levels) {
            return Err(KernelError::InvalidArgument {
                name: "levels",
                reason: format!("{levels} is not a subdivision level from 1 to {MAX_LEVELS}"),
            });
        }
        if face_sizes.is_empty() {
            return Err(non_manifold(
                "the cage has no faces to subdivide".to_owned(),
            ));
        }
        let corner_total: usize = face_sizes.iter().map(|&size| size as usize).sum();
        if corner_total != face_corners.len() {
            return Err(KernelError::LengthMismatch {
                what: "face corners and the sum of face sizes",
                first: face_corners.len(),
                second: corner_total,
            });
        }
        let fine_vertex_estimate =
            (face_corners.len() as u128 + vertex_count as u128) * (1u128 << (2 * levels));
        if fine_vertex_estimate > i32::MAX as u128 {
            return Err(KernelError::TooLarge {
                what: "fine vertices of the subdivided cage",
                count: usize::try_from(fine_vertex_estimate).unwrap_or(usize::MAX),
                max: i32::MAX as usize,
            });
        }
        let mut face_offsets = Vec::with_capacity(face_sizes.len() + 1);
        face_offsets.push(0);
        for &size in face_sizes {
            face_offsets.push(face_offsets[face_offsets.len() - 1] + size as usize);
        }
        let mut mesh = PolygonMesh {
            vertex_count,
            face_offsets,
            corners: face_corners.to_vec(),
        };
        let mut adjacency = Adjacency::new(&mesh)?;
        let cage_edges = adjacency.edges.clone();
        let mut on_face: Vec<bool> = adjacency
            .vertex_faces
            .iter()
            .map(|faces| !faces.is_empty())
            .collect();
        let mut stencils = Stencils::new();
        for vertex in 0..vertex_count {
            stencils.push([(vertex as u32, 1.0)], 1.0);
        }
        let mut scratch = vec![0.0f64; vertex_count];
        for _ in 0..levels {
            let (child, rows) = refine(&mesh, &adjacency, rule);
            stencils = compose(&rows, &stencils, &mut scratch);
            on_face.resize(child.vertex_count, true);
            mesh = child;
            adjacency = Adjacency::new(&mesh)?;
        }
        let limit = limit_rows(&mesh, &adjacency, rule);
        stencils = compose(&limit, &stencils, &mut scratch);
        let fine_quads = (0..mesh.face_count())
            .map(|face| {
                let corners = mesh.face(face);
                [corners[0], corners[1], corners[2], corners[3]]
            })
            .collect();
        Ok(Self {
            cage_vertex_count: vertex_count,
            levels,
            rule,
            stencils,
            fine_quads,
            on_surface: on_face,
            cage_edges,
        })
    }

    /// Number of cage vertices (columns).
    #[must_use]
    pub fn cage_vertex_count(&self) -> usize {
        self.cage_vertex_count
    }

    /// Number of fine vertices (rows).
    #[must_use]
    pub fn fine_vertex_count(&self) -> usize {
        self.stencils.len()
    }

    /// The subdivision level.
    #[must_use]
    pub fn levels(&self) -> u32 {
        self.levels
    }

    /// The border rule.
    #[must_use]
    pub fn rule(&self) -> BoundaryRule {
        self.rule
    }

    /// The matrix, one term per fine vertex over the cage's vertices (weights all 1).
    #[must_use]
    pub fn stencils(&self) -> &Stencils {
        &self.stencils
    }

    /// The quads of the last level, over the fine vertices.
    #[must_use]
    pub fn fine_quads(&self) -> &[[u32; 4]] {
        &self.fine_quads
    }

    /// Per fine vertex, whether it lies on the subdivided surface.
    #[must_use]
    pub fn on_surface(&self) -> &[bool] {
        &self.on_surface
    }

    /// The cage's edges between face corners, each once.
    #[must_use]
    pub fn cage_edges(&self) -> &[[u32; 2]] {
        &self.cage_edges
    }

    /// The fine (limit) points of the cage at `cage` (one position per cage vertex).
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] when `cage` has not one position per cage vertex.
    pub fn apply(&self, cage: &[DVec3]) -> Result<Vec<DVec3>, KernelError> {
        if cage.len() != self.cage_vertex_count {
            return Err(KernelError::LengthMismatch {
                what: "cage positions and cage vertices",
                first: cage.len(),
                second: self.cage_vertex_count,
            });
        }
        Ok((0..self.stencils.len())
            .map(|term| self.stencils.apply(term, cage))
            .collect())
    }

    /// Area-weighted unit normals of the fine vertices at `fine` (zero off the surface).
    #[must_use]
    pub fn fine_normals(&self, fine: &[DVec3]) -> Vec<Vec3> {
        let mut normals = vec![DVec3::ZERO; fine.len()];
        for quad in &self.fine_quads {
            let [a, b, c, d] = quad.map(|vertex| fine[vertex as usize]);
            let normal = (c - a).cross(d - b);
            for &vertex in quad {
                normals[vertex as usize] += normal;
            }
        }
        normals
            .iter()
            .map(|normal| normal.normalize_or_zero().as_vec3())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `size` × `size` grid of unit quads in the z = 0 plane.
    fn grid(size: u32) -> (usize, Vec<u32>, Vec<u32>) {
        let row = size + 1;
        let mut corners = Vec::new();
        for y in 0..size {
            for x in 0..size {
                let v = y * row + x;
                corners.extend_from_slice(&[v, v + 1, v + 1 + row, v + row]);
            }
        }
        let faces = (size * size) as usize;
        ((row * row) as usize, corners, vec![4; faces])
    }

    #[test]
    fn every_stencil_is_an_affine_combination() {
        let (count, corners, sizes) = grid(3);
        for rule in [BoundaryRule::SmoothCorners, BoundaryRule::KeepCorners] {
            for levels in 1..=3 {
                let subdivision =
                    SubdivisionStencils::new(count, &corners, &sizes, levels, rule).unwrap();
                let stencils = subdivision.stencils();
                for term in 0..stencils.len() {
                    let sum: f64 = stencils.entries(term).map(|(_, weight)| weight).sum();
                    assert!((sum - 1.0).abs() < 1e-12, "term {term}: {sum}");
                }
                let side = 3 * (1 << levels) + 1;
                assert_eq!(subdivision.fine_vertex_count(), side * side);
                assert_eq!(subdivision.fine_quads().len(), 9 << (2 * levels));
            }
        }
    }

    #[test]
    fn a_kept_corner_stays_and_a_smooth_one_moves_in() {
        let (count, corners, sizes) = grid(3);
        let cage: Vec<DVec3> = (0..count)
            .map(|v| DVec3::new((v % 4) as f64, (v / 4) as f64, 0.0))
            .collect();
        let kept = SubdivisionStencils::new(count, &corners, &sizes, 2, BoundaryRule::KeepCorners)
            .unwrap()
            .apply(&cage)
            .unwrap();
        assert_eq!(kept[0], DVec3::ZERO);
        let smooth =
            SubdivisionStencils::new(count, &corners, &sizes, 2, BoundaryRule::SmoothCorners)
                .unwrap()
                .apply(&cage)
                .unwrap();
        // On the border's cubic B-spline: (u0 + 4 v + u1) / 6 of the corner's neighbours.
        assert!(smooth[0].x > 0.1 && smooth[0].y > 0.1);
        // A regular interior vertex of a flat grid stays where it is.
        assert!(smooth[5].distance(cage[5]) < 1e-12);
    }

    #[test]
    fn non_manifold_and_bad_faces_are_refused() {
        // Three quads on one edge.
        let corners = [0, 1, 2, 3, 1, 0, 4, 5, 0, 1, 6, 7];
        let error = SubdivisionStencils::new(8, &corners, &[4, 4, 4], 2, BoundaryRule::default())
            .unwrap_err();
        assert!(error.to_string().contains("three or more faces"), "{error}");
        let error = SubdivisionStencils::new(4, &[0, 1, 1, 2], &[4], 2, BoundaryRule::default())
            .unwrap_err();
        assert!(error.to_string().contains("twice"), "{error}");
        // Two quads touching at one vertex (a bow tie).
        let corners = [0, 1, 2, 3, 0, 4, 5, 6];
        let error =
            SubdivisionStencils::new(7, &corners, &[4, 4], 1, BoundaryRule::default()).unwrap_err();
        assert!(error.to_string().contains("non-manifold"), "{error}");
        // Opposite windings.
        let corners = [0, 1, 2, 3, 0, 1, 4, 5];
        let error =
            SubdivisionStencils::new(6, &corners, &[4, 4], 1, BoundaryRule::default()).unwrap_err();
        assert!(error.to_string().contains("opposite windings"), "{error}");
        let error = SubdivisionStencils::new(4, &[], &[], 1, BoundaryRule::default()).unwrap_err();
        assert!(error.to_string().contains("no faces"), "{error}");
        let (count, corners, sizes) = grid(1);
        let error = SubdivisionStencils::new(count, &corners, &sizes, 0, BoundaryRule::default())
            .unwrap_err();
        assert!(error.to_string().contains("levels"), "{error}");
        let error =
            SubdivisionStencils::new(3, &corners, &sizes, 1, BoundaryRule::default()).unwrap_err();
        assert!(
            matches!(error, KernelError::LayoutIndexOutOfRange { .. }),
            "{error}"
        );
    }
}
