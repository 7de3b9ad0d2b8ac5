//! The energy wrap: one energy `E(x)`, minimised by local–global steps with a prefactored sparse
//! Cholesky, every step and every landing checked so that no layout face turns over.
//!
//! ```text
//! E(x) = β Σ_i Σ_{j∈N(i)} |x_j − x_i − T_i (r_j − r_i)|²                  (arc length: edges)
//!      + α Σ_(p,v,n)      |x_p + x_n − 2 x_v − T_v (r_p + r_n − 2 r_v)|²   (fairness: lines)
//!      + γ_tp Σ_v∉lines   |mean_N(x) − x_v − T_v (mean_N(r) − r_v)|²       (thin plate: umbrella)
//!      + γ_con λ_k Σ_i c_i |x_i − p_i|²                                    (data)
//!      + ε Σ_i |x_i − x_i⁰|²                                               (proximal, keeps A definite)
//! ```
//!
//! The weights α, β, γ_tp, γ_con are the settings' weights relative to their defaults (1 at the
//! defaults); γ_fold scales the data term's reach (the Welsch width σ of every level), the
//! tolerance ends each level, the fold tolerance bounds how far the layout may face away from
//! the surface where a point lands.
//!
//! `r` is the rest shape (the template), `T_i = s_i R_i` the similarity of vertex `i`'s rest
//! neighbourhood onto its current one (a Procrustes fit, as in as-rigid-as-possible), the scales
//! `s` smoothed over the layout by a stiffness that relaxes level by level (Amberg et al. 2007:
//! first one scale for all, at the end nearly per vertex). `p_i` is the projection of `x_i` onto
//! the target's tangent plane at its closest point `q_i` (point-to-plane, so the layout slides
//! along the surface), `c_i` a robust weight: Welsch in the distance (in the global-to-local
//! schedule also times the cosine between the layout's and the target's normals), zero when the
//! layout faces away from the target's smoothed normal there (cavities, the far side of a thin
//! part), on a boundary edge (a hole) or on an unreliable triangle. Anchors and curve targets are hard
//! constraints (their vertices are eliminated from the system); a soft pair (`soft_pair.rs`)
//! replaces its vertex's data term by a pull toward its point in the stiff levels (not in the
//! warm-up).
//!
//! **Warm-up**: before any data term, the constraints alone pull the layout as rigidly as
//! possible (the same steps with `λ = 0`, rotations averaged over neighbours, no safeguard), so
//! that a posed target's limbs turn with their anchors instead of being dragged by the data.
//!
//! **Local step**: fit `T_i` and the correspondences at the current positions. **Global step**:
//! solve `A x = b`; `A` is the same scalar matrix for x, y and z, its pattern analysed once; only
//! its diagonal (the data weights) changes, and the linear system decides when to factor it anew
//! (`linear_system.rs`). **Safeguard**: a corner of a layout
//! face (a vertex and its two face neighbours) may not turn more than 90 degrees from its rest
//! normal turned by the layout's mean rotation (one frame for all: a region cannot roll over by
//! small steps), and a corner already beyond may only turn back; the vertices of corners that
//! would turn have their step halved, up to zero (the step is then not taken there), and have no
//! data term in the next iteration, so the shape terms lead them out of the fold the data pulled
//! them into. **Re-settle** (`resettle.rs`): a wrap's result wrapped again (its caller says so)
//! that starts on the target with its constraints met runs the last level alone. **Region restart**: a region of a
//! settled layout started again, the rest held (its caller says so): the global-to-local schedule starts at its
//! second level, and a point the safeguard held back has no data term for the rest of the wrap
//! ([`RESTART_FIRST_LEVEL`], [`Self::note_held_back`]). **Landing**: at the end every free point whose
//! closest surface point is near, trusted and facing lands there as a face-point, unless that
//! turns a corner; the others stay space-points (holes, cavities).

use std::sync::Arc;

use glam::{DVec3, Quat, Vec3, Vec4};
use rayon::prelude::*;

use super::anchor::AnchorTarget;
use super::averaging_pyramid::AveragingPyramid;
use super::global_phase::{
    GLOBAL_MIN_ALIGNMENT, GLOBAL_TO_LOCAL_LEVELS, RECIPROCAL_LEVELS, Stretches, choose_schedule,
    global_phase_fits, keep_reciprocal,
};
use super::linear_system::WRAP_STEP;
use super::linear_system::{LinearSystem, SolveStatistics, Stencils};
use super::ordered_sum::ordered_sum;
use super::plane_constraint::Plane;
use super::profile::{PhaseClock, PhaseTimes, Profiler, WrapPhase};
use super::settings::{WrapSchedule, WrapSettings};
use super::similarity::{RestFit, Similarity};
use super::soft_pair::pull_soft_pairs;
#[cfg(test)]
use crate::cancel::NEVER;
use crate::cancel::{Stop, check};
use crate::error::KernelError;
use crate::face_point::{FacePoint, LayoutPoint, SurfaceHit};
use crate::layout::LayoutStructure;
use crate::mesh::{NO_TRIANGLE, TargetMesh};
use crate::query::QueryState;

mod data_term;
mod landing;
mod local_step;
mod resettle;
mod safeguard;
mod terms;
#[cfg(test)]
mod tests;

use data_term::smoothed_vertex_normals;
use safeguard::corner_normals;
use terms::{build_terms, data_factor, is_flagged, shape_factor};

