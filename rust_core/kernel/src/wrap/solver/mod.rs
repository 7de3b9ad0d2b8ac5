//! The stepping wrap solver: a layout's points moved onto a target a few iterations at a time.
//!
//! It holds the wrap's inputs (the layout, its points, anchors, curve and plane constraints,
//! per-vertex stiffness and free vertices, unreliable triangles) and steps the energy solver
//! (`wrap::energy_solver`): one energy whose weights are the paper's α (fairness), β (arc
//! length), γ_tp (thin plate), γ_con (constraint) and γ_fold (folding), minimised by local–global
//! steps over a stiffness schedule; at the end the points land on the surface as face-points,
//! held points walked onto the plane.

mod anchors;
mod build;
mod plane;
mod step;

use anchors::resolve_anchors;

use std::sync::Arc;

use glam::Vec3;

use super::anchor::{Anchor, AnchorTarget};
use super::curve_constraint::{ArcLengthCurve, CurveConstraint, vertex_fractions};
use super::energy_solver::{EnergyInputs, EnergySolver};
use super::linear_system::SolveStatistics;
use super::plane_constraint::{Plane, PlaneConstraint};
use super::profile::{PhaseClock, PhaseTimes};
use super::settings::WrapSettings;
use super::soft_pair::{SoftPair, SoftPairOfVertex};
use crate::error::KernelError;
use crate::face_point::{FacePoint, LayoutPoint};
use crate::layout::LayoutStructure;
use crate::mesh::{NO_TRIANGLE, TargetMesh};
use crate::surface::WalkEnd;
use crate::validate;

/// Points may move this many times the size of the target (or of the layout's start, if
/// larger) from the target's centre; beyond, the wrap has diverged.
const REACH_FACTOR: f32 = 10.0;
/// A point held on the plane is on it within this fraction of the layout's size.
const ON_PLANE: f32 = 1e-7;
/// Walks that bring a held face-point back onto the plane (each one is exact within a triangle,
/// so one or two suffice unless the point crosses an edge).
const PLANE_WALKS: usize = 4;
/// Below this squared sine between the surface's normal and the plane's, the surface runs along
/// the plane there and walking across it cannot reach the plane.
const PLANE_GRAZING: f32 = 1e-6;

/// Progress of [`WrapSolver::step`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    /// Iterations run by this call.
    pub iterations: usize,
    /// Iterations run since the solver was made.
    pub total_iterations: usize,
    /// Largest displacement of the last iteration, as a fraction of the layout's size.
    pub max_displacement: f32,
    /// Mean displacement of the last iteration, as a fraction of the layout's size.
    pub mean_displacement: f32,
    /// The stiffness schedule is done and the points have landed.
    pub converged: bool,
    /// Face-points now.
    pub face_points: usize,
    /// Space-points now.
    pub space_points: usize,
    /// Anchored points on the surface at the landing (during this call).
    pub landed: usize,
    /// Free points that landed on the surface at the end (during this call).
    pub folded: usize,
    /// The energy after the last iteration.
    pub energy: f64,
    /// Points whose last step was shortened or refused so that no layout face turned over.
    pub held_back: usize,
    /// How much the last iteration lowered the energy, relative to the energy before it (each
    /// stiffness level ends below the tolerance); NaN for a level's first iteration.
    pub energy_decrease: f64,
}

