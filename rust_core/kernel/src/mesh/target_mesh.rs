//! The target mesh: validated geometry, topology, normals and the two search trees.

use std::sync::OnceLock;

use glam::{Vec3, Vec3A};
use obvhs::{aabb::Aabb, bvh2::Bvh2};
use rayon::prelude::*;

use super::normals::{face_normals, vertex_normals};
use super::topology::{NO_TRIANGLE, Topology, TriangleEdge, compute_topology};
use crate::bvh::{Bvh4, build_bvh_with};
use crate::error::KernelError;
use crate::face_point::{FacePoint, LayoutPoint};
use crate::query::point_triangle::is_degenerate;
use crate::query::triangle_packet::TrianglePacket;

/// Face normals and vertex normals.
#[derive(Debug, Clone)]
pub(crate) struct Normals {
    pub(crate) faces: Vec<Vec3>,
    pub(crate) vertices: Vec<Vec3>,
}

/// The fast vertex tree: a BVH over the vertices that some non-degenerate triangle uses.
#[derive(Clone)]
pub(crate) struct VertexTree {
    pub(crate) tree: Bvh4,
    /// Vertex positions in slot order.
    pub(crate) points: Vec<Vec3A>,
    /// Vertex indices in slot order.
    pub(crate) vertices: Vec<u32>,
    /// For each vertex, a non-degenerate triangle using it and the corner, or `NO_TRIANGLE`.
    pub(crate) vertex_triangle: Vec<(u32, u8)>,
}

/// The face tree as closest-point queries search it.
#[derive(Clone)]
pub(crate) struct ClosestTree {
    /// `face_tree` collapsed to four children per node; its leaves are ranges of `packets`.
    pub(crate) tree: Bvh4,
    /// The triangles of each leaf of `tree`, four to a packet, in traversal order.
    pub(crate) packets: Vec<TrianglePacket>,
}

/// Options for [`TargetMesh::new`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TargetMeshOptions {
    /// Refuse the mesh if any triangle is degenerate, instead of keeping it inert.
    pub reject_degenerate: bool,
}

/// The fewest triangles a thread takes in the build's parallel passes (smaller meshes stay on one).
const PARALLEL_MIN: usize = 1 << 14;

/// The largest vertex or triangle count: indices are `u32` and the Python side uses `-1` as "none".
pub const MAX_ELEMENTS: usize = i32::MAX as usize;

/// A triangle mesh prepared for retargeting queries.
///
/// Built once from vertices and triangles (validated: finite, in-range, not all degenerate); holds
/// a BVH over the triangles (the exact "face tree"), a BVH over the vertices (the fast "vertex
/// tree"), triangle adjacency across edges, boundary edges, and face and vertex normals.
/// Degenerate triangles are kept so that indices stay those of the input, but rays never hit them
/// and the vertex tree never lands on them.
#[derive(Clone)]
pub struct TargetMesh {
    pub(crate) vertices: Vec<Vec3>,
    pub(crate) triangles: Vec<[u32; 3]>,
    pub(crate) degenerate: Vec<bool>,
    pub(crate) degenerate_count: usize,
    /// Face and vertex normals, computed on first use.
    pub(crate) normals: OnceLock<Normals>,
    /// Adjacency and boundaries, computed on first use.
    pub(crate) topology: OnceLock<Topology>,
    pub(crate) bounds: Aabb,
    /// BVH over triangle boxes (for rays).
    pub(crate) face_tree: Bvh2,
    /// The closest-point tree, built on first use (rays never need it).
    pub(crate) closest_tree: OnceLock<ClosestTree>,
    /// The largest coordinate magnitude of the mesh (for rounding margins).
    pub(crate) coordinate_scale: f32,
    /// Whether the triangle in each `face_tree` slot is degenerate.
    pub(crate) face_tree_degenerate: Vec<bool>,
    /// Per triangle, its `face_tree` slot (the inverse of `primitive_indices`).
    pub(crate) face_tree_slots: Vec<u32>,
    /// The vertex tree, built on first use (a snap to the surface never needs it).
    pub(crate) vertex_tree: OnceLock<VertexTree>,
}

impl std::fmt::Debug for TargetMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TargetMesh")
            .field("vertex_count", &self.vertices.len())
            .field("triangle_count", &self.triangles.len())
            .field("degenerate_triangle_count", &self.degenerate_count)
            .finish_non_exhaustive()
    }
}