/// Weight of the edge (shape) terms.
const EDGE_WEIGHT: f64 = 1.0;
/// Weight of the line (fairness and arc length) and umbrella terms.
const LINE_WEIGHT: f64 = 1.0;
/// The proximal weight, relative to the edge weight: keeps the matrix definite where nothing
/// else holds a region (a loose piece far from the target, with no anchor).
const PROXIMAL_WEIGHT: f64 = 1e-6;
/// A point is taken as touching its correspondence's tangent plane... the data term's Welsch
/// width, per level, in mean edge lengths, and other per-level settings.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Level {
    /// λ: the data term's weight, relative to the edge weight.
    pub(crate) data_weight: f64,
    /// σ of the Welsch weight, in mean edge lengths; correspondences farther than 3σ are ignored.
    pub(crate) welsch_width: f32,
    /// Rounds of averaging of the log scales (or of the stretches, in the global-to-local
    /// schedule) over edge neighbours; `None`: one scale for all.
    pub(crate) scale_smoothing: Option<usize>,
    /// Rounds of averaging of the fitted rotations over edge neighbours (0: each vertex its own).
    pub(crate) rotation_smoothing: usize,
    /// The most iterations at this level.
    pub(crate) max_iterations: usize,
}

/// The stiffness schedule: the data term tightens, the scale and the rotations loosen level by
/// level (at the first, rotations averaged over about 8 rings move each region as one piece).
pub(crate) const LEVELS: [Level; 4] = [
    Level {
        data_weight: 0.1,
        welsch_width: 3.0,
        scale_smoothing: None,
        rotation_smoothing: 64,
        max_iterations: 6,
    },
    Level {
        data_weight: 1.0,
        welsch_width: 2.0,
        scale_smoothing: Some(32),
        rotation_smoothing: 0,
        max_iterations: 5,
    },
    Level {
        data_weight: 10.0,
        welsch_width: 1.0,
        scale_smoothing: Some(8),
        rotation_smoothing: 0,
        max_iterations: 3,
    },
    Level {
        data_weight: 100.0,
        welsch_width: 1.0,
        scale_smoothing: Some(2),
        rotation_smoothing: 0,
        max_iterations: 4,
    },
];
/// The warm-up before the schedule: the anchors and curve targets alone deform the layout as
/// rigidly as possible (no data term, no safeguard), rotations averaged over this many rounds, for
/// at most this many iterations or until no point moves more than this fraction of a mean edge.
const WARMUP_ROTATION_SMOOTHING: usize = 16;
const WARMUP_MAX_ITERATIONS: usize = 24;
const WARMUP_SETTLED_MOVE: f32 = 0.1;
/// A level is settled when at most one point in this many was held back by the safeguard.
const HELD_BACK_SETTLED: usize = 200;
/// A level also ends once an iteration moves the points by at most this many mean edges on
/// average (its first iteration included): the rest of the level would only slide them by as
/// little. Measured on a 1024² torus grid (`examples/large_grid.rs`, the factor-free path):
/// the second level's last four iterations moved 2.2e-3 to 1.9e-3 mean edges each (the energy
/// still falling 1 to 4 % each), the third level's two 7.3e-4 and 1.9e-4, the last level's two
/// 8.2e-4 and 2.4e-5; at 1e-3 the third and last levels end after their first iteration (15
/// iterations to 13), the result's distance and stretch the same (mean distance 2.722e-8 to
/// 2.722e-8, mean |log stretch| 1.4573e-2 to 1.4574e-2); at 2.5e-3 the second level ends after
/// two iterations too (10 iterations) but the stretch grows (1.4602e-2, its largest 1.066e-1
/// to 1.076e-1).
const LEVEL_SETTLED_MOVE: f32 = 1e-3;
/// A region of a settled layout started again, the rest held (`EnergyInputs::region_restart`: a sequence's later
/// frame, `core.follow`), in the global-to-local schedule: the schedule starts at this level, the second stiff one.
/// The first, the stiffest (stretches smoothed over about 128 rings), carries a whole layout's regions to where they
/// belong; a restarted region is placed by the ring held around it, and there that level ran its 20 iterations on
/// some frames (the 4 to 16 points held back for good keep it from counting as settled). Measured on the body's
/// expression sequence (`benchmarks/sequence.py`, frames 0-19, cold wraps the same cached run): 33.9 iterations a
/// later frame from the first level, 29.5 from the second (the mean and p95 errors within 0.001 mm), 27.6 from the
/// second with [`EnergySolver::note_held_back`]'s hold; from the third, 21.5 but the p95 0.015 mm higher on average,
/// above the cold wrap's on 4 frames (by up to 0.11 mm). Over all 100 frames, both changes (load 1.9): 30.5 -> 26.6
/// iterations, the mean error 1.07 -> 1.06 mm, the p95 2.88 -> 2.84 mm (its worst 3.88 -> 3.84), above the cold
/// wrap's on 2 frames (4 before; by at most 0.03 mm), the jitter 0.044 / 0.235 -> 0.044 / 0.232 mm.
const RESTART_FIRST_LEVEL: usize = 1;
/// Correspondences count only where the layout faces the target's smoothed normal within this
/// cosine (60 degrees).
const MIN_FACING: f32 = 0.5;
/// Rounds of sign matching when averaging the fitted rotations into the safeguard's frame.
const MEAN_ROTATION_ROUNDS: usize = 3;
/// A corner may turn from its frame until this cosine; beyond it, only back toward it (the
/// global-to-local schedule has its own, [`GLOBAL_MIN_ALIGNMENT`]).
const MIN_ALIGNMENT: f32 = 0.0;
/// A global step is solved until its remaining correction is about this fraction of a mean edge.
const SOLVE_PRECISION: f64 = 1e-5;
/// The most memory the global step's factorization may take, in bytes (2 GiB): about a million
/// layout points on a grid. A larger layout is solved without a factor (conjugate gradients
/// preconditioned by a multigrid cycle), in memory that grows only linearly with the points.
pub(crate) const MAX_FACTOR_BYTES: usize = 2 << 30;
/// The stiffness at which a vertex has the energy's own weights.
pub(crate) const NEUTRAL_STIFFNESS: f32 = 0.5;
/// The factor on the shape terms a vertex owns at stiffness 1 (and its inverse at 0).
const STIFFNESS_RANGE: f64 = 100.0;
/// Per-vertex scales stay within this factor of their median.
const SCALE_RANGE: f32 = 3.0;
/// Halvings of a vertex's step before it is not taken at all.
const BACKTRACK_HALVINGS: usize = 6;
/// A free point lands when its closest surface point is within this many landing distances.
const LANDING_REACH: f32 = 2.0;
/// Rounds of normal smoothing per (layout edge / target edge)² (diffusion spreads as the square
/// root of the rounds), and their bounds.
const NORMAL_SMOOTHING_ROUNDS: (usize, usize) = (1, 24);
/// The most vertices whose vote says which way the layout winds against the target.
const ORIENTATION_SAMPLES: usize = 1 << 16;
/// Terms whose targets the global step's assembly computes at once (in parallel).
const TARGETS_PER_PIECE: usize = 1 << 16;
/// Closest-point queries between two asks whether a step is to stop.
const QUERIES_PER_CHECK: usize = 1 << 15;

