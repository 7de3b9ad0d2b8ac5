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

use glam::{DMat3, DVec3, Vec3, Vec3A};
use rayon::prelude::*;

use crate::align::fit::horn_rotation;
use crate::error::KernelError;
use crate::mesh::TargetMesh;
use crate::query::QueryState;
use crate::query::point_triangle::closest_point_on_triangle;

mod placed;
pub use placed::{DistanceTarget, PlacedLayout, PlacedReadout, placed_readout};

/// Faces per rayon task when judging flips: a few microseconds each.
const FACES_PER_TASK: usize = 256;

/// Vertices per rayon task when measuring rings: a microsecond or less each.
const VERTICES_PER_TASK: usize = 1024;

/// Face corners per chunk when checking them against the vertex count.
const CORNERS_PER_CHECK: usize = 1 << 14;

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
        // Checked in parallel, a chunk of corners at a time (a loop the compiler vectorizes); the
        // corner and its face are looked for only when one is out of range.
        let outside = |vertex: &u32| *vertex as usize >= vertex_count;
        let Some(chunk) = self
            .corners
            .par_chunks(CORNERS_PER_CHECK)
            .position_first(|chunk| {
                chunk
                    .iter()
                    .fold(false, |any, vertex| any | outside(vertex))
            })
        else {
            return Ok(starts);
        };
        let corner = chunk * CORNERS_PER_CHECK
            + self.corners[chunk * CORNERS_PER_CHECK..]
                .iter()
                .position(outside)
                .unwrap_or(0);
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
    // As the corners in `LayoutFaces::starts`: a chunk at a time, the edge looked for on a failure.
    let Some(chunk) = edges
        .par_chunks(CORNERS_PER_CHECK / 2)
        .position_first(|chunk| {
            chunk
                .iter()
                .fold(false, |any, [a, b]| any | outside(a) | outside(b))
        })
    else {
        return Ok(());
    };
    let first = chunk * (CORNERS_PER_CHECK / 2);
    let index = first
        + edges[first..]
            .iter()
            .position(|edge| edge.iter().any(outside))
            .unwrap_or(0);
    Err(KernelError::LayoutIndexOutOfRange {
        element: "edge",
        index,
        vertex: *edges[index]
            .iter()
            .find(|vertex| outside(vertex))
            .unwrap_or(&0),
        vertex_count,
    })
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
/// at rest and now, their centred cross-covariance `Σ (rest − rest centroid)(now − now
/// centroid)ᵀ` (rows at rest, columns now) and their spreads `Σ |rest − rest centroid|²`, `Σ |now −
/// now centroid|²`. Groups merge exactly (Chan's pairwise update), so a face's neighbourhood is the
/// merge of its corners' closed rings, each measured once per block of faces.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    count: f64,
    mean_rest: DVec3,
    mean_now: DVec3,
    cross: [[f64; 3]; 3],
    spread_rest: f64,
    spread_now: f64,
}

impl Moments {
    /// The moments of `group`'s vertices finite in both shapes (sums relative to the first of them,
    /// then centred: one pass, precise far from the origin).
    #[cfg(test)]
    fn of(points: &[DVec3], rest: &[DVec3], group: impl IntoIterator<Item = u32>) -> Self {
        let mut sums = Sums::default();
        for vertex in group {
            sums.add(points[vertex as usize], rest[vertex as usize]);
        }
        sums.moments()
    }

    /// [`Moments::of`] `vertex` and then `around` (a closed ring), in a plain loop.
    fn of_ring(points: &[DVec3], rest: &[DVec3], vertex: u32, around: &[u32]) -> Self {
        let mut sums = Sums::default();
        sums.add(points[vertex as usize], rest[vertex as usize]);
        for &other in around {
            sums.add(points[other as usize], rest[other as usize]);
        }
        sums.moments()
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
        self.spread_rest += other.spread_rest + weight * apart_rest.length_squared();
        self.spread_now += other.spread_now + weight * apart_now.length_squared();
        self.count = count;
        self.mean_rest += share * apart_rest;
        self.mean_now += share * apart_now;
    }

