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

use std::sync::Arc;

use glam::{Quat, Vec3};
use rayon::prelude::*;

use super::anchor::{Anchor, AnchorTarget};
use super::curve_constraint::{ArcLengthCurve, CurveConstraint, chain_fractions};
use super::energy_solver::{EnergyInputs, EnergySolver};
use super::forces::{Similarity, SpringRest, Springs, thin_plate};
use super::plane_constraint::{Plane, PlaneConstraint};
use super::settings::{SolverKind, WrapSettings};
use crate::error::KernelError;
use crate::face_point::{FacePoint, LayoutPoint};
use crate::layout::LayoutStructure;
use crate::mesh::{NO_TRIANGLE, TargetMesh};
use crate::surface::WalkEnd;

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
    /// The energy solver, made at the first step of a wrap with [`SolverKind::Energy`].
    energy: Option<Box<EnergySolver>>,
    /// The region the points may reach: a centre and a radius (ten times the target's size and
    /// the layout's start about the target's centre); leaving it is divergence.
    reach: (Vec3, f32),
    /// Set once the wrap diverged: every later step returns it.
    diverged: Option<KernelError>,
}

impl WrapSolver {
    /// Prepares a wrap of the layout (`structure`, one point per vertex) onto `target`.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] (points vs. layout vertices),
    /// [`KernelError::TriangleIndexOutOfRange`] or [`KernelError::NonFinite`] for a bad point or
    /// anchor target, [`KernelError::InvalidArgument`] for a layout without edges, a zero-length
    /// edge, an anchor on a vertex that does not exist or on the same vertex twice, or a setting
    /// out of range.
    pub fn new(
        target: Arc<TargetMesh>,
        structure: LayoutStructure,
        points: Vec<LayoutPoint>,
        anchors: &[Anchor],
        settings: WrapSettings,
    ) -> Result<Self, KernelError> {
        Self::with_rest_shape(target, structure, points, None, anchors, settings)
    }