/// A point's pull toward the target: its Welsch weight and the point on the target's tangent
/// plane it is pulled to.
type Correspondence = (f32, Vec3);

/// What the energy solver needs from the wrap's inputs.
pub(crate) struct EnergyInputs<'a> {
    pub target: &'a Arc<TargetMesh>,
    pub structure: &'a LayoutStructure,
    pub rest: &'a [Vec3],
    pub positions: &'a [Vec3],
    pub anchor_of_vertex: &'a [Option<(AnchorTarget, Vec3)>],
    /// Per vertex, its soft pair's point and confidence (empty: none).
    pub soft_pairs: &'a [Option<(Vec3, f32)>],
    pub curve_target_of_vertex: &'a [Option<Vec3>],
    pub unreliable: &'a [bool],
    /// Per vertex, its stiffness in [0, 1] (empty: [`NEUTRAL_STIFFNESS`] everywhere).
    pub stiffness: &'a [f32],
    /// Per vertex, whether it has no data term (empty: none).
    pub free: &'a [bool],
    /// The points at the start (held points not sliding on the plane stay as they are).
    pub points: &'a [LayoutPoint],
    /// The mirror plane, and per vertex whether it is held on it (empty: none is).
    pub plane: Option<Plane>,
    pub on_plane: &'a [bool],
    /// Whether held points slide along the plane (else they stay where they start).
    pub plane_slide: bool,
    pub mean_edge_length: f32,
    pub landing_distance: f32,
    /// The weights, the tolerance, the fold tolerance and the schedule.
    pub settings: WrapSettings,
    /// The clock that times each phase (`None`: no profile).
    pub profile: Option<PhaseClock>,
    /// The start is a wrap's own result, wrapped again (see `resettle.rs`).
    pub settled_start: bool,
    /// A region of a settled layout started again, the rest held (see [`RESTART_FIRST_LEVEL`] and
    /// [`EnergySolver::note_held_back`]).
    pub region_restart: bool,
}

/// One iteration's outcome.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct EnergyStep {
    /// Largest and mean move of a point.
    pub max_move: f32,
    pub mean_move: f32,
    /// The energy after the step.
    pub energy: f64,
    /// Points whose step was shortened (or refused) so that no corner turned.
    pub held_back: usize,
    /// How much the step lowered the energy, relative to the energy before it (NaN for a
    /// level's first step, whose energy has nothing to compare with).
    pub energy_decrease: f64,
    /// The schedule is done: the points may land.
    pub finished: bool,
}

