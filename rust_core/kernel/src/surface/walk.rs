//! Walking a face-point along the surface: the face-point update of Krishnamurthy & Levoy's
//! spring meshes, with the paper's lift at holes (section 2.5).
//!
//! The displacement is projected onto the start triangle's plane, then followed straight in
//! barycentric space. At an edge the point crosses into the neighbour triangle and the remaining
//! displacement is *rotated* about the shared edge into the neighbour's plane (the two triangles
//! are unfolded into one plane, so its length is kept): the walk is a straightest path. At a
//! boundary or non-manifold edge the point leaves the surface ([`WalkEnd::Lifted`]).
//!
//! All arithmetic is in `f64`; barycentric coordinates are clamped to zero, snapped when they
//! are within [`SNAP`] of it, and renormalised after every step, so they stay valid.
//!
//! Special cases, each decided once:
//! - **Vertices.** A path that reaches an interior vertex leaves it the straightest way
//!   (Polthier & Schmies' straightest geodesics): in the direction that splits the total angle
//!   around the vertex into equal halves on the path's two sides. Where the surface is flat
//!   that is straight on, and walking back retraces the path. When a walk starts on a vertex,
//!   or reaches a boundary vertex (or one beside a degenerate triangle), it leaves its triangle
//!   by one of the two edges at the vertex (the earlier exit; on a tie, an edge with a
//!   neighbour, then the one the path moves away from faster) and turns around the vertex with
//!   zero-length steps, unfolding as at an edge, until it finds the triangle whose angle holds
//!   the direction, or leaves by a boundary edge. The edge a triangle was entered by is never
//!   an exit from it, so no walk bounces between two triangles.
//! - **Along an edge.** A direction within [`PARALLEL`] (relative) of an edge slides along it
//!   inside the current triangle; sliding along a boundary edge stays on the surface.
//! - **Degenerate triangles** (zero area, see [`TargetMesh::degenerate_triangles`]) have no plane
//!   to walk in: they are crossed at zero length. Entering one, the walk looks at its other edges
//!   that pass through the point (they lie on the same line), follows them through further
//!   degenerate triangles (at most [`MAX_DEGENERATE_VISITS`]) to a non-degenerate triangle, and
//!   continues there as if the degenerate ones were not there. A walk that *starts* on a
//!   degenerate triangle first steps this way onto the neighbour the displacement points into.
//!   A degenerate strip that leads only to a boundary is a hole.
//! - **Boundaries.** At a boundary or non-manifold edge the point is lifted: it keeps going
//!   straight in the last triangle's plane for the rest of the displacement, so a point walking
//!   into a hole floats over it along the surface's tangent (the paper's fold into a hole).
//! - **Termination.** A walk crosses at most `64 + 8 × |displacement| / ℓ` edges (ℓ the shortest
//!   edge of the first triangle walked in), and never more than [`MAX_CROSSINGS`]; past that it
//!   stops where it is (on the surface) and says so in [`WalkOutcome::truncated`].
//!
//! [`TargetMesh::walk_many`] walks large batches in start-triangle order (answers come back in
//! input order), so that consecutive walks read nearby mesh data whatever the caller's order.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::error::KernelError;
use crate::face_point::FacePoint;
use crate::mesh::{NO_TRIANGLE, TargetMesh, TriangleEdge};

/// Barycentric coordinates below this are set to exactly zero (the point is on that edge).
pub const SNAP: f64 = 1e-12;

/// A path that leaves a triangle this close to a vertex (as a fraction of the edge) goes through
/// the vertex: `f32` data cannot place it any nearer, and the way on from a vertex is then the
/// straightest one rather than whichever side rounding put it on.
pub const VERTEX_SNAP: f64 = 1e-6;

/// A direction whose rate towards an edge is below this fraction of its largest barycentric rate
/// runs parallel to that edge: it slides along it instead of crossing.
pub const PARALLEL: f64 = 1e-9;

/// Two exits whose step lengths differ by less than this (a fraction of the remaining
/// displacement) are reached at the same time: the path goes through a vertex.
const TIE: f64 = 1e-12;

/// A displacement whose part along the start triangle is below this fraction of its length is
/// normal to the surface (within `f32` rounding of a normal): the point does not move.
pub const NORMAL_ONLY: f64 = 1e-6;

/// Edge crossings every walk may make whatever its length.
pub const MIN_CROSSINGS: u32 = 64;

