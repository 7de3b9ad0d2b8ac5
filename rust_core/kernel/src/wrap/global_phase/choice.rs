//! The automatic choice of the energy wrap's schedule ([`WrapSchedule::Auto`]).
//!
//! The global-to-local schedule finds the right fit where the local one settles into a wrong one:
//! a few anchors, or a change of proportions that slides the surface's points along it (a longer
//! limb, a wider hip: the nearest surface point is not where a point belongs, and stiff, nearly
//! affine levels carry whole regions there). Its stiff levels average the rotations over many
//! rings, so they cannot follow a *pose* (limbs turned each their own way about joints), and an
//! offset along the surface's normals (girth, a scan's template wrapped a little outside it) needs
//! no sliding: the local schedule's closest points find it. `Auto` tells these apart from the
//! anchors alone, against the best similarity of the template onto them:
//!
//! - **articulation**: each anchor with its [`NEIGHBOURHOOD`] − 1 nearest at rest, the rotation of
//!   the best similarity of those onto their positions, against the rotation of all anchors' best
//!   similarity: the root mean square angle. A pose turns a limb's neighbourhoods with the limb.
//! - **sliding**: each anchor's distance from the similarity's image of its rest point, less its
//!   part along the (turned) rest normal there: the root mean square over the anchors, over their
//!   bounding-box diagonal.
//!
//! `Auto` takes the local schedule for fewer than [`FEWEST_ANCHORS`] anchors (they say nothing of
//! the change) or for articulated ones (over [`ARTICULATED_DEGREES`]); else global to local for
//! fewer than [`MANY_ANCHORS`], and for more when the sliding exceeds [`LARGE_SLIDING`].
//!
//! Measured through the kernel (`benchmarks/few_anchors.py`'s bodies at 4, 6, 12 and 24 anchors,
//! `benchmarks/wrap_solvers.py`'s posed body and scans at 24). Articulation: 14–25° on the posed
//! body (6 to 24 anchors), 0.1–9° on every other case (the bodies, the ellipsoid, the scans).
//! Sliding with 12 and 24 anchors: 0.26 % and 0.34 % of the diagonal on the heavy body (whose
//! anchors sit 0.5–0.75 % from a similarity, mostly along the normals), 1.15 % and 1.13 % on the
//! bunny and elephant scans (1.6–1.9 %, half or more along the normals): there the local schedule
//! is better (heavy 24: 0.216 % mean error against 0.222 %; the scans' mean distance 0.021 against
//! 0.069 and 0.090 against 0.306 % of the diagonal); 1.5–1.8 % on the heavy-old, old-male and
//! young-female bodies, where global to local is better (24 anchors: 0.363 against 0.432, 0.307
//! against 0.348, 0.294 against 0.330). On the posed body (24 anchors) the local schedule ends at
//! 0.551 % against 0.616 %.

use glam::{DMat3, Vec3};

use super::super::anchor::AnchorTarget;
use super::super::linear_system::MAX_DIRECT_ROWS;
use super::super::settings::WrapSchedule;
use crate::align::{AlignMethod, Transform, fit_transform};
use crate::layout::LayoutStructure;

/// From this many anchors on, the local schedule unless the anchors slide far.
pub(crate) const MANY_ANCHORS: usize = 12;
/// The fewest anchors that say something of the change (a similarity needs 3).
pub(crate) const FEWEST_ANCHORS: usize = 3;
/// The sliding (see the module) as a fraction of the anchors' bounding-box diagonal above which
/// [`MANY_ANCHORS`] or more call for the global-to-local schedule.
pub(crate) const LARGE_SLIDING: f32 = 0.013;
/// An anchor and its nearest others at rest, whose similarity's rotation measures articulation.
pub(crate) const NEIGHBOURHOOD: usize = 4;
/// The root mean square angle (degrees) of the neighbourhoods' rotations from the rotation of
/// all anchors above which the anchors are articulated (a pose).
pub(crate) const ARTICULATED_DEGREES: f32 = 12.0;

/// The schedule to follow for `schedule` (itself unless it is [`WrapSchedule::Auto`]), a layout
/// of `structure` resting at `rest` with `anchor_of_vertex` (per vertex, its anchor and
/// position).
pub(crate) fn choose_schedule(
    schedule: WrapSchedule,
    structure: &LayoutStructure,
    rest: &[Vec3],
    anchor_of_vertex: &[Option<(AnchorTarget, Vec3)>],
) -> WrapSchedule {
    if schedule != WrapSchedule::Auto {
        return schedule;
    }
    if !global_phase_fits(structure.vertex_count) {
        return WrapSchedule::Local;
    }
    let mut anchors = Anchors::default();
    for (vertex, anchor) in anchor_of_vertex.iter().enumerate() {
        if let (Some((_, position)), Some(&at_rest)) = (anchor, rest.get(vertex)) {
            anchors.sources.push(at_rest);
            let normal = structure.normal_at(rest, vertex as u32);
            anchors.normals.push(normal.normalize_or_zero());
            anchors.targets.push(*position);
        }
    }
    anchors.schedule()
}