/// The energy wrap's state between iterations.
#[derive(Debug, Clone)]
pub(crate) struct EnergySolver {
    target: Arc<TargetMesh>,
    structure: LayoutStructure,
    rest_fit: RestFit,
    /// Per corner (a vertex and one face around it, in `structure.wedges` order), its unit normal
    /// in the rest shape: the orientation the safeguard keeps, turned by the layout's frame.
    rest_corner_normals: Vec<Vec3>,
    stencils: Stencils,
    /// Per term, its owner (whose similarity turns its rest vector) and its rest vector.
    term_owner: Vec<u32>,
    term_rest: Vec<DVec3>,
    system: LinearSystem,
    fixed: Vec<Option<DVec3>>,
    fixed_points: Vec<Option<LayoutPoint>>,
    unreliable: Vec<bool>,
    /// Per vertex, the factor on its data term (0: free, or stiff enough to keep the template).
    data_factors: Vec<f32>,
    /// Per vertex, its soft pair's point and confidence (empty: none).
    soft_pairs: Vec<Option<(Vec3, f32)>>,
    /// The mirror plane when some vertex slides on it, and per vertex whether it is held there.
    plane: Option<Plane>,
    on_plane: Vec<bool>,
    smoothed_normals: Vec<Vec3>,
    positions: Vec<Vec3>,
    similarities: Vec<Similarity>,
    /// The rotation the safeguard turns the rest corner normals by: the mean of the fitted
    /// rotations. One frame for the whole layout, so that no region (an ear, a lip) can roll
    /// over by small steps that each look fine to its own turning neighbourhood.
    frame: Quat,
    /// Per vertex, the triangle of its last closest point (where the next query starts), or
    /// [`NO_TRIANGLE`].
    last_hits: Vec<u32>,
    /// Per vertex, whether the safeguard shortened its last step.
    held_back: Vec<bool>,
    /// +1 when the layout winds as the target, -1 the other way.
    orientation: f32,
    mean_edge_length: f32,
    landing_distance: f32,
    /// The stiffness schedule's levels.
    levels: &'static [Level],
    /// A corner may turn from its frame until this cosine; beyond it, only back toward it.
    min_alignment: f32,
    /// The factors on every level's data weight and Welsch width (the constraint and folding
    /// weights relative to their defaults).
    data_scale: f64,
    reach_scale: f32,
    /// A level ends once an iteration lowers the energy by less than this fraction.
    level_decrease: f64,
    /// ... or once an iteration moves the points by at most this on average
    /// ([`LEVEL_SETTLED_MOVE`] mean edges).
    level_settled_move: f32,
    /// A point lands only where the layout faces the target's smoothed normal within this
    /// cosine (the fold tolerance's): more lenient than the data term, since the landing is
    /// checked corner by corner.
    landing_facing: f32,
    /// The per-vertex stretches of the global-to-local schedule (`None`: similarities alone).
    stretches: Option<Stretches>,
    /// Whether the anchors-only warm-up is still running.
    warming_up: bool,
    level: usize,
    level_iterations: usize,
    iterations: usize,
    last_energy: f64,
    finished: bool,
    /// Where a re-settle started (`resettle.rs`), until its first iteration says whether it stays one.
    resettle_start: Option<Vec<Vec3>>,
    /// A region started again, the rest held, in the global-to-local schedule: the schedule starts at
    /// [`RESTART_FIRST_LEVEL`] and a point held back keeps no data term ([`Self::note_held_back`]).
    region_restart: bool,
    /// The time of each phase, when asked for.
    profiler: Profiler,
    /// Without a factor (a layout of about a million points or more): the coarser levels on
    /// which most rounds of the rotations' and scales' averaging are done.
    pyramid: Option<AveragingPyramid>,
}

impl EnergySolver {
    /// Sets up the energy of a layout at `positions` with the constraints of `inputs`.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the linear system cannot be built (out of memory).
    #[cfg(test)]
    pub(crate) fn new(inputs: &EnergyInputs<'_>) -> Result<Self, KernelError> {
        Self::new_until(inputs, NEVER)
    }