    /// Whether Horn's rotation of the group turns `rest_normal` to within 90° of `normal` (with
    /// [`PROOF_SLACK`] to spare), proved from `rotation` (any proper rotation) without fitting it.
    ///
    /// The proof: at the best rotation `R*` the matrix `M = S R*` is symmetric (`S` the cross
    /// moments), its trace Horn's eigenvalue `λ`; a rotation `R = R* Q`, `Q` a turn by φ about `w`,
    /// falls short of it by `tr((I − Q) M) = 2 sin²(φ/2) (tr M − wᵀ M w) ≥ 2 sin²(φ/2) (λ − σ₁)`,
    /// `σ₁` the largest singular value of `S`. With `λ` at most the spreads' bound `U` and at least
    /// `t = tr(R S)`: `2 sin²(φ/2) ≤ (U − t) / (t − σ₁)`, and `|R* m̂ − R m̂| ≤ 2 sin(φ/2)`. Horn's
    /// computed rotation is as near `R*` as its rounding ([`PROOF_SLACK`] of `U`) allows.
    fn keeps_facing(&self, rotation: &DMat3, rest_normal: DVec3, normal: DVec3) -> bool {
        let cross = self.cross.map(DVec3::from_array);
        let turned = rotation.col(0).dot(cross[0])
            + rotation.col(1).dot(cross[1])
            + rotation.col(2).dot(cross[2]);
        let upper = (self.spread_rest * self.spread_now).sqrt() * (1.0 + PROOF_SLACK);
        // σ₁² ≤ the mean of the squared singular values plus √2 of their standard deviation.
        let gram = DMat3::from_cols(cross[0], cross[1], cross[2]);
        let gram = gram * gram.transpose();
        let trace = gram.x_axis.x + gram.y_axis.y + gram.z_axis.z;
        let squares = gram.x_axis.length_squared()
            + gram.y_axis.length_squared()
            + gram.z_axis.length_squared();
        let largest = (trace / 3.0
            + (2.0 * (squares / 3.0 - trace * trace / 9.0))
                .max(0.0)
                .sqrt())
        .sqrt()
            * (1.0 + PROOF_SLACK);
        let across = turned - largest;
        let facing =
            (*rotation * rest_normal).dot(normal) / (rest_normal.length() * normal.length());
        if !(across > 0.0 && upper.is_finite() && facing.is_finite()) {
            return false;
        }
        let reach = (2.0 * (upper - turned).max(0.0) / across).sqrt()
            + (2.0 * PROOF_SLACK * upper / across).sqrt();
        facing > reach + PROOF_SLACK
    }

    /// The proper rotation that best takes the group's rest points onto their points now (about
    /// their centroids); the identity when nothing can be fitted.
    fn best_rotation(&self) -> glam::DQuat {
        let mut cross = self.cross;
        let mut finite = true;
        for value in cross.iter_mut().flatten() {
            if !value.is_finite() {
                *value = 0.0;
                finite = false;
            }
        }
        // Cauchy-Schwarz: no rotation takes the rest offsets closer onto those now than
        // √(spread at rest · spread now), so Horn's largest eigenvalue is at most that (equal for
        // a rigid motion, a uniform scale too). A bound from a zeroed entry's moments is not used.
        let bound = if finite {
            (self.spread_rest * self.spread_now).sqrt()
        } else {
            f64::INFINITY
        };
        fast_horn_rotation(&cross, bound)
    }
}

/// The running sums [`Moments::of`] takes, relative to the first usable vertex.
#[derive(Default)]
struct Sums {
    count: f64,
    origin_now: DVec3,
    origin_rest: DVec3,
    sum_now: DVec3,
    sum_rest: DVec3,
    squares_now: f64,
    squares_rest: f64,
    cross: [[f64; 3]; 3],
}

impl Sums {
    /// Adds one vertex, left out unless finite in both shapes.
    #[inline]
    fn add(&mut self, now: DVec3, before: DVec3) {
        if !(now.is_finite() && before.is_finite()) {
            return;
        }
        if self.count == 0.0 {
            (self.origin_now, self.origin_rest) = (now, before);
        }
        let (now, before) = (now - self.origin_now, before - self.origin_rest);
        self.count += 1.0;
        self.sum_now += now;
        self.sum_rest += before;
        self.squares_now += now.length_squared();
        self.squares_rest += before.length_squared();
        let (now, before) = (now.to_array(), before.to_array());
        for (row, out) in self.cross.iter_mut().enumerate() {
            for (column, value) in out.iter_mut().enumerate() {
                *value += before[row] * now[column];
            }
        }
    }

    /// The centred moments of what was added.
    fn moments(self) -> Moments {
        let Self {
            count,
            origin_now,
            origin_rest,
            sum_now,
            sum_rest,
            squares_now,
            squares_rest,
            mut cross,
        } = self;
        if count == 0.0 {
            return Moments::default();
        }
        let (mean_now, mean_rest) = (sum_now / count, sum_rest / count);
        let (now, before) = (mean_now.to_array(), mean_rest.to_array());
        for (row, out) in cross.iter_mut().enumerate() {
            for (column, value) in out.iter_mut().enumerate() {
                *value -= count * before[row] * now[column];
            }
        }
        Moments {
            count,
            mean_rest: origin_rest + mean_rest,
            mean_now: origin_now + mean_now,
            cross,
            spread_rest: (squares_rest - count * mean_rest.length_squared()).max(0.0),
            spread_now: (squares_now - count * mean_now.length_squared()).max(0.0),
        }
    }
}

