//! The quality read-out of a layout on its target, measured without a known answer: three numbers
//! an artist reads after a snap, projection, wrap or mirror.
//!
//! - **distance** (per vertex): to the closest point of the target surface
//!   ([`TargetMesh::surface_distances`]: the exact closest point, started from a triangle near the
//!   answer when the caller knows one, in f64 between the point and the hit);
//! - **stretch** (per vertex, [`vertex_stretch`]): the mean length of the vertex's edges now over
//!   their mean length in the rest shape. 1 = unchanged; a vertex without measurable edges reads 1;
//! - **flipped** (per face, [`flipped_faces`]): the face is turned over against its rest shape. Its
//!   Newell normal points against its rest normal carried by the best rotation (Horn's, proper) of
//!   its neighbourhood (its corners and their edge neighbours, a vertex counted once per way it is
//!   reached) from the rest shape to now. A posed limb or a layout turned round is not flipped; a
//!   face folded over its neighbours is. A degenerate face (zero normal, now or at rest) is not.
//!
//! Layout positions are f64 (world coordinates, or the target's frame for the distances): the
//! read-out describes the layout far from the origin as precisely as near it. Non-finite positions
//! are not an error here (the read-out describes what is, it does not judge inputs): their distance
//! is infinite, their edges are left out of the stretch and they are left out of the fits.

use glam::{DVec3, Vec3, Vec3A};
use rayon::prelude::*;

use crate::align::fit::horn_rotation;
use crate::error::KernelError;
use crate::mesh::TargetMesh;
use crate::query::QueryState;
use crate::query::point_triangle::closest_point_on_triangle;

/// Faces per rayon task when judging flips: a few microseconds each.
const FACES_PER_TASK: usize = 256;

/// Vertices per rayon task when measuring rings: a microsecond or less each.
const VERTICES_PER_TASK: usize = 1024;

/// A layout's faces: `corners` lists each face's vertices in order, face after face; `sizes` says
/// how many corners each face has (their sum is `corners.len()`).
#[derive(Debug, Clone, Copy)]
pub struct LayoutFaces<'a> {
    /// The corners of every face, face after face.
    pub corners: &'a [u32],
    /// The corner count of each face.
    pub sizes: &'a [u32],
}

impl LayoutFaces<'_> {
    /// The first corner of each face (prefix sums of the sizes), checked against the corners and
    /// the vertex count.
    pub(crate) fn starts(&self, vertex_count: usize) -> Result<Vec<usize>, KernelError> {
        let mut starts = Vec::with_capacity(self.sizes.len());
        let mut next = 0usize;
        for &size in self.sizes {
            starts.push(next);
            next = next.saturating_add(size as usize);
        }
        if next != self.corners.len() {
            return Err(KernelError::LengthMismatch {
                what: "face corners and the sum of the face sizes",
                first: self.corners.len(),
                second: next,
            });
        }
        // Checked in parallel; the face is looked for only when a corner is out of range.
        let Some(corner) = self
            .corners
            .par_iter()
            .position_first(|&vertex| vertex as usize >= vertex_count)
        else {
            return Ok(starts);
        };
        Err(KernelError::LayoutIndexOutOfRange {
            element: "face",
            index: starts.partition_point(|&start| start <= corner) - 1,
            vertex: self.corners[corner],
            vertex_count,
        })
    }
}

fn check_lengths(points: &[DVec3], rest: &[DVec3]) -> Result<(), KernelError> {
    if points.len() == rest.len() {
        Ok(())
    } else {
        Err(KernelError::LengthMismatch {
            what: "points and rest points",
            first: points.len(),
            second: rest.len(),
        })
    }
}

pub(crate) fn check_edges(edges: &[[u32; 2]], vertex_count: usize) -> Result<(), KernelError> {
    let outside = |vertex: &u32| *vertex as usize >= vertex_count;
    match edges
        .par_iter()
        .position_first(|edge| edge.iter().any(outside))
    {
        None => Ok(()),
        Some(index) => Err(KernelError::LayoutIndexOutOfRange {
            element: "edge",
            index,
            vertex: *edges[index]
                .iter()
                .find(|vertex| outside(vertex))
                .unwrap_or(&0),
            vertex_count,
        }),
    }
}