impl TargetMesh {
    /// Validates the input and builds the face tree; the closest-point tree, the vertex tree,
    /// adjacency and normals are built on first use (or all at once with [`TargetMesh::prepare_all`]).
    ///
    /// # Errors
    /// [`KernelError::EmptyMesh`], [`KernelError::TooLarge`], [`KernelError::NonFinite`] or
    /// [`KernelError::CoordinateOutOfRange`] (a vertex; see [`crate::validate`]),
    /// [`KernelError::VertexIndexOutOfRange`], [`KernelError::DegenerateTriangle`] (only with
    /// `reject_degenerate`), [`KernelError::DegenerateMesh`] (no triangle has an area).
    pub fn new(
        vertices: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        options: TargetMeshOptions,
    ) -> Result<Self, KernelError> {
        if vertices.is_empty() || triangles.is_empty() {
            return Err(KernelError::EmptyMesh {
                vertex_count: vertices.len(),
                triangle_count: triangles.len(),
            });
        }
        for (what, count) in [("vertices", vertices.len()), ("triangles", triangles.len())] {
            if count > MAX_ELEMENTS {
                return Err(KernelError::TooLarge {
                    what,
                    count,
                    max: MAX_ELEMENTS,
                });
            }
        }
        crate::validate::check_coordinates("vertex", &vertices)?;
        let vertex_count = vertices.len();
        let out_of_range = |vertex: &u32| *vertex as usize >= vertex_count;
        if let Some(triangle) = triangles
            .par_iter()
            .with_min_len(PARALLEL_MIN)
            .position_first(|corners| corners.iter().any(out_of_range))
        {
            let corner = triangles[triangle]
                .iter()
                .position(out_of_range)
                .unwrap_or(0);
            return Err(KernelError::VertexIndexOutOfRange {
                triangle,
                corner,
                vertex: triangles[triangle][corner],
                vertex_count,
            });
        }
        let degenerate: Vec<bool> = triangles
            .par_iter()
            .with_min_len(PARALLEL_MIN)
            .map(|corners| {
                let [a, b, c] = corners.map(|index| Vec3A::from(vertices[index as usize]));
                is_degenerate(a, b, c)
            })
            .collect();
        let degenerate_count = degenerate
            .par_iter()
            .with_min_len(PARALLEL_MIN)
            .filter(|&&flag| flag)
            .count();
        if degenerate_count == triangles.len() {
            return Err(KernelError::DegenerateMesh {
                triangle_count: triangles.len(),
            });
        }
        if options.reject_degenerate
            && let Some(triangle) = degenerate.iter().position(|&flag| flag)
        {
            return Err(KernelError::DegenerateTriangle { triangle });
        }

        let (face_tree, face_tree_degenerate) = build_face_tree(&vertices, &triangles, &degenerate);
        let bounds = *face_tree.nodes[0].aabb();
        let coordinate_scale = bounds.min.abs().max(bounds.max.abs()).max_element();
        let mut face_tree_slots = vec![0; triangles.len()];
        for (slot, &triangle) in face_tree.primitive_indices.iter().enumerate() {
            face_tree_slots[triangle as usize] = slot as u32;
        }
        Ok(Self {
            vertices,
            triangles,
            degenerate,
            degenerate_count,
            normals: OnceLock::new(),
            topology: OnceLock::new(),
            bounds,
            face_tree,
            closest_tree: OnceLock::new(),
            coordinate_scale,
            face_tree_degenerate,
            face_tree_slots,
            vertex_tree: OnceLock::new(),
        })
    }

    /// Builds the parts that are otherwise built on first use (closest-point tree, vertex tree,
    /// topology, normals), so that later queries pay nothing.
    ///
    /// Ordered for the peak memory: the builds with the largest transient buffers (the vertex
    /// tree's, then the topology's) run before the closest-point tree, the largest part kept,
    /// exists; each build is parallel inside.
    pub fn prepare_all(&self) {
        rayon::join(|| self.vertex_tree(), || self.normals());
        self.topology();
        self.closest_tree();
    }

    pub(crate) fn closest_tree(&self) -> &ClosestTree {
        self.closest_tree.get_or_init(|| {
            build_closest_tree(&self.face_tree, &self.face_tree_degenerate, |slot| {
                self.slot_corners(slot)
            })
        })
    }

    pub(crate) fn normals(&self) -> &Normals {
        self.normals.get_or_init(|| {
            let faces = face_normals(&self.vertices, &self.triangles, &self.degenerate);
            let vertices = vertex_normals(&self.vertices, &self.triangles, &faces);
            Normals { faces, vertices }
        })
    }

    pub(crate) fn topology(&self) -> &Topology {
        self.topology
            .get_or_init(|| compute_topology(&self.triangles))
    }

    pub(crate) fn vertex_tree(&self) -> &VertexTree {
        self.vertex_tree
            .get_or_init(|| build_vertex_tree(&self.vertices, &self.triangles, &self.degenerate))
    }

    /// The corners of the triangle in `face_tree` slot `slot` (read through the triangle's vertex
    /// indices: a copy in slot order would cost 48 bytes per triangle for every query's lifetime).
    #[inline]
    pub(crate) fn slot_corners(&self, slot: usize) -> [Vec3A; 3] {
        self.triangles[self.face_tree.primitive_indices[slot] as usize]
            .map(|index| Vec3A::from(self.vertices[index as usize]))
    }

