//! Anchors: resolved against the target when the wrap is built, and replaced between steps
//! ([`WrapSolver::set_anchors`]) without building the wrap anew.

use super::*;

impl WrapSolver {
    /// Replaces the anchors between two steps (an anchor dragged while the wrap runs): the points
    /// stay where they are and the stiffness schedule starts again from its warm-up, as a wrap
    /// built anew from them with these anchors would. With the same vertices anchored (targets
    /// moved) the linear system and its factor are kept and only its constrained part changes;
    /// otherwise the energy is set up again at the next step. Curve and plane constraints stay as
    /// built (a curve vertex anchored since follows its anchor).
    ///
    /// # Errors
    /// As [`WrapSolver::new`] for a bad anchor (the solver is then unchanged); the error of a
    /// wrap that diverged or whose step was cancelled.
    pub fn set_anchors(&mut self, anchors: &[Anchor]) -> Result<(), KernelError> {
        if let Some(error) = &self.failed {
            return Err(error.clone());
        }
        let anchor_of_vertex =
            resolve_anchors(&self.target, self.points.len(), anchors, self.reach)?;
        let same_vertices = anchor_of_vertex
            .iter()
            .zip(&self.anchor_of_vertex)
            .all(|(new, old)| new.is_some() == old.is_some());
        self.anchor_of_vertex = anchor_of_vertex;
        if let Some(energy) = self.energy.as_mut()
            && same_vertices
            && energy.move_anchors(&self.anchor_of_vertex).is_ok()
        {
            return Ok(());
        }
        self.energy = None; // set up again at the next step, from the points as they are
        Ok(())
    }

    /// The anchors' targets, per layout vertex: the target and where it is.
    #[must_use]
    pub fn anchor_targets(&self) -> &[Option<(AnchorTarget, Vec3)>] {
        &self.anchor_of_vertex
    }
}

/// Per layout vertex, its anchor's target and where that is on (or off) `target`.
///
/// # Errors
/// [`KernelError::InvalidArgument`] for an anchor on a vertex that does not exist or on the same
/// vertex twice, or a barycentric weight out of range; [`KernelError::TriangleIndexOutOfRange`]
/// (named as the anchor's), [`KernelError::NonFinite`], [`KernelError::CoordinateOutOfRange`]
/// or [`KernelError::BeyondReach`] for a bad target.
pub(super) fn resolve_anchors(
    target: &TargetMesh,
    vertex_count: usize,
    anchors: &[Anchor],
    reach: (Vec3, f32),
) -> Result<Vec<Option<(AnchorTarget, Vec3)>>, KernelError> {
    let mut anchor_of_vertex = vec![None; vertex_count];
    for (index, anchor) in anchors.iter().enumerate() {
        let slot = anchor_of_vertex
            .get_mut(anchor.vertex as usize)
            .ok_or_else(|| KernelError::InvalidArgument {
                name: "anchors",
                reason: format!(
                    "anchor {index} is on vertex {}, but the layout has {} vertices",
                    anchor.vertex, vertex_count
                ),
            })?;
        if slot.is_some() {
            return Err(KernelError::InvalidArgument {
                name: "anchors",
                reason: format!("vertex {} has more than one anchor", anchor.vertex),
            });
        }
        let position = match anchor.target {
            AnchorTarget::Face(face_point) => {
                validate::check_barycentric("anchor barycentric", index, face_point.barycentric)?;
                target
                    .face_point_position(face_point)
                    .map_err(|error| relabel_anchor_error(error, index))?
            }
            AnchorTarget::Space(position) => {
                validate::check_coordinate("anchor target", index, position)?;
                validate::check_within_reach("anchor target", index, position, reach)?;
                position
            }
        };
        *slot = Some((anchor.target, position));
    }
    Ok(anchor_of_vertex)
}

/// A face-point error about anchor targets names the anchor, not a face-point.
fn relabel_anchor_error(error: KernelError, anchor: usize) -> KernelError {
    match error {
        KernelError::TriangleIndexOutOfRange {
            triangle,
            triangle_count,
            ..
        } => KernelError::InvalidArgument {
            name: "anchors",
            reason: format!(
                "anchor {anchor} targets triangle {triangle}, but the target has only {triangle_count} triangles"
            ),
        },
        KernelError::NonFinite { .. } => KernelError::NonFinite {
            what: "anchor target",
            index: anchor,
        },
        other => other,
    }
}