/// Edge crossings allowed per shortest edge length of displacement, on top of [`MIN_CROSSINGS`].
pub const CROSSINGS_PER_EDGE_LENGTH: f64 = 8.0;

/// The most edge crossings any walk makes.
pub const MAX_CROSSINGS: u32 = 1 << 20;

/// The most degenerate triangles looked at to get across one strip of them.
pub const MAX_DEGENERATE_VISITS: usize = 16;

/// A point is on an edge of a degenerate triangle if it is closer to it than this fraction of
/// the triangle's longest edge (degenerate triangles are only nearly flat, see
/// [`crate::query::point_triangle::DEGENERATE_RELATIVE_AREA`]).
const ON_DEGENERATE_EDGE: f64 = 1e-5;

/// The most triangles around a vertex that a path through it turns around.
pub const MAX_FAN: usize = 64;

/// [`TargetMesh::walk_many`] batches at least this large are walked in start-triangle order.
const TRIANGLE_ORDER_MIN_BATCH: usize = 4096;

/// Marks "entered by no edge" (the start of a walk).
const NO_EDGE: u8 = 3;

/// Where a walk ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WalkEnd {
    /// Still on the surface.
    OnSurface(FacePoint),
    /// Walked off a boundary edge (a hole, an open border or a non-manifold edge): the point is
    /// lifted and becomes a space-point.
    Lifted {
        /// Where the point ends: the exit point plus the rest of the displacement, straight on
        /// in the plane of the last triangle walked in.
        position: Vec3,
        /// Where the point left the surface, on `edge`.
        exit: FacePoint,
        /// The edge it left by, of `exit.triangle`: a boundary or non-manifold edge. (Only
        /// when a strip of degenerate triangles leads neither on nor to a boundary within
        /// [`MAX_DEGENERATE_VISITS`] is it the edge the walk entered that strip by, or edge 0 of
        /// a degenerate start triangle.)
        edge: TriangleEdge,
    },
}

impl WalkEnd {
    /// The face-point if the walk stayed on the surface.
    #[must_use]
    pub fn face_point(&self) -> Option<FacePoint> {
        match *self {
            Self::OnSurface(face_point) => Some(face_point),
            Self::Lifted { .. } => None,
        }
    }
}

/// A walk's end and how it got there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkOutcome {
    /// Where the walk ended.
    pub end: WalkEnd,
    /// Unit direction of travel at the end, in the plane of the last triangle walked in (the
    /// displacement carried along the surface); zero if the point did not move.
    pub direction: Vec3,
    /// Number of edges crossed, degenerate triangles included (a pass through a vertex counts
    /// the edges turned around it, at least one).
    pub edge_crossings: u32,
    /// Whether the crossing cap stopped the walk before the displacement was used up.
    pub truncated: bool,
}

impl TargetMesh {
    /// Moves a face-point along the surface by `displacement`: projected onto the start
    /// triangle's plane, then followed straight across edges, unfolding each neighbour into the
    /// plane of the last (see the [module docs](crate::surface::walk) for vertices, degenerate
    /// triangles and boundaries).
    ///
    /// A zero displacement, or one normal to the start triangle, returns `start` unchanged.
    /// Inputs are not checked ([`TargetMesh::walk_many`] checks them): a non-finite displacement
    /// or barycentric leaves `start` unchanged.
    ///
    /// # Panics
    /// If `start.triangle` is not a triangle of the mesh.
    #[must_use]
    pub fn walk(&self, start: FacePoint, displacement: Vec3) -> WalkEnd {
        self.walk_traced(start, displacement).end
    }

    /// [`TargetMesh::walk`], also returning the direction of travel at the end, the number of
    /// edges crossed and whether the crossing cap cut the walk short.
    ///
    /// # Panics
    /// If `start.triangle` is not a triangle of the mesh.
    #[must_use]
    pub fn walk_traced(&self, start: FacePoint, displacement: Vec3) -> WalkOutcome {
        self.walk_traced_on(self.triangle_neighbors(), start, displacement)
    }

    /// [`TargetMesh::walk`] over a given adjacency table instead of the mesh's own: an edge whose
    /// entry is [`NO_TRIANGLE`] is a boundary. The wrap cuts the edges into unreliable triangles
    /// this way, so that noisy regions act as holes.
    #[must_use]
    pub(crate) fn walk_on(
        &self,
        neighbors: &[[u32; 3]],
        start: FacePoint,
        displacement: Vec3,
    ) -> WalkEnd {
        self.walk_traced_on(neighbors, start, displacement).end
    }