/// Each vertex's mean incident edge length now over the same at rest (1 where nothing can be
/// measured: no edge, or every rest edge of zero length). Edges with a non-finite length, now or
/// at rest, are left out.
///
/// # Errors
/// [`KernelError::LengthMismatch`] when `points` and `rest` differ in length,
/// [`KernelError::LayoutIndexOutOfRange`] for an edge naming a vertex that does not exist.
pub fn vertex_stretch(
    points: &[DVec3],
    rest: &[DVec3],
    edges: &[[u32; 2]],
) -> Result<Vec<f64>, KernelError> {
    check_lengths(points, rest)?;
    check_edges(edges, points.len())?;
    let mut now_sum = vec![0.0f64; points.len()];
    let mut rest_sum = vec![0.0f64; points.len()];
    for &[a, b] in edges {
        let (a, b) = (a as usize, b as usize);
        let now = points[a].distance(points[b]);
        let before = rest[a].distance(rest[b]);
        if now.is_finite() && before.is_finite() {
            for vertex in [a, b] {
                now_sum[vertex] += now;
                rest_sum[vertex] += before;
            }
        }
    }
    Ok(now_sum
        .into_iter()
        .zip(rest_sum)
        .map(|(now, before)| if before > 0.0 { now / before } else { 1.0 })
        .collect())
}

/// The Newell normal of one face (twice its area vector), its corners taken relative to their
/// centre (precise far from the origin); a non-finite component reads 0.
fn newell_normal(points: &[DVec3], corners: &[u32]) -> DVec3 {
    if corners.is_empty() {
        return DVec3::ZERO;
    }
    let centre = corners
        .iter()
        .map(|&vertex| points[vertex as usize])
        .sum::<DVec3>()
        / corners.len() as f64;
    let mut normal = DVec3::ZERO;
    for (index, &vertex) in corners.iter().enumerate() {
        let next = corners[(index + 1) % corners.len()];
        normal += (points[vertex as usize] - centre).cross(points[next as usize] - centre);
    }
    DVec3::from_array(
        normal
            .to_array()
            .map(|value| if value.is_finite() { value } else { 0.0 }),
    )
}

/// Each face's Newell normal (twice its area vector; zero for a degenerate face), its corners
/// taken relative to their centre.
///
/// # Errors
/// [`KernelError::LengthMismatch`] when the sizes do not add up to the corners,
/// [`KernelError::LayoutIndexOutOfRange`] for a corner naming a vertex that does not exist.
pub fn face_normals(points: &[DVec3], faces: LayoutFaces<'_>) -> Result<Vec<DVec3>, KernelError> {
    let starts = faces.starts(points.len())?;
    Ok(starts
        .par_iter()
        .zip(faces.sizes)
        .with_min_len(FACES_PER_TASK)
        .map(|(&start, &size)| newell_normal(points, &faces.corners[start..start + size as usize]))
        .collect())
}

/// Each vertex's edge neighbours, in compressed rows: the neighbours of `v` are
/// `neighbours[offsets[v]..offsets[v + 1]]`.
struct Neighbours {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
}

impl Neighbours {
    fn new(edges: &[[u32; 2]], vertex_count: usize) -> Self {
        // Counts at index v + 1, then their sums: offsets[v + 1] is where v's row ends, and, while
        // the rows fill, offsets[v] where the next of v's neighbours goes (it ends at v's start).
        let mut offsets = vec![0u32; vertex_count + 1];
        for &[a, b] in edges {
            offsets[a as usize + 1] += 1;
            offsets[b as usize + 1] += 1;
        }
        for index in 0..vertex_count {
            offsets[index + 1] += offsets[index];
        }
        let mut neighbours = vec![0u32; offsets[vertex_count] as usize];
        for &[a, b] in edges {
            for (from, to) in [(a, b), (b, a)] {
                neighbours[offsets[from as usize] as usize] = to;
                offsets[from as usize] += 1;
            }
        }
        // Each start moved to the next row's: shift back.
        for index in (1..=vertex_count).rev() {
            offsets[index] = offsets[index - 1];
        }
        offsets[0] = 0;
        Self {
            offsets,
            neighbours,
        }
    }

    fn of(&self, vertex: u32) -> &[u32] {
        &self.neighbours
            [self.offsets[vertex as usize] as usize..self.offsets[vertex as usize + 1] as usize]
    }
}

