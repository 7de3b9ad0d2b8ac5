//! `SubdivisionStencils` and `SubdivisionFit`: the subdivision cage fit.
//!
//! Positions cross as float32 (the array contract); the kernel works in float64 inside.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use springwrap_kernel::fit::{
    BoundaryRule, SubdivisionFit, SubdivisionFitSettings, SubdivisionStencils,
};

use crate::arrays::{read_array, read_faces, read_positions, rows_array};
use crate::errors::{InvalidArgumentError, run_kernel};
use crate::target_mesh::PyTargetMesh;

fn boundary_rule(name: &str) -> PyResult<BoundaryRule> {
    match name {
        "ALL" => Ok(BoundaryRule::SmoothCorners),
        "PRESERVE_CORNERS" => Ok(BoundaryRule::KeepCorners),
        other => Err(InvalidArgumentError::new_err(format!(
            "invalid boundary: {other:?} (Blender's Boundary Smooth: 'ALL' or 'PRESERVE_CORNERS')"
        ))),
    }
}

fn read_points(name: &str, array: &Bound<'_, PyAny>) -> PyResult<Vec<DVec3>> {
    Ok(read_positions(name, array)?
        .into_iter()
        .map(|point| point.as_dvec3())
        .collect())
}

fn points_array<'py>(py: Python<'py>, points: &[DVec3]) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let flat = points
        .iter()
        .flat_map(|point| point.as_vec3().to_array())
        .collect();
    rows_array(py, flat, 3)
}

/// The limit points of a cage subdivided `levels` times (Catmull–Clark, Blender's rules), as a
/// sparse matrix over the cage's vertices, and the fine quads.
#[pyclass(name = "SubdivisionStencils", module = "springwrap_kernel", frozen)]
pub(crate) struct PySubdivisionStencils {
    stencils: Arc<SubdivisionStencils>,
}

#[pymethods]
impl PySubdivisionStencils {
    #[new]
    #[pyo3(signature = (vertex_count, face_corners, face_sizes, levels, *, boundary = "ALL"))]
    fn new(
        py: Python<'_>,
        vertex_count: usize,
        face_corners: &Bound<'_, PyAny>,
        face_sizes: &Bound<'_, PyAny>,
        levels: u32,
        boundary: &str,
    ) -> PyResult<Self> {
        let (face_corners, face_sizes) = read_faces(face_corners, face_sizes)?;
        let rule = boundary_rule(boundary)?;
        let stencils = run_kernel(py, || {
            SubdivisionStencils::new(vertex_count, &face_corners, &face_sizes, levels, rule)
        })?;
        Ok(Self {
            stencils: Arc::new(stencils),
        })
    }

    /// The subdivision level.
    #[getter]
    fn levels(&self) -> u32 {
        self.stencils.levels()
    }

    /// Blender's Boundary Smooth: "ALL" or "PRESERVE_CORNERS".
    #[getter]
    fn boundary(&self) -> &'static str {
        match self.stencils.rule() {
            BoundaryRule::SmoothCorners => "ALL",
            BoundaryRule::KeepCorners => "PRESERVE_CORNERS",
        }
    }

    /// Number of cage vertices (columns).
    #[getter]
    fn cage_vertex_count(&self) -> usize {
        self.stencils.cage_vertex_count()
    }

    /// Number of fine vertices (rows).
    #[getter]
    fn fine_vertex_count(&self) -> usize {
        self.stencils.fine_vertex_count()
    }

    /// The matrix in CSR form: (row offsets uint32, cage vertices uint32, weights float64).
    #[allow(clippy::type_complexity)]
    fn matrix<'py>(
        &self,
        py: Python<'py>,
    ) -> (
        Bound<'py, PyArray1<u32>>,
        Bound<'py, PyArray1<u32>>,
        Bound<'py, PyArray1<f64>>,
    ) {
        let stencils = self.stencils.stencils();
        (
            PyArray1::from_vec(py, stencils.offsets.clone()),
            PyArray1::from_vec(py, stencils.vertices.clone()),
            PyArray1::from_vec(py, stencils.coefficients.clone()),
        )
    }

    /// (Q, 4) uint32 quads of the last level over the fine vertices, wound as the cage's faces.
    fn fine_quads<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let flat = self
            .stencils
            .fine_quads()
            .iter()
            .flatten()
            .copied()
            .collect();
        rows_array(py, flat, 4)
    }

    /// (F,) bool: whether each fine vertex lies on the surface (not a cage vertex on no face).
    fn on_surface<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_vec(py, self.stencils.on_surface().to_vec())
    }

    /// (F, 3) float32 limit points of the cage at `cage` ((N, 3) float32).
    fn apply<'py>(
        &self,
        py: Python<'py>,
        cage: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let cage = read_points("cage", cage)?;
        let stencils = Arc::clone(&self.stencils);
        let fine = run_kernel(py, || stencils.apply(&cage))?;
        points_array(py, &fine)
    }
}