    fn walk_traced_on(
        &self,
        neighbors: &[[u32; 3]],
        start: FacePoint,
        displacement: Vec3,
    ) -> WalkOutcome {
        assert!(
            (start.triangle as usize) < self.triangles.len(),
            "walk: triangle {} out of range ({} triangles)",
            start.triangle,
            self.triangles.len()
        );
        let unchanged = WalkOutcome {
            end: WalkEnd::OnSurface(start),
            direction: Vec3::ZERO,
            edge_crossings: 0,
            truncated: false,
        };
        if displacement == Vec3::ZERO || !displacement.is_finite() || !start.barycentric.is_finite()
        {
            return unchanged;
        }
        let walker = Walker {
            mesh: self,
            neighbors,
        };
        walker
            .walk(start, displacement.as_dvec3())
            .unwrap_or(unchanged)
    }

    /// [`TargetMesh::walk`] for many face-points, each with its own displacement, in parallel.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] if `starts` and `displacements` differ in length,
    /// [`KernelError::TriangleIndexOutOfRange`] naming the first start whose triangle does not
    /// exist, [`KernelError::InvalidArgument`] for a barycentric weight outside [`crate::BARYCENTRIC_RANGE`],
    /// [`KernelError::CoordinateOutOfRange`] for a displacement beyond [`crate::MAX_COORDINATE`],
    /// [`KernelError::NonFinite`] for a NaN or infinite barycentric (`"barycentric"`) or
    /// displacement (`"displacement"`).
    pub fn walk_many(
        &self,
        starts: &[FacePoint],
        displacements: &[Vec3],
    ) -> Result<Vec<WalkEnd>, KernelError> {
        if starts.len() != displacements.len() {
            return Err(KernelError::LengthMismatch {
                what: "walk starts and displacements",
                first: starts.len(),
                second: displacements.len(),
            });
        }
        for (index, start) in starts.iter().enumerate() {
            if start.triangle as usize >= self.triangles.len() {
                return Err(KernelError::TriangleIndexOutOfRange {
                    index,
                    triangle: start.triangle,
                    triangle_count: self.triangles.len(),
                });
            }
            crate::validate::check_barycentric("barycentric", index, start.barycentric)?;
        }
        crate::query::check_finite("displacement", displacements)?;
        // Build the adjacency once, outside the workers.
        let _ = self.triangle_neighbors();
        let walk = |index: usize| self.walk(starts[index], displacements[index]);
        if starts.len() < TRIANGLE_ORDER_MIN_BATCH {
            return Ok((0..starts.len())
                .into_par_iter()
                .with_min_len(crate::query::QUERIES_PER_TASK)
                .map(walk)
                .collect());
        }
        // Walks in start-triangle order touch the mesh data in the order it is stored (close
        // triangles usually have close indices), whatever order the caller used.
        let mut order: Vec<u64> = starts
            .par_iter()
            .enumerate()
            .map(|(index, start)| (u64::from(start.triangle) << 32) | index as u64)
            .collect();
        order.par_sort_unstable();
        let sorted: Vec<WalkEnd> = order
            .par_iter()
            .with_min_len(crate::query::QUERIES_PER_TASK)
            .map(|&key| walk((key & u64::from(u32::MAX)) as usize))
            .collect();
        let mut ends = vec![WalkEnd::OnSurface(starts[0]); starts.len()];
        for (&key, end) in order.iter().zip(sorted) {
            ends[(key & u64::from(u32::MAX)) as usize] = end;
        }
        Ok(ends)
    }
}

/// How a walk got off a degenerate triangle.
enum Leave {
    /// Onto the non-degenerate `triangle`, entering by its edge `edge`, whose unit vector
    /// pointing into the triangle, perpendicular to the edge, is `inward`; after `hops` crossings.
    Onto {
        triangle: u32,
        edge: u8,
        inward: DVec3,
        hops: u32,
    },
    /// Into a hole: the boundary edge through the point, and the point on it.
    Hole { exit: FacePoint, edge: TriangleEdge },
    /// Nowhere (every way through ends in the search limit).
    Nowhere,
}

/// The mesh data one walk reads.
struct Walker<'a> {
    mesh: &'a TargetMesh,
    neighbors: &'a [[u32; 3]],
}