    /// [`EnergySolver::new`], asking `stop` between its long pieces (the matrix's analysis, the
    /// target's smoothed normals, the first fit).
    ///
    /// # Errors
    /// As [`EnergySolver::new`]; [`KernelError::Cancelled`] once `stop` said true.
    pub(crate) fn new_until(
        inputs: &EnergyInputs<'_>,
        stop: Stop<'_>,
    ) -> Result<Self, KernelError> {
        let mut profiler = Profiler::new(inputs.profile);
        let mut clock = profiler.start();
        let structure = inputs.structure;
        let vertex_count = structure.vertex_count;
        let settings = inputs.settings;
        let schedule = choose_schedule(
            settings.schedule,
            structure,
            inputs.rest,
            inputs.anchor_of_vertex,
        );
        if schedule == WrapSchedule::GlobalToLocal && !global_phase_fits(vertex_count) {
            return Err(KernelError::InvalidArgument {
                name: "schedule",
                reason: format!(
                    "the global-to-local schedule smooths over the whole layout by one factored solve, \
                     too large for {vertex_count} vertices: choose the local schedule (or Auto)"
                ),
            });
        }
        let mut fixed = vec![None; vertex_count];
        let mut fixed_points = vec![None; vertex_count];
        for vertex in 0..vertex_count {
            if let Some((target, position)) = inputs.anchor_of_vertex[vertex] {
                fixed[vertex] = Some(position.as_dvec3());
                fixed_points[vertex] = Some(match target {
                    AnchorTarget::Face(face_point) => LayoutPoint::Face(face_point),
                    AnchorTarget::Space(position) => LayoutPoint::Space(position),
                });
            } else if inputs.on_plane.get(vertex).copied().unwrap_or(false)
                && !inputs.plane_slide
                && matches!(inputs.points[vertex], LayoutPoint::Face(_))
            {
                // Held where it starts, on the cross-section (a held space-point slides within
                // the plane until it lands).
                fixed[vertex] = Some(inputs.positions[vertex].as_dvec3());
                fixed_points[vertex] = Some(inputs.points[vertex]);
            } else if let Some(position) =
                inputs.curve_target_of_vertex.get(vertex).copied().flatten()
            {
                fixed[vertex] = Some(position.as_dvec3());
                // On the surface when the curve lies on it there.
                let tolerance = inputs.landing_distance * 1e-2;
                let point = match inputs.target.closest_point(position, tolerance) {
                    Some(hit) if !is_flagged(inputs.unreliable, hit.face_point.triangle) => {
                        LayoutPoint::Face(hit.face_point)
                    }
                    _ => LayoutPoint::Space(position),
                };
                fixed_points[vertex] = Some(point);
            }
        }
        let [fairness, arc_length, thin_plate, constraint, folding] = settings.weights.relative();
        let (mut stencils, term_owner, term_rest) =
            build_terms(structure, inputs.rest, [arc_length, fairness, thin_plate]);
        let stiffness_of = |vertex: usize| {
            inputs
                .stiffness
                .get(vertex)
                .copied()
                .unwrap_or(NEUTRAL_STIFFNESS)
        };
        for (weight, &owner) in stencils.weights.iter_mut().zip(&term_owner) {
            *weight *= shape_factor(stiffness_of(owner as usize));
        }
        let data_factors: Vec<f32> = (0..vertex_count)
            .map(|vertex| {
                if inputs.free.get(vertex).copied().unwrap_or(false) {
                    0.0
                } else {
                    data_factor(stiffness_of(vertex))
                }
            })
            .collect();
        check(stop, WRAP_STEP)?;
        let system = LinearSystem::new(&stencils, vertex_count, &fixed, MAX_FACTOR_BYTES)?;
        clock = profiler.add(WrapPhase::System, clock);
        check(stop, WRAP_STEP)?;
        // Constrained vertices move to their constraints in the first step, with their
        // neighbours: the safeguard then sees the whole move.
        let positions = inputs.positions.to_vec();
        let rest_corner_normals = corner_normals(structure, inputs.rest)
            .into_iter()
            .map(Vec3::normalize_or_zero)
            .collect();
        let smoothed_normals = smoothed_vertex_normals(inputs.target, inputs.mean_edge_length);
        clock = profiler.add(WrapPhase::Normals, clock);
        check(stop, WRAP_STEP)?;
        let mut solver = Self {
            target: Arc::clone(inputs.target),
            structure: structure.clone(),
            rest_fit: RestFit::new(inputs.rest),
            rest_corner_normals,
            stencils,
            term_owner,
            term_rest,
            system,
            fixed,
            fixed_points,
            unreliable: inputs.unreliable.to_vec(),
            data_factors,
            // Soft pairs steer the stiff levels of the global-to-local schedule; the local
            // schedule (many anchors, a small change) has no need of them.
            soft_pairs: if schedule == WrapSchedule::GlobalToLocal {
                inputs.soft_pairs.to_vec()
            } else {
                Vec::new()
            },
            plane: inputs
                .plane
                .filter(|_| inputs.on_plane.iter().any(|&held| held)),
            on_plane: inputs.on_plane.to_vec(),
            smoothed_normals,
            positions,
            similarities: vec![Similarity::IDENTITY; vertex_count],
            frame: Quat::IDENTITY,
            held_back: vec![false; vertex_count],
            // A face-point's triangle starts its first query: the answer is the same, found
            // without a search from the tree's root.
            last_hits: (0..vertex_count)
                .map(|vertex| match inputs.points.get(vertex) {
                    Some(LayoutPoint::Face(face_point)) => face_point.triangle,
                    _ => NO_TRIANGLE,
                })
                .collect(),
            orientation: 1.0,
            mean_edge_length: inputs.mean_edge_length,
            landing_distance: inputs.landing_distance,
            levels: match schedule {
                WrapSchedule::GlobalToLocal => &GLOBAL_TO_LOCAL_LEVELS,
                WrapSchedule::Local | WrapSchedule::Auto => &LEVELS,
            },
            min_alignment: match schedule {
                WrapSchedule::GlobalToLocal => GLOBAL_MIN_ALIGNMENT,
                WrapSchedule::Local | WrapSchedule::Auto => MIN_ALIGNMENT,
            },
            stretches: (schedule == WrapSchedule::GlobalToLocal)
                .then(|| Stretches::new(structure, inputs.rest))
                .transpose()?,
            data_scale: constraint,
            reach_scale: folding as f32,
            level_decrease: f64::from(settings.tolerance),
            level_settled_move: LEVEL_SETTLED_MOVE * inputs.mean_edge_length,
            landing_facing: settings.fold_tolerance.cos(),
            warming_up: true,
            level: 0,
            level_iterations: 0,
            iterations: 0,
            last_energy: f64::INFINITY,
            finished: false,
            resettle_start: None,
            // Measured in the global-to-local schedule alone (what a sequence's Auto takes there).
            region_restart: inputs.region_restart && schedule == WrapSchedule::GlobalToLocal,
            profiler,
            pyramid: None,
        };
        if !solver.system.is_direct() {
            solver.pyramid = AveragingPyramid::new(structure, inputs.rest);
        }
        solver.start_schedule();
        solver.resettle_if_on_target(inputs.points, inputs.settled_start);
        solver.profiler.add(WrapPhase::FirstFit, clock);
        Ok(solver)
    }