/// [`horn_rotation`] without the eigen-solver's sweeps, as Theobald's QCP finds it: the largest
/// eigenvalue of Horn's symmetric 4x4 `K` by Newton's method on its characteristic polynomial
/// (from above: every root is real, so the iteration falls monotonically onto the largest), its
/// eigenvector from the adjugate of `K - λI`. When that eigenvector is ill-defined (the largest
/// eigenvalue repeated: no single best rotation) the eigen-solver decides, as it always did.
///
/// `bound` is a known upper bound of that eigenvalue (infinite for none): Newton starts at the
/// lower of it (raised by [`BOUND_MARGIN`] for its rounding) and `√3 ‖S‖`, QCP's own start
/// (`√(G_a G_b)`, tight for a neighbourhood moved nearly rigidly, takes a few steps fewer).
fn fast_horn_rotation(cross: &[[f64; 3]; 3], bound: f64) -> glam::DQuat {
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
    // λ_max ≤ σ1 + σ2 + σ3 ≤ √3 ‖S‖, and λ_max ≤ bound: start at the lower.
    let mut lambda = (3.0 * squared).sqrt().min(bound * (1.0 + BOUND_MARGIN));
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

/// The relative margin a start from a computed upper bound of Horn's eigenvalue is raised by: far
/// above the rounding of the moments' sums, far below what one Newton step removes.
const BOUND_MARGIN: f64 = 1e-8;

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
    Ok(flips(points, rest, faces, &starts, &neighbours))
}

/// Whether each face is turned over (see the module's documentation), its neighbourhood the merge
/// of its corners' closed rings (each vertex itself and its edge neighbours, as often as each is
/// reached).
///
/// The faces are judged a block at a time; a block measures each ring its corners need once, into
/// a buffer of its own thread kept between calls (see [`RingCache`]), so no per-vertex array is
/// allocated. A ring is the same [`Moments::of`] however often it is measured, so the result does
/// not depend on the blocks.
///
/// A face is judged without Horn's rotation where [`Moments::keeps_facing`] proves that rotation
/// turns its rest normal to within 90° of its normal (the rotation last fitted in the block, a
/// neighbouring face's, near enough): the same faces are flipped either way.
fn flips(
    points: &[DVec3],
    rest: &[DVec3],
    faces: LayoutFaces<'_>,
    starts: &[usize],
    neighbours: &Neighbours,
) -> Vec<bool> {
    flips_cached(
        points,
        rest,
        faces,
        starts,
        neighbours,
        RING_CACHE_SPAN,
        true,
    )
    .0
}

/// [`flips`], its blocks' rings cached when their corners span at most `span` vertex indices, a
/// face proved unflipped by the block's last rotation not fitted when `shortcut`; and how many
/// faces were judged so.
fn flips_cached(
    points: &[DVec3],
    rest: &[DVec3],
    faces: LayoutFaces<'_>,
    starts: &[usize],
    neighbours: &Neighbours,
    span: usize,
    shortcut: bool,
) -> (Vec<bool>, usize) {
    let ring = |vertex: u32| Moments::of_ring(points, rest, vertex, neighbours.of(vertex));
    let mut flipped = vec![false; starts.len()];
    let proved = flipped
        .par_chunks_mut(FACES_PER_BLOCK)
        .zip(starts.par_chunks(FACES_PER_BLOCK))
        .zip(faces.sizes.par_chunks(FACES_PER_BLOCK))
        .map(|((flipped, starts), sizes)| {
            let block = &faces.corners
                [starts[0]..starts[starts.len() - 1] + sizes[sizes.len() - 1] as usize];
            let mut proved = 0usize;
            RING_CACHE.with_borrow_mut(|cache| {
                let cached = cache.start(block, span);
                let mut last: Option<DMat3> = None;
                for ((out, &start), &size) in flipped.iter_mut().zip(starts).zip(sizes) {
                    let corners = &faces.corners[start..start + size as usize];
                    let normal = newell_normal(points, corners);
                    let rest_normal = newell_normal(rest, corners);
                    if normal == DVec3::ZERO || rest_normal == DVec3::ZERO {
                        continue;
                    }
                    let mut group = Moments::default();
                    for &corner in corners {
                        if cached {
                            group.merge(cache.ring(corner, ring));
                        } else {
                            group.merge(&ring(corner));
                        }
                    }
                    if shortcut
                        && last.is_some_and(|rotation| {
                            group.keeps_facing(&rotation, rest_normal, normal)
                        })
                    {
                        proved += 1;
                        continue;
                    }
                    let rotation = group.best_rotation();
                    last = Some(DMat3::from_quat(rotation));
                    let facing = (rotation * rest_normal).dot(normal);
                    *out = facing.is_finite() && facing < 0.0;
                }
            });
            proved
        })
        .sum();
    (flipped, proved)
}