    /// The bytes each structure of the mesh holds (allocated capacity), by name: what a dense
    /// target costs and where (the parts built on first use count once built).
    #[must_use]
    pub fn memory_bytes(&self) -> Vec<(&'static str, usize)> {
        fn bytes<T>(items: &Vec<T>) -> usize {
            items.capacity() * size_of::<T>()
        }
        let tree = |bvh: &Bvh2| {
            bytes(&bvh.nodes)
                + bytes(&bvh.primitive_indices)
                + bytes(&bvh.primitive_indices_freelist)
                + bytes(&bvh.primitives_to_nodes)
                + bytes(&bvh.parents)
        };
        let mut parts = vec![
            ("vertices", bytes(&self.vertices)),
            ("triangles", bytes(&self.triangles)),
            (
                "degenerate flags",
                bytes(&self.degenerate) + bytes(&self.face_tree_degenerate),
            ),
            ("face tree", tree(&self.face_tree)),
            ("face tree slots", bytes(&self.face_tree_slots)),
        ];
        if let Some(closest) = self.closest_tree.get() {
            parts.push(("closest tree nodes", bytes(&closest.tree.nodes)));
            parts.push(("closest tree packets", bytes(&closest.packets)));
        }
        if let Some(vertex) = self.vertex_tree.get() {
            parts.push((
                "vertex tree",
                bytes(&vertex.tree.nodes)
                    + bytes(&vertex.points)
                    + bytes(&vertex.vertices)
                    + bytes(&vertex.vertex_triangle),
            ));
        }
        if let Some(normals) = self.normals.get() {
            parts.push(("normals", bytes(&normals.faces) + bytes(&normals.vertices)));
        }
        if let Some(topology) = self.topology.get() {
            parts.push((
                "topology",
                bytes(&topology.neighbors) + bytes(&topology.boundary_edges),
            ));
        }
        parts
    }

    /// The vertex positions.
    #[must_use]
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// The triangles, as vertex indices.
    #[must_use]
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Whether each triangle is degenerate (zero area; inert for rays and the vertex tree).
    #[must_use]
    pub fn degenerate_triangles(&self) -> &[bool] {
        &self.degenerate
    }

    /// How many triangles are degenerate.
    #[must_use]
    pub fn degenerate_triangle_count(&self) -> usize {
        self.degenerate_count
    }

    /// Unit normal per triangle (zero for degenerate ones).
    #[must_use]
    pub fn face_normals(&self) -> &[Vec3] {
        &self.normals().faces
    }

    /// Angle-weighted unit normal per vertex (zero where no triangle has an area).
    #[must_use]
    pub fn vertex_normals(&self) -> &[Vec3] {
        &self.normals().vertices
    }

    /// `triangle_neighbors()[t][e]`: the triangle across edge `e` of `t` (from corner `e` to corner
    /// `(e + 1) % 3`), or [`NO_TRIANGLE`] on boundary and non-manifold edges.
    #[must_use]
    pub fn triangle_neighbors(&self) -> &[[u32; 3]] {
        &self.topology().neighbors
    }

    /// Edges with a single triangle: holes and open borders.
    #[must_use]
    pub fn boundary_edges(&self) -> &[TriangleEdge] {
        &self.topology().boundary_edges
    }

    /// Number of edges shared by three or more triangles.
    #[must_use]
    pub fn non_manifold_edge_count(&self) -> usize {
        self.topology().non_manifold_edge_count
    }

