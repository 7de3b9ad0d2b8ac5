//! The stepping wrap solver: every iteration moves every layout point by its resultant force.
//!
//! `F = α F_fair + β F_arc + γ_tp F_tp + γ_con F_con + γ_fold F_fold` (paper, section 2.5), computed
//! Jacobi-style from a snapshot of the positions, in parallel. Then:
//!
//! - a **face-point** walks along the surface by the tangential part of its force (triangle to
//!   triangle, no BVH query); walking off a boundary edge lifts it to a space-point;
//! - a **space-point** moves freely in 3D, also feeling the thin-plate force; an anchored one whose
//!   anchor is on the surface *lands* there once closer than the landing distance; one next to a
//!   face-point *folds*: its offset from that seed is marched along the surface and, when the angle
//!   between where it is and where the march ends is within the folding tolerance, it lands there,
//!   otherwise it is rotated by the fraction γ_fold toward it;
//! - the folding tolerance **anneals**: it grows while nothing folds and shrinks when many points
//!   fold at once (the paper's simulated annealing), so the user never sets it.

mod build;
mod fold;
mod plane;
mod point_update;
mod step;

use std::sync::Arc;

use glam::{Quat, Vec3};
use rayon::prelude::*;

use super::anchor::{Anchor, AnchorTarget};
use super::curve_constraint::{ArcLengthCurve, CurveConstraint, chain_fractions};
use super::energy_solver::{EnergyInputs, EnergySolver};
use super::forces::{Similarity, SpringRest, Springs, thin_plate};
use super::plane_constraint::{Plane, PlaneConstraint};
use super::settings::{SolverKind, WrapSettings};
use super::soft_pair::{SoftPair, SoftPairOfVertex};
use crate::error::KernelError;
use crate::face_point::{FacePoint, LayoutPoint};
use crate::layout::LayoutStructure;
use crate::mesh::{NO_TRIANGLE, TargetMesh};
use crate::surface::WalkEnd;
use crate::validate;

/// Bounds of the annealed folding tolerance, in radians.
const FOLD_TOLERANCE_RANGE: (f32, f32) = (
    0.5 * std::f32::consts::PI / 180.0,
    std::f32::consts::FRAC_PI_4,
);
/// A space-point whose offset from a seed turns more than this from the surface's way does not
/// fold around that seed (radians).
const FOLD_MAX_ANGLE: f32 = 75.0 * std::f32::consts::PI / 180.0;
/// A space-point folds only onto surface facing the same way as the layout around it, within
/// this cosine (75°): a layout region facing away from the surface (the inside of a mouth bag or
/// an eye socket pressed against the face) would land inside out.
const FOLD_MIN_FACING: f32 = 0.26;
/// At convergence no point moves more than this many times the tolerance (the mean move is below
/// it): a few points rocking in a crease do not hold the wrap up, a region still sliding does.
const MAX_MOVE_AT_CONVERGENCE: f32 = 100.0;
/// Converged only after this many iterations without a change of state: folding comes in bursts
/// as its tolerance anneals (from its least to its largest in about 30 iterations).
const QUIET_ITERATIONS: usize = 32;
/// An iteration is quiet when at most one point in this many changed state.
const QUIET_CHANGES_PER_POINT: usize = 2000;
/// Every this many iterations, free space-points touching the surface land on it.
const PROXIMITY_INTERVAL: usize = 4;
/// A space-point touches the surface within this fraction of its mean edge length...
const PROXIMITY_REACH: f32 = 0.1;
/// ... facing the way the layout does there within this cosine (45 degrees).
const PROXIMITY_FACING: f32 = std::f32::consts::FRAC_1_SQRT_2;
/// A face-point whose layout faces against the surface by more than this cosine (120 degrees)
/// lifts off.
const INSIDE_OUT: f32 = -0.5;
/// The facing check waits for this many face-points with a normal...
const ORIENTATION_MIN_POINTS: usize = 16;
/// ... whose mean agreement with the target's normals (cosine) is at least this, either way.
const ORIENTATION_AGREEMENT: f32 = 0.5;
/// Weight of the newest move in a point's moving averages.
const MOVE_AVERAGING: f32 = 0.25;
/// A point rocks when its mean move is shorter than this fraction of its mean move length.
const ROCKING: f32 = 0.3;
/// The smallest step scale a rocking point is slowed to.
const MIN_STEP_SCALE: f32 = 1.0 / 1024.0;
/// Iterations a point may not fold after its first lift off a boundary; doubled at every lift.
const FOLD_BACK_OFF: usize = 2;
/// A target curve point lies on the surface when this close to it, as a fraction of the landing
/// distance.
const ON_CURVE: f32 = 1e-2;
/// Aim of the annealing: the fraction of foldable points that fold in one iteration.
const FOLD_FRACTION_HIGH: f32 = 0.25;
/// Points may move this many times the size of the target (or of the layout's start, if
/// larger) from the target's centre; beyond, the wrap has diverged.
const REACH_FACTOR: f32 = 10.0;
/// A point held on the plane is on it within this fraction of the layout's size.
const ON_PLANE: f32 = 1e-7;
/// Walks that bring a held face-point back onto the plane after each move (each one is exact
/// within a triangle, so one or two suffice unless the point crosses an edge).
const PLANE_WALKS: usize = 4;
/// Below this squared sine between the surface's normal and the plane's, the surface runs along
/// the plane there and walking across it cannot reach the plane.
const PLANE_GRAZING: f32 = 1e-6;

