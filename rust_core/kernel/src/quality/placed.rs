//! The quality read-out of a layout as its object stores it, in one call: its local f32 positions
//! (and rest shape) placed in the world by the object's transform, measured on a target whose
//! coordinates are the world's less an origin.
//!
//! The result is the one of the read-out's separate steps (the positions and the rest shape taken
//! to the world in f64, [`layout_readout`] on them, [`TargetMesh::surface_distances`] of the
//! positions in the target's frame), without handing world copies between them: the world
//! positions are made once, in parallel, and the distances' frame is taken point by point.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{LayoutFaces, LayoutReadout, VERTICES_PER_TASK, layout_readout};
use crate::align::Transform;
use crate::error::KernelError;
use crate::mesh::TargetMesh;

/// A layout as its object stores it.
#[derive(Debug, Clone, Copy)]
pub struct PlacedLayout<'a> {
    /// The positions in the object's space, as stored (f32).
    pub positions: &'a [Vec3],
    /// The rest shape in the object's space (the template as made), as long as `positions`;
    /// `None`: no rest shape.
    pub rest: Option<&'a [Vec3]>,
    /// The object's transform: its space to the world.
    pub to_world: &'a Transform,
    /// The layout's faces.
    pub faces: LayoutFaces<'a>,
    /// Every edge of the layout (those on no face too), as vertex pairs.
    pub edges: &'a [[u32; 2]],
}

/// The target the distances are measured to, and where each search starts.
#[derive(Debug, Clone, Copy)]
pub struct DistanceTarget<'a> {
    /// The target; its coordinates are world coordinates less `origin`.
    pub mesh: &'a TargetMesh,
    /// The world position of the mesh's origin.
    pub origin: DVec3,
    /// As `near` of [`TargetMesh::surface_distances`], one per layout vertex.
    pub near: Option<&'a [u32]>,
    /// As `on_surface` of [`TargetMesh::surface_distances`] (world units).
    pub on_surface: f64,
}

/// The whole quality read-out of a placed layout.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacedReadout {
    /// Per vertex, the distance from its world position to the target's surface (world units;
    /// infinite for a non-finite position).
    pub distances: Vec<f64>,
    /// The stretch, the flips and the world bounding-box diagonal, as [`layout_readout`] of the
    /// world positions and rest shape.
    pub layout: LayoutReadout,
}

/// The read-out of `layout` on `target`: each position and rest point taken to the world in f64
/// ([`Transform::apply_f64`]), then [`layout_readout`] of them and the distances of the world
/// positions to the target. A rest shape with a point that is not finite in the world is no
/// usable rest shape (the stretch reads 1, no face is flipped), as when there is none.
///
/// # Errors
/// [`KernelError::LengthMismatch`] when the rest shape or `near` differs from the positions in
/// length, or the face sizes do not add up to the corners; as [`layout_readout`] for faces or
/// edges naming a vertex that does not exist; [`KernelError::CoordinateOutOfRange`] for a
/// position beyond [`crate::MAX_COORDINATE`] in the target's frame.
pub fn placed_readout(
    layout: PlacedLayout<'_>,
    target: DistanceTarget<'_>,
) -> Result<PlacedReadout, KernelError> {
    let count = layout.positions.len();
    for (what, length) in [
        ("positions and rest points", layout.rest.map(<[Vec3]>::len)),
        (
            "positions and near triangles",
            target.near.map(<[u32]>::len),
        ),
    ] {
        if let Some(length) = length.filter(|&length| length != count) {
            return Err(KernelError::LengthMismatch {
                what,
                first: count,
                second: length,
            });
        }
    }
    let world = to_world(layout.to_world, layout.positions);
    let rest = layout
        .rest
        .map(|rest| to_world(layout.to_world, rest))
        .filter(|rest| rest.par_iter().all(|point| point.is_finite()));
    let measures = layout_readout(&world, rest.as_deref(), layout.faces, layout.edges)?;
    drop(rest);
    let origin = target.origin;
    let distances = target.mesh.distances_of(
        count,
        |index| world[index] - origin,
        target.near,
        target.on_surface,
    )?;
    Ok(PlacedReadout {
        distances,
        layout: measures,
    })
}

/// `points` taken to the world by `to_world`, in f64, in parallel.
fn to_world(to_world: &Transform, points: &[Vec3]) -> Vec<DVec3> {
    points
        .par_iter()
        .with_min_len(VERTICES_PER_TASK)
        .map(|point| to_world.apply_f64(point.as_dvec3()))
        .collect()
}