    /// Like [`WrapSolver::new`], with the shape the springs rest in given apart from the starting
    /// points: `rest` (one position per layout vertex, in any placement, size and orientation: only
    /// the shape matters) is the template as the artist made it, for a layout that was snapped or
    /// projected since. `None` rests at the starting positions.
    ///
    /// # Errors
    /// As [`WrapSolver::new`]; the zero-length edge check applies to the rest shape, and a rest
    /// shape of the wrong length or with a NaN is refused.
    pub fn with_rest_shape(
        target: Arc<TargetMesh>,
        structure: LayoutStructure,
        points: Vec<LayoutPoint>,
        rest: Option<Vec<Vec3>>,
        anchors: &[Anchor],
        settings: WrapSettings,
    ) -> Result<Self, KernelError> {
        settings.validate()?;
        if points.len() != structure.vertex_count {
            return Err(KernelError::LengthMismatch {
                what: "layout points and layout vertices",
                first: points.len(),
                second: structure.vertex_count,
            });
        }
        if structure.neighbors.is_empty() {
            return Err(KernelError::InvalidArgument {
                name: "layout",
                reason: "it has no edges: there is nothing to wrap".to_owned(),
            });
        }
        let positions = resolve_positions(&target, &points)?;
        let rest = match rest {
            None => positions.clone(),
            Some(rest) => {
                if rest.len() != structure.vertex_count {
                    return Err(KernelError::LengthMismatch {
                        what: "rest positions and layout vertices",
                        first: rest.len(),
                        second: structure.vertex_count,
                    });
                }
                if let Some(index) = rest.iter().position(|p| !p.is_finite()) {
                    return Err(KernelError::NonFinite {
                        what: "rest position",
                        index,
                    });
                }
                rest
            }
        };
        for vertex in 0..structure.vertex_count as u32 {
            for &other in structure.neighbors_of(vertex) {
                if other > vertex && rest[vertex as usize] == rest[other as usize] {
                    return Err(KernelError::InvalidArgument {
                        name: "layout",
                        reason: format!(
                            "the edge between vertices {vertex} and {other} has zero length"
                        ),
                    });
                }
            }
        }
        // The landing distance is a fraction of the mean edge length where the points are now
        // (snapping may have made a few edges zero: they do not count).
        let mut edge_length_sum = 0.0f64;
        let mut edge_count = 0usize;
        for vertex in 0..structure.vertex_count as u32 {
            for &other in structure.neighbors_of(vertex) {
                let length = positions[vertex as usize].distance(positions[other as usize]);
                if other > vertex && length > 0.0 {
                    edge_length_sum += f64::from(length);
                    edge_count += 1;
                }
            }
        }
        if edge_count == 0 {
            return Err(KernelError::InvalidArgument {
                name: "layout",
                reason: "all its points are at one place".to_owned(),
            });
        }
        let mean_edge_length = (edge_length_sum / edge_count as f64) as f32;
        let mut anchor_of_vertex = vec![None; structure.vertex_count];
        for (index, anchor) in anchors.iter().enumerate() {
            let slot = anchor_of_vertex
                .get_mut(anchor.vertex as usize)
                .ok_or_else(|| KernelError::InvalidArgument {
                    name: "anchors",
                    reason: format!(
                        "anchor {index} is on vertex {}, but the layout has {} vertices",
                        anchor.vertex, structure.vertex_count
                    ),
                })?;
            if slot.is_some() {
                return Err(KernelError::InvalidArgument {
                    name: "anchors",
                    reason: format!("vertex {} has more than one anchor", anchor.vertex),
                });
            }
            let position = match anchor.target {
                AnchorTarget::Face(face_point) => target
                    .face_point_position(face_point)
                    .map_err(|error| relabel_anchor_error(error, index))?,
                AnchorTarget::Space(position) => {
                    if !position.is_finite() {
                        return Err(KernelError::NonFinite {
                            what: "anchor target",
                            index,
                        });
                    }
                    position
                }
            };
            *slot = Some((anchor.target, position));
        }
        let (min, max) = positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(min, max), &p| {
                (min.min(p), max.max(p))
            });
        let layout_size = (max - min).length().max(f32::MIN_POSITIVE);
        let springs = Springs::new(&structure, &rest, settings.rest);
        let energy_rest = if settings.solver == SolverKind::Energy {
            rest
        } else {
            Vec::new()
        };
        let mut is_corner = vec![false; structure.vertex_count];
        for &corner in &structure.corners {
            is_corner[corner as usize] = true;
        }
        let _ = target.face_normals(); // built now rather than inside the first iteration
        let reach = {
            let bounds = target.bounds;
            let centre = Vec3::from((bounds.min + bounds.max) * 0.5);
            let target_size = Vec3::from(bounds.max - bounds.min).length();
            let start_size = positions
                .iter()
                .map(|position| position.distance(centre))
                .fold(0.0f32, f32::max);
            (centre, REACH_FACTOR * target_size.max(start_size))
        };
        Ok(Self {
            orientation: 0.0,
            target,
            springs,
            similarities: vec![Similarity::IDENTITY; structure.vertex_count],
            global_scale: 1.0,
            settings,
            fold_tolerance: settings.fold_tolerance,
            landing_distance: settings.landing_distance * mean_edge_length,
            lift_counts: vec![0; structure.vertex_count],
            no_fold_until: vec![0; structure.vertex_count],
            layout_size,
            velocities: vec![Vec3::ZERO; structure.vertex_count],
            step_scales: vec![1.0; structure.vertex_count],
            mean_moves: vec![(Vec3::ZERO, 0.0); structure.vertex_count],
            structure,
            points,
            positions,
            anchor_of_vertex,
            is_corner,
            unreliable: Vec::new(),
            walk_neighbors: None,
            curve_target_of_vertex: Vec::new(),
            plane: None,
            on_plane: Vec::new(),
            plane_slide: true,
            total_iterations: 0,
            quiet_iterations: 0,
            iteration: 0,
            rest: energy_rest,
            mean_edge_length,
            stiffness: Vec::new(),
            free: Vec::new(),
            energy: None,
            reach,
            diverged: None,
        })
    }

    /// Sets how firmly each vertex keeps the template's shape: 0 follows the target freely, 0.5
    /// is the wrap's own balance, 1 keeps the template's shape (no pull toward the target; the
    /// shape terms it owns weigh 100 times more). One value per layout vertex, in [0, 1]. Only the
    /// energy solver ([`SolverKind::Energy`]) takes it; the spring solver refuses it at its first
    /// step.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] unless there is one value per layout vertex,
    /// [`KernelError::InvalidArgument`] for a value outside [0, 1] or NaN.
    pub fn with_vertex_stiffness(mut self, stiffness: Vec<f32>) -> Result<Self, KernelError> {
        if stiffness.len() != self.structure.vertex_count {
            return Err(KernelError::LengthMismatch {
                what: "stiffness values and layout vertices",
                first: stiffness.len(),
                second: self.structure.vertex_count,
            });
        }
        if let Some(vertex) = stiffness
            .iter()
            .position(|value| !(0.0..=1.0).contains(value))
        {
            return Err(KernelError::InvalidArgument {
                name: "stiffness",
                reason: format!(
                    "vertex {vertex} has stiffness {}; it must be within 0 … 1",
                    stiffness[vertex]
                ),
            });
        }
        self.stiffness = stiffness;
        Ok(self)
    }

    /// Marks layout vertices as free: no pull toward the target (eye and mouth sockets, teeth,
    /// a region the target does not have); they follow their neighbours by the template's shape
    /// and stay space-points. One flag per layout vertex. Only the energy solver takes it.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] unless there is one flag per layout vertex.
    pub fn with_free_vertices(mut self, free: Vec<bool>) -> Result<Self, KernelError> {
        if free.len() != self.structure.vertex_count {
            return Err(KernelError::LengthMismatch {
                what: "free vertex flags and layout vertices",
                first: free.len(),
                second: self.structure.vertex_count,
            });
        }
        self.free = free;
        Ok(self)
    }

    /// Marks target triangles as unreliable (noisy or untrusted data, paper 2.5): points there
    /// behave as space-points. Face-points on them are detached now; walks that end on them lift
    /// off; folding never lands on them. Holes need no marking.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] unless there is one flag per target triangle.
    pub fn with_unreliable_triangles(mut self, unreliable: Vec<bool>) -> Result<Self, KernelError> {
        let triangle_count = self.target.triangles().len();
        if unreliable.len() != triangle_count {
            return Err(KernelError::LengthMismatch {
                what: "unreliable triangle flags and target triangles",
                first: unreliable.len(),
                second: triangle_count,
            });
        }
        for (point, &position) in self.points.iter_mut().zip(&self.positions) {
            if let LayoutPoint::Face(face_point) = point
                && unreliable[face_point.triangle as usize]
            {
                *point = LayoutPoint::Space(position);
            }
        }
        let walk_neighbors = self
            .target
            .triangle_neighbors()
            .iter()
            .map(|neighbors| {
                neighbors.map(|neighbor| {
                    if neighbor != NO_TRIANGLE && unreliable[neighbor as usize] {
                        NO_TRIANGLE
                    } else {
                        neighbor
                    }
                })
            })
            .collect();
        self.walk_neighbors = Some(walk_neighbors);
        self.unreliable = unreliable;
        Ok(self)
    }

    /// Holds layout chains to target curves, matched by arc length (paper, section 2.4): each
    /// chain vertex is pulled to the target point at the same fraction of the curve's length as it
    /// has along the chain *now* (the template's spacing is kept; matching on the moving positions
    /// would feed back on itself), and lands on the surface when that point lies on it. Anchored
    /// vertices keep their anchors; constrained points do not fold.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] for a chain shorter than 2 vertices, a vertex that does not
    /// exist, a vertex in two constraints, or a target curve with fewer than 2 points, a NaN, or
    /// zero length.
    pub fn with_curve_constraints(
        mut self,
        constraints: &[CurveConstraint],
    ) -> Result<Self, KernelError> {
        let mut owner: Vec<Option<usize>> = vec![None; self.points.len()];
        let mut targets = vec![None; self.points.len()];
        for (index, constraint) in constraints.iter().enumerate() {
            let invalid = |reason: String| KernelError::InvalidArgument {
                name: "curve constraints",
                reason: format!("curve constraint {index}: {reason}"),
            };
            if constraint.layout_vertices.len() < 2 {
                return Err(invalid(format!(
                    "the layout chain needs at least 2 vertices, it has {}",
                    constraint.layout_vertices.len()
                )));
            }
            for &vertex in &constraint.layout_vertices {
                let slot = owner.get_mut(vertex as usize).ok_or_else(|| {
                    invalid(format!(
                        "vertex {vertex} does not exist (the layout has {} vertices)",
                        self.points.len()
                    ))
                })?;
                if self.anchor_of_vertex[vertex as usize].is_some() {
                    continue;
                }
                if self.is_on_plane(vertex) {
                    return Err(invalid(format!(
                        "vertex {vertex} is also held on the plane constraint"
                    )));
                }
                if let Some(other) = *slot
                    && other != index
                {
                    return Err(invalid(format!(
                        "vertex {vertex} is also in curve constraint {other}"
                    )));
                }
                *slot = Some(index);
            }
            let curve = ArcLengthCurve::new(index, &constraint.target)?;
            let chain = &constraint.layout_vertices;
            for (&vertex, fraction) in chain.iter().zip(chain_fractions(&self.positions, chain)) {
                if self.anchor_of_vertex[vertex as usize].is_none() {
                    targets[vertex as usize] = Some(curve.point_at(fraction));
                }
            }
        }
        self.curve_target_of_vertex = targets;
        Ok(self)
    }

    /// Holds layout vertices on a plane (a mirrored layout's seam; paper, section 3): a held
    /// face-point slides only along the target's cross-section with the plane and is walked back
    /// onto the plane after every move; a held space-point moves within the plane and lands on
    /// the cross-section when it comes within the landing distance of it. Anchored vertices keep
    /// their anchors; held points do not fold.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] for a NaN or a zero normal, a vertex that does not exist,
    /// or a vertex also held by a curve constraint.
    pub fn with_plane_constraint(
        mut self,
        constraint: &PlaneConstraint,
    ) -> Result<Self, KernelError> {
        let plane = Plane::new(constraint.point, constraint.normal)?;
        let mut on_plane = vec![false; self.points.len()];
        for &vertex in &constraint.vertices {
            let invalid = |reason: String| KernelError::InvalidArgument {
                name: "plane constraint",
                reason,
            };
            if vertex as usize >= self.points.len() {
                return Err(invalid(format!(
                    "vertex {vertex} does not exist (the layout has {} vertices)",
                    self.points.len()
                )));
            }
            if self.anchor_of_vertex[vertex as usize].is_some() {
                continue;
            }
            if self
                .curve_target_of_vertex
                .get(vertex as usize)
                .is_some_and(Option::is_some)
            {
                return Err(invalid(format!(
                    "vertex {vertex} is also held by a curve constraint"
                )));
            }
            on_plane[vertex as usize] = true;
        }
        // Held points start on the plane: the springs' first look at the seam is where it stays.
        for (vertex, _) in on_plane.iter().enumerate().filter(|(_, held)| **held) {
            let (point, position) = match self.points[vertex] {
                LayoutPoint::Face(face_point) => match self.walk_onto_plane(&plane, face_point) {
                    Some((face_point, position)) => (LayoutPoint::Face(face_point), position),
                    None => {
                        let position = plane.project(self.positions[vertex]);
                        (LayoutPoint::Space(position), position)
                    }
                },
                LayoutPoint::Space(position) => {
                    let position = plane.project(position);
                    (LayoutPoint::Space(position), position)
                }
            };
            self.points[vertex] = point;
            self.positions[vertex] = position;
        }
        self.plane = Some(plane);
        self.plane_slide = constraint.slide;
        self.on_plane = on_plane;
        Ok(self)
    }

    /// Whether `vertex` is held on the plane.
    fn is_on_plane(&self, vertex: u32) -> bool {
        self.on_plane.get(vertex as usize).copied().unwrap_or(false)
    }

    /// Walks a face-point onto the plane along the surface (across the cross-section): `None`
    /// when the walk leaves the surface (a hole) or the surface runs along the plane there.
    fn walk_onto_plane(&self, plane: &Plane, start: FacePoint) -> Option<(FacePoint, Vec3)> {
        let tolerance = ON_PLANE * self.layout_size;
        let mut face_point = start;
        let mut position = self
            .target
            .interpolate(face_point.triangle, face_point.barycentric);
        for _ in 0..PLANE_WALKS {
            let distance = plane.distance(position);
            if distance.abs() <= tolerance {
                return Some((face_point, position));
            }
            let normal = self.target.face_normals()[face_point.triangle as usize];
            // The steepest way across the plane on the surface; walking `across * t` changes the
            // distance by `t |across|²`.
            let across = plane.normal - normal * plane.normal.dot(normal);
            let rate = across.length_squared();
            if rate < PLANE_GRAZING {
                return None;
            }
            let step = across * (-distance / rate);
            let step = step.clamp_length_max(distance.abs() * 4.0 + self.landing_distance);
            match self.walk(face_point, step) {
                WalkEnd::OnSurface(moved) if !self.is_unreliable(moved.triangle) => {
                    face_point = moved;
                    position = self.target.interpolate(moved.triangle, moved.barycentric);
                }
                _ => return None,
            }
        }
        (plane.distance(position).abs() <= tolerance * 100.0).then_some((face_point, position))
    }

    /// The new state of a point held on the plane, pushed by `force` (reads only the snapshot).
    fn update_on_plane(
        &self,
        plane: &Plane,
        vertex: u32,
        force: Vec3,
        deviations: &[Vec3],
    ) -> (LayoutPoint, Vec3, Event) {
        let index = vertex as usize;
        let here = self.positions[index];
        let scale = if self.plane_slide {
            self.step_scales[index]
        } else {
            0.0
        };
        match self.points[index] {
            LayoutPoint::Face(face_point) => {
                let normal = self.target.face_normals()[face_point.triangle as usize];
                // Along the cross-section only: where the surface's tangent plane meets the plane.
                let along = normal.cross(plane.normal).normalize_or_zero();
                let slide = along * force.dot(along) * scale;
                let walked = if slide == Vec3::ZERO {
                    WalkEnd::OnSurface(face_point)
                } else {
                    self.walk(face_point, slide)
                };
                let moved = match walked {
                    WalkEnd::OnSurface(moved) if !self.is_unreliable(moved.triangle) => moved,
                    WalkEnd::OnSurface(moved) => {
                        let position = plane
                            .project(self.target.interpolate(moved.triangle, moved.barycentric));
                        return (LayoutPoint::Space(position), position, Event::Lifted);
                    }
                    WalkEnd::Lifted { position, .. } => {
                        let position = plane.project(position);
                        return (LayoutPoint::Space(position), position, Event::Lifted);
                    }
                };
                match self.walk_onto_plane(plane, moved) {
                    Some((face_point, position)) => {
                        (LayoutPoint::Face(face_point), position, Event::None)
                    }
                    None => {
                        let position = plane
                            .project(self.target.interpolate(moved.triangle, moved.barycentric));
                        (LayoutPoint::Space(position), position, Event::Lifted)
                    }
                }
            }
            LayoutPoint::Space(_) => {
                let push = force
                    + thin_plate(deviations, &self.structure, vertex)
                        * self.settings.weights.thin_plate;
                let moved = plane.project(here + plane.in_plane(push) * scale);
                // Sliding, the springs bring the point down to the surface; held, it only looks
                // as far as about an edge length (a landing distance is a quarter of one).
                let reach = if self.plane_slide {
                    self.landing_distance
                } else {
                    self.landing_distance * 4.0
                };
                if self.iteration >= self.no_fold_until[index]
                    && let Some(hit) = self.target.closest_point(moved, reach)
                    && !self.is_unreliable(hit.face_point.triangle)
                    && let Some((face_point, position)) =
                        self.walk_onto_plane(plane, hit.face_point)
                    && position.distance(moved) <= reach
                {
                    return (LayoutPoint::Face(face_point), position, Event::Landed);
                }
                (LayoutPoint::Space(moved), moved, Event::None)
            }
        }
    }

    /// Walks on the target, stopping at unreliable regions as at holes.
    fn walk(&self, start: FacePoint, displacement: Vec3) -> WalkEnd {
        match &self.walk_neighbors {
            Some(neighbors) => self.target.walk_on(neighbors, start, displacement),
            None => self.target.walk(start, displacement),
        }
    }

    /// Whether points on `triangle` must behave as space-points.
    fn is_unreliable(&self, triangle: u32) -> bool {
        self.unreliable
            .get(triangle as usize)
            .copied()
            .unwrap_or(false)
    }

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

    /// Runs up to `iterations` iterations, stopping early once converged.
    ///
    /// # Errors
    /// [`KernelError::Diverged`] when a point stops being finite or leaves the region the wrap
    /// can reach (the points are rolled back to where they were before this call, and every
    /// later call returns the same error). With [`SolverKind::Energy`]:
    /// [`KernelError::InvalidArgument`] when its linear system cannot be built or factored; with
    /// [`SolverKind::Springs`]: [`KernelError::InvalidArgument`] when vertex stiffness or free
    /// vertices are set.
    pub fn step(&mut self, iterations: usize) -> Result<StepReport, KernelError> {
        if let Some(error) = &self.diverged {
            return Err(error.clone());
        }
        let before = (self.points.clone(), self.positions.clone());
        let report = self.step_either(iterations);
        if let Some(vertex) = self.escaped_vertex() {
            (self.points, self.positions) = before;
            let error = KernelError::Diverged {
                iteration: self.total_iterations,
                vertex,
            };
            self.diverged = Some(error.clone());
            return Err(error);
        }
        report
    }

    /// The first point outside the region the wrap can reach (or not finite), if any.
    fn escaped_vertex(&self) -> Option<usize> {
        let (centre, radius) = self.reach;
        self.positions.iter().position(|position| {
            let distance = position.distance_squared(centre);
            distance.is_nan() || distance > radius * radius
        })
    }

    /// [`WrapSolver::step`] with the configured solver, before the divergence check.
    fn step_either(&mut self, iterations: usize) -> Result<StepReport, KernelError> {
        if self.settings.solver == SolverKind::Energy {
            return self.step_energy(iterations);
        }
        if !self.stiffness.is_empty() || !self.free.is_empty() {
            return Err(KernelError::InvalidArgument {
                name: "solver",
                reason: "vertex stiffness and free vertices need the energy solver".to_owned(),
            });
        }
        Ok(self.step_springs(iterations))
    }

    /// [`WrapSolver::step`] with the energy solver.
    fn step_energy(&mut self, iterations: usize) -> Result<StepReport, KernelError> {
        if self.energy.is_none() {
            let inputs = EnergyInputs {
                target: &self.target,
                structure: &self.structure,
                rest: &self.rest,
                positions: &self.positions,
                anchor_of_vertex: &self.anchor_of_vertex,
                curve_target_of_vertex: &self.curve_target_of_vertex,
                unreliable: &self.unreliable,
                stiffness: &self.stiffness,
                free: &self.free,
                points: &self.points,
                plane: self.plane,
                on_plane: &self.on_plane,
                plane_slide: self.plane_slide,
                mean_edge_length: self.mean_edge_length,
                landing_distance: self.landing_distance,
            };
            self.energy = Some(Box::new(EnergySolver::new(&inputs)?));
        }
        let mut report = self.empty_report();
        // Taken out while it steps, so that the plane's walks can read the rest of `self`.
        let mut energy = self.energy.take().expect("made above");
        if energy.is_finished() {
            report.converged = true;
        }
        while report.iterations < iterations && !report.converged {
            let outcome = match energy.iterate() {
                Ok(outcome) => outcome,
                Err(error) => {
                    self.energy = Some(energy);
                    return Err(error);
                }
            };
            report.iterations += 1;
            report.max_displacement = outcome.max_move / self.layout_size;
            report.mean_displacement = outcome.mean_move / self.layout_size;
            report.energy = outcome.energy;
            report.held_back = outcome.held_back;
            report.energy_decrease = outcome.energy_decrease;
            if outcome.finished {
                let (mut points, landed) = energy.land();
                // Held points end exactly on the plane: on the cross-section where they landed.
                if let Some(plane) = self.plane {
                    for (vertex, point) in points.iter_mut().enumerate() {
                        if !self.on_plane.get(vertex).copied().unwrap_or(false) {
                            continue;
                        }
                        *point = match *point {
                            LayoutPoint::Face(face_point) => {
                                match self.walk_onto_plane(&plane, face_point) {
                                    Some((face_point, _)) => LayoutPoint::Face(face_point),
                                    None => LayoutPoint::Space(
                                        plane.project(energy.positions()[vertex]),
                                    ),
                                }
                            }
                            LayoutPoint::Space(position) => {
                                LayoutPoint::Space(plane.project(position))
                            }
                        };
                    }
                    energy.set_positions_of(&points, &self.target);
                }
                report.folded = landed;
                report.landed = points
                    .iter()
                    .zip(&self.anchor_of_vertex)
                    .filter(|(point, anchor)| {
                        anchor.is_some() && matches!(point, LayoutPoint::Face(_))
                    })
                    .count();
                self.points = points;
                report.converged = true;
            } else {
                self.points = energy
                    .positions()
                    .iter()
                    .map(|&position| LayoutPoint::Space(position))
                    .collect();
            }
            self.positions = energy.positions().to_vec();
        }
        self.energy = Some(energy);
        self.close_report(&mut report);
        Ok(report)
    }

    /// A report of no iteration yet, at the current state.
    fn empty_report(&self) -> StepReport {
        StepReport {
            iterations: 0,
            total_iterations: self.total_iterations,
            max_displacement: 0.0,
            mean_displacement: 0.0,
            converged: false,
            face_points: 0,
            space_points: 0,
            landed: 0,
            folded: 0,
            lifted: 0,
            fold_tolerance: self.fold_tolerance,
            energy: f64::NAN,
            held_back: 0,
            energy_decrease: f64::NAN,
        }
    }

    /// Counts `report`'s iterations in, and fills in the totals and the point counts.
    fn close_report(&mut self, report: &mut StepReport) {
        self.total_iterations += report.iterations;
        report.total_iterations = self.total_iterations;
        report.face_points = self
            .points
            .iter()
            .filter(|point| matches!(point, LayoutPoint::Face(_)))
            .count();
        report.space_points = self.points.len() - report.face_points;
        report.fold_tolerance = self.fold_tolerance;
    }

    /// [`WrapSolver::step`] with the spring solver.
    fn step_springs(&mut self, iterations: usize) -> StepReport {
        let mut report = self.empty_report();
        for _ in 0..iterations {
            let (max_displacement, mean_displacement, counts) = self.iterate();
            report.iterations += 1;
            report.max_displacement = max_displacement / self.layout_size;
            report.mean_displacement = mean_displacement / self.layout_size;
            report.landed += counts.landed;
            report.folded += counts.folded;
            report.lifted += counts.lifted;
            if self.escaped_vertex().is_some() {
                break; // diverged: `step` rolls back and reports it
            }
            let changed = counts.landed + counts.folded + counts.lifted;
            // A few points flipping state at a hole's rim or in a crease do not keep a large layout
            // from converging; a front of folding points does.
            let few = self.points.len() / QUIET_CHANGES_PER_POINT;
            self.quiet_iterations = if changed <= few {
                self.quiet_iterations + 1
            } else {
                0
            };
            if report.mean_displacement <= self.settings.tolerance
                && report.max_displacement <= self.settings.tolerance * MAX_MOVE_AT_CONVERGENCE
                && self.quiet_iterations >= QUIET_ITERATIONS
            {
                report.converged = true;
                break;
            }
        }
        self.close_report(&mut report);
        report
    }

    /// One Jacobi iteration over all points; returns the largest and the mean displacement and
    /// the events.
    fn iterate(&mut self) -> (f32, f32, EventCounts) {
        let vertex_count = self.points.len();
        let first = self.iteration == 0;
        // Rotations per vertex; one scale for all: the median of the vertices' own scales (see
        // `global_scale`), from the fits of the previous iteration (of this one at the start).
        let fits =
            self.springs
                .fit_all(&self.positions, &self.structure, &self.similarities, first);
        let scale = if first {
            median_scale(&fits).unwrap_or(1.0)
        } else {
            self.global_scale
        };
        if let Some(median) = median_scale(&fits) {
            self.global_scale = median;
        }
        for (slot, fit) in self.similarities.iter_mut().zip(&fits) {
            *slot = Similarity {
                rotation: fit.rotation,
                scale,
            };
        }
        let deviations: Vec<Vec3> = (0..vertex_count as u32)
            .into_par_iter()
            .with_min_len(1024)
            .map(|vertex| {
                self.springs.umbrella_deviation(
                    &self.positions,
                    &self.structure,
                    vertex,
                    self.similarities[vertex as usize],
                )
            })
            .collect();
        self.orientation = self.measure_orientation();
        let updates: Vec<(LayoutPoint, Vec3, Event)> = (0..vertex_count as u32)
            .into_par_iter()
            .with_min_len(512)
            .map(|vertex| {
                let curve_target = self
                    .curve_target_of_vertex
                    .get(vertex as usize)
                    .copied()
                    .flatten();
                self.update_point(vertex, &deviations, curve_target)
            })
            .collect();
        let mut counts = EventCounts::default();
        let mut max_displacement = 0.0f32;
        let mut total_displacement = 0.0f64;
        for (vertex, (point, position, event)) in updates.into_iter().enumerate() {
            let finite = position.is_finite()
                && match point {
                    LayoutPoint::Face(face_point) => face_point.barycentric.is_finite(),
                    LayoutPoint::Space(at) => at.is_finite(),
                };
            // A degenerate configuration (points at one place, a zero-area fold) must never write
            // a NaN into the layout: such a point stays where it was this iteration.
            let (point, position, event) = if finite {
                (point, position, event)
            } else {
                (self.points[vertex], self.positions[vertex], Event::None)
            };
            let moved = position - self.positions[vertex];
            max_displacement = max_displacement.max(moved.length());
            total_displacement += f64::from(moved.length());
            let same_state = matches!(
                (point, self.points[vertex]),
                (LayoutPoint::Face(_), LayoutPoint::Face(_))
                    | (LayoutPoint::Space(_), LayoutPoint::Space(_))
            );
            // Momentum carries a move on only while the point keeps its state.
            let keeps_moving = same_state && matches!(event, Event::None | Event::FoldCandidate);
            let (mean_move, mean_length) = &mut self.mean_moves[vertex];
            *mean_move = *mean_move * (1.0 - MOVE_AVERAGING) + moved * MOVE_AVERAGING;
            *mean_length = *mean_length * (1.0 - MOVE_AVERAGING) + moved.length() * MOVE_AVERAGING;
            let rocking = mean_move.length() < ROCKING * *mean_length;
            let scale = &mut self.step_scales[vertex];
            *scale = if !keeps_moving {
                1.0
            } else if rocking {
                (*scale * 0.5).max(MIN_STEP_SCALE)
            } else {
                (*scale * 1.25).min(1.0)
            };
            self.velocities[vertex] = if keeps_moving { moved } else { Vec3::ZERO };
            self.points[vertex] = point;
            self.positions[vertex] = position;
            match event {
                Event::Landed => counts.landed += 1,
                Event::Folded => {
                    counts.folded += 1;
                    counts.fold_candidates += 1;
                }
                Event::FoldCandidate => counts.fold_candidates += 1,
                Event::Lifted => {
                    counts.lifted += 1;
                    let lifts = self.lift_counts[vertex].saturating_add(1);
                    self.lift_counts[vertex] = lifts;
                    let back_off = FOLD_BACK_OFF << lifts.min(16);
                    self.no_fold_until[vertex] = self.iteration + back_off;
                }
                Event::None => {}
            }
        }
        self.anneal(&counts);
        self.iteration += 1;
        let mean_displacement = (total_displacement / vertex_count.max(1) as f64) as f32;
        (max_displacement, mean_displacement, counts)
    }

    /// Whether the layout's faces wind the way the target's do where it lies on the target: +1,
    /// -1, or 0 while too few points are on it or they disagree (a layout still turning over).
    fn measure_orientation(&self) -> f32 {
        let face_normals = self.target.face_normals();
        let (agreement, count) = self
            .points
            .par_iter()
            .with_min_len(1024)
            .enumerate()
            .filter_map(|(vertex, point)| match point {
                LayoutPoint::Face(face_point) => {
                    let normal = self
                        .structure
                        .normal_at(&self.positions, vertex as u32)
                        .normalize_or_zero();
                    (normal != Vec3::ZERO)
                        .then(|| normal.dot(face_normals[face_point.triangle as usize]))
                }
                LayoutPoint::Space(_) => None,
            })
            .map(|dot| (dot, 1usize))
            .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        if count < ORIENTATION_MIN_POINTS {
            return 0.0;
        }
        let mean = agreement / count as f32;
        if mean > ORIENTATION_AGREEMENT {
            1.0
        } else if mean < -ORIENTATION_AGREEMENT {
            -1.0
        } else {
            0.0
        }
    }

    /// Simulated annealing of the folding tolerance: loosen while nothing folds, tighten when a
    /// large share of the candidates folds at once.
    fn anneal(&mut self, counts: &EventCounts) {
        if counts.fold_candidates == 0 {
            return;
        }
        let fraction = counts.folded as f32 / counts.fold_candidates as f32;
        if counts.folded == 0 {
            self.fold_tolerance *= 1.15;
        } else if fraction > FOLD_FRACTION_HIGH {
            self.fold_tolerance *= 0.85;
        }
        self.fold_tolerance = self
            .fold_tolerance
            .clamp(FOLD_TOLERANCE_RANGE.0, FOLD_TOLERANCE_RANGE.1);
    }

    /// The new state and position of one point (reads only the snapshot).
    fn update_point(
        &self,
        vertex: u32,
        deviations: &[Vec3],
        curve_target: Option<Vec3>,
    ) -> (LayoutPoint, Vec3, Event) {
        let weights = self.settings.weights;
        let index = vertex as usize;
        let here = self.positions[index];
        let anchor = self.anchor_of_vertex[index];
        if let Some((anchor_target, anchor_position)) = anchor {
            let pinned = match (self.points[index], anchor_target) {
                (LayoutPoint::Face(point), AnchorTarget::Face(target)) => point == target,
                (LayoutPoint::Space(_), AnchorTarget::Space(_)) => here == anchor_position,
                _ => false,
            };
            if pinned {
                // Anchors are constraints: once met, the point stays exactly there.
                return (self.points[index], here, Event::None);
            }
        }
        let constraint_target = anchor.map(|(_, position)| position).or(curve_target);
        let force = if let Some(target_position) = constraint_target {
            // Anchors and curve constraints are constraints: a constrained point heads straight
            // for its target (other forces would hold it at an equilibrium short of it); anchored
            // points are pinned once there.
            (target_position - here) * weights.constraint
        } else {
            let (fairness, arc_length) = self
                .springs
                .line_forces(&self.positions, vertex, self.similarities[index])
                .unwrap_or_else(|| {
                    // Straightening a corner would cut it and shrink the patch; holding it to its
                    // rest offset from its two neighbours does not.
                    if self.is_corner[index] && self.springs.kind() == SpringRest::Even {
                        (Vec3::ZERO, Vec3::ZERO)
                    } else {
                        (deviations[index], Vec3::ZERO)
                    }
                });
            let spring = fairness * weights.fairness + arc_length * weights.arc_length;
            // Adaptive restart: momentum only while the springs still pull the way the point was
            // going; carrying it against them overshoots, and overshoot is what flips quads.
            let velocity = self.velocities[index];
            if spring.dot(velocity) > 0.0 {
                spring + velocity * self.settings.momentum
            } else {
                spring
            }
        };
        if anchor.is_none()
            && self.is_on_plane(vertex)
            && let Some(plane) = &self.plane
        {
            return self.update_on_plane(plane, vertex, force, deviations);
        }
        match self.points[index] {
            LayoutPoint::Face(face_point) => {
                let normal = self.target.face_normals()[face_point.triangle as usize];
                if anchor.is_none() && curve_target.is_none() && self.is_inside_out(vertex, normal)
                {
                    // Pressed onto the surface inside out (a mouth bag snapped onto the lips): it
                    // lifts off, and the springs give the region its shape back.
                    return (LayoutPoint::Space(here), here, Event::Lifted);
                }
                let tangential = (force - normal * force.dot(normal)) * self.step_scales[index];
                match self.walk(face_point, tangential) {
                    WalkEnd::OnSurface(moved) => {
                        let position = self.target.interpolate(moved.triangle, moved.barycentric);
                        if let Some((AnchorTarget::Face(target), anchor_position)) = anchor
                            && anchor_position.distance(position) <= self.landing_distance
                        {
                            return (LayoutPoint::Face(target), anchor_position, Event::Landed);
                        }
                        if self.is_unreliable(moved.triangle) {
                            return (LayoutPoint::Space(position), position, Event::Lifted);
                        }
                        (LayoutPoint::Face(moved), position, Event::None)
                    }
                    WalkEnd::Lifted { position, .. } => {
                        (LayoutPoint::Space(position), position, Event::Lifted)
                    }
                }
            }
            LayoutPoint::Space(_) => {
                let moved = if constraint_target.is_some() {
                    here + force
                } else {
                    here + force
                        + thin_plate(deviations, &self.structure, vertex) * weights.thin_plate
                };
                if let Some((anchor_target, anchor_position)) = anchor
                    && anchor_position.distance(moved) <= self.landing_distance
                {
                    let landed = match anchor_target {
                        AnchorTarget::Face(face_point) => LayoutPoint::Face(face_point),
                        AnchorTarget::Space(_) => LayoutPoint::Space(anchor_position),
                    };
                    return (landed, anchor_position, Event::Landed);
                }
                if let Some(curve_position) = curve_target
                    && curve_position.distance(moved) <= self.landing_distance
                    && let Some(hit) = self
                        .target
                        .closest_point(curve_position, self.landing_distance * ON_CURVE)
                    && !self.is_unreliable(hit.face_point.triangle)
                {
                    // The target curve lies on the surface here: the point lands on it.
                    return (
                        LayoutPoint::Face(hit.face_point),
                        hit.position,
                        Event::Landed,
                    );
                }
                let scale = self.step_scales[index];
                let may_fold = weights.folding > 0.0
                    && constraint_target.is_none()
                    && self.iteration >= self.no_fold_until[index];
                if may_fold
                    && self.iteration.is_multiple_of(PROXIMITY_INTERVAL)
                    && let Some(landed) = self.land_nearby(vertex, moved)
                {
                    return landed;
                }
                if may_fold && let Some(outcome) = self.fold(vertex, moved) {
                    return match outcome {
                        (LayoutPoint::Space(rotated), _, event) => {
                            let scaled = here + (rotated - here) * scale;
                            (LayoutPoint::Space(scaled), scaled, event)
                        }
                        landed => landed,
                    };
                }
                let scaled = here + (moved - here) * scale;
                (LayoutPoint::Space(scaled), scaled, Event::None)
            }
        }
    }

    /// Whether the layout around `vertex` faces against the surface normal `normal` (by more than
    /// [`INSIDE_OUT`]), once the layout's orientation on the target is known.
    fn is_inside_out(&self, vertex: u32, normal: Vec3) -> bool {
        if self.orientation == 0.0 {
            return false;
        }
        let layout_normal = self
            .structure
            .normal_at(&self.positions, vertex)
            .normalize_or_zero();
        layout_normal != Vec3::ZERO && layout_normal.dot(normal) * self.orientation < INSIDE_OUT
    }

    /// A space-point already lying on the surface, facing the way the layout does there, lands
    /// on it at once (the paper: space-points land once close enough): within a tenth of its mean
    /// edge length of the surface, and turned less than 45 degrees from it. Folding alone would
    /// take the points from the anchors one ring at a time; a template aligned on its target is
    /// mostly touching it already.
    fn land_nearby(&self, vertex: u32, position: Vec3) -> Option<(LayoutPoint, Vec3, Event)> {
        if self.orientation == 0.0 {
            return None;
        }
        let neighbors = self.structure.neighbors_of(vertex);
        if neighbors.is_empty() {
            return None;
        }
        let reach = neighbors
            .iter()
            .map(|&other| self.positions[other as usize].distance(position))
            .sum::<f32>()
            / neighbors.len() as f32
            * PROXIMITY_REACH;
        let normal = self
            .structure
            .normal_at(&self.positions, vertex)
            .normalize_or_zero();
        if normal == Vec3::ZERO || reach.is_nan() || reach <= 0.0 {
            return None;
        }
        let hit = self.target.closest_point(position, reach)?;
        let triangle = hit.face_point.triangle;
        if self.is_unreliable(triangle)
            || normal.dot(self.target.face_normals()[triangle as usize]) * self.orientation
                < PROXIMITY_FACING
        {
            return None;
        }
        Some((
            LayoutPoint::Face(hit.face_point),
            hit.position,
            Event::Folded,
        ))
    }

    /// Folding of a space-point at `position` around its face-point neighbours (the seeds):
    /// `None` when it has none.
    ///
    /// Each seed gives a fold: land (the marched point is within the tolerance) or a rotation.
    /// The point lands by the seed with the smallest angle; otherwise it moves to the mean of the
    /// rotated positions. Using every seed keeps the fold continuous: with only the nearest one it
    /// jumps when two neighbours swap places, and the point rocks between two positions.
    fn fold(&self, vertex: u32, position: Vec3) -> Option<(LayoutPoint, Vec3, Event)> {
        let layout_normal = self
            .structure
            .normal_at(&self.positions, vertex)
            .normalize_or_zero();
        let mut seeds = 0usize;
        let mut best_landing: Option<(f32, FacePoint, Vec3)> = None;
        let mut rotated_sum = Vec3::ZERO;
        for &other in self.structure.neighbors_of(vertex) {
            let LayoutPoint::Face(seed) = self.points[other as usize] else {
                continue;
            };
            seeds += 1;
            match self.fold_from(
                seed,
                self.positions[other as usize],
                position,
                layout_normal,
            ) {
                Fold::Land {
                    angle,
                    face_point,
                    position: landed,
                } => {
                    if best_landing.is_none_or(|(best, _, _)| angle < best) {
                        best_landing = Some((angle, face_point, landed));
                    }
                    rotated_sum += landed;
                }
                Fold::Rotate(rotated) => rotated_sum += rotated,
                Fold::Stay => rotated_sum += position,
            }
        }
        if seeds == 0 {
            return None;
        }
        if let Some((_, face_point, landed)) = best_landing {
            return Some((LayoutPoint::Face(face_point), landed, Event::Folded));
        }
        let rotated = rotated_sum / seeds as f32;
        Some((LayoutPoint::Space(rotated), rotated, Event::FoldCandidate))
    }

    /// The fold of a space-point at `position` around one seed (paper, section 2.5): its offset
    /// from the seed, projected on the seed's tangent plane, is marched along the surface.
    fn fold_from(
        &self,
        seed: FacePoint,
        seed_position: Vec3,
        position: Vec3,
        layout_normal: Vec3,
    ) -> Fold {
        let offset = position - seed_position;
        let length = offset.length();
        let normal = self.target.face_normals()[seed.triangle as usize];
        // A vertex of no face (a loose curve) has no facing to check.
        if layout_normal != Vec3::ZERO
            && self.orientation != 0.0
            && layout_normal.dot(normal) * self.orientation < FOLD_MIN_FACING
        {
            return Fold::Stay;
        }
        let along = (offset - normal * offset.dot(normal)).normalize_or_zero();
        if length == 0.0 || along == Vec3::ZERO {
            return Fold::Stay;
        }
        let (folded_point, folded_position) = match self.walk(seed, along * length) {
            WalkEnd::OnSurface(face_point) => (
                // Never land on unreliable data: the fold target then only guides the rotation.
                (!self.is_unreliable(face_point.triangle)).then_some(face_point),
                self.target
                    .interpolate(face_point.triangle, face_point.barycentric),
            ),
            // A hole on the way: the fold target floats in space (paper, section 2.5).
            WalkEnd::Lifted { position, .. } => (None, position),
        };
        // A march that did not move at all (it can happen exactly along an edge through vertices)
        // says nothing: the exact closest surface point is the fold target instead.
        let (folded_point, folded_position) =
            if folded_position.distance_squared(seed_position) <= (length * 1e-6).powi(2) {
                match self.target.closest_point(position, length) {
                    Some(hit) if !self.is_unreliable(hit.face_point.triangle) => {
                        (Some(hit.face_point), hit.position)
                    }
                    _ => return Fold::Stay,
                }
            } else {
                (folded_point, folded_position)
            };
        let folded_offset = folded_position - seed_position;
        let angle = offset.angle_between(folded_offset);
        if !angle.is_finite() || angle > FOLD_MAX_ANGLE {
            // Farther than this from the surface's way, the layout turns away from the target on
            // purpose (a mouth bag, an eye socket, a nostril the target has no surface for):
            // folding it flat would crush the region around it.
            return Fold::Stay;
        }
        if angle <= self.fold_tolerance
            && let Some(face_point) = folded_point
        {
            return Fold::Land {
                angle,
                face_point,
                position: folded_position,
            };
        }
        let axis = offset.cross(folded_offset).normalize_or_zero();
        if axis == Vec3::ZERO {
            return Fold::Stay;
        }
        let rotation = Quat::from_axis_angle(axis, angle * self.settings.weights.folding);
        Fold::Rotate(seed_position + rotation * offset)
    }
}

