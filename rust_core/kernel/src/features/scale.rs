//! The automatic feature scale: chosen from the target and, when given, the layout's edge length.
//!
//! Why these numbers: a blend reads as one crest only when the surface is fitted over about its
//! radius or more (narrower, its constant curvature is a plateau without a crest, see
//! [`super::ridges`]); a scale of a few mesh edges therefore finds the noise and the edges of
//! every plateau instead, in many short fragments. What an artist constrains a layout to is at
//! the scale of the layout: a feature narrower than a layout edge cannot be followed by an edge
//! chain anyway. So with a layout the scale is its median edge length; without one, a tenth of
//! the target's bounding-box diagonal (the size of a part's main shapes). Either is kept within
//! [`AUTOMATIC_SCALE_MIN_EDGES`] and [`AUTOMATIC_SCALE_MAX_EDGES`] mean target edges: below the
//! first a fit sees too few vertices, above the second each fit gathers more than a few
//! thousand and a fine mesh becomes slow.

use crate::error::KernelError;
use crate::mesh::TargetMesh;
use crate::validate::{MAX_COORDINATE, SettingRange, check_setting};

/// Without a layout, the automatic scale is this fraction of the target's bounding-box diagonal.
pub const AUTOMATIC_SCALE_DIAGONAL_FRACTION: f32 = 0.1;

/// The automatic scale is at least this many mean target edge lengths: a fit over fewer sees a
/// scanned or voxel-remeshed surface's own roughness (on the MakeHuman body remeshed with 4 mm
/// voxels, from a layout of 5.6 mm edges: 632 ridges and 138 valleys at 3 with joins within one
/// scale, most of them the voxels' steps; 281 and 58 at 6 with joins within two).
pub const AUTOMATIC_SCALE_MIN_EDGES: f32 = 6.0;

/// The automatic scale is at most this many mean target edge lengths.
pub const AUTOMATIC_SCALE_MAX_EDGES: f32 = 30.0;

/// The range of a layout edge length (0: no layout).
pub const LAYOUT_EDGE_RANGE: SettingRange = SettingRange::closed(0.0, MAX_COORDINATE as f64);

/// Mean length of the mesh's edges (over its non-degenerate triangles' sides; 0 for none).
#[must_use]
pub fn mean_edge_length(mesh: &TargetMesh) -> f32 {
    let positions = mesh.vertices();
    let (mut sum, mut count) = (0.0f64, 0u64);
    for (corners, &degenerate) in mesh.triangles().iter().zip(mesh.degenerate_triangles()) {
        if degenerate {
            continue;
        }
        for side in 0..3 {
            let (start, end) = (corners[side], corners[(side + 1) % 3]);
            sum += f64::from(positions[start as usize].distance(positions[end as usize]));
            count += 1;
        }
    }
    if count == 0 {
        0.0
    } else {
        (sum / count as f64) as f32
    }
}

/// The feature scale used when none is given: the layout's median edge length
/// (`layout_edge_length`, 0 for no layout) or, without a layout, a tenth of the target's
/// bounding-box diagonal; kept between 3 and 30 mean target edges and at most the diagonal (see
/// the module docs).
///
/// # Errors
/// [`KernelError::InvalidArgument`] for a `layout_edge_length` that is negative, not finite or
/// beyond [`MAX_COORDINATE`]; [`KernelError::InvalidScale`] when the mesh has no extent (all its
/// vertices at one point: there is no scale to choose).
pub fn automatic_scale(mesh: &TargetMesh, layout_edge_length: f32) -> Result<f32, KernelError> {
    check_setting(
        "layout_edge_length",
        "layout edge length",
        layout_edge_length,
        LAYOUT_EDGE_RANGE,
    )?;
    let (min, max) = mesh.bounding_box();
    let diagonal = (max - min).length();
    let edge = mean_edge_length(mesh);
    if !(diagonal > 0.0 && edge > 0.0) {
        return Err(KernelError::InvalidScale {
            scale: 0.0,
            diagonal,
        });
    }
    let wanted = if layout_edge_length > 0.0 {
        layout_edge_length
    } else {
        AUTOMATIC_SCALE_DIAGONAL_FRACTION * diagonal
    };
    let bounded = wanted.clamp(
        AUTOMATIC_SCALE_MIN_EDGES * edge,
        AUTOMATIC_SCALE_MAX_EDGES * edge,
    );
    Ok(bounded.min(diagonal))
}
