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
//! along the surface), `c_i` a robust weight: Welsch in the distance, zero when the layout faces
//! away from the target's smoothed normal there (cavities, the far side of a thin part), on a
//! boundary edge (a hole) or on an unreliable triangle. Anchors and curve targets are hard
//! constraints (their vertices are eliminated from the system); a soft pair (`soft_pair.rs`)
//! replaces its vertex's data term by a pull toward its point in the warm-up and the stiff levels.
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
//! them into. **Landing**: at the end every free point whose
//! closest surface point is near, trusted and facing lands there as a face-point, unless that
//! turns a corner; the others stay space-points (holes, cavities).

use std::sync::Arc;

use glam::{DVec3, Quat, Vec3, Vec4};
use rayon::prelude::*;

use super::anchor::AnchorTarget;
use super::global_phase::{
    GLOBAL_MIN_ALIGNMENT, GLOBAL_TO_LOCAL_LEVELS, RECIPROCAL_LEVELS, Stretches, choose_schedule,
    keep_reciprocal,
};
use super::linear_system::{LinearSystem, Stencils};
use super::plane_constraint::Plane;
use super::settings::{WrapSchedule, WrapSettings};
use super::similarity::{RestFit, Similarity};
use super::soft_pair::{pull_soft_pairs, warm_up_pulls};
use crate::error::KernelError;
use crate::face_point::{FacePoint, LayoutPoint, SurfaceHit};
use crate::layout::LayoutStructure;
use crate::mesh::{NO_TRIANGLE, TargetMesh};
use crate::query::QueryState;

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
/// preconditioned by the diagonal), in memory that grows only linearly with the points.
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
}