/// The relative slack [`Moments::keeps_facing`] allows for rounding: in the bounds of Horn's
/// eigenvalue and of the largest singular value, in Horn's rotation and in the facing; far above
/// the rounding of the moments' sums and of Horn's rotation.
const PROOF_SLACK: f64 = 1e-9;

/// Faces per block when judging flips: their corners' rings are measured once per block.
const FACES_PER_BLOCK: usize = 8192;

/// The widest range of vertex indices a block's rings are cached for (128 bytes each); a block
/// whose corners spread wider (a layout whose vertices are not numbered near their faces) measures
/// each corner's ring where it is needed.
const RING_CACHE_SPAN: usize = 1 << 16;

thread_local! {
    /// Each rayon thread's ring buffer, kept between calls: no fresh memory per read-out.
    static RING_CACHE: std::cell::RefCell<RingCache> = std::cell::RefCell::new(RingCache::default());
}

/// The rings of one block's corners, by vertex index from the block's lowest, each measured on
/// first use.
#[derive(Default)]
struct RingCache {
    lowest: u32,
    rings: Vec<Moments>,
    measured: Vec<bool>,
}

impl RingCache {
    /// Prepares the cache for a block with these corners; false when they spread wider than
    /// `widest` indices.
    fn start(&mut self, corners: &[u32], widest: usize) -> bool {
        let (Some(&lowest), Some(&highest)) = (corners.iter().min(), corners.iter().max()) else {
            return false;
        };
        let span = (highest - lowest) as usize + 1;
        if span > widest {
            return false;
        }
        self.lowest = lowest;
        if self.rings.len() < span {
            self.rings.resize(span, Moments::default());
        }
        self.measured.clear();
        self.measured.resize(span, false);
        true
    }

    /// The ring of `vertex` (a corner of the started block), measured by `ring` on first use.
    fn ring(&mut self, vertex: u32, ring: impl Fn(u32) -> Moments) -> &Moments {
        let slot = (vertex - self.lowest) as usize;
        if !self.measured[slot] {
            self.rings[slot] = ring(vertex);
            self.measured[slot] = true;
        }
        &self.rings[slot]
    }
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
    let stretch = (0..points.len() as u32)
        .into_par_iter()
        .with_min_len(VERTICES_PER_TASK)
        .map(|vertex| ring_stretch(points, rest, vertex, neighbours.of(vertex)))
        .collect();
    let flipped = flips(points, rest, faces, &starts, &neighbours);
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
        self.distances_of(points.len(), |index| points[index], near, on_surface)
    }

    /// [`TargetMesh::surface_distances`] of the `count` points `point(0..count)` (in the mesh's
    /// coordinates), each computed where it is needed; `near` is as long as they are.
    pub(crate) fn distances_of(
        &self,
        count: usize,
        point: impl Fn(usize) -> DVec3 + Sync,
        near: Option<&[u32]>,
        on_surface: f64,
    ) -> Result<Vec<f64>, KernelError> {
        // In parallel (a million points is milliseconds serially); the first point out of range
        // is the one named.
        let queries: Vec<Vec3> = (0..count)
            .into_par_iter()
            .with_min_len(VERTICES_PER_TASK)
            .map(|index| point(index).as_vec3())
            .collect();
        let beyond = |query: &Vec3| {
            query.is_finite() && crate::validate::check_coordinate("point", 0, *query).is_err()
        };
        if let Some(index) = queries.par_iter().position_first(beyond) {
            crate::validate::check_coordinate("point", index, queries[index])?;
        }
        self.closest_tree();
        Ok((0..count)
            .into_par_iter()
            .with_min_len(crate::query::QUERIES_PER_TASK)
            .map_init(QueryState::default, |state, index| {
                let exact = point(index);
                if !exact.is_finite() || !queries[index].is_finite() {
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
                    let distance = exact.distance(Vec3::from(hit).as_dvec3());
                    if distance <= on_surface && !self.degenerate[start as usize] {
                        return distance;
                    }
                }
                self.closest_point_near(queries[index], f32::INFINITY, start, state)
                    .map_or(f64::INFINITY, |hit| exact.distance(hit.position.as_dvec3()))
            })
            .collect())
    }
}

#[cfg(test)]
mod tests;