    /// Starts the schedule from the current positions, as a wrap from them does: the warm-up when
    /// [`Self::needs_warm_up`], the first level, no energy measured yet, nothing held back, no hits remembered, the
    /// similarities fitted afresh and the layout's orientation measured. A new solver starts so, and so does a
    /// re-settle that moved too far on its first iteration ([`Self::keep_resettle_if_settled`]).
    fn start_schedule(&mut self) {
        self.warming_up = self.needs_warm_up();
        let first_level = if self.region_restart {
            RESTART_FIRST_LEVEL
        } else {
            0
        };
        (self.level, self.level_iterations, self.iterations) = (first_level, 0, 0);
        self.last_energy = f64::INFINITY;
        self.finished = false;
        self.held_back.fill(false);
        self.last_hits.fill(NO_TRIANGLE);
        self.similarities.fill(Similarity::IDENTITY);
        self.fit_similarities(true);
        self.orientation = self.measure_orientation();
    }

    /// Whether the wrap starts with the warm-up: always with a factor; without one, only when
    /// something moves the layout before the data term does (a fixed vertex: an anchor, a curve
    /// target, a point held where it starts; a vertex held on the plane). Nothing
    /// pulling, the warm-up only relaxes the layout toward the template's shape, which the data
    /// term then undoes: on a 512² grid 21 iterations of 37.
    fn needs_warm_up(&self) -> bool {
        self.system.is_direct() || self.fixed.iter().any(Option::is_some) || self.plane.is_some()
    }

    /// The seconds of each phase so far (all zero unless a profile was asked for).
    pub(crate) fn phase_times(&self) -> PhaseTimes {
        self.profiler.times()
    }

    /// How the global step's solves went so far.
    pub(crate) fn solve_statistics(&self) -> SolveStatistics {
        self.system.statistics()
    }

    /// The current positions.
    pub(crate) fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Whether the schedule is done and the points have landed.
    pub(crate) fn is_finished(&self) -> bool {
        self.finished
    }

    /// Moves the positions to `points` (after the caller corrected some landed points).
    pub(crate) fn set_positions_of(&mut self, points: &[LayoutPoint], target: &TargetMesh) {
        for (position, point) in self.positions.iter_mut().zip(points) {
            *position = match *point {
                LayoutPoint::Face(face_point) => {
                    target.interpolate(face_point.triangle, face_point.barycentric)
                }
                LayoutPoint::Space(position) => position,
            };
        }
    }

    /// Moves the anchors to `anchor_of_vertex` (the same vertices anchored as when this solver
    /// was made, other targets) and starts the schedule again as a solver made from the points
    /// as they are would ([`Self::start_schedule`]: its whole warm-up, similarities fitted
    /// afresh, no hits remembered). The matrix and its factor stay.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when other vertices are anchored (nothing changed then).
    pub(crate) fn move_anchors(
        &mut self,
        anchor_of_vertex: &[Option<(AnchorTarget, Vec3)>],
    ) -> Result<(), KernelError> {
        let mut fixed = self.fixed.clone();
        let mut fixed_points = self.fixed_points.clone();
        for (vertex, anchor) in anchor_of_vertex.iter().enumerate() {
            if let Some((target, position)) = *anchor {
                fixed[vertex] = Some(position.as_dvec3());
                fixed_points[vertex] = Some(match target {
                    AnchorTarget::Face(face_point) => LayoutPoint::Face(face_point),
                    AnchorTarget::Space(position) => LayoutPoint::Space(position),
                });
            }
        }
        self.system.move_fixed(&self.stencils, &fixed)?;
        (self.fixed, self.fixed_points) = (fixed, fixed_points);
        self.resettle_start = None;
        self.start_schedule();
        Ok(())
    }

    /// One local–global iteration.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the factorization fails.
    #[cfg(test)]
    pub(crate) fn iterate(&mut self) -> Result<EnergyStep, KernelError> {
        self.iterate_until(NEVER)
    }

