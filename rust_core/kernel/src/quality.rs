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
        for (face, &start) in starts.iter().enumerate() {
            let end = start + self.sizes[face] as usize;
            if let Some(&vertex) = self.corners[start..end]
                .iter()
                .find(|&&vertex| vertex as usize >= vertex_count)
            {
                return Err(KernelError::LayoutIndexOutOfRange {
                    element: "face",
                    index: face,
                    vertex,
                    vertex_count,
                });
            }
        }
        Ok(starts)
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

fn check_edges(edges: &[[u32; 2]], vertex_count: usize) -> Result<(), KernelError> {
    for (index, edge) in edges.iter().enumerate() {
        if let Some(&vertex) = edge.iter().find(|&&vertex| vertex as usize >= vertex_count) {
            return Err(KernelError::LayoutIndexOutOfRange {
                element: "edge",
                index,
                vertex,
                vertex_count,
            });
        }
    }
    Ok(())
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
    offsets: Vec<usize>,
    neighbours: Vec<u32>,
}

impl Neighbours {
    fn new(edges: &[[u32; 2]], vertex_count: usize) -> Self {
        let mut offsets = vec![0usize; vertex_count + 1];
        for &[a, b] in edges {
            offsets[a as usize + 1] += 1;
            offsets[b as usize + 1] += 1;
        }
        for index in 0..vertex_count {
            offsets[index + 1] += offsets[index];
        }
        let mut next = offsets.clone();
        let mut neighbours = vec![0u32; offsets[vertex_count]];
        for &[a, b] in edges {
            for (from, to) in [(a, b), (b, a)] {
                neighbours[next[from as usize]] = to;
                next[from as usize] += 1;
            }
        }
        Self {
            offsets,
            neighbours,
        }
    }

    fn of(&self, vertex: u32) -> &[u32] {
        &self.neighbours[self.offsets[vertex as usize]..self.offsets[vertex as usize + 1]]
    }
}

/// The proper rotation that best takes the rest points of `group` onto their points now (about
/// their centroids); the identity when nothing can be fitted. Vertices not finite in both shapes
/// are left out.
fn best_rotation(
    points: &[DVec3],
    rest: &[DVec3],
    group: impl Iterator<Item = u32> + Clone,
) -> glam::DQuat {
    // Sums relative to the group's first usable vertex, then centred: one pass, precise far from
    // the origin.
    let usable =
        |vertex: &u32| points[*vertex as usize].is_finite() && rest[*vertex as usize].is_finite();
    let Some(first) = group.clone().find(usable) else {
        return glam::DQuat::IDENTITY;
    };
    let (origin_now, origin_rest) = (points[first as usize], rest[first as usize]);
    let mut count = 0.0f64;
    let (mut sum_now, mut sum_rest) = (DVec3::ZERO, DVec3::ZERO);
    let mut cross = [[0.0f64; 3]; 3];
    for vertex in group.filter(usable) {
        let now = points[vertex as usize] - origin_now;
        let before = rest[vertex as usize] - origin_rest;
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
    let (mean_now, mean_rest) = ((sum_now / count).to_array(), (sum_rest / count).to_array());
    for (row, out) in cross.iter_mut().enumerate() {
        for (column, value) in out.iter_mut().enumerate() {
            *value -= count * mean_rest[row] * mean_now[column];
            if !value.is_finite() {
                *value = 0.0;
            }
        }
    }
    fast_horn_rotation(&cross)
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
    Ok(starts
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
            let group = corners.iter().copied().chain(
                corners
                    .iter()
                    .flat_map(|&corner| neighbours.of(corner).iter().copied()),
            );
            let facing = (best_rotation(points, rest, group) * rest_normal).dot(normal);
            facing.is_finite() && facing < 0.0
        })
        .collect())
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