/// The first and second moments of a group of vertices in both shapes: how many, their centroids
/// at rest and now, and their centred cross-covariance `Σ (rest − rest centroid)(now − now
/// centroid)ᵀ` (rows at rest, columns now). Groups merge exactly (Chan's pairwise update), so a
/// face's neighbourhood is the merge of its corners' closed rings, each computed once.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    count: f64,
    mean_rest: DVec3,
    mean_now: DVec3,
    cross: [[f64; 3]; 3],
}

impl Moments {
    /// The moments of `group`'s vertices finite in both shapes (sums relative to the first of them,
    /// then centred: one pass, precise far from the origin).
    fn of(points: &[DVec3], rest: &[DVec3], group: impl Iterator<Item = u32>) -> Self {
        let mut usable = group
            .map(|vertex| (points[vertex as usize], rest[vertex as usize]))
            .filter(|(now, before)| now.is_finite() && before.is_finite())
            .peekable();
        let Some(&(origin_now, origin_rest)) = usable.peek() else {
            return Self::default();
        };
        let mut count = 0.0f64;
        let (mut sum_now, mut sum_rest) = (DVec3::ZERO, DVec3::ZERO);
        let mut cross = [[0.0f64; 3]; 3];
        for (now, before) in usable {
            let (now, before) = (now - origin_now, before - origin_rest);
            count += 1.0;
            sum_now += now;
            sum_rest += before;
            let (now, before) = (now.to_array(), before.to_array());
            for (row, out) in cross.iter_mut().enumerate() {
                for (column, value) in out.iter_mut().enumerate() {
                    *value += before[row] * now[column];
                }
            }
        }
        let (mean_now, mean_rest) = (sum_now / count, sum_rest / count);
        let (now, before) = (mean_now.to_array(), mean_rest.to_array());
        for (row, out) in cross.iter_mut().enumerate() {
            for (column, value) in out.iter_mut().enumerate() {
                *value -= count * before[row] * now[column];
            }
        }
        Self {
            count,
            mean_rest: origin_rest + mean_rest,
            mean_now: origin_now + mean_now,
            cross,
        }
    }

    /// The moments of both groups together.
    fn merge(&mut self, other: &Self) {
        if other.count == 0.0 {
            return;
        }
        if self.count == 0.0 {
            *self = *other;
            return;
        }
        let count = self.count + other.count;
        let share = other.count / count;
        let (apart_rest, apart_now) = (
            other.mean_rest - self.mean_rest,
            other.mean_now - self.mean_now,
        );
        let weight = self.count * share;
        let (rest, now) = (apart_rest.to_array(), apart_now.to_array());
        for (row, out) in self.cross.iter_mut().enumerate() {
            for (column, value) in out.iter_mut().enumerate() {
                *value += other.cross[row][column] + weight * rest[row] * now[column];
            }
        }
        self.count = count;
        self.mean_rest += share * apart_rest;
        self.mean_now += share * apart_now;
    }

    /// The proper rotation that best takes the group's rest points onto their points now (about
    /// their centroids); the identity when nothing can be fitted.
    fn best_rotation(&self) -> glam::DQuat {
        let mut cross = self.cross;
        for value in cross.iter_mut().flatten() {
            if !value.is_finite() {
                *value = 0.0;
            }
        }
        fast_horn_rotation(&cross)
    }
}

