//! The automatic choice of the energy wrap's schedule ([`WrapSchedule::Auto`]).
//!
//! The global-to-local schedule finds the right fit where the local one settles into a wrong one:
//! a few anchors on a large change of shape. With many anchors the local schedule is as good or
//! better. Measured through the kernel on the benchmark bodies (`benchmarks/few_anchors.py`'s
//! cases): with 6 anchors global to local lowers the mean error on every body; with 12 it wins on
//! the bodies whose anchors sit 1.8–2.1 % of their diagonal from any similarity of the template
//! and loses on the heavy body (0.5 %); with 24 it is better on three bodies but slightly worse on
//! the heavy one (0.222 % against 0.216 % of the diagonal). So `Auto`
//! takes the global-to-local schedule for 3 to 11 anchors, and for `n` ≥ 12 when the anchors'
//! distance from the best similarity of the template onto them (root mean square, over their
//! bounding-box diagonal) exceeds [`LARGE_CHANGE`] × `n` / 12: the more anchors, the larger the
//! change must be (with 24, over 2.4 %: none of the bodies, whose 24 anchors sit 0.75–1.9 % off).
//! Fewer than 3 anchors say nothing of the change: the local schedule.

use glam::Vec3;

use super::super::anchor::AnchorTarget;
use super::super::settings::WrapSchedule;
use crate::align::{AlignMethod, fit_transform};

/// From this many anchors on, the local schedule unless the change is large for their number.
pub(crate) const MANY_ANCHORS: usize = 12;
/// The fewest anchors that say something of the change (a similarity needs 3).
pub(crate) const FEWEST_ANCHORS: usize = 3;
/// The anchors' root mean square distance from the best similarity of the template onto them,
/// as a fraction of their bounding-box diagonal, above which a change of shape is large for
/// [`MANY_ANCHORS`] anchors (for `n` anchors: this × `n` / [`MANY_ANCHORS`]).
pub(crate) const LARGE_CHANGE: f32 = 0.012;

/// The schedule to follow for `schedule` (itself unless it is [`WrapSchedule::Auto`]), a layout
/// resting at `rest` with `anchor_of_vertex` (per vertex, its anchor and position).
pub(crate) fn choose_schedule(
    schedule: WrapSchedule,
    rest: &[Vec3],
    anchor_of_vertex: &[Option<(AnchorTarget, Vec3)>],
) -> WrapSchedule {
    if schedule != WrapSchedule::Auto {
        return schedule;
    }
    let (sources, targets): (Vec<Vec3>, Vec<Vec3>) = anchor_of_vertex
        .iter()
        .zip(rest)
        .filter_map(|(anchor, &rest)| anchor.map(|(_, position)| (rest, position)))
        .unzip();
    if sources.len() < FEWEST_ANCHORS {
        return WrapSchedule::Local;
    }
    if sources.len() < MANY_ANCHORS {
        return WrapSchedule::GlobalToLocal;
    }
    let large = LARGE_CHANGE * sources.len() as f32 / MANY_ANCHORS as f32;
    match change_of_shape(&sources, &targets) {
        Some(change) if change > large => WrapSchedule::GlobalToLocal,
        _ => WrapSchedule::Local,
    }
}

/// The root mean square distance of `targets` from the best similarity of `sources` onto them,
/// over the targets' bounding-box diagonal; `None` when no similarity fits (the anchors on one
/// line or at one point).
pub(crate) fn change_of_shape(sources: &[Vec3], targets: &[Vec3]) -> Option<f32> {
    let similarity = fit_transform(sources, targets, AlignMethod::Similarity, None).ok()?;
    let (low, high) = targets.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(low, high), &point| (low.min(point), high.max(point)),
    );
    let diagonal = (high - low).length();
    if !(diagonal > 0.0 && diagonal.is_finite()) {
        return None;
    }
    let squares: f32 = sources
        .iter()
        .zip(targets)
        .map(|(&source, &target)| similarity.apply(source).distance_squared(target))
        .sum();
    let change = (squares / sources.len() as f32).sqrt() / diagonal;
    change.is_finite().then_some(change)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::face_point::FacePoint;

    /// Anchors at `count` points spread over a unit box, their positions `moved` from rest.
    fn anchored(
        count: usize,
        moved: impl Fn(Vec3) -> Vec3,
    ) -> (Vec<Vec3>, Vec<Option<(AnchorTarget, Vec3)>>) {
        let rest: Vec<Vec3> = (0..count + 5)
            .map(|index| {
                let t = index as f32;
                Vec3::new((t * 0.37).fract(), (t * 0.61).fract(), (t * 0.83).fract())
            })
            .collect();
        let anchors = rest
            .iter()
            .enumerate()
            .map(|(index, &point)| {
                (index < count).then(|| {
                    let face_point = FacePoint {
                        triangle: 0,
                        barycentric: Vec3::X,
                    };
                    (AnchorTarget::Face(face_point), moved(point))
                })
            })
            .collect();
        (rest, anchors)
    }

    #[test]
    fn auto_takes_global_for_a_few_anchors_or_a_large_change_and_local_otherwise() {
        let similar = |point: Vec3| point * 1.5 + Vec3::new(2.0, 0.0, -1.0);
        let bent = |point: Vec3| Vec3::new(point.x, point.y + point.x * point.x, point.z);
        let chosen = |count: usize, moved: &dyn Fn(Vec3) -> Vec3| {
            let (rest, anchors) = anchored(count, moved);
            choose_schedule(WrapSchedule::Auto, &rest, &anchors)
        };
        assert_eq!(chosen(2, &similar), WrapSchedule::Local);
        assert_eq!(chosen(6, &similar), WrapSchedule::GlobalToLocal);
        assert_eq!(chosen(24, &similar), WrapSchedule::Local);
        assert_eq!(chosen(24, &bent), WrapSchedule::GlobalToLocal);
        // A schedule asked for is followed.
        let (rest, anchors) = anchored(24, similar);
        for schedule in [WrapSchedule::Local, WrapSchedule::GlobalToLocal] {
            assert_eq!(choose_schedule(schedule, &rest, &anchors), schedule);
        }
    }

    #[test]
    fn the_change_of_a_similarity_is_nothing_and_bad_anchors_give_none() {
        let sources = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let turned: Vec<Vec3> = sources
            .iter()
            .map(|&p| glam::Quat::from_rotation_z(0.7) * p * 2.0)
            .collect();
        assert!(change_of_shape(&sources, &turned).unwrap() < 1e-5);
        let on_a_line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert_eq!(change_of_shape(&on_a_line, &on_a_line), None);
        let nan = [Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)];
        assert_eq!(change_of_shape(&nan, &sources[..3]), None);
    }
}
