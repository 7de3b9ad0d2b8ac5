//! Stepping: the spring solver's Jacobi iterations (or the energy solver's), convergence, the
//! reports, the orientation check and the annealing of the folding tolerance.

use super::*;

impl WrapSolver {
    /// Runs up to `iterations` iterations, stopping early once converged.
    ///
    /// # Errors
    /// [`KernelError::Diverged`] when a point stops being finite or leaves the region the wrap
    /// can reach (the points are rolled back to where they were before this call, and every
    /// later call returns the same error). With [`SolverKind::Energy`]:
    /// [`KernelError::InvalidArgument`] when its linear system cannot be built or factored; with
    /// [`SolverKind::Springs`]: [`KernelError::InvalidArgument`] when vertex stiffness or free
    /// vertices are set; [`KernelError::InvalidArgument`] for more than
    /// [`WrapSettings::MAX_STEP_ITERATIONS`] iterations.
    pub fn step(&mut self, iterations: usize) -> Result<StepReport, KernelError> {
        WrapSettings::check_step_iterations(iterations)?;
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
        if !self.stiffness.is_empty() || !self.free.is_empty() || !self.soft_pairs.is_empty() {
            return Err(KernelError::InvalidArgument {
                name: "solver",
                reason: "vertex stiffness, free vertices and soft pairs need the energy solver"
                    .to_owned(),
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
                schedule: self.settings.schedule,
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