/// [`horn_rotation`] without the eigen-solver's sweeps, as Theobald's QCP finds it: the largest
/// eigenvalue of Horn's symmetric 4x4 `K` by Newton's method on its characteristic polynomial
/// (from above: every root is real, so the iteration falls monotonically onto the largest), its
/// eigenvector from the adjugate of `K - λI`. When that eigenvector is ill-defined (the largest
/// eigenvalue repeated: no single best rotation) the eigen-solver decides, as it always did.
fn fast_horn_rotation(cross: &[[f64; 3]; 3]) -> glam::DQuat {
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = *cross;
    let squared: f64 = cross.iter().flatten().map(|value| value * value).sum();
    if squared == 0.0 || !squared.is_finite() {
        return horn_rotation(cross);
    }
    let horn = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    // det(K - λI) = λ⁴ + c2 λ² + c1 λ + c0.
    let c2 = -2.0 * squared;
    let c1 = -8.0
        * (sxx * (syy * szz - syz * szy) - sxy * (syx * szz - syz * szx)
            + sxz * (syx * szy - syy * szx));
    let c0 = cofactors(&horn, 0)
        .iter()
        .zip(&horn[0])
        .map(|(cofactor, entry)| cofactor * entry)
        .sum::<f64>();
    // λ_max ≤ σ1 + σ2 + σ3 ≤ √3 ‖S‖: start there.
    let mut lambda = (3.0 * squared).sqrt();
    for _ in 0..60 {
        let lambda2 = lambda * lambda;
        let value = lambda2 * lambda2 + c2 * lambda2 + c1 * lambda + c0;
        let slope = 4.0 * lambda2 * lambda + 2.0 * c2 * lambda + c1;
        if slope <= 0.0 {
            break;
        }
        let step = value / slope;
        lambda -= step;
        if step.abs() <= 1e-13 * lambda.abs().max(squared.sqrt()) {
            break;
        }
    }
    let mut shifted = horn;
    for (index, row) in shifted.iter_mut().enumerate() {
        row[index] -= lambda;
    }
    // A row of the adjugate of K - λI is a multiple of the eigenvector: row 0's, else row 1's when row 0's is
    // too short to be precise.
    let cubed = squared * squared.sqrt();
    let length = |vector: &[f64; 4]| vector.iter().map(|value| value * value).sum::<f64>().sqrt();
    let mut vector = cofactors(&shifted, 0);
    if length(&vector) <= 1e-2 * cubed {
        let other = cofactors(&shifted, 1);
        if length(&other) > length(&vector) {
            vector = other;
        }
    }
    let precise = length(&vector) > 1e-6 * cubed; // false for NaN too
    if !precise {
        return horn_rotation(cross);
    }
    let [w, x, y, z] = vector;
    glam::DQuat::from_xyzw(x, y, z, w).normalize()
}

/// The cofactors of row `row` (0 or 1) of a 4x4 matrix, from the 2x2 minors of its rows 2 and 3.
fn cofactors(matrix: &[[f64; 4]; 4], row: usize) -> [f64; 4] {
    let [third, fourth] = [matrix[2], matrix[3]];
    let minor = |a: usize, b: usize| third[a] * fourth[b] - third[b] * fourth[a];
    let other = matrix[1 - row];
    // det of the other row and rows 2, 3 over columns (p, q, r).
    let determinant = |p: usize, q: usize, r: usize| {
        other[p] * minor(q, r) - other[q] * minor(p, r) + other[r] * minor(p, q)
    };
    let sign = if row == 0 { 1.0 } else { -1.0 };
    [
        sign * determinant(1, 2, 3),
        -sign * determinant(0, 2, 3),
        sign * determinant(0, 1, 3),
        -sign * determinant(0, 1, 2),
    ]
}

/// Whether each face is turned over against its rest shape (see the module's documentation).
///
/// # Errors
/// [`KernelError::LengthMismatch`] when `points` and `rest` differ in length or the sizes do not
/// add up to the corners; [`KernelError::LayoutIndexOutOfRange`] for a corner or an edge naming a
/// vertex that does not exist.
pub fn flipped_faces(
    points: &[DVec3],
    rest: &[DVec3],
    faces: LayoutFaces<'_>,
    edges: &[[u32; 2]],
) -> Result<Vec<bool>, KernelError> {
    check_lengths(points, rest)?;
    let starts = faces.starts(points.len())?;
    check_edges(edges, points.len())?;
    let neighbours = Neighbours::new(edges, points.len());
    let rings = ring_moments(points, rest, &neighbours);
    Ok(flips(points, rest, faces, &starts, &rings))
}

/// Each vertex's closed ring (itself and its edge neighbours, as often as each is reached).
fn ring_moments(points: &[DVec3], rest: &[DVec3], neighbours: &Neighbours) -> Vec<Moments> {
    (0..points.len() as u32)
        .into_par_iter()
        .with_min_len(VERTICES_PER_TASK)
        .map(|vertex| {
            let ring = std::iter::once(vertex).chain(neighbours.of(vertex).iter().copied());
            Moments::of(points, rest, ring)
        })
        .collect()
}