impl EnergySolver {
    /// Sets up the energy of a layout at `positions` with the constraints of `inputs`.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the linear system cannot be built (out of memory).
    pub(crate) fn new(inputs: &EnergyInputs<'_>) -> Result<Self, KernelError> {
        let structure = inputs.structure;
        let vertex_count = structure.vertex_count;
        let settings = inputs.settings;
        let schedule = choose_schedule(settings.schedule, inputs.rest, inputs.anchor_of_vertex);
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
        let system = LinearSystem::new(&stencils, vertex_count, &fixed, MAX_FACTOR_BYTES)?;
        // Constrained vertices move to their constraints in the first step, with their
        // neighbours: the safeguard then sees the whole move.
        let positions = inputs.positions.to_vec();
        let rest_corner_normals = corner_normals(structure, inputs.rest)
            .into_iter()
            .map(Vec3::normalize_or_zero)
            .collect();
        let smoothed_normals = smoothed_vertex_normals(inputs.target, inputs.mean_edge_length);
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
            last_hits: vec![NO_TRIANGLE; vertex_count],
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
            landing_facing: settings.fold_tolerance.cos(),
            warming_up: true,
            level: 0,
            level_iterations: 0,
            iterations: 0,
            last_energy: f64::INFINITY,
            finished: false,
        };
        solver.fit_similarities(true);
        solver.orientation = solver.measure_orientation();
        Ok(solver)
    }

    /// The current positions.
    pub(crate) fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Whether the schedule is done and the points have landed.
    pub(crate) fn is_finished(&self) -> bool {
        self.finished
    }

    /// The layout points after landing (call once finished): face-points where they landed,
    /// anchors and curve targets as their constraints say, space-points elsewhere.
    pub(crate) fn land(&mut self) -> (Vec<LayoutPoint>, usize) {
        let vertex_count = self.positions.len();
        let reach = self.landing_distance * LANDING_REACH;
        let normals = self.layout_normals(&self.positions);
        let hits: Vec<Option<SurfaceHit>> = (0..vertex_count)
            .into_par_iter()
            .with_min_len(256)
            .map(|vertex| {
                if self.fixed[vertex].is_some() || self.data_factors[vertex] == 0.0 {
                    return None;
                }
                let hit = self.target.closest_point(self.positions[vertex], reach)?;
                self.surface_trusted(&hit, normals[vertex], self.landing_facing)
                    .then_some(hit)
            })
            .collect();
        let mut candidate = self.positions.clone();
        let mut landing = vec![false; vertex_count];
        for (vertex, hit) in hits.iter().enumerate() {
            if let Some(hit) = hit {
                // Where the face-point is, exactly as it will be read back.
                candidate[vertex] = self
                    .target
                    .interpolate(hit.face_point.triangle, hit.face_point.barycentric);
                landing[vertex] = true;
            }
        }
        // A landing that would turn a corner is not made; refusing one can turn another corner
        // back, so repeat until none turns.
        let before = self.corner_orientations(&self.positions);
        loop {
            let turned = self.turned_corners(&before, &candidate);
            let mut refused = false;
            for vertex in turned {
                if landing[vertex as usize] {
                    landing[vertex as usize] = false;
                    candidate[vertex as usize] = self.positions[vertex as usize];
                    refused = true;
                }
            }
            if !refused {
                break;
            }
        }
        // Refusing every vertex of a turning corner refuses some that could land alone: try
        // those one at a time, nearest first, each kept only if it turns no corner around it.
        let mut retry: Vec<usize> = (0..vertex_count)
            .filter(|&vertex| hits[vertex].is_some() && !landing[vertex])
            .collect();
        retry.sort_by(|&a, &b| {
            let distance = |vertex: usize| hits[vertex].map_or(f32::INFINITY, |hit| hit.distance);
            distance(a).total_cmp(&distance(b))
        });
        for vertex in retry {
            let hit = hits[vertex].expect("retried points have a hit");
            let old = candidate[vertex];
            candidate[vertex] = self
                .target
                .interpolate(hit.face_point.triangle, hit.face_point.barycentric);
            if self.turns_corner_around(vertex as u32, &before, &candidate) {
                candidate[vertex] = old;
            } else {
                landing[vertex] = true;
            }
        }
        let mut points = Vec::with_capacity(vertex_count);
        let mut landed = 0;
        for vertex in 0..vertex_count {
            let point = if let Some(point) = self.fixed_points[vertex] {
                point
            } else if landing[vertex] {
                landed += 1;
                let hit = hits[vertex].expect("a landing point has a hit");
                LayoutPoint::Face(hit.face_point)
            } else {
                LayoutPoint::Space(candidate[vertex])
            };
            points.push(point);
        }
        self.positions = candidate;
        (points, landed)
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

    /// One local–global iteration.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the factorization fails.
    pub(crate) fn iterate(&mut self) -> Result<EnergyStep, KernelError> {
        if self.finished {
            return Ok(EnergyStep {
                finished: true,
                ..EnergyStep::default()
            });
        }
        if self.warming_up {
            return self.warm_up();
        }
        let level = self.levels[self.level];
        let data_weight = level.data_weight * self.data_scale;
        // Local step: similarities and correspondences at the current positions.
        if self.iterations > 0 {
            self.fit_similarities(false);
        }
        self.smooth_rotations(level.rotation_smoothing)?;
        self.fit_scales(level.scale_smoothing)?;
        let normals = self.layout_normals(&self.positions);
        let width = level.welsch_width * self.mean_edge_length * self.reach_scale;
        let mut correspondences = self.correspondences(&normals, width);
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
        let mut proposed = self.global_solve(&correspondences, data_weight)?;
        self.keep_on_plane(&mut proposed);
        // Safeguard: no corner may turn over.
        let (accepted, held_back) = self.safeguard(&proposed);
        for ((held, accepted), proposed) in self.held_back.iter_mut().zip(&accepted).zip(&proposed)
        {
            *held = accepted != proposed;
        }
        let (max_move, mean_move) = moves(&accepted, &self.positions);
        let energy = self.energy_at(&accepted, &correspondences, data_weight, &self.positions);
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
        if self.level_iterations >= level.max_iterations
            || (self.level_iterations > 1 && decrease.abs() < self.level_decrease && settled)
        {
            self.level += 1;
            self.level_iterations = 0;
            self.last_energy = f64::INFINITY;
            if self.level == self.levels.len() {
                self.level = self.levels.len() - 1;
                self.finished = true;
            }
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

    /// One iteration of the warm-up: the constraints alone pull the layout, as rigidly as
    /// possible (a posed target's limbs turn with their anchors before any data is asked for).
    fn warm_up(&mut self) -> Result<EnergyStep, KernelError> {
        if self.iterations > 0 {
            self.fit_similarities(false);
        }
        self.smooth_rotations(WARMUP_ROTATION_SMOOTHING)?;
        self.fit_scales(None)?;
        let pulls = warm_up_pulls(&self.soft_pairs, self.positions.len());
        let mut proposed = self.global_solve(&pulls, 1.0)?;
        self.keep_on_plane(&mut proposed);
        let (max_move, mean_move) = moves(&proposed, &self.positions);
        let energy = self.energy_at(&proposed, &pulls, 1.0, &self.positions);
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

    /// Fits every vertex's similarity at the current positions (from the last fit).
    fn fit_similarities(&mut self, first: bool) {
        self.similarities =
            self.rest_fit
                .fit_all(&self.positions, &self.structure, &self.similarities, first);
        self.frame = self.mean_rotation();
    }

    /// Replaces each fitted rotation by its average over edge neighbours, `rounds` times (as
    /// quaternions, each neighbour's sign matched to the vertex's own): the shape terms then
    /// keep regions about `√rounds` rings wide rigid.
    fn smooth_rotations(&mut self, rounds: usize) -> Result<(), KernelError> {
        if let Some(stretches) = self.stretches.as_mut() {
            return stretches.smooth_rotations(&mut self.similarities, rounds, self.frame);
        }
        if rounds == 0 {
            return Ok(());
        }
        let mut rotations: Vec<Quat> = self.similarities.iter().map(|fit| fit.rotation).collect();
        for _ in 0..rounds {
            rotations = (0..rotations.len() as u32)
                .into_par_iter()
                .with_min_len(2048)
                .map(|vertex| {
                    let own = rotations[vertex as usize];
                    let sum = self
                        .structure
                        .neighbors_of(vertex)
                        .iter()
                        .fold(Vec4::from(own), |sum, &other| {
                            add_matched(sum, rotations[other as usize], own)
                        });
                    normalized_rotation(sum).unwrap_or(own)
                })
                .collect();
        }
        for (fit, rotation) in self.similarities.iter_mut().zip(rotations) {
            fit.rotation = rotation;
        }
        Ok(())
    }

    /// The mean of the fitted rotations (as quaternions, each one's sign matched to the mean's).
    fn mean_rotation(&self) -> Quat {
        let Some(first) = self.similarities.first() else {
            return Quat::IDENTITY;
        };
        let mut mean = first.rotation;
        for _ in 0..MEAN_ROTATION_ROUNDS {
            let sum = self
                .similarities
                .iter()
                .fold(Vec4::ZERO, |sum, fit| add_matched(sum, fit.rotation, mean));
            let Some(next) = normalized_rotation(sum) else {
                break;
            };
            mean = next;
        }
        mean
    }

    /// Fits the stretches (global-to-local schedule) or smooths the scales, `rounds` as
    /// [`Self::smooth_scales`] takes them.
    fn fit_scales(&mut self, rounds: Option<usize>) -> Result<(), KernelError> {
        if let Some(stretches) = self.stretches.as_mut() {
            return stretches.fit(&self.structure, &self.positions, &self.similarities, rounds);
        }
        self.smooth_scales(rounds);
        Ok(())
    }

    /// Replaces the fitted scales by their median (`None`) or by their log averaged over edge
    /// neighbours `rounds` times, within [`SCALE_RANGE`] of the median.
    fn smooth_scales(&mut self, rounds: Option<usize>) {
        let Some(median) = Similarity::median_scale(&self.similarities) else {
            return;
        };
        let Some(rounds) = rounds else {
            for fit in &mut self.similarities {
                fit.scale = median;
            }
            return;
        };
        let (low, high) = ((median / SCALE_RANGE).ln(), (median * SCALE_RANGE).ln());
        let mut logs: Vec<f32> = self
            .similarities
            .iter()
            .map(|fit| {
                if fit.scale > 0.0 && fit.scale.is_finite() {
                    fit.scale.ln().clamp(low, high)
                } else {
                    median.ln()
                }
            })
            .collect();
        for _ in 0..rounds {
            logs = (0..logs.len() as u32)
                .into_par_iter()
                .with_min_len(2048)
                .map(|vertex| {
                    let neighbors = self.structure.neighbors_of(vertex);
                    let sum: f32 = neighbors.iter().map(|&other| logs[other as usize]).sum();
                    (logs[vertex as usize] + sum) / (1 + neighbors.len()) as f32
                })
                .collect();
        }
        for (fit, log) in self.similarities.iter_mut().zip(logs) {
            fit.scale = log.exp();
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
    ) -> Result<Vec<Vec3>, KernelError> {
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
        for term in 0..self.stencils.len() {
            let wanted = self.term_target(term);
            let weight = self.stencils.weights[term];
            for (vertex, coefficient) in self.stencils.entries(term) {
                if let Some(row) = self.system.row_of(vertex) {
                    right_hand_side[row as usize] += wanted * (weight * coefficient);
                }
            }
        }
        // Within a level the diagonal changes little from one iteration to the next: the system
        // reuses its last factorization as a preconditioner, warm-started here.
        let start: Vec<DVec3> = vertex_of_row
            .iter()
            .map(|&vertex| self.positions[vertex as usize].as_dvec3())
            .collect();
        let solution = self.system.solve_reusing(
            &diagonal,
            &right_hand_side,
            &start,
            SOLVE_PRECISION * f64::from(self.mean_edge_length),
        )?;
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
        let springs: f64 = (0..self.stencils.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|term| {
                let residual = self.stencils.apply(term, &positions) - self.term_target(term);
                self.stencils.weights[term] * residual.length_squared()
            })
            .sum();
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

    /// Per free vertex, its correspondence, or `None`; the closest-point queries start from each
    /// vertex's last hit (and record the new one).
    fn correspondences(&mut self, normals: &[Vec3], width: f32) -> Vec<Option<Correspondence>> {
        if width <= 0.0 {
            return vec![None; self.positions.len()]; // folding off: nothing is drawn on
        }
        let found: Vec<(Option<Correspondence>, u32)> = (0..self.positions.len())
            .into_par_iter()
            .with_min_len(256)
            .map_init(QueryState::default, |state, vertex| {
                if self.fixed[vertex].is_some() || self.data_factors[vertex] == 0.0 {
                    return (None, NO_TRIANGLE);
                }
                let position = self.positions[vertex];
                let Some(hit) = self.target.closest_point_near(
                    position,
                    width * 3.0,
                    self.last_hits[vertex],
                    state,
                ) else {
                    return (None, NO_TRIANGLE);
                };
                let triangle = hit.face_point.triangle;
                if !self.correspondence_trusted(&hit, normals[vertex]) {
                    return (None, triangle);
                }
                let weight = (-(hit.distance * hit.distance) / (2.0 * width * width)).exp()
                    * self.data_factors[vertex];
                let normal = self.smoothed_normal(hit.face_point);
                let face_normal = self.target.face_normals()[triangle as usize];
                // The tangent plane of the triangle itself: the point is pulled onto the surface,
                // not onto a smoothed plane beside it.
                let plane_normal = if face_normal == Vec3::ZERO {
                    normal
                } else {
                    face_normal
                };
                let mut projected =
                    position - plane_normal * plane_normal.dot(position - hit.position);
                if let Some(plane) = self.plane
                    && self.on_plane.get(vertex).copied().unwrap_or(false)
                {
                    projected = plane.project(projected);
                }
                (Some((weight, projected)), triangle)
            })
            .collect();
        let mut correspondences = Vec::with_capacity(found.len());
        for (vertex, (correspondence, triangle)) in found.into_iter().enumerate() {
            if triangle != NO_TRIANGLE {
                self.last_hits[vertex] = triangle;
            }
            correspondences.push(correspondence);
        }
        correspondences
    }

    /// Whether a closest-point hit may pull or receive a point whose layout normal is `normal`:
    /// not on an unreliable triangle, not on a boundary edge (a hole), and facing the way of the
    /// target's smoothed normal there.
    fn correspondence_trusted(&self, hit: &SurfaceHit, normal: Vec3) -> bool {
        self.surface_trusted(hit, normal, MIN_FACING)
    }

    /// [`Self::correspondence_trusted`] with the facing cosine `min_facing`.
    fn surface_trusted(&self, hit: &SurfaceHit, normal: Vec3, min_facing: f32) -> bool {
        let triangle = hit.face_point.triangle;
        if is_flagged(&self.unreliable, triangle) {
            return false;
        }
        let neighbors = self.target.triangle_neighbors()[triangle as usize];
        let barycentric = hit.face_point.barycentric.to_array();
        // Edge e runs from corner e to corner e + 1: on it, the weight of corner e + 2 is 0.
        if (0..3).any(|edge| neighbors[edge] == NO_TRIANGLE && barycentric[(edge + 2) % 3] <= 1e-5)
        {
            return false;
        }
        if normal == Vec3::ZERO {
            return true;
        }
        let surface_normal = self.smoothed_normal(hit.face_point);
        normal.dot(surface_normal) * self.orientation >= min_facing
    }

    /// The target's smoothed normal at a face-point.
    fn smoothed_normal(&self, face_point: FacePoint) -> Vec3 {
        let corners = self.target.triangles()[face_point.triangle as usize];
        let weights = face_point.barycentric;
        (self.smoothed_normals[corners[0] as usize] * weights.x
            + self.smoothed_normals[corners[1] as usize] * weights.y
            + self.smoothed_normals[corners[2] as usize] * weights.z)
            .normalize_or_zero()
    }

    /// +1 when the layout's faces wind as the target's where they are close, -1 when the other
    /// way (most layouts agree; a mirrored copy does not).
    fn measure_orientation(&self) -> f32 {
        let normals = self.layout_normals(&self.positions);
        let reach = self.mean_edge_length * 2.0;
        let agreement: f32 = (0..self.positions.len())
            .into_par_iter()
            .with_min_len(256)
            .filter_map(|vertex| {
                let normal = normals[vertex];
                if normal == Vec3::ZERO {
                    return None;
                }
                let hit = self.target.closest_point(self.positions[vertex], reach)?;
                Some(normal.dot(self.smoothed_normal(hit.face_point)))
            })
            .sum();
        if agreement < 0.0 { -1.0 } else { 1.0 }
    }

    /// Unit layout normals at `positions`.
    fn layout_normals(&self, positions: &[Vec3]) -> Vec<Vec3> {
        (0..positions.len() as u32)
            .into_par_iter()
            .with_min_len(2048)
            .map(|vertex| {
                self.structure
                    .normal_at(positions, vertex)
                    .normalize_or_zero()
            })
            .collect()
    }

    /// Per corner (a vertex and one face around it, in `structure.wedges` order), the cosine
    /// between its normal and its rest normal turned by the layout's frame (0 when degenerate).
    fn corner_orientations(&self, positions: &[Vec3]) -> Vec<f32> {
        let structure = &self.structure;
        (0..positions.len() as u32)
            .into_par_iter()
            .with_min_len(1024)
            .flat_map_iter(|vertex| {
                structure
                    .wedge_range(vertex)
                    .map(move |corner| self.corner_alignment(vertex, corner, positions))
            })
            .collect()
    }

    /// The cosine between corner `corner` (of vertex `owner`) at `positions` and its rest
    /// normal turned by the layout's frame (0 when degenerate).
    fn corner_alignment(&self, owner: u32, corner: usize, positions: &[Vec3]) -> f32 {
        let (previous, next) = self.structure.wedges[corner];
        let here = positions[owner as usize];
        (positions[next as usize] - here)
            .cross(positions[previous as usize] - here)
            .normalize_or_zero()
            .dot(self.frame * self.rest_corner_normals[corner])
    }

    /// The vertices of corners that turn away from their frame at `positions`: below
    /// the schedule's least alignment and less aligned than in `before`.
    fn turned_corners(&self, before: &[f32], positions: &[Vec3]) -> Vec<u32> {
        let after = self.corner_orientations(positions);
        let structure = &self.structure;
        let mut vertices = Vec::new();
        for vertex in 0..positions.len() {
            for corner in structure.wedge_range(vertex as u32) {
                if turned(before[corner], after[corner], self.min_alignment) {
                    let (previous, next) = structure.wedges[corner];
                    vertices.extend([vertex as u32, previous, next]);
                }
            }
        }
        vertices.sort_unstable();
        vertices.dedup();
        vertices
    }

    /// Whether `positions` turn a corner (as [`Self::turned_corners`] judges against `before`)
    /// among the corners that `vertex` belongs to: its own and its neighbours'.
    fn turns_corner_around(&self, vertex: u32, before: &[f32], positions: &[Vec3]) -> bool {
        let structure = &self.structure;
        let turns = |owner: u32, corner: usize| {
            turned(
                before[corner],
                self.corner_alignment(owner, corner, positions),
                self.min_alignment,
            )
        };
        let own = structure
            .wedge_range(vertex)
            .any(|corner| turns(vertex, corner));
        own || structure.neighbors_of(vertex).iter().any(|&other| {
            structure.wedge_range(other).any(|corner| {
                let (previous, next) = structure.wedges[corner];
                (previous == vertex || next == vertex) && turns(other, corner)
            })
        })
    }

    /// The proposed positions with the steps of vertices around turning corners halved until
    /// none turns (after [`BACKTRACK_HALVINGS`] halvings a step is not taken at all); and how many
    /// vertices were held back. Only a corner turned by constrained vertices alone can remain.
    fn safeguard(&self, proposed: &[Vec3]) -> (Vec<Vec3>, usize) {
        let before = self.corner_orientations(&self.positions);
        let mut fractions = vec![1.0f32; proposed.len()];
        let mut candidate = proposed.to_vec();
        for round in 0.. {
            let mut changed = false;
            for vertex in self.turned_corners(&before, &candidate) {
                let vertex = vertex as usize;
                if self.fixed[vertex].is_some() || fractions[vertex] == 0.0 {
                    continue;
                }
                fractions[vertex] = if round >= BACKTRACK_HALVINGS {
                    0.0
                } else {
                    fractions[vertex] * 0.5
                };
                candidate[vertex] = self.positions[vertex]
                    + (proposed[vertex] - self.positions[vertex]) * fractions[vertex];
                changed = true;
            }
            if !changed {
                break;
            }
        }
        let held_back = fractions.iter().filter(|&&fraction| fraction < 1.0).count();
        (candidate, held_back)
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

/// Whether a corner aligned `before` with its frame has turned at `after`: beyond
/// `min_alignment` and further from its frame than it was.
fn turned(before: f32, after: f32, min_alignment: f32) -> bool {
    after < min_alignment && after < before
}

/// `sum` plus `rotation` as a quaternion, its sign matched to `reference` (q and -q are the
/// same rotation; averaging must not let them cancel).
fn add_matched(sum: Vec4, rotation: Quat, reference: Quat) -> Vec4 {
    let rotation = Vec4::from(rotation);
    if rotation.dot(Vec4::from(reference)) < 0.0 {
        sum - rotation
    } else {
        sum + rotation
    }
}

/// The unit quaternion along `sum`, or `None` when it has no length (or is not finite).
fn normalized_rotation(sum: Vec4) -> Option<Quat> {
    let length = sum.length();
    (length > 0.0 && length.is_finite()).then(|| Quat::from_vec4(sum / length))
}

/// Per corner (a vertex and one face around it, in `structure.wedges` order), its normal at
/// `positions` (twice the corner triangle's area long; the faces' winding).
fn corner_normals(structure: &LayoutStructure, positions: &[Vec3]) -> Vec<Vec3> {
    (0..positions.len())
        .into_par_iter()
        .with_min_len(1024)
        .flat_map_iter(|vertex| {
            let here = positions[vertex];
            structure.wedges[structure.wedge_range(vertex as u32)]
                .iter()
                .map(move |&(previous, next)| {
                    (positions[next as usize] - here).cross(positions[previous as usize] - here)
                })
        })
        .collect()
}

/// The factor on the shape terms a vertex of this stiffness owns: 1 at
/// [`NEUTRAL_STIFFNESS`], [`STIFFNESS_RANGE`] at 1, its inverse at 0 (geometric in between).
fn shape_factor(stiffness: f32) -> f64 {
    STIFFNESS_RANGE.powf(f64::from(stiffness - NEUTRAL_STIFFNESS) / f64::from(NEUTRAL_STIFFNESS))
}

/// The factor on the data term of a vertex of this stiffness: 1 up to [`NEUTRAL_STIFFNESS`],
/// falling linearly to 0 at 1 (a vertex that keeps the template's shape is not pulled).
fn data_factor(stiffness: f32) -> f32 {
    ((1.0 - stiffness) / (1.0 - NEUTRAL_STIFFNESS)).clamp(0.0, 1.0)
}

/// Whether `triangle` is flagged in `flags` (empty: none is).
fn is_flagged(flags: &[bool], triangle: u32) -> bool {
    flags.get(triangle as usize).copied().unwrap_or(false)
}

/// The energy's quadratic terms with their owners and rest vectors: one edge term per directed
/// edge, one line term per grid-line triple, one umbrella term per vertex on no line (corners
/// excepted: straightening them would cut them); `[edge, line, umbrella]` scale their weights.
fn build_terms(
    structure: &LayoutStructure,
    rest: &[Vec3],
    [edge_scale, line_scale, umbrella_scale]: [f64; 3],
) -> (Stencils, Vec<u32>, Vec<DVec3>) {
    let mut stencils = Stencils::new();
    let mut owners = Vec::new();
    let mut rests = Vec::new();
    let rest: Vec<DVec3> = rest.iter().map(|p| p.as_dvec3()).collect();
    let mut on_line = vec![false; structure.vertex_count];
    for triple in &structure.line_triples {
        on_line[triple.vertex as usize] = true;
    }
    let mut is_corner = vec![false; structure.vertex_count];
    for &corner in &structure.corners {
        is_corner[corner as usize] = true;
    }
    for vertex in 0..structure.vertex_count as u32 {
        for &other in structure.neighbors_of(vertex) {
            stencils.push([(other, 1.0), (vertex, -1.0)], EDGE_WEIGHT * edge_scale);
            owners.push(vertex);
            rests.push(rest[other as usize] - rest[vertex as usize]);
        }
    }
    for triple in &structure.line_triples {
        stencils.push(
            [
                (triple.previous, 1.0),
                (triple.next, 1.0),
                (triple.vertex, -2.0),
            ],
            LINE_WEIGHT * line_scale,
        );
        owners.push(triple.vertex);
        rests.push(
            rest[triple.previous as usize] + rest[triple.next as usize]
                - rest[triple.vertex as usize] * 2.0,
        );
    }
    for vertex in 0..structure.vertex_count as u32 {
        let neighbors = structure.neighbors_of(vertex);
        if on_line[vertex as usize] || is_corner[vertex as usize] || neighbors.is_empty() {
            continue;
        }
        let share = 1.0 / neighbors.len() as f64;
        let mean: DVec3 = neighbors
            .iter()
            .map(|&other| rest[other as usize])
            .sum::<DVec3>()
            * share;
        stencils.push(
            neighbors
                .iter()
                .map(|&other| (other, share))
                .chain([(vertex, -1.0)]),
            LINE_WEIGHT * umbrella_scale,
        );
        owners.push(vertex);
        rests.push(mean - rest[vertex as usize]);
    }
    (stencils, owners, rests)
}

/// The target's vertex normals averaged over a neighbourhood about `radius` wide (rounds of
/// vertex → triangle → vertex averaging, as many as `(radius / mean target edge)²`).
fn smoothed_vertex_normals(target: &TargetMesh, radius: f32) -> Vec<Vec3> {
    let vertices = target.vertices();
    let triangles = target.triangles();
    let mut normals = target.vertex_normals().to_vec();
    let edge_sum: f64 = triangles
        .par_iter()
        .with_min_len(4096)
        .map(|corners| {
            f64::from(vertices[corners[0] as usize].distance(vertices[corners[1] as usize]))
        })
        .sum();
    let target_edge = (edge_sum / triangles.len().max(1) as f64) as f32;
    let ratio = if target_edge > 0.0 {
        radius / target_edge
    } else {
        1.0
    };
    let rounds =
        ((ratio * ratio) as usize).clamp(NORMAL_SMOOTHING_ROUNDS.0, NORMAL_SMOOTHING_ROUNDS.1);
    let mut triangle_normals = vec![Vec3::ZERO; triangles.len()];
    for _ in 0..rounds {
        triangle_normals
            .par_iter_mut()
            .with_min_len(4096)
            .zip(triangles.par_iter())
            .for_each(|(normal, corners)| {
                *normal = corners.iter().map(|&corner| normals[corner as usize]).sum();
            });
        let mut sums = vec![Vec3::ZERO; vertices.len()];
        for (corners, normal) in triangles.iter().zip(&triangle_normals) {
            for &corner in corners {
                sums[corner as usize] += *normal;
            }
        }
        normals = sums
            .into_iter()
            .zip(&normals)
            .map(|(sum, old)| {
                let smoothed = sum.normalize_or_zero();
                if smoothed == Vec3::ZERO {
                    *old
                } else {
                    smoothed
                }
            })
            .collect();
    }
    normals
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TargetMeshOptions;

    /// A flat target (z = 0, [-1, 1]², 20 x 20 cells) and an `n` x `n` quad grid layout of cell
    /// `size` at height `height`, lower corner at (-n size / 2, -n size / 2).
    fn plane_and_grid(
        n: u32,
        size: f32,
        height: f32,
    ) -> (Arc<TargetMesh>, LayoutStructure, Vec<Vec3>) {
        let cells = 20u32;
        let row = cells + 1;
        let vertices = (0..row * row)
            .map(|index| {
                Vec3::new(
                    (index % row) as f32 / cells as f32 * 2.0 - 1.0,
                    (index / row) as f32 / cells as f32 * 2.0 - 1.0,
                    0.0,
                )
            })
            .collect();
        let mut triangles = Vec::new();
        for y in 0..cells {
            for x in 0..cells {
                let a = y * row + x;
                triangles.push([a, a + 1, a + row + 1]);
                triangles.push([a, a + row + 1, a + row]);
            }
        }
        let target =
            Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
        let layout_row = n + 1;
        let half = n as f32 * size * 0.5;
        let positions: Vec<Vec3> = (0..layout_row * layout_row)
            .map(|index| {
                Vec3::new(
                    (index % layout_row) as f32 * size - half,
                    (index / layout_row) as f32 * size - half,
                    height,
                )
            })
            .collect();
        let mut corners = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let a = y * layout_row + x;
                corners.extend([a, a + 1, a + layout_row + 1, a + layout_row]);
            }
        }
        let structure = LayoutStructure::new(
            positions.len(),
            &corners,
            &vec![4; (n * n) as usize],
            &[],
            &[],
        )
        .unwrap();
        (target, structure, positions)
    }

    fn solver(
        target: &Arc<TargetMesh>,
        structure: &LayoutStructure,
        positions: &[Vec3],
        rest: &[Vec3],
        anchors: &[Option<(AnchorTarget, Vec3)>],
    ) -> EnergySolver {
        let schedule = WrapSchedule::Local;
        solver_following(schedule, target, structure, positions, rest, anchors)
    }

    fn solver_following(
        schedule: WrapSchedule,
        target: &Arc<TargetMesh>,
        structure: &LayoutStructure,
        positions: &[Vec3],
        rest: &[Vec3],
        anchors: &[Option<(AnchorTarget, Vec3)>],
    ) -> EnergySolver {
        let points: Vec<LayoutPoint> = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
        EnergySolver::new(&EnergyInputs {
            target,
            structure,
            rest,
            positions,
            anchor_of_vertex: anchors,
            soft_pairs: &[],
            curve_target_of_vertex: &[],
            unreliable: &[],
            stiffness: &[],
            free: &[],
            points: &points,
            plane: None,
            on_plane: &[],
            plane_slide: true,
            mean_edge_length: 0.1,
            landing_distance: 0.025,
            settings: WrapSettings {
                schedule,
                ..WrapSettings::default()
            },
        })
        .unwrap()
    }

    #[test]
    fn the_global_step_zeroes_the_energys_gradient_by_finite_differences() {
        let (target, structure, rest) = plane_and_grid(6, 0.1, 0.05);
        // Start bent and shifted away from the rest shape, with one anchor, so that every term
        // (edges, lines, umbrellas at the corners' neighbours, data, fixed columns) is active.
        let positions: Vec<Vec3> = rest
            .iter()
            .map(|p| *p + Vec3::new(0.02 * (p.y * 9.0).sin(), 0.01, 0.1 * p.x * p.x))
            .collect();
        let mut anchors = vec![None; rest.len()];
        let anchor_position = Vec3::new(0.05, 0.0, 0.0);
        let hit = target.closest_point(anchor_position, 1.0).unwrap();
        anchors[24] = Some((AnchorTarget::Face(hit.face_point), hit.position));
        let mut solver = solver(&target, &structure, &positions, &rest, &anchors);
        solver.smooth_scales(Some(2));
        let normals = solver.layout_normals(&solver.positions);
        let correspondences = solver.correspondences(&normals, 0.2);
        assert!(correspondences.iter().filter(|c| c.is_some()).count() > 30);
        let data_weight = 3.0;
        let solution = solver.global_solve(&correspondences, data_weight).unwrap();
        let previous = solver.positions.clone();
        let energy = |positions: &[Vec3]| {
            solver.energy_at(positions, &correspondences, data_weight, &previous)
        };
        let gradient_norm = |at: &[Vec3]| {
            let step = 1e-3f32;
            let mut norm = 0.0f64;
            for vertex in 0..at.len() {
                if solver.fixed[vertex].is_some() {
                    continue;
                }
                for axis in 0..3 {
                    let mut plus = at.to_vec();
                    let mut minus = at.to_vec();
                    plus[vertex][axis] += step;
                    minus[vertex][axis] -= step;
                    let derivative = (energy(&plus) - energy(&minus)) / (2.0 * f64::from(step));
                    norm += derivative * derivative;
                }
            }
            norm.sqrt()
        };
        let at_start = gradient_norm(&previous);
        let at_solution = gradient_norm(&solution);
        assert!(at_start > 0.1, "{at_start}");
        assert!(
            at_solution < at_start * 1e-3,
            "gradient {at_solution} at the solution, {at_start} at the start"
        );
        assert!(energy(&solution) < energy(&previous));
        assert_eq!(solution[24], hit.position, "the anchor is met exactly");
    }

    #[test]
    fn the_safeguard_backs_off_exactly_the_steps_that_turn_a_corner() {
        let (target, structure, rest) = plane_and_grid(6, 0.1, 0.05);
        let solver = solver(&target, &structure, &rest, &rest, &vec![None; rest.len()]);
        // Every point moves down by 0.01; vertex 24 (interior) also jumps across its right-hand
        // neighbour, which turns its corners over.
        let mut proposed: Vec<Vec3> = rest.iter().map(|p| *p - Vec3::Z * 0.01).collect();
        proposed[24] += Vec3::new(0.25, 0.0, 0.0);
        let before = solver.corner_orientations(&rest);
        assert!(!solver.turned_corners(&before, &proposed).is_empty());
        let (accepted, held_back) = solver.safeguard(&proposed);
        assert!(solver.turned_corners(&before, &accepted).is_empty());
        assert!((1..=9).contains(&held_back), "{held_back}");
        let far_away = [0usize, 6, 42, 48];
        for vertex in far_away {
            assert_eq!(
                accepted[vertex], proposed[vertex],
                "vertex {vertex} far from the fold"
            );
        }
        assert_ne!(accepted[24], proposed[24]);
    }

    /// A strip of a grid (its last two columns) folded up about a grid line by 10 degrees a step
    /// through the safeguard of a solver following `schedule`: the least corner alignment at the
    /// end and the angle the strip turned by, in degrees.
    fn folded_strip(schedule: WrapSchedule) -> (f32, f32) {
        let (target, structure, rest) = plane_and_grid(10, 0.1, 0.05);
        let none = vec![None; rest.len()];
        let mut solver = solver_following(schedule, &target, &structure, &rest, &rest, &none);
        let hinge = rest[8].x;
        for step in 1..=18 {
            let angle = (step as f32 * 10.0).to_radians();
            let turn = Quat::from_rotation_y(-angle);
            let proposed: Vec<Vec3> = rest
                .iter()
                .map(|&p| {
                    if p.x > hinge + 1e-6 {
                        let arm = Vec3::new(p.x - hinge, p.y, p.z - rest[0].z);
                        let turned = turn * Vec3::new(arm.x, 0.0, arm.z);
                        Vec3::new(hinge + turned.x, p.y, rest[0].z + turned.z)
                    } else {
                        p
                    }
                })
                .collect();
            solver.fit_similarities(false);
            let (accepted, _) = solver.safeguard(&proposed);
            solver.positions = accepted;
        }
        solver.fit_similarities(false);
        let worst = solver
            .corner_orientations(&solver.positions)
            .into_iter()
            .fold(f32::INFINITY, f32::min);
        let arm = solver.positions[10] - solver.positions[8];
        (worst, arm.z.atan2(arm.x).to_degrees())
    }

    #[test]
    fn a_region_cannot_roll_over_by_small_steps() {
        // Each step is small to the strip's own neighbourhood; the safeguard's frame is the whole
        // layout's, so the strip stops before its faces turn over.
        let (worst, angle) = folded_strip(WrapSchedule::Local);
        assert!(worst >= 0.0, "a corner turned to cosine {worst}");
        // The strip did fold up, as far as the safeguard let it: past 60 degrees, short of flat.
        assert!(
            (60.0..150.0).contains(&angle),
            "the strip turned by {angle} degrees"
        );
    }

    #[test]
    fn the_global_to_local_schedule_lets_a_corner_turn_less() {
        let (worst, angle) = folded_strip(WrapSchedule::GlobalToLocal);
        assert!(
            worst >= GLOBAL_MIN_ALIGNMENT - 1e-4,
            "a corner turned to cosine {worst}"
        );
        let (_, local_angle) = folded_strip(WrapSchedule::Local);
        assert!(
            angle > 20.0 && angle < local_angle - 20.0,
            "the strip turned by {angle} degrees, {local_angle} in the local schedule"
        );
    }

    #[test]
    fn a_landing_that_would_turn_a_corner_is_refused() {
        let (target, structure, rest) = plane_and_grid(6, 0.1, 0.0);
        // The layout hovers just above the plane, but vertex 24 dips below it past its right-hand
        // neighbour's column: landing it straight down would fold its quads.
        let mut positions: Vec<Vec3> = rest.iter().map(|p| *p + Vec3::Z * 0.01).collect();
        positions[24] = Vec3::new(positions[25].x + 0.03, positions[24].y, 0.2);
        let mut solver = solver(
            &target,
            &structure,
            &positions,
            &rest,
            &vec![None; rest.len()],
        );
        solver.landing_distance = 1.0;
        let before = solver.corner_orientations(&positions);
        let (points, landed) = solver.land();
        assert!(solver.turned_corners(&before, &solver.positions).is_empty());
        // Vertex 24 stays up, and at most one neighbour whose quad it would fold; the others,
        // refused with it at first (their corners turn when all land at once), land one by one
        // afterwards (43 landed without that second pass).
        assert!(landed >= points.len() - 2, "{landed}");
        assert!(
            matches!(points[24], LayoutPoint::Space(_)),
            "{:?}",
            points[24]
        );
        for (vertex, point) in points.iter().enumerate() {
            if let LayoutPoint::Face(face_point) = point {
                assert_eq!(
                    target.face_point_position(*face_point).unwrap(),
                    solver.positions[vertex]
                );
            }
        }
    }

    #[test]
    fn without_a_factor_the_wrap_ends_where_it_ends_with_one() {
        // A layout too large to factor is solved by Jacobi-preconditioned iterations: on a small
        // grid above a plane (no factor allowed), the same place as with factors.
        let (target, structure, rest) = plane_and_grid(10, 0.1, 0.3);
        let mut anchors = vec![None; rest.len()];
        for corner in [0usize, 10, 110, 120] {
            let position = rest[corner] - Vec3::Z * 0.3;
            let hit = target.closest_point(position, 1.0).unwrap();
            anchors[corner] = Some((AnchorTarget::Face(hit.face_point), position));
        }
        let mut results = Vec::new();
        for limit in [MAX_FACTOR_BYTES, 0] {
            let mut wrap = solver(&target, &structure, &rest, &rest, &anchors);
            wrap.system =
                LinearSystem::new(&wrap.stencils, rest.len(), &wrap.fixed, limit).unwrap();
            assert_eq!(wrap.system.is_direct(), limit > 0);
            while !wrap.iterate().unwrap().finished {}
            assert_eq!(wrap.system.statistics().factorizations > 0, limit > 0);
            results.push(wrap.positions.clone());
        }
        let largest = results[0]
            .iter()
            .zip(&results[1])
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max);
        assert!(largest < 1e-3, "{largest}");
        assert!(results[1].iter().all(|p| p.z.abs() < 1e-3), "on the plane");
    }

    #[test]
    fn the_warm_up_carries_the_layout_with_its_anchors_as_rigidly_as_possible() {
        // Anchors far from the template (a posed limb): the corners of the grid, turned 70
        // degrees and shifted by three grid widths. Before any data term, the warm-up moves the
        // whole grid with them, with no step held back.
        let (target, structure, rest) = plane_and_grid(8, 0.1, 0.05);
        let motion =
            |p: Vec3| Quat::from_rotation_y(70f32.to_radians()) * p + Vec3::new(0.5, 0.3, 2.4);
        let mut anchors = vec![None; rest.len()];
        for vertex in [0, 8, 72, 80] {
            let position = motion(rest[vertex]);
            anchors[vertex] = Some((AnchorTarget::Space(position), position));
        }
        let mut solver = solver(&target, &structure, &rest, &rest, &anchors);
        let mut steps = 0;
        while solver.warming_up {
            let step = solver.iterate().unwrap();
            assert_eq!(step.held_back, 0);
            steps += 1;
        }
        assert!(steps <= WARMUP_MAX_ITERATIONS, "{steps}");
        for (vertex, position) in solver.positions.iter().enumerate() {
            let wanted = motion(rest[vertex]);
            assert!(
                position.distance(wanted) < 0.025,
                "vertex {vertex} at {position}, {wanted} wanted (edge 0.1)"
            );
        }
    }
}