/// What folding around one seed proposes.
enum Fold {
    /// Land there, on the surface (the angle was within the tolerance).
    Land {
        angle: f32,
        face_point: FacePoint,
        position: Vec3,
    },
    /// Rotate toward the fold target, to this position.
    Rotate(Vec3),
    /// No fold: the offset or the march says nothing.
    Stay,
}

#[derive(Debug, Default, Clone, Copy)]
struct EventCounts {
    landed: usize,
    folded: usize,
    fold_candidates: usize,
    lifted: usize,
}

/// The median of the positive scales of `fits`; `None` when there is none.
fn median_scale(fits: &[Similarity]) -> Option<f32> {
    let mut scales: Vec<f32> = fits
        .iter()
        .map(|fit| fit.scale)
        .filter(|scale| *scale > 0.0)
        .collect();
    if scales.is_empty() {
        return None;
    }
    let middle = scales.len() / 2;
    Some(*scales.select_nth_unstable_by(middle, f32::total_cmp).1)
}

/// Positions of layout points; face-points are checked against the target.
fn resolve_positions(
    target: &TargetMesh,
    points: &[LayoutPoint],
) -> Result<Vec<Vec3>, KernelError> {
    let (layout_indices, face_points): (Vec<usize>, Vec<FacePoint>) = points
        .iter()
        .enumerate()
        .filter_map(|(index, point)| match point {
            LayoutPoint::Face(face_point) => Some((index, *face_point)),
            LayoutPoint::Space(_) => None,
        })
        .unzip();
    // Errors name the layout vertex, not the position among the face-points.
    let face_positions =
        target
            .face_point_positions(&face_points)
            .map_err(|error| match error {
                KernelError::TriangleIndexOutOfRange {
                    index,
                    triangle,
                    triangle_count,
                } => KernelError::TriangleIndexOutOfRange {
                    index: layout_indices[index],
                    triangle,
                    triangle_count,
                },
                KernelError::NonFinite { index, .. } => KernelError::NonFinite {
                    what: "barycentric",
                    index: layout_indices[index],
                },
                other => other,
            })?;
    let mut positions = Vec::with_capacity(points.len());
    let mut face_positions = face_positions.into_iter();
    for (index, point) in points.iter().enumerate() {
        positions.push(match point {
            LayoutPoint::Face(_) => face_positions.next().unwrap_or(Vec3::ZERO),
            LayoutPoint::Space(position) if position.is_finite() => *position,
            LayoutPoint::Space(_) => {
                return Err(KernelError::NonFinite {
                    what: "layout point",
                    index,
                });
            }
        });
    }
    Ok(positions)
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