/// Whether the global-to-local schedule can run on a layout of `vertex_count` vertices: its
/// smoothing is one factored solve of the layout's Laplacian, not analysed past
/// [`MAX_DIRECT_ROWS`] rows (`Auto` then chooses the local schedule).
pub(crate) fn global_phase_fits(vertex_count: usize) -> bool {
    vertex_count <= MAX_DIRECT_ROWS
}

/// Anchors: rest points, unit rest normals (zero where a vertex has none) and positions.
#[derive(Debug, Clone, Default)]
pub(crate) struct Anchors {
    pub(crate) sources: Vec<Vec3>,
    pub(crate) normals: Vec<Vec3>,
    pub(crate) targets: Vec<Vec3>,
}

impl Anchors {
    /// The schedule `Auto` chooses for these anchors (see the module).
    pub(crate) fn schedule(&self) -> WrapSchedule {
        let count = self.sources.len();
        if count < FEWEST_ANCHORS {
            return WrapSchedule::Local;
        }
        if count < MANY_ANCHORS {
            return WrapSchedule::GlobalToLocal;
        }
        if self
            .articulation()
            .is_some_and(|degrees| degrees > ARTICULATED_DEGREES)
        {
            return WrapSchedule::Local;
        }
        match self.sliding() {
            Some(sliding) if sliding > LARGE_SLIDING => WrapSchedule::GlobalToLocal,
            _ => WrapSchedule::Local,
        }
    }

    /// The root mean square distance of the targets from the best similarity of the sources onto
    /// them, less its part along the similarity's turned rest normals, over the targets'
    /// bounding-box diagonal; `None` when no similarity fits (the anchors on one line or at one
    /// point).
    pub(crate) fn sliding(&self) -> Option<f32> {
        let similarity =
            fit_transform(&self.sources, &self.targets, AlignMethod::Similarity, None).ok()?;
        let rotation = rotation_of(&similarity)?.as_mat3();
        let (low, high) = self.targets.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(low, high), &point| (low.min(point), high.max(point)),
        );
        let diagonal = (high - low).length();
        if !(diagonal > 0.0 && diagonal.is_finite()) {
            return None;
        }
        let squares: f32 = (0..self.sources.len())
            .map(|index| {
                let off = self.targets[index] - similarity.apply(self.sources[index]);
                let normal = rotation * self.normals[index];
                (off - normal * off.dot(normal)).length_squared()
            })
            .sum();
        let sliding = (squares / self.sources.len() as f32).sqrt() / diagonal;
        sliding.is_finite().then_some(sliding)
    }

    /// How far the anchors' neighbourhoods turn each their own way: over the anchors whose
    /// [`NEIGHBOURHOOD`] (the anchor and its nearest others at rest) a similarity fits, the root
    /// mean square angle in degrees between that similarity's rotation and the rotation of the
    /// similarity of all anchors. `None` with no more anchors than a neighbourhood (it would be
    /// all of them) or when no similarity fits.
    pub(crate) fn articulation(&self) -> Option<f32> {
        let (sources, targets) = (&self.sources, &self.targets);
        if sources.len() <= NEIGHBOURHOOD {
            return None;
        }
        let whole = fit_transform(sources, targets, AlignMethod::Similarity, None).ok()?;
        let whole = rotation_of(&whole)?;
        let (mut squares, mut count) = (0.0f64, 0usize);
        for &anchor in sources {
            let mut order: Vec<usize> = (0..sources.len()).collect();
            order.sort_by(|&a, &b| {
                anchor
                    .distance_squared(sources[a])
                    .total_cmp(&anchor.distance_squared(sources[b]))
            });
            order.truncate(NEIGHBOURHOOD);
            let near: Vec<Vec3> = order.iter().map(|&index| sources[index]).collect();
            let far: Vec<Vec3> = order.iter().map(|&index| targets[index]).collect();
            let Some(turned) = fit_transform(&near, &far, AlignMethod::Similarity, None)
                .ok()
                .and_then(|fit| rotation_of(&fit))
            else {
                continue;
            };
            // trace(turned wholeᵀ): the sum of the products of their entries.
            let trace: f64 = (0..3)
                .map(|axis| turned.col(axis).dot(whole.col(axis)))
                .sum();
            let angle = ((trace - 1.0) * 0.5).clamp(-1.0, 1.0).acos().to_degrees();
            squares += angle * angle;
            count += 1;
        }
        let degrees = (count > 0).then(|| (squares / count as f64).sqrt() as f32)?;
        degrees.is_finite().then_some(degrees)
    }
}