impl Walker<'_> {
    /// The corners of a triangle, in `f64`.
    #[inline]
    fn corners(&self, triangle: u32) -> [DVec3; 3] {
        self.mesh.triangles[triangle as usize]
            .map(|vertex| self.mesh.vertices[vertex as usize].as_dvec3())
    }

    #[inline]
    fn is_degenerate(&self, triangle: u32) -> bool {
        self.mesh.degenerate[triangle as usize]
    }

    /// The edge of `triangle` joining vertices `first` and `second` (either way round).
    #[inline]
    fn shared_edge(&self, triangle: u32, first: u32, second: u32) -> Option<u8> {
        let corners = self.mesh.triangles[triangle as usize];
        (0..3u8).find(|&edge| {
            let (start, end) = (
                corners[usize::from(edge)],
                corners[(usize::from(edge) + 1) % 3],
            );
            (start == first && end == second) || (start == second && end == first)
        })
    }

    /// The walk; `None` when the point does not move (a displacement normal to the surface).
    fn walk(&self, start: FacePoint, displacement: DVec3) -> Option<WalkOutcome> {
        let mut triangle = start.triangle;
        let mut barycentric = sanitize(start.barycentric);
        let mut entry = NO_EDGE;
        let mut crossings = 0u32;
        let mut remaining = displacement;

        if self.is_degenerate(triangle) {
            let point = interpolate(&self.corners(triangle), barycentric);
            match self.leave_degenerate(triangle, NO_EDGE, point, displacement, NO_TRIANGLE) {
                Leave::Onto {
                    triangle: next,
                    edge,
                    hops,
                    ..
                } => {
                    barycentric = on_edge(&self.corners(next), edge, point);
                    triangle = next;
                    entry = edge;
                    crossings = hops;
                }
                Leave::Hole { exit, edge } => {
                    return Some(lifted(point, remaining, exit, edge, 0));
                }
                Leave::Nowhere => {
                    let exit = FacePoint {
                        triangle,
                        barycentric: to_f32(barycentric),
                    };
                    let edge = TriangleEdge { triangle, edge: 0 };
                    return Some(lifted(point, remaining, exit, edge, 0));
                }
            }
        }

        let corners = self.corners(triangle);
        let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        remaining -= normal * (remaining.dot(normal) / normal.length_squared());
        let length = remaining.length();
        if length <= NORMAL_ONLY * displacement.length() {
            return None;
        }
        // The crossing cap, worked out only for walks that get past the first crossings.
        let cap = || {
            let shortest_edge = (0..3)
                .map(|corner| corners[corner].distance_squared(corners[(corner + 1) % 3]))
                .fold(f64::INFINITY, f64::min)
                .sqrt();
            (f64::from(MIN_CROSSINGS) + CROSSINGS_PER_EDGE_LENGTH * length / shortest_edge)
                .min(f64::from(MAX_CROSSINGS)) as u32
        };
        let mut limit = MIN_CROSSINGS;

        loop {
            let vertex_before = vertex_corner(barycentric);
            let corners = self.corners(triangle);
            let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
            let inverse_area = 1.0 / normal.length_squared();
            // Rate of change of each barycentric coordinate along `remaining`: the gradient of
            // coordinate i is n × (corner k - corner j) / |n|² with (i, j, k) cyclic.
            let rates: [f64; 3] = std::array::from_fn(|corner| {
                let opposite = corners[(corner + 2) % 3] - corners[(corner + 1) % 3];
                normal.cross(opposite).dot(remaining) * inverse_area
            });
            let largest_rate = rates.iter().fold(0.0f64, |largest, r| largest.max(r.abs()));
            let threshold = -PARALLEL * largest_rate;

            // The first edge the path reaches, if before the end of the displacement.
            let mut exit: Option<(usize, f64)> = None;
            for corner in 0..3 {
                let edge = (corner + 1) % 3;
                if edge == usize::from(entry) || rates[corner] >= threshold {
                    continue;
                }
                let step = barycentric[corner] / -rates[corner];
                if step >= 1.0 - TIE {
                    continue; // the displacement ends first (or on the edge)
                }
                exit = match exit {
                    None => Some((corner, step)),
                    Some((_, best)) if step < best - TIE => Some((corner, step)),
                    Some((other, best)) if step <= best + TIE => {
                        let pick = self.tie_break(triangle, &corners, &rates, other, corner);
                        Some((pick, best.min(step)))
                    }
                    keep => keep,
                };
            }

            let Some((corner, step)) = exit else {
                for (coordinate, rate) in barycentric.iter_mut().zip(rates) {
                    *coordinate += rate;
                }
                return Some(WalkOutcome {
                    end: WalkEnd::OnSurface(FacePoint {
                        triangle,
                        barycentric: to_f32(clean(barycentric)),
                    }),
                    direction: remaining.normalize_or_zero().as_vec3(),
                    edge_crossings: crossings,
                    truncated: false,
                });
            };

            for (coordinate, rate) in barycentric.iter_mut().zip(rates) {
                *coordinate += rate * step;
            }
            barycentric[corner] = 0.0;
            barycentric = clean(barycentric);
            // An exit this close to a vertex goes through it.
            for other in [(corner + 1) % 3, (corner + 2) % 3] {
                if barycentric[other] < VERTEX_SNAP {
                    barycentric = [0.0; 3];
                    barycentric[3 - corner - other] = 1.0;
                    break;
                }
            }
            remaining *= 1.0 - step;
            if crossings >= limit && limit == MIN_CROSSINGS {
                limit = cap().max(MIN_CROSSINGS + 1);
            }
            if crossings >= limit {
                return Some(WalkOutcome {
                    end: WalkEnd::OnSurface(FacePoint {
                        triangle,
                        barycentric: to_f32(barycentric),
                    }),
                    direction: remaining.normalize_or_zero().as_vec3(),
                    edge_crossings: crossings,
                    truncated: true,
                });
            }
            crossings += 1;

            // Arrived at a vertex: leave it by the straightest way.
            if let Some(vertex) = vertex_corner(barycentric)
                && vertex_before != Some(vertex)
                && let Some((next, next_corner, direction, steps)) =
                    self.through_vertex(triangle, vertex, remaining)
            {
                triangle = next;
                barycentric = [0.0; 3];
                barycentric[next_corner] = 1.0;
                remaining = direction * remaining.length();
                entry = NO_EDGE;
                crossings += steps.saturating_sub(1);
                continue;
            }

            let edge = (corner + 1) % 3;
            let (start_corner, end_corner) = (edge, (edge + 1) % 3);
            let point = corners[start_corner] * barycentric[start_corner]
                + corners[end_corner] * barycentric[end_corner];
            let exit_here = || {
                let exit = FacePoint {
                    triangle,
                    barycentric: to_f32(barycentric),
                };
                let edge = TriangleEdge {
                    triangle,
                    edge: edge as u8,
                };
                (exit, edge)
            };
            let neighbor = self.neighbors[triangle as usize][edge];
            if neighbor == NO_TRIANGLE {
                let (exit, edge) = exit_here();
                return Some(lifted(point, remaining, exit, edge, crossings));
            }

            let vertex_indices = self.mesh.triangles[triangle as usize];
            let (first, second) = (vertex_indices[start_corner], vertex_indices[end_corner]);

            if !self.is_degenerate(neighbor) {
                let Some(next_edge) = self.shared_edge(neighbor, first, second) else {
                    let (exit, edge) = exit_here();
                    return Some(lifted(point, remaining, exit, edge, crossings));
                };
                let next_corners = self.corners(neighbor);
                let next_indices = self.mesh.triangles[neighbor as usize];
                let mut next_barycentric = [0.0; 3];
                for (slot, &vertex) in next_indices.iter().enumerate() {
                    if vertex == first {
                        next_barycentric[slot] = barycentric[start_corner];
                    } else if vertex == second {
                        next_barycentric[slot] = barycentric[end_corner];
                    }
                }
                // Unfold: keep the part along the edge, turn the part across it from this
                // triangle's plane into the neighbour's (unnormalised vectors, one square root).
                let edge_vector = corners[end_corner] - corners[start_corner];
                let inverse_length_squared = 1.0 / edge_vector.length_squared();
                let across = |vector: DVec3| {
                    vector - edge_vector * (vector.dot(edge_vector) * inverse_length_squared)
                };
                let outward = across(corners[start_corner] - corners[corner]);
                let far = next_corners[(usize::from(next_edge) + 2) % 3];
                let inward = across(far - corners[start_corner]);
                let scale = (outward.length_squared() * inward.length_squared()).sqrt();
                let turned = if scale > 0.0 {
                    inward * (remaining.dot(outward) / scale)
                } else {
                    DVec3::ZERO
                };
                remaining =
                    edge_vector * (remaining.dot(edge_vector) * inverse_length_squared) + turned;
                triangle = neighbor;
                barycentric = clean(next_barycentric);
                entry = next_edge;
                continue;
            }

            let axis = (corners[end_corner] - corners[start_corner]).normalize();
            let outward = perpendicular(corners[start_corner] - corners[corner], axis);
            let Some(degenerate_edge) = self.shared_edge(neighbor, first, second) else {
                let (exit, edge) = exit_here();
                return Some(lifted(point, remaining, exit, edge, crossings));
            };
            match self.leave_degenerate(neighbor, degenerate_edge, point, remaining, triangle) {
                Leave::Onto {
                    triangle: next,
                    edge: next_edge,
                    inward,
                    hops,
                } => {
                    let next_corners = self.corners(next);
                    let next_start = next_corners[usize::from(next_edge)];
                    let next_end = next_corners[(usize::from(next_edge) + 1) % 3];
                    let mut next_axis = (next_end - next_start).normalize();
                    if next_axis.dot(axis) < 0.0 {
                        next_axis = -next_axis;
                    }
                    remaining = next_axis * remaining.dot(axis) + inward * remaining.dot(outward);
                    barycentric = on_edge(&next_corners, next_edge, point);
                    triangle = next;
                    entry = next_edge;
                    crossings += hops;
                }
                Leave::Hole { exit, edge } => {
                    return Some(lifted(point, remaining, exit, edge, crossings));
                }
                Leave::Nowhere => {
                    let (exit, edge) = exit_here();
                    return Some(lifted(point, remaining, exit, edge, crossings));
                }
            }
        }
    }

    /// The straightest way on from a vertex the path has just reached (Polthier & Schmies'
    /// straightest geodesics): the direction that splits the total angle around the vertex in
    /// two equal halves, one on each side of the path. `triangle` holds the vertex at `corner`
    /// and the path arrived through it travelling along `remaining`.
    ///
    /// Returns the triangle to go on in, the vertex's corner there, the unit direction in its
    /// plane and how many edges around the vertex that is from `triangle`; `None` when the
    /// vertex is on a boundary, next to a degenerate triangle or has more than [`MAX_FAN`]
    /// triangles around it (the walk then goes on by unfolding, as at an edge).
    #[cold]
    fn through_vertex(
        &self,
        triangle: u32,
        corner: usize,
        remaining: DVec3,
    ) -> Option<(u32, usize, DVec3, u32)> {
        let vertex = self.mesh.triangles[triangle as usize][corner];
        let center = self.mesh.vertices[vertex as usize].as_dvec3();
        // Around the vertex: each triangle with the corner of the vertex, the corner shared with
        // the previous triangle ("first") and the other one ("second"), and its angle there.
        let mut fan = [(0u32, 0u8, 0u8, 0.0f64); MAX_FAN];
        let mut fan_len = 0;
        let mut total_angle = 0.0;
        let (mut current, mut current_corner) = (triangle, corner);
        let (mut first, mut second) = ((corner + 1) % 3, (corner + 2) % 3);
        loop {
            let corners = self.corners(current);
            let angle = wedge_angle(corners[first] - center, corners[second] - center);
            fan[fan_len] = (current, current_corner as u8, first as u8, angle);
            fan_len += 1;
            total_angle += angle;
            let vertices = self.mesh.triangles[current as usize];
            let crossing = if second == (current_corner + 1) % 3 {
                current_corner
            } else {
                second
            };
            let next = self.neighbors[current as usize][crossing];
            if next == triangle {
                break;
            }
            if next == NO_TRIANGLE || self.is_degenerate(next) || fan_len == MAX_FAN {
                return None;
            }
            let shared = vertices[second];
            let next_vertices = self.mesh.triangles[next as usize];
            let next_corner = next_vertices.iter().position(|&v| v == vertex)?;
            let shared_corner = next_vertices.iter().position(|&v| v == shared)?;
            current = next;
            current_corner = next_corner;
            first = shared_corner;
            second = 3 - next_corner - shared_corner;
        }

        // Where the path came from, as an angle from the first edge of `triangle` (it came
        // through that triangle, so it is within its angle).
        let corners = self.corners(triangle);
        let first_edge = corners[(corner + 1) % 3] - center;
        let arrival = wedge_angle(first_edge, -remaining).clamp(0.0, fan[0].3);
        let mut target = arrival + 0.5 * total_angle;
        if target >= total_angle {
            target -= total_angle;
        }
        let mut start = 0.0;
        for (steps, &(current, current_corner, first, angle)) in fan[..fan_len].iter().enumerate() {
            if target <= start + angle || steps + 1 == fan_len {
                let local = (target - start).clamp(0.0, angle);
                let corners = self.corners(current);
                let first_edge = (corners[usize::from(first)] - center).normalize();
                let second_corner = 3 - usize::from(current_corner) - usize::from(first);
                let across = perpendicular(corners[second_corner] - center, first_edge);
                let direction = first_edge * local.cos() + across * local.sin();
                return Some((
                    current,
                    usize::from(current_corner),
                    direction,
                    steps as u32,
                ));
            }
            start += angle;
        }
        None
    }

    /// Of two exits reached at the same time (a vertex), the one to take: an edge with a
    /// neighbour first, then the edge the path moves away from faster (per unit of distance).
    #[cold]
    fn tie_break(
        &self,
        triangle: u32,
        corners: &[DVec3; 3],
        rates: &[f64; 3],
        first: usize,
        second: usize,
    ) -> usize {
        let has_neighbor =
            |corner: usize| self.neighbors[triangle as usize][(corner + 1) % 3] != NO_TRIANGLE;
        match (has_neighbor(first), has_neighbor(second)) {
            (true, false) => return first,
            (false, true) => return second,
            _ => {}
        }
        // The gradient of coordinate i has length |edge opposite i| / |n|, so the speed away
        // from that edge is -rate_i * |n| / |edge|; |n| is common.
        let speed = |corner: usize| {
            let edge_length = corners[(corner + 2) % 3].distance(corners[(corner + 1) % 3]);
            -rates[corner] / edge_length
        };
        if speed(second) > speed(first) {
            second
        } else {
            first
        }
    }

    /// Gets off the degenerate `triangle` at `point` (on it, entered by `entry` or `NO_EDGE`),
    /// through its edges that pass through the point, and through further degenerate triangles,
    /// onto the non-degenerate triangle (other than `origin`) that `direction` points into most.
    #[cold]
    fn leave_degenerate(
        &self,
        triangle: u32,
        entry: u8,
        point: DVec3,
        direction: DVec3,
        origin: u32,
    ) -> Leave {
        let mut stack = [(0u32, 0u8, 0u32); MAX_DEGENERATE_VISITS];
        let mut stack_len = 0;
        let mut visited = [NO_TRIANGLE; MAX_DEGENERATE_VISITS];
        let mut visited_len = 0;
        stack[stack_len] = (triangle, entry, 1);
        stack_len += 1;
        visited[visited_len] = triangle;
        visited_len += 1;

        let mut best: Option<(f64, Leave)> = None;
        let mut hole: Option<Leave> = None;
        while stack_len > 0 {
            stack_len -= 1;
            let (current, current_entry, depth) = stack[stack_len];
            let corners = self.corners(current);
            let vertex_indices = self.mesh.triangles[current as usize];
            let longest = (0..3)
                .map(|corner| corners[corner].distance(corners[(corner + 1) % 3]))
                .fold(0.0f64, f64::max);
            let tolerance = ON_DEGENERATE_EDGE * longest;
            for edge in 0..3u8 {
                if edge == current_entry {
                    continue;
                }
                let (start_corner, end_corner) = (usize::from(edge), (usize::from(edge) + 1) % 3);
                let (along, distance) =
                    segment_parameter(point, corners[start_corner], corners[end_corner]);
                if distance > tolerance {
                    continue;
                }
                let neighbor = self.neighbors[current as usize][usize::from(edge)];
                if neighbor == NO_TRIANGLE {
                    if hole.is_none() {
                        let mut barycentric = [0.0; 3];
                        barycentric[start_corner] = 1.0 - along;
                        barycentric[end_corner] = along;
                        hole = Some(Leave::Hole {
                            exit: FacePoint {
                                triangle: current,
                                barycentric: to_f32(barycentric),
                            },
                            edge: TriangleEdge {
                                triangle: current,
                                edge,
                            },
                        });
                    }
                    continue;
                }
                if neighbor == origin || visited[..visited_len].contains(&neighbor) {
                    continue;
                }
                let (first, second) = (vertex_indices[start_corner], vertex_indices[end_corner]);
                let Some(next_edge) = self.shared_edge(neighbor, first, second) else {
                    continue;
                };
                if self.is_degenerate(neighbor) {
                    if visited_len < MAX_DEGENERATE_VISITS {
                        visited[visited_len] = neighbor;
                        visited_len += 1;
                        stack[stack_len] = (neighbor, next_edge, depth + 1);
                        stack_len += 1;
                    }
                    continue;
                }
                let next_corners = self.corners(neighbor);
                let next_start = next_corners[usize::from(next_edge)];
                let next_end = next_corners[(usize::from(next_edge) + 1) % 3];
                let far = next_corners[(usize::from(next_edge) + 2) % 3];
                let inward = perpendicular(far - next_start, (next_end - next_start).normalize());
                let score = direction.dot(inward);
                if best
                    .as_ref()
                    .is_none_or(|(best_score, _)| score > *best_score)
                {
                    best = Some((
                        score,
                        Leave::Onto {
                            triangle: neighbor,
                            edge: next_edge,
                            inward,
                            hops: depth,
                        },
                    ));
                }
            }
        }
        best.map(|(_, leave)| leave)
            .or(hole)
            .unwrap_or(Leave::Nowhere)
    }
}