/// What one point's update did, besides moving.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Event {
    None,
    /// A space-point landed on its anchor's surface point.
    Landed,
    /// A space-point folded onto the surface.
    Folded,
    /// A space-point could fold (it has a face-point neighbour) but did not this time.
    FoldCandidate,
    /// A face-point walked off a boundary and became a space-point.
    Lifted,
}

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
    /// The last iteration moved the points by less than the tolerance on average, none by more
    /// than a hundred times it, and for a while (32 iterations) no more than one point in 2,000
    /// changed state per iteration.
    pub converged: bool,
    /// Face-points now.
    pub face_points: usize,
    /// Space-points now.
    pub space_points: usize,
    /// Space-points that landed on their anchors during this call.
    pub landed: usize,
    /// Space-points that folded onto the surface during this call.
    pub folded: usize,
    /// Face-points lifted off boundaries during this call.
    pub lifted: usize,
    /// The annealed folding tolerance now, in radians.
    pub fold_tolerance: f32,
    /// The energy after the last iteration (the energy solver; NaN for the spring solver).
    pub energy: f64,
    /// Points whose last step was shortened or refused so that no layout face turned over (the
    /// energy solver; 0 for the spring solver).
    pub held_back: usize,
    /// How much the last iteration lowered the energy, relative to the energy before it: what
    /// the energy solver stops on (each stiffness level ends below 0.2 %); NaN for the spring
    /// solver and for a level's first iteration.
    pub energy_decrease: f64,
}

/// A wrap in progress: the layout's points on (or near) a target, moved a few iterations at a time.
#[derive(Debug, Clone)]
pub struct WrapSolver {
    target: Arc<TargetMesh>,
    structure: LayoutStructure,
    springs: Springs,
    /// Per vertex, the similarity from its rest neighbourhood to its current one (refined each
    /// iteration from the last).
    similarities: Vec<Similarity>,
    /// The template's scale on the target: the median of the vertices' own scales, updated every
    /// iteration. One scale for all: with a scale per vertex, nothing would keep a region from
    /// shrinking (small dense quads at toes and eyelids collapse and flip); with one, the
    /// template's proportions are kept, a morph's stretch is shared out by the springs, and the
    /// layout still grows or shrinks as a whole to where its anchors put it.
    global_scale: f32,
    settings: WrapSettings,
    points: Vec<LayoutPoint>,
    positions: Vec<Vec3>,
    /// Each point's move in the last iteration (zero after a change of state), for the momentum.
    velocities: Vec<Vec3>,
    /// Each free point's step scale: halved while it goes round in circles (a face-point rocking
    /// across a crease of the target, where the tangential forces on the two sides point at each
    /// other; a space-point between folding and the springs), regrown slowly while it makes
    /// progress.
    step_scales: Vec<f32>,
    /// Per point, moving averages of its moves and of their lengths: their ratio says whether
    /// it makes progress (near 1) or rocks (near 0), whatever the period of the rocking.
    mean_moves: Vec<(Vec3, f32)>,
    anchor_of_vertex: Vec<Option<(AnchorTarget, Vec3)>>,
    is_corner: Vec<bool>,
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
    /// Whether held points slide along the cross-section (else they only move onto it).
    plane_slide: bool,
    fold_tolerance: f32,
    /// +1 when the layout's faces wind the same way as the target's, -1 when the other way, 0
    /// while that is not clear yet: measured every iteration over the face-points.
    orientation: f32,
    layout_size: f32,
    landing_distance: f32,
    /// Per point: how many times it lifted off a boundary, and the iteration before which it may
    /// not fold again (exponential back-off, so that flip-flops at a rim die out).
    lift_counts: Vec<u32>,
    no_fold_until: Vec<usize>,
    total_iterations: usize,
    /// Iterations since a point last changed state.
    quiet_iterations: usize,
    /// Iterations run so far, counted inside `iterate` (for the fold back-off).
    iteration: usize,
    /// The rest shape (the energy solver's springs).
    rest: Vec<Vec3>,
    mean_edge_length: f32,
    /// Per vertex, how firmly it keeps the template's shape (0 … 1, 0.5 the wrap's own balance);
    /// empty: 0.5 everywhere. Energy solver only.
    stiffness: Vec<f32>,
    /// Per vertex, whether it has no pull toward the target (a socket, teeth); empty: none.
    /// Energy solver only.
    free: Vec<bool>,
    /// Per vertex, its soft pair's point and confidence; empty: none. Energy solver only.
    soft_pairs: SoftPairOfVertex,
    /// The energy solver, made at the first step of a wrap with [`SolverKind::Energy`].
    energy: Option<Box<EnergySolver>>,
    /// The region the points may reach: a centre and a radius (ten times the target's size and
    /// the layout's start about the target's centre); leaving it is divergence.
    reach: (Vec3, f32),
    /// Set once the wrap diverged: every later step returns it.
    diverged: Option<KernelError>,
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
        for solver_kind in [SolverKind::Springs, SolverKind::Energy] {
            let (target, structure, points) = plane_and_layout();
            let settings = WrapSettings {
                solver: solver_kind,
                ..WrapSettings::default()
            };
            let mut solver = WrapSolver::new(target, structure, points, &[], settings).unwrap();
            let start = solver.positions().to_vec();
            // A reach smaller than the layout: the first step leaves it.
            solver.reach = (Vec3::new(0.0, 0.0, 10.0), 1e-3);
            let error = solver.step(5).unwrap_err();
            assert!(
                matches!(error, KernelError::Diverged { .. }),
                "{solver_kind:?}: {error:?}"
            );
            assert_eq!(solver.positions(), start.as_slice(), "{solver_kind:?}");
            assert_eq!(solver.step(1).unwrap_err(), error);
        }
    }
}