/// Whether each face is turned over (see the module's documentation), its neighbourhood the merge
/// of its corners' closed rings.
fn flips(
    points: &[DVec3],
    rest: &[DVec3],
    faces: LayoutFaces<'_>,
    starts: &[usize],
    rings: &[Moments],
) -> Vec<bool> {
    starts
        .par_iter()
        .zip(faces.sizes)
        .with_min_len(FACES_PER_TASK)
        .map(|(&start, &size)| {
            let corners = &faces.corners[start..start + size as usize];
            let normal = newell_normal(points, corners);
            let rest_normal = newell_normal(rest, corners);
            if normal == DVec3::ZERO || rest_normal == DVec3::ZERO {
                return false;
            }
            let mut group = Moments::default();
            for &corner in corners {
                group.merge(&rings[corner as usize]);
            }
            let facing = (group.best_rotation() * rest_normal).dot(normal);
            facing.is_finite() && facing < 0.0
        })
        .collect()
}

/// The read-out's layout measures in one pass (see [`layout_readout`]).
#[derive(Debug, Clone, PartialEq)]
pub struct LayoutReadout {
    /// Per vertex, as [`vertex_stretch`] (all 1 without a rest shape).
    pub stretch: Vec<f64>,
    /// Per face, as [`flipped_faces`] (none without a rest shape).
    pub flipped: Vec<bool>,
    /// The diagonal of the finite points' bounding box (0 for none).
    pub diagonal: f64,
}

/// The stretch, the flips and the layout's size at once: the faces, edges and neighbourhoods are
/// checked and built once, each vertex's edges are measured once for the stretch and the ring it
/// adds to its faces' neighbourhoods. `rest` `None`: no usable rest shape (the stretch reads 1,
/// no face is flipped).
///
/// # Errors
/// As [`flipped_faces`].
pub fn layout_readout(
    points: &[DVec3],
    rest: Option<&[DVec3]>,
    faces: LayoutFaces<'_>,
    edges: &[[u32; 2]],
) -> Result<LayoutReadout, KernelError> {
    let starts = faces.starts(points.len())?;
    check_edges(edges, points.len())?;
    let diagonal = finite_diagonal(points);
    let Some(rest) = rest else {
        return Ok(LayoutReadout {
            stretch: vec![1.0; points.len()],
            flipped: vec![false; starts.len()],
            diagonal,
        });
    };
    check_lengths(points, rest)?;
    let neighbours = Neighbours::new(edges, points.len());
    let (mut stretch, mut rings) = (Vec::new(), Vec::new());
    (0..points.len() as u32)
        .into_par_iter()
        .with_min_len(VERTICES_PER_TASK)
        .map(|vertex| {
            let around = neighbours.of(vertex);
            let ring = std::iter::once(vertex).chain(around.iter().copied());
            (
                ring_stretch(points, rest, vertex, around),
                Moments::of(points, rest, ring),
            )
        })
        .unzip_into_vecs(&mut stretch, &mut rings);
    let flipped = flips(points, rest, faces, &starts, &rings);
    Ok(LayoutReadout {
        stretch,
        flipped,
        diagonal,
    })
}

/// One vertex's stretch from its edges (as [`vertex_stretch`] sums them edge by edge).
fn ring_stretch(points: &[DVec3], rest: &[DVec3], vertex: u32, around: &[u32]) -> f64 {
    let (mut now_sum, mut rest_sum) = (0.0f64, 0.0f64);
    let (here, here_before) = (points[vertex as usize], rest[vertex as usize]);
    for &other in around {
        let now = here.distance(points[other as usize]);
        let before = here_before.distance(rest[other as usize]);
        if now.is_finite() && before.is_finite() {
            now_sum += now;
            rest_sum += before;
        }
    }
    if rest_sum > 0.0 {
        now_sum / rest_sum
    } else {
        1.0
    }
}

