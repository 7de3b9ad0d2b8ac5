//! A re-settle: a wrap started from a wrap's own result, said so by its caller (`WrapSolver::with_settled_start`:
//! the layout as a wrap left it, wrapped again with the same rest shape and target), that still lies on the target
//! with its constraints met, runs the schedule's last level alone, without the warm-up and the
//! stiffer levels. Those are made for a start far from the target: the warm-up (no data term) relaxes the layout
//! back toward the template's shape and the first levels hold it to one scale and smoothed rotations, which from a
//! converged start undo the fit that the capped later levels then only partly redo. Measured on the MakeHuman body
//! onto a remeshed frame (13,380 vertices, no anchors, three wraps in a row): the whole schedule again made the
//! mean error 1.49, 2.37, 3.37 mm and moved the points 2.04 mm on the second wrap; from the last level alone
//! 1.49, 1.49, 1.49 mm and 0.04 mm (starting two levels before the end: 1.50 mm and 0.07 mm). A first iteration
//! that barely moves the points says the layout is settled: it is kept as it started ([`KEPT_MEAN_MOVE`]).

use super::*;
use crate::wrap::soft_pair::SOFT_PAIR_RELEASE;

/// A start is on the target when at least this share of the points the data term pulls are face-points.
const ON_TARGET_SHARE: f32 = 0.75;
/// A re-settle stays one when its first iteration moves the points by at most this many mean edges on average;
/// otherwise the layout was on the target but far from settled (snapped or projected onto it, its edges squeezed)
/// and the wrap starts again from the same points with the whole schedule. Measured: 0.004 to 0.019 on the body
/// wrapped again (frames 0 and 50, second and third wraps), 0.066 on a 31 x 31 grid snapped to a plane's vertices.
const SETTLED_MEAN_MOVE: f32 = 0.03;
/// A re-settle whose first iteration moves the points by at most this many mean edges on average keeps the start
/// as it is and ends there: the layout is settled, and running on would only carry on the last level's slow slide
/// along the surface, a little further at every press. Measured on the MakeHuman body on a remeshed sequence frame
/// (13,380 vertices, no anchors): the first iteration moved 0.006 mean edges on frame 0 and 0.010 on frame 50, where
/// running the last level on moved the layout 0.136 mm on average (501 points over 1 mm, the mean error 1.539 ->
/// 1.545 -> 1.556 mm in three presses); kept, 0.003 mm (the few points that land now that their neighbours have)
/// and 1.540 mm.
const KEPT_MEAN_MOVE: f32 = 0.015;
/// A re-settle runs the schedule's last this many levels.
const RESETTLE_LEVELS: usize = 1;

impl EnergySolver {
    /// Starts the schedule at its last level, without the warm-up, when the caller said the start is a settled wrap
    /// and the layout starts on the target
    /// (`points`, as given, after the first fit) with every constraint already met and its shape near a settled one
    /// (see the module's description); otherwise leaves the schedule as it is. Soft pairs keep the whole schedule
    /// when a level re-settled would pull them (the last level lets them go: it runs as without them).
    pub(super) fn resettle_if_on_target(&mut self, points: &[LayoutPoint], settled: bool) {
        let last_levels = &self.levels[self.levels.len().saturating_sub(RESETTLE_LEVELS)..];
        let pairs_pull = self.soft_pairs.iter().any(Option::is_some)
            && last_levels
                .iter()
                .any(|level| level.data_weight < SOFT_PAIR_RELEASE);
        if !settled || pairs_pull || !self.constraints_met() {
            return;
        }
        let (mut pulled, mut on_target) = (0usize, 0usize);
        for (vertex, point) in points.iter().enumerate() {
            if self.fixed[vertex].is_some() || self.data_factors[vertex] == 0.0 {
                continue;
            }
            pulled += 1;
            on_target += usize::from(matches!(point, LayoutPoint::Face(_)));
        }
        if pulled > 0 && on_target as f32 >= ON_TARGET_SHARE * pulled as f32 {
            self.warming_up = false;
            self.level = self.levels.len().saturating_sub(RESETTLE_LEVELS);
            self.resettle_start = Some(self.positions.clone());
        }
    }

    /// After a re-settle's first iteration, which moved the points `mean_move` on average: ends with the start as
    /// it was when that is tiny ([`KEPT_MEAN_MOVE`]), goes on re-settling when it is small, else starts the whole
    /// schedule from where the re-settle started (as a wrap that never re-settled).
    pub(super) fn keep_resettle_if_settled(&mut self, mean_move: f32) {
        let Some(start) = self.resettle_start.take() else {
            return;
        };
        if mean_move <= KEPT_MEAN_MOVE * self.mean_edge_length {
            self.positions = start;
            self.finished = true;
            return;
        }
        if mean_move <= SETTLED_MEAN_MOVE * self.mean_edge_length {
            return;
        }
        self.positions = start;
        self.start_schedule();
    }

    /// Whether every anchor and curve target is where its vertex starts and every point held on the plane lies on
    /// it (within the landing distance): nothing but the data term would move the layout.
    fn constraints_met(&self) -> bool {
        let near = |distance: f32| distance.abs() <= self.landing_distance;
        let fixed_met = self
            .fixed
            .iter()
            .zip(&self.positions)
            .all(|(fixed, position)| {
                fixed.is_none_or(|fixed| near(fixed.as_vec3().distance(*position)))
            });
        let plane_met = self.plane.is_none_or(|plane| {
            self.positions
                .iter()
                .zip(&self.on_plane)
                .all(|(&position, &held)| !held || near(plane.distance(position)))
        });
        fixed_met && plane_met
    }
}