/// A subdivision cage fit: Gauss–Newton rounds moving the cage so that its limit surface lies on
/// the target.
#[pyclass(name = "SubdivisionFit", module = "springwrap_kernel", frozen)]
pub(crate) struct PySubdivisionFit {
    fit: Arc<SubdivisionFit>,
}

fn read_offsets(offsets: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Vec<DVec3>>> {
    offsets
        .filter(|offsets| !offsets.is_none())
        .map(|offsets| read_points("offsets", offsets))
        .transpose()
}

#[pymethods]
impl PySubdivisionFit {
    #[new]
    #[pyo3(signature = (
        stencils,
        *,
        fixed = None,
        smoothness = None,
        max_distance = None,
        min_facing = None,
        damping = None,
        anchor_vertices = None,
        anchor_points = None,
        anchor_weight = None,
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        stencils: &Bound<'_, PyAny>,
        fixed: Option<&Bound<'_, PyAny>>,
        smoothness: Option<f64>,
        max_distance: Option<f32>,
        min_facing: Option<f32>,
        damping: Option<f64>,
        anchor_vertices: Option<&Bound<'_, PyAny>>,
        anchor_points: Option<&Bound<'_, PyAny>>,
        anchor_weight: Option<f64>,
    ) -> PyResult<Self> {
        let Ok(stencils) = stencils.cast::<PySubdivisionStencils>() else {
            return Err(PyTypeError::new_err(
                "stencils must be a springwrap_kernel.SubdivisionStencils",
            ));
        };
        let stencils = (*stencils.get().stencils).clone();
        let fixed = match fixed.filter(|fixed| !fixed.is_none()) {
            Some(fixed) => read_array::<bool>("fixed", fixed, None)?,
            None => vec![false; stencils.cage_vertex_count()],
        };
        let defaults = SubdivisionFitSettings::default();
        let settings = SubdivisionFitSettings {
            smoothness: smoothness.unwrap_or(defaults.smoothness),
            max_distance: max_distance.unwrap_or(defaults.max_distance),
            min_facing: min_facing.unwrap_or(defaults.min_facing),
            damping: damping.unwrap_or(defaults.damping),
            anchor_weight: anchor_weight.unwrap_or(defaults.anchor_weight),
        };
        let anchor_vertices = match anchor_vertices.filter(|array| !array.is_none()) {
            Some(array) => read_array::<u32>("anchor_vertices", array, None)?,
            None => Vec::new(),
        };
        let anchor_points = match anchor_points.filter(|array| !array.is_none()) {
            Some(array) => read_points("anchor_points", array)?,
            None => Vec::new(),
        };
        let fit = run_kernel(py, || {
            SubdivisionFit::new(stencils, &fixed, settings)?
                .with_anchors(&anchor_vertices, &anchor_points)
        })?;
        Ok(Self { fit: Arc::new(fit) })
    }

    /// (N,) bool: the cage vertices the fit holds (those given, and those on no face).
    fn fixed<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_vec(py, self.fit.fixed().to_vec())
    }

    /// (F, 3) float32 fine points of `cage`, plus `offsets` ((F, 3) float32) when given.
    #[pyo3(signature = (cage, offsets = None))]
    fn fine_points<'py>(
        &self,
        py: Python<'py>,
        cage: &Bound<'py, PyAny>,
        offsets: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let cage = read_points("cage", cage)?;
        let offsets = read_offsets(offsets)?;
        let fit = Arc::clone(&self.fit);
        let fine = run_kernel(py, || fit.fine_points(&cage, offsets.as_deref()))?;
        points_array(py, &fine)
    }

    /// (F,) float32 distance of each fine point to `target`: NaN off the surface or beyond the
    /// match distance.
    #[pyo3(signature = (target, cage, offsets = None))]
    fn distances<'py>(
        &self,
        py: Python<'py>,
        target: &Bound<'py, PyTargetMesh>,
        cage: &Bound<'py, PyAny>,
        offsets: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let mesh = Arc::clone(&target.get().mesh);
        let cage = read_points("cage", cage)?;
        let offsets = read_offsets(offsets)?;
        let fit = Arc::clone(&self.fit);
        let distances = run_kernel(py, || fit.distances(&mesh, &cage, offsets.as_deref()))?;
        Ok(PyArray1::from_vec(py, distances))
    }

    /// One Gauss–Newton round: ((N, 3) float32 new cage, (F,) float32 distances before it,
    /// trusted matches). `cancel` (a `CancelFlag`): the round asks it inside its long loops and
    /// raises `CancelledError` soon after another thread set it (the GIL is free while it runs).
    #[pyo3(signature = (target, cage, offsets = None, *, cancel = None))]
    #[allow(clippy::type_complexity)]
    fn round<'py>(
        &self,
        py: Python<'py>,
        target: &Bound<'py, PyTargetMesh>,
        cage: &Bound<'py, PyAny>,
        offsets: Option<&Bound<'py, PyAny>>,
        cancel: Option<&Bound<'py, PyCancelFlag>>,
    ) -> PyResult<(Bound<'py, PyArray2<f32>>, Bound<'py, PyArray1<f32>>, usize)> {
        let mesh = Arc::clone(&target.get().mesh);
        let cage = read_points("cage", cage)?;
        let offsets = read_offsets(offsets)?;
        let fit = Arc::clone(&self.fit);
        let flag = cancel.map_or_else(
            || Arc::new(AtomicBool::new(false)),
            |cancel| Arc::clone(&cancel.get().flag),
        );
        let round = run_kernel(py, || {
            fit.round_until(&mesh, &cage, offsets.as_deref(), &|| {
                flag.load(Ordering::Relaxed)
            })
        })?;
        Ok((
            points_array(py, &round.positions)?,
            PyArray1::from_vec(py, round.distances),
            round.trusted,
        ))
    }
}

