//! Principal curvatures and directions per vertex, fitted over a scale.
//!
//! Method: for each vertex, the vertices within `scale` of it (reached along edges, see
//! [`super::neighborhood::gather`]) are expressed in a frame whose normal is the weighted mean of
//! their vertex normals, and a height function `h(u, w) = a u² + b uw + c w² + d u + e w + f` is
//! fitted to them by weighted least squares (weights `(1 − (r/scale)²)²`). The curvatures are
//! those of that graph at the vertex (its first and second fundamental forms), so the linear
//! terms absorb a tilted normal and the constant one a noisy centre vertex. Everything smaller
//! than the scale averages out: the scale is the size below which bumps count as noise (and
//! the radius up to which a blend is measured as one curve).
//!
//! Why a quadric fit rather than per-triangle tensors (Rusinkiewicz 2004): tensors measure the
//! mesh at the scale of its edges, so scan noise of the order of an edge length swamps them and
//! they must then be smoothed, which biases them towards zero; a fit over a metric radius gives
//! the curvature *at* that radius whatever the tessellation (a test checks a noisy sphere).
//!
//! Sign convention: curvatures are positive where the surface bends away from its outward normal
//! (the side the triangles' right-handed winding points to): convex, e.g. `+1/r` on a sphere of
//! radius `r` with outward normals; concave is negative. `k1 ≥ k2`; `d1` is the direction of `k1`,
//! `d2 = n × d1`, both unit and tangent.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::neighborhood::{Scratch, VertexAdjacency, gather};
use crate::align::linear_algebra::cholesky_solve;
use crate::error::KernelError;
use crate::mesh::TargetMesh;

/// Per-vertex principal curvatures and directions (see the module docs for the convention).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PrincipalCurvatures {
    /// The scale they were fitted over.
    pub scale: f32,
    /// Largest curvature per vertex (1 / length; positive = convex).
    pub k1: Vec<f32>,
    /// Smallest curvature per vertex.
    pub k2: Vec<f32>,
    /// Unit direction of `k1` per vertex (zero for vertices on no triangle).
    pub d1: Vec<Vec3>,
    /// Unit direction of `k2` per vertex, `normal × d1`.
    pub d2: Vec<Vec3>,
    /// The fitted unit normal per vertex.
    pub normals: Vec<Vec3>,
}

/// The fewest vertices a fit uses: below it, rings beyond the scale are added.
const MIN_FIT_VERTICES: usize = 16;

/// Coefficients of the fitted height function: quadric, linear, constant and the quartic terms.
const FIT_TERMS: usize = 11;

/// Checks a feature scale: positive, finite and no larger than the mesh's bounding-box diagonal.
///
/// # Errors
/// [`KernelError::InvalidScale`].
pub fn check_scale(mesh: &TargetMesh, scale: f32) -> Result<(), KernelError> {
    let (min, max) = mesh.bounding_box();
    let diagonal = (max - min).length();
    if !scale.is_finite() || scale <= 0.0 || scale > diagonal {
        return Err(KernelError::InvalidScale { scale, diagonal });
    }
    Ok(())
}

/// Principal curvatures and directions of every vertex, fitted over `scale` (a radius in model
/// units), in parallel.
///
/// # Errors
/// [`KernelError::InvalidScale`] when `scale` is not positive and finite or exceeds the mesh's
/// bounding-box diagonal.
pub fn principal_curvatures(
    mesh: &TargetMesh,
    scale: f32,
) -> Result<PrincipalCurvatures, KernelError> {
    check_scale(mesh, scale)?;
    let positions = mesh.vertices();
    let vertex_normals = mesh.vertex_normals();
    let adjacency = VertexAdjacency::new(positions.len(), mesh.triangles());
    let fits: Vec<VertexCurvature> = (0..positions.len() as u32)
        .into_par_iter()
        .with_min_len(512)
        .map_init(
            || (Scratch::new(positions.len()), Vec::new()),
            |(scratch, neighborhood), vertex| {
                if vertex_normals[vertex as usize] == Vec3::ZERO {
                    return VertexCurvature::default();
                }
                gather(
                    positions,
                    &adjacency,
                    vertex,
                    scale,
                    MIN_FIT_VERTICES,
                    scratch,
                    neighborhood,
                );
                fit_vertex(positions, vertex_normals, vertex, neighborhood, scale)
            },
        )
        .collect();
    let mut result = PrincipalCurvatures {
        scale,
        k1: Vec::with_capacity(fits.len()),
        k2: Vec::with_capacity(fits.len()),
        d1: Vec::with_capacity(fits.len()),
        d2: Vec::with_capacity(fits.len()),
        normals: Vec::with_capacity(fits.len()),
    };
    for fit in fits {
        result.k1.push(fit.k1);
        result.k2.push(fit.k2);
        result.d1.push(fit.d1);
        result.d2.push(fit.d2);
        result.normals.push(fit.normal);
    }
    Ok(result)
}

#[derive(Debug, Clone, Copy, Default)]
struct VertexCurvature {
    k1: f32,
    k2: f32,
    d1: Vec3,
    d2: Vec3,
    normal: Vec3,
}