    /// Axis-aligned bounds of the mesh, `(min, max)`.
    #[must_use]
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        (self.bounds.min.into(), self.bounds.max.into())
    }

    /// Position of a face-point.
    ///
    /// # Errors
    /// [`KernelError::TriangleIndexOutOfRange`] (reported as face-point 0) if the triangle does not exist.
    pub fn face_point_position(&self, face_point: FacePoint) -> Result<Vec3, KernelError> {
        self.face_point_positions(&[face_point])
            .map(|positions| positions[0])
    }

    /// Positions of many face-points, in parallel.
    ///
    /// # Errors
    /// [`KernelError::TriangleIndexOutOfRange`] naming the first face-point whose triangle does
    /// not exist; [`KernelError::NonFinite`] for a NaN or infinite barycentric coordinate,
    /// [`KernelError::InvalidArgument`] for one outside [`crate::BARYCENTRIC_RANGE`].
    pub fn face_point_positions(
        &self,
        face_points: &[FacePoint],
    ) -> Result<Vec<Vec3>, KernelError> {
        for (index, face_point) in face_points.iter().enumerate() {
            if face_point.triangle as usize >= self.triangles.len() {
                return Err(KernelError::TriangleIndexOutOfRange {
                    index,
                    triangle: face_point.triangle,
                    triangle_count: self.triangles.len(),
                });
            }
            crate::validate::check_barycentric("barycentric", index, face_point.barycentric)?;
        }
        Ok(face_points
            .par_iter()
            .with_min_len(1024)
            .map(|face_point| self.interpolate(face_point.triangle, face_point.barycentric))
            .collect())
    }

    /// Position of any layout point.
    ///
    /// # Errors
    /// As [`TargetMesh::face_point_position`].
    pub fn layout_point_position(&self, point: LayoutPoint) -> Result<Vec3, KernelError> {
        match point {
            LayoutPoint::Face(face_point) => self.face_point_position(face_point),
            LayoutPoint::Space(position) => Ok(position),
        }
    }

    /// Barycentric interpolation of a triangle's corners (index already checked).
    #[inline]
    pub(crate) fn interpolate(&self, triangle: u32, barycentric: Vec3) -> Vec3 {
        let [a, b, c] =
            self.triangles[triangle as usize].map(|index| self.vertices[index as usize]);
        a * barycentric.x + b * barycentric.y + c * barycentric.z
    }
}

/// The face tree and whether the triangle in each of its slots is degenerate.
fn build_face_tree(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    degenerate: &[bool],
) -> (Bvh2, Vec<bool>) {
    let tree = build_bvh_with(triangles.len(), |index| {
        let [a, b, c] = triangles[index].map(|vertex| Vec3A::from(vertices[vertex as usize]));
        Aabb::new(a.min(b).min(c), a.max(b).max(c))
    });
    let slot_degenerate = tree
        .primitive_indices
        .par_iter()
        .with_min_len(PARALLEL_MIN)
        .map(|&triangle| degenerate[triangle as usize])
        .collect();
    (tree, slot_degenerate)
}

/// The face tree collapsed to four children per node, its leaves renumbered to ranges of
/// packets holding their triangles four at a time.
fn build_closest_tree(
    face_tree: &Bvh2,
    degenerate: &[bool],
    corners: impl Fn(usize) -> [Vec3A; 3] + Sync,
) -> ClosestTree {
    let mut tree = Bvh4::from_bvh2(face_tree);
    // Each packet's slot range, in the order the leaves are renumbered.
    let mut ranges: Vec<(u32, u32)> = Vec::with_capacity(degenerate.len() / 3 + 1);
    tree.renumber_leaves(|first, count| {
        let first_packet = u32::try_from(ranges.len()).expect("fewer than 2^32 packets");
        ranges.extend(
            (first..first + count)
                .step_by(4)
                .map(|start| (start, (start + 4).min(first + count))),
        );
        (first_packet, count.div_ceil(4))
    });
    let packets = ranges
        .par_iter()
        .with_min_len(1024)
        .map(|&(start, end)| {
            let mut lanes = [(0, [Vec3A::ZERO; 3], false); 4];
            for (lane, slot) in (start..end).enumerate() {
                lanes[lane] = (slot, corners(slot as usize), degenerate[slot as usize]);
            }
            TrianglePacket::new(&lanes[..(end - start) as usize])
        })
        .collect();
    ClosestTree { tree, packets }
}

/// The vertex tree over vertices used by a non-degenerate triangle, and for every vertex one such
/// triangle and corner (so that a vertex hit can become a face-point).
fn build_vertex_tree(vertices: &[Vec3], triangles: &[[u32; 3]], degenerate: &[bool]) -> VertexTree {
    let mut vertex_triangle = vec![(NO_TRIANGLE, 0u8); vertices.len()];
    for (triangle, corners) in triangles.iter().enumerate() {
        if degenerate[triangle] {
            continue;
        }
        for (corner, &vertex) in corners.iter().enumerate() {
            let slot = &mut vertex_triangle[vertex as usize];
            if slot.0 == NO_TRIANGLE {
                *slot = (triangle as u32, corner as u8);
            }
        }
    }
    let used: Vec<u32> = (0..vertices.len() as u32)
        .filter(|&vertex| vertex_triangle[vertex as usize].0 != NO_TRIANGLE)
        .collect();
    let tree = build_bvh_with(used.len(), |index| {
        Aabb::from_point(vertices[used[index] as usize].into())
    });
    let slot_vertices: Vec<u32> = tree
        .primitive_indices
        .iter()
        .map(|&primitive| used[primitive as usize])
        .collect();
    let slot_points = slot_vertices
        .iter()
        .map(|&vertex| Vec3A::from(vertices[vertex as usize]))
        .collect();
    VertexTree {
        tree: Bvh4::from_bvh2(&tree),
        points: slot_points,
        vertices: slot_vertices,
        vertex_triangle,
    }
}