/// A wrap in progress: the layout's points on (or near) a target, moved a few iterations at a time.
#[derive(Debug, Clone)]
pub struct WrapSolver {
    target: Arc<TargetMesh>,
    structure: LayoutStructure,
    settings: WrapSettings,
    points: Vec<LayoutPoint>,
    positions: Vec<Vec3>,
    anchor_of_vertex: Vec<Option<(AnchorTarget, Vec3)>>,
    /// Target triangles whose data is not to be trusted (noise); empty when all are.
    unreliable: Vec<bool>,
    /// The target's adjacency with the edges into unreliable triangles cut (walks stop there as at
    /// a hole); `None` when every triangle is reliable.
    walk_neighbors: Option<Vec<[u32; 3]>>,
    /// For each curve-constrained (and not anchored) vertex, its fixed point on the target curve.
    curve_target_of_vertex: Vec<Option<Vec3>>,
    /// The mirror plane and, per vertex, whether it is held on it (empty: no plane constraint).
    plane: Option<Plane>,
    on_plane: Vec<bool>,
    /// Whether held points slide along the cross-section (else they stay where they start).
    plane_slide: bool,
    layout_size: f32,
    landing_distance: f32,
    total_iterations: usize,
    /// The rest shape (the template).
    rest: Vec<Vec3>,
    mean_edge_length: f32,
    /// Per vertex, how firmly it keeps the template's shape (0 … 1, 0.5 the wrap's own balance);
    /// empty: 0.5 everywhere.
    stiffness: Vec<f32>,
    /// Per vertex, whether it has no pull toward the target (a socket, teeth); empty: none.
    free: Vec<bool>,
    /// Per vertex, its soft pair's point and confidence; empty: none.
    soft_pairs: SoftPairOfVertex,
    /// The energy solver, made at the first step.
    energy: Option<Box<EnergySolver>>,
    /// The clock that times the energy solver's phases (`None`: no profile).
    profile: Option<PhaseClock>,
    /// The region the points may reach: a centre and a radius (ten times the target's size and
    /// the layout's start about the target's centre); leaving it is divergence.
    reach: (Vec3, f32),
    /// Set once the wrap diverged or a step was cancelled: every later step returns it.
    failed: Option<KernelError>,
    /// The start is a wrap's own result, wrapped again ([`WrapSolver::with_settled_start`]).
    settled_start: bool,
    /// The wrap re-settles a region started again, the rest held ([`WrapSolver::with_region_restart`]).
    region_restart: bool,
}

impl WrapSolver {
    /// The layout points (face- or space-points), one per layout vertex.
    #[must_use]
    pub fn points(&self) -> &[LayoutPoint] {
        &self.points
    }

    /// The positions of the layout points.
    #[must_use]
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// The settings in use.
    #[must_use]
    pub fn settings(&self) -> &WrapSettings {
        &self.settings
    }

    /// Times each phase of the energy solver's setup and iterations by `clock` from the next
    /// step that makes it (set before the first step); read them with
    /// [`WrapSolver::phase_times`].
    pub fn profile_with(&mut self, clock: PhaseClock) {
        self.profile = Some(clock);
    }

    /// The seconds of each phase so far (all zero without [`WrapSolver::profile_with`]).
    #[must_use]
    pub fn phase_times(&self) -> PhaseTimes {
        self.energy
            .as_ref()
            .map_or_else(PhaseTimes::default, |energy| energy.phase_times())
    }

    /// How the energy solver's global steps were solved so far (factorizations, iterations).
    #[must_use]
    pub fn solve_statistics(&self) -> SolveStatistics {
        self.energy
            .as_ref()
            .map_or_else(SolveStatistics::default, |energy| energy.solve_statistics())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TargetMeshOptions;

    /// A flat square target and a 3 x 3 quad layout floating 0.2 above it.
    fn plane_and_layout() -> (Arc<TargetMesh>, LayoutStructure, Vec<LayoutPoint>) {
        let vertices = vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        let target = Arc::new(
            TargetMesh::new(
                vertices,
                vec![[0, 1, 2], [0, 2, 3]],
                TargetMeshOptions::default(),
            )
            .unwrap(),
        );
        let mut corners = Vec::new();
        for y in 0..3u32 {
            for x in 0..3u32 {
                let a = y * 4 + x;
                corners.extend([a, a + 1, a + 5, a + 4]);
            }
        }
        let structure = LayoutStructure::new(16, &corners, &[4; 9], &[], &[]).unwrap();
        let points = (0..16)
            .map(|index| {
                let (x, y) = ((index % 4) as f32, (index / 4) as f32);
                LayoutPoint::Space(Vec3::new(x * 0.2 - 0.3, y * 0.2 - 0.3, 0.2))
            })
            .collect();
        (target, structure, points)
    }

    #[test]
    fn a_wrap_that_leaves_its_reach_is_rolled_back_and_stays_failed() {
        let (target, structure, points) = plane_and_layout();
        let settings = WrapSettings::default();
        let mut solver = WrapSolver::new(target, structure, points, &[], settings).unwrap();
        let start = solver.positions().to_vec();
        // A reach smaller than the layout: the first step leaves it.
        solver.reach = (Vec3::new(0.0, 0.0, 10.0), 1e-3);
        let error = solver.step(5).unwrap_err();
        assert!(matches!(error, KernelError::Diverged { .. }), "{error:?}");
        assert_eq!(solver.positions(), start.as_slice());
        assert_eq!(solver.step(1).unwrap_err(), error);
    }
}