/// The quadric fit of one vertex over its neighbourhood (the vertex first).
fn fit_vertex(
    positions: &[Vec3],
    vertex_normals: &[Vec3],
    vertex: u32,
    neighborhood: &[u32],
    scale: f32,
) -> VertexCurvature {
    let origin = positions[vertex as usize].as_dvec3();
    // The ball may have been widened by whole rings: weigh over the farthest vertex used.
    let farthest = neighborhood
        .iter()
        .map(|&index| positions[index as usize].as_dvec3().distance(origin))
        .fold(0.0f64, f64::max);
    let radius = f64::from(scale).max(farthest) * 1.0001;
    let weight_of = |distance: f64| {
        let t = (distance / radius).powi(2);
        (1.0 - t) * (1.0 - t)
    };
    let mut normal_sum = DVec3::ZERO;
    for &index in neighborhood {
        let distance = positions[index as usize].as_dvec3().distance(origin);
        normal_sum += vertex_normals[index as usize].as_dvec3() * weight_of(distance);
    }
    let normal = normal_sum
        .try_normalize()
        .unwrap_or_else(|| vertex_normals[vertex as usize].as_dvec3());
    let (u_axis, w_axis) = normal.any_orthonormal_pair();

    // Normal equations of the coefficients, in coordinates divided by the radius.
    let mut matrix = [[0.0f64; FIT_TERMS]; FIT_TERMS];
    let mut rhs = [0.0f64; FIT_TERMS];
    for &index in neighborhood {
        let offset = (positions[index as usize].as_dvec3() - origin) / radius;
        let weight = weight_of(offset.length() * radius);
        let (u, w, h) = (offset.dot(u_axis), offset.dot(w_axis), offset.dot(normal));
        let (uu, ww) = (u * u, w * w);
        let basis = [
            uu,
            u * w,
            ww,
            u,
            w,
            1.0,
            uu * uu,
            uu * u * w,
            uu * ww,
            u * w * ww,
            ww * ww,
        ];
        // The lower triangle only (the matrix is symmetric): half the work of the whole fit.
        for row in 0..FIT_TERMS {
            let weighted = weight * basis[row];
            for column in 0..=row {
                matrix[row][column] += weighted * basis[column];
            }
            rhs[row] += weighted * h;
        }
    }
    #[allow(clippy::needless_range_loop)] // a transpose reads one index pair both ways
    for row in 0..FIT_TERMS {
        for column in row + 1..FIT_TERMS {
            matrix[row][column] = matrix[column][row];
        }
    }
    let trace: f64 = (0..FIT_TERMS).map(|i| matrix[i][i]).sum();
    for (i, row) in matrix.iter_mut().enumerate() {
        row[i] += 1e-9 * trace;
    }
    let Some(coefficients) = cholesky_solve(&matrix, &rhs) else {
        return VertexCurvature {
            normal: normal.as_vec3(),
            ..VertexCurvature::default()
        };
    };
    // Back to model units: h = a u² + ... with u in units of the radius.
    let [a, b, c] = [0, 1, 2].map(|i| coefficients[i] / radius);
    let [d, e] = [coefficients[3], coefficients[4]];
    shape_of_graph(a, b, c, d, e, normal, u_axis, w_axis)
}

/// Principal curvatures and directions of the graph `h = a u² + b uw + c w² + d u + e w` (over the
/// frame `u_axis`, `w_axis`, `normal`) at `u = w = 0`, convex positive.
#[allow(clippy::too_many_arguments, clippy::many_single_char_names)] // the textbook names
fn shape_of_graph(
    a: f64,
    b: f64,
    c: f64,
    d: f64,
    e: f64,
    normal: DVec3,
    u_axis: DVec3,
    w_axis: DVec3,
) -> VertexCurvature {
    // First fundamental form of (u, w, h(u, w)).
    let (big_e, big_f, big_g) = (1.0 + d * d, d * e, 1.0 + e * e);
    let length = (1.0 + d * d + e * e).sqrt();
    // Second fundamental form against the surface normal on the -h side, so convex is positive.
    let (big_l, big_m, big_n) = (-2.0 * a / length, -b / length, -2.0 * c / length);
    let determinant = big_e * big_g - big_f * big_f;
    let mean = (big_e * big_n + big_g * big_l - 2.0 * big_f * big_m) / (2.0 * determinant);
    let gaussian = (big_l * big_n - big_m * big_m) / determinant;
    let root = (mean * mean - gaussian).max(0.0).sqrt();
    let (k1, k2) = (mean + root, mean - root);
    // (II − k1 I) x = 0: either row gives x; take the longer for accuracy.
    let first = [big_m - k1 * big_f, -(big_l - k1 * big_e)];
    let second = [big_n - k1 * big_g, -(big_m - k1 * big_f)];
    let pick = if first[0].hypot(first[1]) >= second[0].hypot(second[1]) {
        first
    } else {
        second
    };
    let fitted_normal = (normal - d * u_axis - e * w_axis).normalize();
    let tangent_u = u_axis + d * normal;
    let tangent_w = w_axis + e * normal;
    let direction = (pick[0] * tangent_u + pick[1] * tangent_w)
        .try_normalize()
        .unwrap_or_else(|| tangent_u.normalize());
    // Project onto the fitted tangent plane (rounding), then d2 completes the frame.
    let d1 = (direction - fitted_normal * direction.dot(fitted_normal)).normalize_or_zero();
    let d2 = fitted_normal.cross(d1);
    VertexCurvature {
        k1: k1 as f32,
        k2: k2 as f32,
        d1: d1.as_vec3(),
        d2: d2.as_vec3(),
        normal: fitted_normal.as_vec3(),
    }
}