    /// [`EnergySolver::iterate`], asking `stop` between the pieces of the iteration and inside
    /// its long loops (closest-point batches, rounds of smoothing, iterations of the global
    /// solve).
    ///
    /// # Errors
    /// As [`EnergySolver::iterate`]; [`KernelError::Cancelled`] once `stop` said true, the
    /// solver then half-stepped (its caller drops it).
    pub(crate) fn iterate_until(&mut self, stop: Stop<'_>) -> Result<EnergyStep, KernelError> {
        check(stop, WRAP_STEP)?;
        if self.finished {
            return Ok(EnergyStep {
                finished: true,
                ..EnergyStep::default()
            });
        }
        if self.warming_up {
            return self.warm_up(stop);
        }
        let level = self.levels[self.level];
        let data_weight = level.data_weight * self.data_scale;
        let mut clock = self.profiler.start();
        // Local step: similarities and correspondences at the current positions.
        if self.iterations > 0 {
            self.fit_similarities(false);
        }
        clock = self.profiler.add(WrapPhase::Fit, clock);
        self.smooth_rotations(level.rotation_smoothing, stop)?;
        self.fit_scales(level.scale_smoothing)?;
        clock = self.profiler.add(WrapPhase::Smoothing, clock);
        check(stop, WRAP_STEP)?;
        let normals = self.layout_normals(&self.positions);
        let width = level.welsch_width * self.mean_edge_length * self.reach_scale;
        let mut correspondences = self.correspondences(&normals, width, stop)?;
        if self.stretches.is_some() && self.level < RECIPROCAL_LEVELS {
            keep_reciprocal(&self.positions, &mut correspondences, self.mean_edge_length);
        }
        pull_soft_pairs(&self.soft_pairs, &mut correspondences, level.data_weight);
        // A point the safeguard held back last time has no data term now: the shape terms
        // alone move it, away from the fold the data pulled it into.
        for (correspondence, held) in correspondences.iter_mut().zip(&self.held_back) {
            if *held {
                *correspondence = None;
            }
        }
        self.profiler.add(WrapPhase::Correspondences, clock);
        let mut proposed = self.global_solve(&correspondences, data_weight, stop)?;
        clock = self.profiler.start();
        self.keep_on_plane(&mut proposed);
        check(stop, WRAP_STEP)?;
        // Safeguard: no corner may turn over.
        let (accepted, held_back) = self.safeguard(&proposed);
        clock = self.profiler.add(WrapPhase::Safeguard, clock);
        check(stop, WRAP_STEP)?;
        self.note_held_back(&accepted, &proposed);
        let (max_move, mean_move) = moves(&accepted, &self.positions);
        let energy = self.energy_at(&accepted, &correspondences, data_weight, &self.positions);
        self.profiler.add(WrapPhase::Energy, clock);
        self.positions = accepted;
        self.iterations += 1;
        self.level_iterations += 1;
        let decrease = if self.last_energy.is_finite() {
            (self.last_energy - energy) / self.last_energy.max(f64::MIN_POSITIVE)
        } else {
            f64::NAN
        };
        self.last_energy = energy;
        // A level also waits while the safeguard holds many points back: they have not arrived.
        let settled = held_back * HELD_BACK_SETTLED <= self.positions.len();
        let still = mean_move <= self.level_settled_move;
        if self.level_iterations >= level.max_iterations
            || (settled
                && (still || (self.level_iterations > 1 && decrease.abs() < self.level_decrease)))
        {
            self.level += 1;
            self.level_iterations = 0;
            self.last_energy = f64::INFINITY;
            if self.level == self.levels.len() {
                self.level = self.levels.len() - 1;
                self.finished = true;
            }
        }
        if self.resettle_start.is_some() {
            self.keep_resettle_if_settled(mean_move);
        }
        Ok(EnergyStep {
            max_move,
            mean_move,
            energy,
            held_back,
            energy_decrease: decrease,
            finished: self.finished,
        })
    }

    /// Marks the points the safeguard held back (`accepted` short of `proposed`): they have no data term in the next
    /// iteration, so the shape terms lead them out of the fold the data pulled them into. In a region restart
    /// (`EnergyInputs::region_restart`, in the global-to-local schedule) a point once held back keeps no data term for the rest of the wrap: there the
    /// same points were pulled back into the fold as soon as their data term returned and held back again, on
    /// alternate iterations (5 and 110 to 270 points in the local levels on the body's expression sequence), the
    /// energy swinging with their data term (by -10 and +0.9 of itself). Measured on that sequence
    /// (`benchmarks/sequence.py`, frames 0-19, cold wraps the same cached run), both with [`RESTART_FIRST_LEVEL`]:
    /// the mean error 0.825 -> 0.816 mm and the p95 2.175 -> 2.141 mm on average, the p95 above the cold wrap's on
    /// 2 frames (3 before), 29.5 -> 27.6 iterations a later frame (the local levels still run their most: the
    /// region still slides, its energy falling 1 to 5 % an iteration). Off for the rest of its level only: 0.817 and
    /// 2.144 mm, 28.7 iterations.
    fn note_held_back(&mut self, accepted: &[Vec3], proposed: &[Vec3]) {
        let for_good = self.region_restart;
        for ((held, accepted), proposed) in self.held_back.iter_mut().zip(accepted).zip(proposed) {
            *held = accepted != proposed || (for_good && *held);
        }
    }

    /// One iteration of the warm-up: the constraints alone pull the layout, as rigidly as
    /// possible (a posed target's limbs turn with their anchors before any data is asked for).
    fn warm_up(&mut self, stop: Stop<'_>) -> Result<EnergyStep, KernelError> {
        let mut clock = self.profiler.start();
        if self.iterations > 0 {
            self.fit_similarities(false);
        }
        clock = self.profiler.add(WrapPhase::Fit, clock);
        self.smooth_rotations(WARMUP_ROTATION_SMOOTHING, stop)?;
        self.fit_scales(None)?;
        self.profiler.add(WrapPhase::Smoothing, clock);
        // Soft pairs do not pull here: with the data term off, a pull would act as an anchor on
        // its whole limb (see `soft_pair.rs`).
        let none = vec![None; self.positions.len()];
        let mut proposed = self.global_solve(&none, 0.0, stop)?;
        clock = self.profiler.start();
        self.keep_on_plane(&mut proposed);
        let (max_move, mean_move) = moves(&proposed, &self.positions);
        let energy = self.energy_at(&proposed, &none, 0.0, &self.positions);
        self.profiler.add(WrapPhase::Energy, clock);
        self.positions = proposed;
        self.iterations += 1;
        if self.iterations >= WARMUP_MAX_ITERATIONS
            || max_move <= WARMUP_SETTLED_MOVE * self.mean_edge_length
        {
            self.warming_up = false;
        }
        Ok(EnergyStep {
            max_move,
            mean_move,
            energy,
            held_back: 0,
            energy_decrease: f64::NAN,
            finished: false,
        })
    }