/// The diagonal of the finite points' bounding box (0 for none).
fn finite_diagonal(points: &[DVec3]) -> f64 {
    let (low, high) = points
        .par_iter()
        .with_min_len(VERTICES_PER_TASK)
        .filter(|point| point.is_finite())
        .fold(
            || (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(low, high), point| (low.min(*point), high.max(*point)),
        )
        .reduce(
            || (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(a, b), (c, d)| (a.min(c), b.max(d)),
        );
    if low.x <= high.x {
        low.distance(high)
    } else {
        0.0
    }
}

impl TargetMesh {
    /// Each point's distance to the closest point of the surface, in f64 between the point and
    /// the exact hit; `points` are in the mesh's coordinates. A non-finite point's distance is
    /// infinite.
    ///
    /// `near[i]`, when a triangle index, is a triangle the point is known to lie on (its
    /// face-point's): when the point is within `on_surface` of it, its distance to that triangle
    /// is the answer (the surface's closest point is no farther, and no nearer than 0: the two
    /// differ by at most `on_surface`, a rounding-sized tolerance), without a search; otherwise
    /// the search starts there.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] when `near` is given and differs from `points` in length,
    /// [`KernelError::CoordinateOutOfRange`] for a point beyond [`crate::MAX_COORDINATE`].
    pub fn surface_distances(
        &self,
        points: &[DVec3],
        near: Option<&[u32]>,
        on_surface: f64,
    ) -> Result<Vec<f64>, KernelError> {
        if let Some(near) = near
            && near.len() != points.len()
        {
            return Err(KernelError::LengthMismatch {
                what: "points and near triangles",
                first: points.len(),
                second: near.len(),
            });
        }
        let queries: Vec<Vec3> = points.iter().map(|point| point.as_vec3()).collect();
        for (index, query) in queries.iter().enumerate() {
            if query.is_finite() {
                crate::validate::check_coordinate("point", index, *query)?;
            }
        }
        self.closest_tree();
        Ok((0..points.len())
            .into_par_iter()
            .with_min_len(crate::query::QUERIES_PER_TASK)
            .map_init(QueryState::default, |state, index| {
                if !points[index].is_finite() || !queries[index].is_finite() {
                    return f64::INFINITY;
                }
                let start = near.map_or(crate::mesh::NO_TRIANGLE, |near| near[index]);
                if let Some(&[a, b, c]) = self.triangles.get(start as usize) {
                    let corner = |vertex: u32| Vec3A::from(self.vertices[vertex as usize]);
                    let (hit, _) = closest_point_on_triangle(
                        queries[index].into(),
                        corner(a),
                        corner(b),
                        corner(c),
                    );
                    let distance = points[index].distance(Vec3::from(hit).as_dvec3());
                    if distance <= on_surface && !self.degenerate[start as usize] {
                        return distance;
                    }
                }
                self.closest_point_near(queries[index], f32::INFINITY, start, state)
                    .map_or(f64::INFINITY, |hit| {
                        points[index].distance(hit.position.as_dvec3())
                    })
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An n x n grid of quads in z = 0, unit cells: positions, corners, sizes, edges.
    fn grid(n: u32) -> (Vec<DVec3>, Vec<u32>, Vec<u32>, Vec<[u32; 2]>) {
        let side = n + 1;
        let points = (0..side * side)
            .map(|index| DVec3::new(f64::from(index % side), f64::from(index / side), 0.0))
            .collect();
        let mut corners = Vec::new();
        let mut edges = Vec::new();
        for row in 0..n {
            for column in 0..n {
                let first = row * side + column;
                corners.extend([first, first + 1, first + side + 1, first + side]);
            }
        }
        for row in 0..side {
            for column in 0..side {
                let vertex = row * side + column;
                if column + 1 < side {
                    edges.push([vertex, vertex + 1]);
                }
                if row + 1 < side {
                    edges.push([vertex, vertex + side]);
                }
            }
        }
        let sizes = vec![4; (n * n) as usize];
        (points, corners, sizes, edges)
    }

    #[test]
    fn a_layout_scaled_by_two_stretches_two_and_unchanged_reads_one() {
        let (points, _, _, edges) = grid(3);
        let doubled: Vec<DVec3> = points.iter().map(|&point| point * 2.0).collect();
        assert!(
            vertex_stretch(&doubled, &points, &edges)
                .unwrap()
                .iter()
                .all(|&s| (s - 2.0).abs() < 1e-12)
        );
        assert!(
            vertex_stretch(&points, &points, &edges)
                .unwrap()
                .iter()
                .all(|&s| s == 1.0)
        );
        let collapsed = vec![DVec3::ONE; points.len()];
        assert!(
            vertex_stretch(&points, &collapsed, &edges)
                .unwrap()
                .iter()
                .all(|&s| s == 1.0)
        );
    }

    #[test]
    fn a_fold_flips_the_faces_it_turns_over_and_a_turn_flips_none() {
        let (points, corners, sizes, edges) = grid(4);
        let faces = LayoutFaces {
            corners: &corners,
            sizes: &sizes,
        };
        assert!(
            !flipped_faces(&points, &points, faces, &edges)
                .unwrap()
                .contains(&true)
        );
        let turned: Vec<DVec3> = points
            .iter()
            .map(|&p| DVec3::new(-p.x, p.y, -p.z + 3.0))
            .collect();
        assert!(
            !flipped_faces(&turned, &points, faces, &edges)
                .unwrap()
                .contains(&true)
        );
        let mut folded = points.clone();
        folded[6] = points[18] + DVec3::new(0.4, 0.4, 0.0); // an inner vertex dragged over others
        let flipped = flipped_faces(&folded, &points, faces, &edges).unwrap();
        let normals = face_normals(&folded, faces).unwrap();
        assert!(flipped.contains(&true));
        for (flip, normal) in flipped.iter().zip(&normals) {
            assert_eq!(*flip, normal.z < 0.0);
        }
    }

    #[test]
    fn degenerate_and_non_finite_faces_are_not_flipped() {
        let (points, corners, sizes, edges) = grid(2);
        let faces = LayoutFaces {
            corners: &corners,
            sizes: &sizes,
        };
        let mut broken = points.clone();
        for &corner in &corners[..4] {
            broken[corner as usize] = DVec3::splat(0.5); // face 0 to a point
        }
        broken[8] = DVec3::NAN;
        let flipped = flipped_faces(&broken, &points, faces, &edges).unwrap();
        assert!(!flipped[0] && !flipped[3]);
        assert_eq!(face_normals(&broken, faces).unwrap()[0], DVec3::ZERO);
    }

    #[test]
    fn the_fast_rotation_is_the_eigen_solvers() {
        let mut seed = 7u64;
        let mut random = move || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for case in 0..2000 {
            let mut cross: [[f64; 3]; 3] =
                std::array::from_fn(|_| std::array::from_fn(|_| random()));
            if case % 3 == 0 {
                cross[2] = [0.0; 3]; // planar neighbourhoods: rank 2
            }
            let fast = fast_horn_rotation(&cross);
            let reference = horn_rotation(&cross);
            assert!(
                fast.dot(reference).abs() > 1.0 - 1e-9,
                "case {case}: {fast} against {reference}"
            );
        }
        assert_eq!(fast_horn_rotation(&[[0.0; 3]; 3]), glam::DQuat::IDENTITY);
    }

    #[test]
    fn bad_indices_and_lengths_are_refused() {
        let (points, corners, sizes, edges) = grid(1);
        let faces = LayoutFaces {
            corners: &corners,
            sizes: &[3],
        };
        assert!(matches!(
            face_normals(&points, faces),
            Err(KernelError::LengthMismatch { .. })
        ));
        let bad = [0, 1, 9, 3];
        let faces = LayoutFaces {
            corners: &bad,
            sizes: &sizes,
        };
        assert!(matches!(
            face_normals(&points, faces),
            Err(KernelError::LayoutIndexOutOfRange { .. })
        ));
        assert!(matches!(
            vertex_stretch(&points, &points, &[[0, 7]]),
            Err(KernelError::LayoutIndexOutOfRange { .. })
        ));
        assert!(matches!(
            vertex_stretch(&points, &points[1..], &edges),
            Err(KernelError::LengthMismatch { .. })
        ));
    }

    /// Positions now and at rest, face corners, face sizes, edges.
    type Warped = (Vec<DVec3>, Vec<DVec3>, Vec<u32>, Vec<u32>, Vec<[u32; 2]>);

    /// A grid of `n` x `n` quads warped and folded at random.
    fn warped(n: u32, seed: u64) -> Warped {
        let (rest, corners, sizes, edges) = grid(n);
        let mut state = seed;
        let mut random = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let points = rest
            .iter()
            .map(|p| {
                let bent = DVec3::new(p.x, p.y * p.y.cos(), p.y.sin() * 3.0);
                bent + 1.5 * DVec3::new(random(), random(), random()) + DVec3::splat(1e4)
            })
            .collect();
        (points, rest, corners, sizes, edges)
    }

    #[test]
    fn a_neighbourhood_merged_from_rings_has_the_groups_moments() {
        let (points, rest, corners, sizes, edges) = warped(6, 3);
        let neighbours = Neighbours::new(&edges, points.len());
        let rings = ring_moments(&points, &rest, &neighbours);
        for face in corners.chunks_exact(sizes[0] as usize) {
            let group = face.iter().flat_map(|&corner| {
                std::iter::once(corner).chain(neighbours.of(corner).iter().copied())
            });
            let direct = Moments::of(&points, &rest, group);
            let mut merged = Moments::default();
            for &corner in face {
                merged.merge(&rings[corner as usize]);
            }
            assert_eq!(merged.count, direct.count);
            assert!(merged.mean_now.distance(direct.mean_now) < 1e-9);
            assert!(merged.mean_rest.distance(direct.mean_rest) < 1e-9);
            for (a, b) in merged
                .cross
                .iter()
                .flatten()
                .zip(direct.cross.iter().flatten())
            {
                assert!((a - b).abs() < 1e-8 * (1.0 + b.abs()), "{a} against {b}");
            }
        }
    }

    #[test]
    fn the_one_pass_readout_is_the_stretch_flips_and_size() {
        let (points, rest, corners, sizes, edges) = warped(12, 5);
        let faces = LayoutFaces {
            corners: &corners,
            sizes: &sizes,
        };
        let readout = layout_readout(&points, Some(&rest), faces, &edges).unwrap();
        let stretch = vertex_stretch(&points, &rest, &edges).unwrap();
        for (a, b) in readout.stretch.iter().zip(&stretch) {
            assert!((a - b).abs() < 1e-12 * b.abs().max(1.0));
        }
        let flipped = flipped_faces(&points, &rest, faces, &edges).unwrap();
        assert_eq!(readout.flipped, flipped);
        assert!(flipped.contains(&true) && flipped.contains(&false));
        let (low, high) = points
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(low, high), p| {
                (low.min(*p), high.max(*p))
            });
        assert!((readout.diagonal - low.distance(high)).abs() < 1e-9);
        let unmeasured = layout_readout(&points, None, faces, &edges).unwrap();
        assert!(unmeasured.stretch.iter().all(|&s| s == 1.0));
        assert!(!unmeasured.flipped.contains(&true));
        assert_eq!(unmeasured.diagonal, readout.diagonal);
        let mut broken = points.clone();
        broken[0] = DVec3::NAN;
        let partial = layout_readout(&broken, Some(&rest), faces, &edges).unwrap();
        assert!(partial.diagonal > 0.0 && partial.diagonal <= readout.diagonal);
        assert!(partial.flipped.len() == flipped.len() && partial.stretch[0] == 1.0);
        assert!(matches!(
            layout_readout(&points, Some(&rest[1..]), faces, &edges),
            Err(KernelError::LengthMismatch { .. })
        ));
        assert_eq!(
            layout_readout(
                &[],
                None,
                LayoutFaces {
                    corners: &[],
                    sizes: &[]
                },
                &[]
            )
            .unwrap()
            .diagonal,
            0.0
        );
    }

    #[test]
    fn surface_distances_match_the_closest_points_with_or_without_a_start() {
        let (points, corners, _, _) = grid(4);
        let vertices: Vec<Vec3> = points.iter().map(|point| point.as_vec3()).collect();
        let triangles: Vec<[u32; 3]> = corners
            .chunks_exact(4)
            .flat_map(|quad| [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]])
            .collect();
        let mesh =
            TargetMesh::new(vertices, triangles, crate::TargetMeshOptions::default()).unwrap();
        let queries = [
            DVec3::new(1.5, 2.5, 0.25),
            DVec3::new(-1.0, 2.0, 0.0),
            DVec3::NAN,
        ];
        let plain = mesh.surface_distances(&queries, None, 0.0).unwrap();
        let started = mesh
            .surface_distances(&queries, Some(&[30, 0, 5]), 1e-6)
            .unwrap();
        assert_eq!(plain, started);
        assert!((plain[0] - 0.25).abs() < 1e-7 && (plain[1] - 1.0).abs() < 1e-7);
        assert_eq!(plain[2], f64::INFINITY);
        assert!(mesh.surface_distances(&queries, Some(&[0]), 0.0).is_err());
        // On its own triangle within the tolerance: that triangle's distance, the same as the search's.
        let on = [DVec3::new(1.25, 1.5, 1e-7)];
        let found = mesh.surface_distances(&on, Some(&[8]), 1e-6).unwrap();
        assert!((found[0] - 1e-7).abs() < 1e-9);
        assert!((found[0] - mesh.surface_distances(&on, None, 0.0).unwrap()[0]).abs() < 1e-9);
    }
}
