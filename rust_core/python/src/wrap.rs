//! `WrapSolver`: a wrap in progress, built from the layout's arrays, anchors and constraints.

use std::sync::Arc;
use std::sync::atomic::Ordering;

use glam::Vec3;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use springwrap_kernel::{
    Anchor, AnchorTarget, CurveConstraint, FacePoint, LayoutPoint, PlaneConstraint, SoftPair,
    WrapSettings, WrapSolver,
};

use crate::arguments;
use crate::arrays::{read_array, read_positions, rows_array};
use crate::errors::{ArrayError, IndexOutOfRangeError, InvalidArgumentError, run_kernel};
use crate::fit::PyCancelFlag;
use crate::layout::PyLayoutStructure;
use crate::target_mesh::PyTargetMesh;
use crate::wrap_settings::PyWrapSettings;

/// Per-vertex state arrays: (states, triangles, barycentrics).
type StateArrays<'py> = (
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray2<f32>>,
);

/// A wrap in progress: call `step(n)` repeatedly, read `positions()` and `states()`; its
/// weights, tolerance, rest shape and solver are one `WrapSettings` (the kernel's defaults when
/// none is given).
#[pyclass(name = "WrapSolver", module = "springwrap_kernel", subclass)]
pub(crate) struct PyWrapSolver {
    solver: WrapSolver,
}