/// A flag another thread sets to stop a long kernel computation (`SubdivisionFit.round(...,
/// cancel=flag)`): the computation asks it inside its loops and raises `CancelledError`.
#[pyclass(name = "CancelFlag", module = "springwrap_kernel", frozen)]
pub(crate) struct PyCancelFlag {
    pub(crate) flag: Arc<AtomicBool>,
}

#[pymethods]
impl PyCancelFlag {
    #[new]
    fn new() -> Self {
        Self {
            flag: Arc::new(AtomicBool::new(false)),
        }
    }

    /// Ask every computation holding this flag to stop.
    fn cancel(&self) {
        self.flag.store(true, Ordering::Relaxed);
    }

    /// Whether `cancel()` was called.
    #[getter]
    fn cancelled(&self) -> bool {
        self.flag.load(Ordering::Relaxed)
    }
}

/// The fit's default settings: {"smoothness", "max_distance", "min_facing", "damping",
/// "anchor_weight", "max_levels"}.
#[pyfunction(name = "subdivision_fit_defaults")]
fn subdivision_fit_defaults_py(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let defaults = SubdivisionFitSettings::default();
    let dict = PyDict::new(py);
    dict.set_item("smoothness", defaults.smoothness)?;
    dict.set_item("max_distance", defaults.max_distance)?;
    dict.set_item("min_facing", defaults.min_facing)?;
    dict.set_item("damping", defaults.damping)?;
    dict.set_item("anchor_weight", defaults.anchor_weight)?;
    dict.set_item("max_levels", springwrap_kernel::fit::MAX_LEVELS)?;
    Ok(dict)
}

/// Adds the fit's classes and functions to the native module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySubdivisionStencils>()?;
    m.add_class::<PySubdivisionFit>()?;
    m.add_class::<PyCancelFlag>()?;
    m.add_function(wrap_pyfunction!(subdivision_fit_defaults_py, m)?)?;
    Ok(())
}
