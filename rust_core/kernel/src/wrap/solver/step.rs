//! Stepping: the energy solver's iterations, the landing at the end and the reports.

use super::*;
use crate::cancel::{NEVER, Stop};

impl WrapSolver {
    /// Runs up to `iterations` iterations, stopping early once converged.
    ///
    /// # Errors
    /// [`KernelError::Diverged`] when a point stops being finite or leaves the region the wrap
    /// can reach (the points are rolled back to where they were before this call, and every
    /// later call returns the same error); [`KernelError::InvalidArgument`] when the linear
    /// system cannot be built or factored, or for more than
    /// [`WrapSettings::MAX_STEP_ITERATIONS`] iterations.
    pub fn step(&mut self, iterations: usize) -> Result<StepReport, KernelError> {
        self.step_until(iterations, NEVER)
    }

    /// [`WrapSolver::step`], asking `stop` (from any thread) inside the iterations' long loops
    /// (closest-point batches, rounds of smoothing, iterations of the global solve, before a
    /// factorization) and in the energy's setup at the first step: once it says true the call
    /// ends within about one such piece. A step that does not stop is the same as
    /// [`WrapSolver::step`]'s, bit for bit.
    ///
    /// # Errors
    /// As [`WrapSolver::step`]; [`KernelError::Cancelled`] once `stop` said true: the points and
    /// positions are as they were before this call (what [`WrapSolver::points`] and
    /// [`WrapSolver::positions`] read), the half-stepped energy is dropped, and every later call
    /// (and [`WrapSolver::set_anchors`]) returns the same error.
    pub fn step_until(
        &mut self,
        iterations: usize,
        stop: Stop<'_>,
    ) -> Result<StepReport, KernelError> {
        WrapSettings::check_step_iterations(iterations)?;
        if let Some(error) = &self.failed {
            return Err(error.clone());
        }
        let before = (self.points.clone(), self.positions.clone());
        let report = self.step_energy(iterations, stop);
        if let Err(error @ KernelError::Cancelled { .. }) = &report {
            (self.points, self.positions) = before;
            self.energy = None;
            self.failed = Some(error.clone());
            return report;
        }
        if let Some(vertex) = self.escaped_vertex() {
            (self.points, self.positions) = before;
            let error = KernelError::Diverged {
                iteration: self.total_iterations,
                vertex,
            };
            self.failed = Some(error.clone());
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

    /// [`WrapSolver::step`] before the divergence check.
    fn step_energy(
        &mut self,
        iterations: usize,
        stop: Stop<'_>,
    ) -> Result<StepReport, KernelError> {
        if self.energy.is_none() {
            let inputs = EnergyInputs {
                target: &self.target,
                structure: &self.structure,
                rest: &self.rest,
                positions: &self.positions,
                anchor_of_vertex: &self.anchor_of_vertex,
                soft_pairs: &self.soft_pairs,
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
                settings: self.settings,
                profile: self.profile,
                settled_start: self.settled_start,
                region_restart: self.region_restart,
            };
            self.energy = Some(Box::new(EnergySolver::new_until(&inputs, stop)?));
        }
        let mut report = self.empty_report();
        // Taken out while it steps, so that the plane's walks can read the rest of `self`.
        let mut energy = self.energy.take().expect("made above");
        if energy.is_finished() {
            report.converged = true;
        }
        while report.iterations < iterations && !report.converged {
            let outcome = match energy.iterate_until(stop) {
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
    }
}