/// The lifted end of a walk that left the surface at `point`.
fn lifted(
    point: DVec3,
    remaining: DVec3,
    exit: FacePoint,
    edge: TriangleEdge,
    crossings: u32,
) -> WalkOutcome {
    WalkOutcome {
        end: WalkEnd::Lifted {
            position: (point + remaining).as_vec3(),
            exit,
            edge,
        },
        direction: remaining.normalize_or_zero().as_vec3(),
        edge_crossings: crossings,
        truncated: false,
    }
}

/// Start barycentrics made valid: negatives clamped to zero, renormalised (the centroid if
/// nothing is left).
fn sanitize(barycentric: Vec3) -> [f64; 3] {
    let coordinates = barycentric.as_dvec3().max(DVec3::ZERO);
    let sum = coordinates.element_sum();
    if sum > 0.0 {
        (coordinates / sum).to_array()
    } else {
        [1.0 / 3.0; 3]
    }
}

/// Barycentrics after a step: tiny and negative ones set to zero, renormalised.
#[inline]
fn clean(barycentric: [f64; 3]) -> [f64; 3] {
    let snapped = barycentric.map(|coordinate| if coordinate < SNAP { 0.0 } else { coordinate });
    let sum = snapped[0] + snapped[1] + snapped[2];
    if sum > 0.0 {
        let inverse = 1.0 / sum;
        snapped.map(|coordinate| coordinate * inverse)
    } else {
        [1.0 / 3.0; 3]
    }
}