#[pymethods]
impl PyWrapSolver {
    #[new]
    #[pyo3(signature = (
        target, structure, states, triangles, barycentrics, positions, *,
        anchor_vertices = None, anchor_triangles = None, anchor_barycentrics = None,
        anchor_positions = None, unreliable_triangles = None, curve_vertices = None,
        curve_vertex_counts = None, curve_points = None, curve_point_counts = None,
        curve_fractions = None, rest_positions = None, plane_vertices = None, plane_point = None,
        plane_normal = None, plane_slide = None, settings = None, stiffness = None, free_vertices = None,
        soft_pair_vertices = None, soft_pair_positions = None, soft_pair_confidences = None,
        settled_start = None, region_restart = None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        target: &Bound<'_, PyAny>,
        structure: &Bound<'_, PyAny>,
        states: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        barycentrics: &Bound<'_, PyAny>,
        positions: &Bound<'_, PyAny>,
        anchor_vertices: Option<&Bound<'_, PyAny>>,
        anchor_triangles: Option<&Bound<'_, PyAny>>,
        anchor_barycentrics: Option<&Bound<'_, PyAny>>,
        anchor_positions: Option<&Bound<'_, PyAny>>,
        unreliable_triangles: Option<&Bound<'_, PyAny>>,
        curve_vertices: Option<&Bound<'_, PyAny>>,
        curve_vertex_counts: Option<&Bound<'_, PyAny>>,
        curve_points: Option<&Bound<'_, PyAny>>,
        curve_point_counts: Option<&Bound<'_, PyAny>>,
        curve_fractions: Option<&Bound<'_, PyAny>>,
        rest_positions: Option<&Bound<'_, PyAny>>,
        plane_vertices: Option<&Bound<'_, PyAny>>,
        plane_point: Option<&Bound<'_, PyAny>>,
        plane_normal: Option<&Bound<'_, PyAny>>,
        plane_slide: Option<&Bound<'_, PyAny>>,
        settings: Option<&Bound<'_, PyAny>>,
        stiffness: Option<&Bound<'_, PyAny>>,
        free_vertices: Option<&Bound<'_, PyAny>>,
        soft_pair_vertices: Option<&Bound<'_, PyAny>>,
        soft_pair_positions: Option<&Bound<'_, PyAny>>,
        soft_pair_confidences: Option<&Bound<'_, PyAny>>,
        settled_start: Option<&Bound<'_, PyAny>>,
        region_restart: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let settled_start = arguments::flag("settled_start", settled_start, false)?;
        let region_restart = arguments::flag("region_restart", region_restart, false)?;
        let target = arguments::instance::<PyTargetMesh>("target", "TargetMesh", target)?;
        let structure =
            arguments::instance::<PyLayoutStructure>("structure", "LayoutStructure", structure)?;
        let settings = match settings.filter(|settings| !settings.is_none()) {
            Some(settings) => {
                arguments::instance::<PyWrapSettings>("settings", "WrapSettings", settings)?
                    .get()
                    .settings
            }
            None => WrapSettings::default(),
        };
        let plane_point = arguments::vector3("plane_point", plane_point)?;
        let plane_normal = arguments::vector3("plane_normal", plane_normal)?;
        let plane_slide = arguments::flag("plane_slide", plane_slide, true)?;
        let plane = read_plane_constraint(plane_vertices, plane_point, plane_normal, plane_slide)?;
        let states = read_array::<i32>("states", states, None)?;
        let triangles = read_array::<i32>("triangles", triangles, None)?;
        let barycentrics = read_positions("barycentrics", barycentrics)?;
        let positions = read_positions("positions", positions)?;
        let count = states.len();
        for (name, length) in [
            ("triangles", triangles.len()),
            ("barycentrics", barycentrics.len()),
            ("positions", positions.len()),
        ] {
            if length != count {
                return Err(ArrayError::new_err(format!(
                    "{name} has {length} rows but states has {count}: one per layout vertex"
                )));
            }
        }
        let points = layout_points(&states, &triangles, &barycentrics, &positions)?;
        let rest_positions = rest_positions
            .map(|array| read_positions("rest_positions", array))
            .transpose()?;
        let anchors = read_anchors(
            anchor_vertices,
            anchor_triangles,
            anchor_barycentrics,
            anchor_positions,
        )?;
        let curves = read_curve_constraints(
            curve_vertices,
            curve_vertex_counts,
            curve_points,
            curve_point_counts,
            curve_fractions,
        )?;
        let unreliable = unreliable_triangles
            .map(|flags| read_array::<bool>("unreliable_triangles", flags, None))
            .transpose()?;
        let stiffness = stiffness
            .map(|values| read_array::<f32>("stiffness", values, None))
            .transpose()?;
        let free_vertices = free_vertices
            .map(|flags| read_array::<bool>("free_vertices", flags, None))
            .transpose()?;
        let soft_pairs = read_soft_pairs(
            soft_pair_vertices,
            soft_pair_positions,
            soft_pair_confidences,
        )?;
        let target = Arc::clone(&target.get().mesh);
        let structure = structure.get().structure.clone();
        let solver = run_kernel(py, || {
            let solver = WrapSolver::with_rest_shape(
                target,
                structure,
                points,
                rest_positions,
                &anchors,
                settings,
            )?
            .with_settled_start(settled_start)
            .with_region_restart(region_restart)
            .with_curve_constraints(&curves)?;
            let solver = match &plane {
                Some(plane) => solver.with_plane_constraint(plane)?,
                None => solver,
            };
            let solver = match unreliable {
                Some(flags) => solver.with_unreliable_triangles(flags)?,
                None => solver,
            };
            let solver = match stiffness {
                Some(values) => solver.with_vertex_stiffness(values)?,
                None => solver,
            };
            let solver = match free_vertices {
                Some(flags) => solver.with_free_vertices(flags)?,
                None => solver,
            };
            match soft_pairs {
                Some(pairs) => solver.with_soft_pairs(&pairs),
                None => Ok(solver),
            }
        })?;
        Ok(Self { solver })
    }

    /// Runs up to `iterations` iterations (fewer once converged); returns the progress as
    /// ((iterations, total_iterations, max_displacement, converged, face_points, space_points,
    /// landed, folded, mean_displacement), energy, held_back, energy_decrease). `cancel` (a
    /// `CancelFlag`): the step asks it inside its long loops and raises `CancelledError` soon
    /// after another thread set it (the GIL is free while it runs); `positions()` and `states()`
    /// then read the points as they were before the call, and every later step raises again.
    #[pyo3(signature = (iterations, *, cancel = None))]
    #[allow(clippy::type_complexity)]
    fn step(
        &mut self,
        py: Python<'_>,
        iterations: &Bound<'_, PyAny>,
        cancel: Option<&Bound<'_, PyCancelFlag>>,
    ) -> PyResult<(
        (usize, usize, f32, bool, usize, usize, usize, usize, f32),
        f64,
        usize,
        f64,
    )> {
        let iterations =
            arguments::count("iterations", iterations, WrapSettings::MAX_STEP_ITERATIONS)?;
        let solver = &mut self.solver;
        let flag = cancel.map(|cancel| Arc::clone(&cancel.get().flag));
        let stop = || {
            flag.as_ref()
                .is_some_and(|flag| flag.load(Ordering::Relaxed))
        };
        let report = run_kernel(py, || solver.step_until(iterations, &stop))?;
        Ok((
            (
                report.iterations,
                report.total_iterations,
                report.max_displacement,
                report.converged,
                report.face_points,
                report.space_points,
                report.landed,
                report.folded,
                report.mean_displacement,
            ),
            report.energy,
            report.held_back,
            report.energy_decrease,
        ))
    }

    /// Replaces the anchors between two steps, as the constructor's four anchor arrays (none:
    /// no anchor): the points stay where they are and the schedule starts again from its
    /// warm-up, as a wrap built anew from them would (same anchored vertices: the linear system
    /// is kept). A bad anchor raises and changes nothing.
    #[pyo3(signature = (
        anchor_vertices = None, anchor_triangles = None, anchor_barycentrics = None,
        anchor_positions = None
    ))]
    fn set_anchors(
        &mut self,
        py: Python<'_>,
        anchor_vertices: Option<&Bound<'_, PyAny>>,
        anchor_triangles: Option<&Bound<'_, PyAny>>,
        anchor_barycentrics: Option<&Bound<'_, PyAny>>,
        anchor_positions: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let anchors = read_anchors(
            anchor_vertices,
            anchor_triangles,
            anchor_barycentrics,
            anchor_positions,
        )?;
        let solver = &mut self.solver;
        run_kernel(py, || solver.set_anchors(&anchors))
    }

    /// The settings the wrap runs with (a `WrapSettings`).
    #[getter]
    fn settings(&self) -> PyWrapSettings {
        PyWrapSettings {
            settings: *self.solver.settings(),
        }
    }

    /// (N, 3) float32 positions of the layout points.
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat = self
            .solver
            .positions()
            .iter()
            .flat_map(|p| p.to_array())
            .collect();
        rows_array(py, flat, 3)
    }

    /// (states int32 (N,), triangles int32 (N,), barycentrics float32 (N, 3)): 1 for face-points
    /// with their triangle and weights, 0 for space-points (triangle -1).
    fn states<'py>(&self, py: Python<'py>) -> PyResult<StateArrays<'py>> {
        let points = self.solver.points();
        let mut states = Vec::with_capacity(points.len());
        let mut triangles = Vec::with_capacity(points.len());
        let mut barycentrics = Vec::with_capacity(points.len() * 3);
        for point in points {
            match point {
                LayoutPoint::Face(face_point) => {
                    states.push(1);
                    triangles.push(face_point.triangle as i32);
                    barycentrics.extend(face_point.barycentric.to_array());
                }
                LayoutPoint::Space(_) => {
                    states.push(0);
                    triangles.push(-1);
                    barycentrics.extend([0.0; 3]);
                }
            }
        }
        Ok((
            PyArray1::from_vec(py, states),
            PyArray1::from_vec(py, triangles),
            rows_array(py, barycentrics, 3)?,
        ))
    }
}

