//! The local step: each vertex's similarity of its rest neighbourhood onto its current one, the rotations
//! smoothed over neighbours (the warm-up), the scales fitted and smoothed by the level's stiffness.

use super::*;
use crate::cancel::NEVER;
use crate::wrap::averaging_pyramid::smooth_over;

impl EnergySolver {
    /// Fits every vertex's similarity at the current positions (from the last fit).
    pub(super) fn fit_similarities(&mut self, first: bool) {
        self.similarities =
            self.rest_fit
                .fit_all(&self.positions, &self.structure, &self.similarities, first);
        self.frame = self.mean_rotation();
    }

    /// Replaces each fitted rotation by its average over edge neighbours, `rounds` times (as
    /// quaternions, each neighbour's sign matched to the vertex's own): the shape terms then
    /// keep regions about `√rounds` rings wide rigid.
    /// `stop` is asked before each round.
    pub(super) fn smooth_rotations(
        &mut self,
        rounds: usize,
        stop: Stop<'_>,
    ) -> Result<(), KernelError> {
        check(stop, WRAP_STEP)?;
        if let Some(stretches) = self.stretches.as_mut() {
            return stretches.smooth_rotations(&mut self.similarities, rounds, self.frame);
        }
        if rounds == 0 {
            return Ok(());
        }
        let mut rotations: Vec<Quat> = self.similarities.iter().map(|fit| fit.rotation).collect();
        smooth_over(
            self.pyramid.as_ref(),
            &self.structure,
            &mut rotations,
            rounds,
            stop,
        )?;
        for (fit, rotation) in self.similarities.iter_mut().zip(rotations) {
            fit.rotation = rotation;
        }
        Ok(())
    }

    /// The mean of the fitted rotations (as quaternions, each one's sign matched to the mean's).
    pub(super) fn mean_rotation(&self) -> Quat {
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
    pub(super) fn fit_scales(&mut self, rounds: Option<usize>) -> Result<(), KernelError> {
        if let Some(stretches) = self.stretches.as_mut() {
            return stretches.fit(&self.structure, &self.positions, &self.similarities, rounds);
        }
        self.smooth_scales(rounds)
    }

    /// Replaces the fitted scales by their median (`None`) or by their log averaged over edge
    /// neighbours `rounds` times, within [`SCALE_RANGE`] of the median.
    pub(super) fn smooth_scales(&mut self, rounds: Option<usize>) -> Result<(), KernelError> {
        let Some(median) = Similarity::median_scale(&self.similarities) else {
            return Ok(());
        };
        let Some(rounds) = rounds else {
            for fit in &mut self.similarities {
                fit.scale = median;
            }
            return Ok(());
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
        smooth_over(
            self.pyramid.as_ref(),
            &self.structure,
            &mut logs,
            rounds,
            NEVER,
        )?;
        for (fit, log) in self.similarities.iter_mut().zip(logs) {
            fit.scale = log.exp();
        }
        Ok(())
    }
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