/// The rotation of a similarity (its linear part over its scale); `None` for a degenerate one.
fn rotation_of(similarity: &Transform) -> Option<DMat3> {
    let linear = DMat3::from_cols_array_2d(&similarity.linear()).transpose();
    let scale = linear.determinant().cbrt();
    (scale > 0.0 && scale.is_finite()).then(|| linear / scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::face_point::FacePoint;
    use glam::Quat;

    #[test]
    fn the_global_phase_fits_layouts_its_laplacian_can_be_factored_for() {
        assert!(global_phase_fits(4) && global_phase_fits(MAX_DIRECT_ROWS));
        assert!(!global_phase_fits(MAX_DIRECT_ROWS + 1) && !global_phase_fits(2048 * 2048));
    }

    /// The anchors at `rest` with unit `normals`, their positions `moved` from rest.
    fn anchors(rest: &[Vec3], normals: &[Vec3], moved: impl Fn(Vec3) -> Vec3) -> Anchors {
        Anchors {
            sources: rest.to_vec(),
            normals: normals.to_vec(),
            targets: rest.iter().map(|&point| moved(point)).collect(),
        }
    }

    /// `count` points spread over the unit sphere (a Fibonacci spiral): each is its own normal.
    fn sphere(count: usize) -> Vec<Vec3> {
        (0..count)
            .map(|index| {
                let height = 1.0 - 2.0 * (index as f32 + 0.5) / count as f32;
                let around = index as f32 * 2.399_963;
                let ring = (1.0 - height * height).sqrt();
                Vec3::new(ring * around.cos(), height, ring * around.sin())
            })
            .collect()
    }

    /// A stick figure of 24 points: a torso of 12, then arms of 6 reaching out along ±x from
    /// shoulders at (±0.2, 0.6, 0), the points of an arm off its line by a few centimetres.
    fn figure() -> Vec<Vec3> {
        let sign = |positive: bool| if positive { 1.0 } else { -1.0 };
        let torso = (0..12).map(|index| {
            let (x, z) = (sign(index % 2 == 1), sign((index / 2) % 2 == 1));
            Vec3::new(0.15 * x, 0.25 * (index / 4) as f32, 0.1 * z)
        });
        let arms = [1.0f32, -1.0].into_iter().flat_map(|side| {
            (0..6).map(move |index| {
                let (along, lift) = (0.25 + 0.1 * index as f32, 0.03 * (index % 2) as f32);
                Vec3::new(side * along, 0.6 + lift, 0.03 * ((index / 2) % 2) as f32)
            })
        });
        torso.chain(arms).collect()
    }

    /// The figure's arms turned about their shoulders (70° down and 50° up: a pose).
    fn posed(point: Vec3) -> Vec3 {
        if point.x.abs() < 0.2 {
            return point;
        }
        let side = point.x.signum();
        let shoulder = Vec3::new(0.2 * side, 0.6, 0.0);
        let angle = if side > 0.0 { -70.0f32 } else { 50.0 };
        Quat::from_rotation_z(angle.to_radians()) * (point - shoulder) + shoulder
    }

    /// A change of proportions: 40 % wider and deeper, as tall.
    fn wider(point: Vec3) -> Vec3 {
        point * Vec3::new(1.4, 1.0, 1.4)
    }

    /// An offset along the sphere's normals: bumps of 15 % of its radius.
    fn bumped(point: Vec3) -> Vec3 {
        point * (1.0 + 0.15 * (3.0 * point.x).sin() * (2.0 * point.y).cos())
    }

    fn similar(point: Vec3) -> Vec3 {
        Quat::from_rotation_y(1.1) * point * 1.5 + Vec3::new(2.0, 0.0, -1.0)
    }

    #[test]
    fn auto_takes_global_for_a_few_anchors_or_a_sliding_change_and_local_otherwise() {
        let chosen = |count: usize, moved: fn(Vec3) -> Vec3| {
            let points = sphere(count);
            anchors(&points, &points, moved).schedule()
        };
        assert_eq!(chosen(2, similar), WrapSchedule::Local);
        assert_eq!(chosen(6, similar), WrapSchedule::GlobalToLocal);
        assert_eq!(chosen(6, wider), WrapSchedule::GlobalToLocal);
        assert_eq!(chosen(24, similar), WrapSchedule::Local);
        assert_eq!(chosen(24, wider), WrapSchedule::GlobalToLocal);
        // Far from any similarity, but along the normals: the closest points find it.
        assert_eq!(chosen(24, bumped), WrapSchedule::Local);
        let points = sphere(24);
        let offset = |moved: fn(Vec3) -> Vec3| {
            let moved = anchors(&points, &[Vec3::ZERO; 24], moved);
            moved.sliding().unwrap()
        };
        assert!(offset(bumped) > LARGE_SLIDING, "{}", offset(bumped));
    }

    #[test]
    fn auto_tells_a_pose_from_a_change_of_proportions() {
        let rest = figure();
        let (zero, turned) = ([Vec3::ZERO; 24], anchors(&rest, &[Vec3::ZERO; 24], posed));
        let widened = anchors(&rest, &zero, wider);
        // Both slide far from any similarity of the figure...
        for moved in [&turned, &widened] {
            let sliding = moved.sliding().unwrap();
            assert!(sliding > LARGE_SLIDING, "{sliding}");
        }
        // ...but only the pose turns the anchors' neighbourhoods each their own way.
        let (pose, proportions) = (turned.articulation(), widened.articulation());
        assert!(pose.unwrap() > ARTICULATED_DEGREES, "{pose:?}");
        assert!(
            proportions.unwrap() < ARTICULATED_DEGREES * 0.75,
            "{proportions:?}"
        );
        assert_eq!(turned.schedule(), WrapSchedule::Local);
        assert_eq!(widened.schedule(), WrapSchedule::GlobalToLocal);
    }

    #[test]
    fn a_similarity_neither_slides_nor_turns_and_bad_anchors_give_none() {
        let rest = figure();
        let moved = anchors(&rest, &[Vec3::ZERO; 24], similar);
        assert!(moved.sliding().unwrap() < 1e-5);
        assert!(moved.articulation().unwrap() < 0.1);
        let few = anchors(&rest[..NEIGHBOURHOOD], &[Vec3::ZERO; 4], similar);
        assert_eq!(few.articulation(), None);
        let on_a_line: Vec<Vec3> = (0..8).map(|index| Vec3::X * index as f32).collect();
        let line = anchors(&on_a_line, &[Vec3::ZERO; 8], |point| point);
        assert_eq!((line.sliding(), line.articulation()), (None, None));
        let nan = [Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)];
        assert_eq!(anchors(&nan, &[Vec3::ZERO; 3], similar).sliding(), None);
    }

    #[test]
    fn auto_reads_the_layout_and_a_schedule_asked_for_is_followed() {
        // A 4 x 4 grid of unit cells, every vertex anchored.
        let row = 5u32;
        let rest: Vec<Vec3> = (0..row * row)
            .map(|index| Vec3::new((index % row) as f32, (index / row) as f32, 0.0))
            .collect();
        let corners: Vec<u32> = (0..16)
            .flat_map(|cell| {
                let a = (cell / 4) * row + cell % 4;
                [a, a + 1, a + row + 1, a + row]
            })
            .collect();
        let structure = LayoutStructure::new(rest.len(), &corners, &[4; 16], &[], &[]).unwrap();
        let face_point = FacePoint {
            triangle: 0,
            barycentric: Vec3::X,
        };
        let anchored = |moved: fn(Vec3) -> Vec3| -> Vec<Option<(AnchorTarget, Vec3)>> {
            let anchor = |point: Vec3| Some((AnchorTarget::Face(face_point), moved(point)));
            rest.iter().map(|&point| anchor(point)).collect()
        };
        // Lifting the grid along its normal is no sliding; stretching it along x is.
        let lifted = |point: Vec3| point + Vec3::Z * (0.3 * point.x * point.y).sin();
        let stretched = |point: Vec3| point * Vec3::new(2.0, 1.0, 1.0);
        let auto = |moved| choose_schedule(WrapSchedule::Auto, &structure, &rest, &anchored(moved));
        assert_eq!(auto(lifted), WrapSchedule::Local);
        assert_eq!(auto(stretched), WrapSchedule::GlobalToLocal);
        for schedule in [WrapSchedule::Local, WrapSchedule::GlobalToLocal] {
            let anchors = anchored(stretched);
            assert_eq!(
                choose_schedule(schedule, &structure, &rest, &anchors),
                schedule
            );
        }
    }
}