/// Layout points from the state arrays (1 = face-point on `triangles[i]`, else a space-point).
fn layout_points(
    states: &[i32],
    triangles: &[i32],
    barycentrics: &[Vec3],
    positions: &[Vec3],
) -> PyResult<Vec<LayoutPoint>> {
    states
        .iter()
        .enumerate()
        .map(|(index, &state)| {
            if state != 0 && state != 1 {
                return Err(InvalidArgumentError::new_err(format!(
                    "invalid states: layout vertex {index} has state {state} (0: space-point, 1: face-point)"
                )));
            }
            if state == 1 {
                let triangle = u32::try_from(triangles[index]).map_err(|_| {
                    IndexOutOfRangeError::new_err(format!(
                        "layout vertex {index} is a face-point on triangle {}",
                        triangles[index]
                    ))
                })?;
                Ok(LayoutPoint::Face(FacePoint {
                    triangle,
                    barycentric: barycentrics[index],
                }))
            } else {
                Ok(LayoutPoint::Space(positions[index]))
            }
        })
        .collect()
}

/// Curve constraints from flat arrays: chain `c` is the next `curve_vertex_counts[c]` entries of
/// `curve_vertices`, its target polyline the next `curve_point_counts[c]` rows of `curve_points`;
/// `curve_fractions` (optional, one per entry of `curve_vertices`): where along its polyline each
/// chain vertex goes (fraction of its length), all NaN for a chain spaced as it is.
fn read_curve_constraints(
    vertices: Option<&Bound<'_, PyAny>>,
    vertex_counts: Option<&Bound<'_, PyAny>>,
    points: Option<&Bound<'_, PyAny>>,
    point_counts: Option<&Bound<'_, PyAny>>,
    fractions: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<CurveConstraint>> {
    let (Some(vertices), Some(vertex_counts), Some(points), Some(point_counts)) =
        (vertices, vertex_counts, points, point_counts)
    else {
        if vertices.is_some()
            || vertex_counts.is_some()
            || points.is_some()
            || point_counts.is_some()
        {
            return Err(ArrayError::new_err(
                "curve constraints need all four of curve_vertices, curve_vertex_counts, curve_points and curve_point_counts",
            ));
        }
        return Ok(Vec::new());
    };
    let vertices = read_array::<u32>("curve_vertices", vertices, None)?;
    let vertex_counts = read_array::<u32>("curve_vertex_counts", vertex_counts, None)?;
    let points = read_positions("curve_points", points)?;
    let point_counts = read_array::<u32>("curve_point_counts", point_counts, None)?;
    let fractions = fractions
        .map(|array| read_array::<f32>("curve_fractions", array, None))
        .transpose()?;
    if let Some(fractions) = &fractions
        && fractions.len() != vertices.len()
    {
        return Err(ArrayError::new_err(format!(
            "curve_fractions has {} entries for {} curve_vertices: one per chain vertex",
            fractions.len(),
            vertices.len()
        )));
    }
    let total = |counts: &[u32]| {
        counts
            .iter()
            .try_fold(0usize, |total, &count| total.checked_add(count as usize))
            .unwrap_or(usize::MAX)
    };
    let (vertex_total, point_total) = (total(&vertex_counts), total(&point_counts));
    if vertex_counts.len() != point_counts.len()
        || vertex_total != vertices.len()
        || point_total != points.len()
    {
        return Err(ArrayError::new_err(format!(
            "curve constraint arrays do not add up: {} chains with {vertex_total} vertices for {} given, {} curves with {point_total} points for {} given",
            vertex_counts.len(),
            vertices.len(),
            point_counts.len(),
            points.len()
        )));
    }
    let mut vertex_offset = 0;
    let mut point_offset = 0;
    Ok(vertex_counts
        .iter()
        .zip(&point_counts)
        .map(|(&vertex_count, &point_count)| {
            let (vertex_count, point_count) = (vertex_count as usize, point_count as usize);
            let given = fractions
                .as_ref()
                .map(|all| all[vertex_offset..vertex_offset + vertex_count].to_vec())
                .unwrap_or_default();
            let constraint = CurveConstraint {
                layout_vertices: vertices[vertex_offset..vertex_offset + vertex_count].to_vec(),
                target: points[point_offset..point_offset + point_count].to_vec(),
                // All NaN: the chain's own spacing.
                fractions: if given.iter().all(|value| value.is_nan()) {
                    Vec::new()
                } else {
                    given
                },
            };
            vertex_offset += vertex_count;
            point_offset += point_count;
            constraint
        })
        .collect())
}

/// The mirror plane constraint: held vertices (uint32) and the plane's point and normal, all
/// three or none; `slide`: whether held points slide along the cross-section.
fn read_plane_constraint(
    vertices: Option<&Bound<'_, PyAny>>,
    point: Option<[f32; 3]>,
    normal: Option<[f32; 3]>,
    slide: bool,
) -> PyResult<Option<PlaneConstraint>> {
    match (vertices, point, normal) {
        (None, None, None) => Ok(None),
        (Some(vertices), Some(point), Some(normal)) => Ok(Some(PlaneConstraint {
            vertices: read_array::<u32>("plane_vertices", vertices, None)?,
            point: Vec3::from_array(point),
            normal: Vec3::from_array(normal),
            slide,
        })),
        _ => Err(ArrayError::new_err(
            "a plane constraint needs all three of plane_vertices, plane_point and plane_normal",
        )),
    }
}

/// Anchors from parallel arrays; a negative triangle means a space anchor at its position.
/// The soft pairs from their three arrays (all or none).
fn read_soft_pairs(
    vertices: Option<&Bound<'_, PyAny>>,
    positions: Option<&Bound<'_, PyAny>>,
    confidences: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<Vec<SoftPair>>> {
    let (Some(vertices), Some(positions), Some(confidences)) = (vertices, positions, confidences)
    else {
        if vertices.is_some() || positions.is_some() || confidences.is_some() {
            return Err(ArrayError::new_err(
                "soft pairs need all three of soft_pair_vertices, soft_pair_positions and soft_pair_confidences",
            ));
        }
        return Ok(None);
    };
    let vertices = read_array::<u32>("soft_pair_vertices", vertices, None)?;
    let positions = read_positions("soft_pair_positions", positions)?;
    let confidences = read_array::<f32>("soft_pair_confidences", confidences, None)?;
    let count = vertices.len();
    if positions.len() != count || confidences.len() != count {
        return Err(ArrayError::new_err(format!(
            "the soft pair arrays differ in length: {count} vertices, {} positions, {} confidences",
            positions.len(),
            confidences.len()
        )));
    }
    Ok(Some(
        (0..count)
            .map(|index| SoftPair {
                vertex: vertices[index],
                target: positions[index],
                confidence: confidences[index],
            })
            .collect(),
    ))
}

fn read_anchors(
    vertices: Option<&Bound<'_, PyAny>>,
    triangles: Option<&Bound<'_, PyAny>>,
    barycentrics: Option<&Bound<'_, PyAny>>,
    positions: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<Anchor>> {
    let (Some(vertices), Some(triangles), Some(barycentrics), Some(positions)) =
        (vertices, triangles, barycentrics, positions)
    else {
        if vertices.is_some()
            || triangles.is_some()
            || barycentrics.is_some()
            || positions.is_some()
        {
            return Err(ArrayError::new_err(
                "anchors need all four of anchor_vertices, anchor_triangles, anchor_barycentrics and anchor_positions",
            ));
        }
        return Ok(Vec::new());
    };
    let vertices = read_array::<u32>("anchor_vertices", vertices, None)?;
    let triangles = read_array::<i32>("anchor_triangles", triangles, None)?;
    let barycentrics = read_positions("anchor_barycentrics", barycentrics)?;
    let positions = read_positions("anchor_positions", positions)?;
    let count = vertices.len();
    if triangles.len() != count || barycentrics.len() != count || positions.len() != count {
        return Err(ArrayError::new_err(format!(
            "the anchor arrays differ in length: {count} vertices, {} triangles, {} barycentrics, {} positions",
            triangles.len(),
            barycentrics.len(),
            positions.len()
        )));
    }
    Ok((0..count)
        .map(|index| Anchor {
            vertex: vertices[index],
            target: match u32::try_from(triangles[index]) {
                Ok(triangle) => AnchorTarget::Face(FacePoint {
                    triangle,
                    barycentric: barycentrics[index],
                }),
                Err(_) => AnchorTarget::Space(positions[index]),
            },
        })
        .collect())
}