    /// Held points slide within the plane: a step's part across it is dropped (a step shortened
    /// by the safeguard later stays within it, between two points on it).
    fn keep_on_plane(&self, positions: &mut [Vec3]) {
        if let Some(plane) = self.plane {
            for (position, &held) in positions.iter_mut().zip(&self.on_plane) {
                if held {
                    *position = plane.project(*position);
                }
            }
        }
    }

    /// What term `term` asks of its stencil now: its rest vector under its owner's similarity.
    fn term_target(&self, term: usize) -> DVec3 {
        let owner = self.term_owner[term] as usize;
        let fit = self.similarities[owner];
        if let Some(stretches) = &self.stretches {
            let stretched = stretches.values[owner].as_dmat3() * self.term_rest[term];
            return fit.rotation.as_dquat() * stretched;
        }
        let turned = fit.rotation.as_dquat() * self.term_rest[term];
        turned * f64::from(fit.scale)
    }

    /// The global step: the positions minimising the energy for the current similarities and
    /// these correspondences (fixed vertices at their constraints).
    fn global_solve(
        &mut self,
        correspondences: &[Option<Correspondence>],
        data_weight: f64,
        stop: Stop<'_>,
    ) -> Result<Vec<Vec3>, KernelError> {
        let mut clock = self.profiler.start();
        let rows = self.system.rows();
        let vertex_of_row = self.system.vertex_of_row().to_vec();
        let proximal = PROXIMAL_WEIGHT * EDGE_WEIGHT;
        let mut diagonal = vec![proximal; rows];
        let mut right_hand_side: Vec<DVec3> = vertex_of_row
            .iter()
            .map(|&vertex| self.positions[vertex as usize].as_dvec3() * proximal)
            .collect();
        for (row, &vertex) in vertex_of_row.iter().enumerate() {
            if let Some((weight, point)) = correspondences[vertex as usize] {
                let weight = f64::from(weight) * data_weight;
                diagonal[row] += weight;
                right_hand_side[row] += point.as_dvec3() * weight;
            }
        }
        // The terms' targets in parallel, a piece at a time; added in term order, as one thread
        // would (the same sums to the bit).
        let mut wanted = Vec::with_capacity(TARGETS_PER_PIECE.min(self.stencils.len()));
        for first in (0..self.stencils.len()).step_by(TARGETS_PER_PIECE) {
            let terms = first..(first + TARGETS_PER_PIECE).min(self.stencils.len());
            terms
                .clone()
                .into_par_iter()
                .with_min_len(1024)
                .map(|term| self.term_target(term))
                .collect_into_vec(&mut wanted);
            for (term, wanted) in terms.zip(&wanted) {
                let weight = self.stencils.weights[term];
                for (vertex, coefficient) in self.stencils.entries(term) {
                    if let Some(row) = self.system.row_of(vertex) {
                        right_hand_side[row as usize] += *wanted * (weight * coefficient);
                    }
                }
            }
        }
        // Within a level the diagonal changes little from one iteration to the next: the system
        // reuses its last factorization as a preconditioner, warm-started here.
        let start: Vec<DVec3> = vertex_of_row
            .iter()
            .map(|&vertex| self.positions[vertex as usize].as_dvec3())
            .collect();
        clock = self.profiler.add(WrapPhase::Assembly, clock);
        let solution = self.system.solve_reusing_until(
            &diagonal,
            &right_hand_side,
            &start,
            SOLVE_PRECISION * f64::from(self.mean_edge_length),
            stop,
        )?;
        self.profiler.add(WrapPhase::Solve, clock);
        let mut proposed = self.positions.clone();
        for (position, fixed) in proposed.iter_mut().zip(&self.fixed) {
            if let Some(fixed) = fixed {
                *position = fixed.as_vec3();
            }
        }
        for (row, &vertex) in vertex_of_row.iter().enumerate() {
            let position = solution[row].as_vec3();
            if position.is_finite() {
                proposed[vertex as usize] = position;
            }
        }
        Ok(proposed)
    }

    /// The energy at `positions` with these correspondences, the proximal term measured from
    /// `previous`.
    fn energy_at(
        &self,
        positions: &[Vec3],
        correspondences: &[Option<Correspondence>],
        data_weight: f64,
        previous: &[Vec3],
    ) -> f64 {
        let positions: Vec<DVec3> = positions.iter().map(|p| p.as_dvec3()).collect();
        let springs: f64 = ordered_sum(self.stencils.len(), |term| {
            let residual = self.stencils.apply(term, &positions) - self.term_target(term);
            self.stencils.weights[term] * residual.length_squared()
        });
        let mut data = 0.0;
        let mut proximal = 0.0;
        for vertex in 0..positions.len() {
            if self.fixed[vertex].is_some() {
                continue;
            }
            if let Some((weight, point)) = correspondences[vertex] {
                data += f64::from(weight) * positions[vertex].distance_squared(point.as_dvec3());
            }
            proximal += positions[vertex].distance_squared(previous[vertex].as_dvec3());
        }
        springs + data * data_weight + proximal * PROXIMAL_WEIGHT * EDGE_WEIGHT
    }
}

/// The largest and the mean distance between `new` and `old` positions.
fn moves(new: &[Vec3], old: &[Vec3]) -> (f32, f32) {
    let (mut largest, mut total) = (0.0f32, 0.0f64);
    for (new, old) in new.iter().zip(old) {
        let moved = new.distance(*old);
        largest = largest.max(moved);
        total += f64::from(moved);
    }
    (largest, (total / new.len().max(1) as f64) as f32)
}