#[inline]
fn to_f32(barycentric: [f64; 3]) -> Vec3 {
    DVec3::from_array(barycentric).as_vec3()
}

#[inline]
fn interpolate(corners: &[DVec3; 3], barycentric: [f64; 3]) -> DVec3 {
    corners[0] * barycentric[0] + corners[1] * barycentric[1] + corners[2] * barycentric[2]
}

/// The corner a point sits on (two zero barycentrics), if any.
#[inline]
fn vertex_corner(barycentric: [f64; 3]) -> Option<usize> {
    match barycentric.map(|coordinate| coordinate == 0.0) {
        [false, true, true] => Some(0),
        [true, false, true] => Some(1),
        [true, true, false] => Some(2),
        _ => None,
    }
}

/// The angle between two vectors, in `[0, π]`.
#[inline]
fn wedge_angle(first: DVec3, second: DVec3) -> f64 {
    first.cross(second).length().atan2(first.dot(second))
}

/// The unit part of `vector` perpendicular to the unit `axis`.
#[inline]
fn perpendicular(vector: DVec3, axis: DVec3) -> DVec3 {
    (vector - axis * vector.dot(axis)).normalize_or_zero()
}

/// The parameter in `[0, 1]` of the point of segment `start`–`end` closest to `point`, and the
/// distance to it.
fn segment_parameter(point: DVec3, start: DVec3, end: DVec3) -> (f64, f64) {
    let segment = end - start;
    let length_squared = segment.length_squared();
    let along = if length_squared > 0.0 {
        ((point - start).dot(segment) / length_squared).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (along, point.distance(start + segment * along))
}

/// Barycentrics of `point` placed on edge `edge` of a triangle (its closest point there).
fn on_edge(corners: &[DVec3; 3], edge: u8, point: DVec3) -> [f64; 3] {
    let (start_corner, end_corner) = (usize::from(edge), (usize::from(edge) + 1) % 3);
    let (along, _) = segment_parameter(point, corners[start_corner], corners[end_corner]);
    let mut barycentric = [0.0; 3];
    barycentric[start_corner] = 1.0 - along;
    barycentric[end_corner] = along;
    clean(barycentric)
}
