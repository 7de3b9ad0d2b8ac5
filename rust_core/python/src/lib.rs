//! PyO3 binding of the Springwrap kernel: the only crate that knows Python.
//!
//! Thin by design: check and copy the numpy inputs into owned Rust data, run the kernel with the
//! GIL released (`py.detach`) and any panic caught, and wrap the results as numpy arrays. The
//! pure-Python package `springwrap_kernel` re-exports this module and adds named results.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;

use glam::Vec3;
use numpy::{
    Element, PyArray1, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use springwrap_kernel::{
    AlignMethod, Anchor, AnchorTarget, CurveConstraint, CurveKind, FacePoint, KernelError,
    LayoutPoint, LayoutStructure, NO_TRIANGLE, PlaneConstraint, SolverKind, SpringRest, SurfaceHit,
    TargetMesh, TargetMeshOptions, VertexHit, WrapSettings, WrapSolver, WrapWeights,
};
use springwrap_kernel::{
    IcpAnchors, IcpSettings, IcpUpdate, Transform, fit_transform, icp_anchored,
};

mod features;

create_exception!(
    springwrap_kernel,
    SpringwrapError,
    PyValueError,
    "Base class of every error the Springwrap kernel raises."
);
create_exception!(
    springwrap_kernel,
    ArrayError,
    SpringwrapError,
    "An input array has the wrong dtype, shape or memory layout."
);
create_exception!(
    springwrap_kernel,
    EmptyMeshError,
    SpringwrapError,
    "The mesh has no vertices or no triangles."
);
create_exception!(
    springwrap_kernel,
    NonFiniteError,
    SpringwrapError,
    "A coordinate is NaN or infinite."
);
create_exception!(
    springwrap_kernel,
    IndexOutOfRangeError,
    SpringwrapError,
    "An index refers to a vertex or triangle that does not exist."
);
create_exception!(
    springwrap_kernel,
    DegenerateMeshError,
    SpringwrapError,
    "Every triangle has zero area: there is no surface."
);
create_exception!(
    springwrap_kernel,
    DegenerateTriangleError,
    SpringwrapError,
    "A triangle has zero area (raised only with reject_degenerate=True)."
);
create_exception!(
    springwrap_kernel,
    InvalidArgumentError,
    SpringwrapError,
    "A scalar argument is out of its domain."
);
create_exception!(
    springwrap_kernel,
    InternalError,
    SpringwrapError,
    "A bug in the kernel (a caught Rust panic). Please report it."
);

/// The one place where kernel errors become Python exceptions.
fn to_python_error(error: &KernelError) -> PyErr {
    let message = error.to_string();
    match error {
        KernelError::EmptyMesh { .. } => EmptyMeshError::new_err(message),
        KernelError::NonFinite { .. } => NonFiniteError::new_err(message),
        KernelError::VertexIndexOutOfRange { .. }
        | KernelError::LayoutIndexOutOfRange { .. }
        | KernelError::TriangleIndexOutOfRange { .. } => IndexOutOfRangeError::new_err(message),
        KernelError::DegenerateMesh { .. } => DegenerateMeshError::new_err(message),
        KernelError::DegenerateTriangle { .. } => DegenerateTriangleError::new_err(message),
        KernelError::ZeroDirection { .. }
        | KernelError::LengthMismatch { .. }
        | KernelError::InvalidArgument { .. }
        | KernelError::TooLarge { .. }
        | KernelError::TooFewPairs { .. }
        | KernelError::CoincidentAnchors { .. }
        | KernelError::CollinearAnchors { .. }
        | KernelError::CoplanarAnchors { .. } => InvalidArgumentError::new_err(message),
        KernelError::InvalidScale { .. } => InvalidArgumentError::new_err(message),
        KernelError::FlatSurface { .. } => features::FlatSurfaceError::new_err(message),
    }
}

/// Runs kernel work without the GIL, turning kernel errors and panics into Python exceptions.
fn run_kernel<T: Send>(
    py: Python<'_>,
    work: impl FnOnce() -> Result<T, KernelError> + Send,
) -> PyResult<T> {
    let outcome = py.detach(|| catch_unwind(AssertUnwindSafe(work)));
    match outcome {
        Ok(Ok(value)) => Ok(value),
        Ok(Err(error)) => Err(to_python_error(&error)),
        Err(panic) => {
            let reason = panic
                .downcast_ref::<&str>()
                .map(ToString::to_string)
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_owned());
            Err(InternalError::new_err(format!(
                "internal error in the Springwrap kernel: {reason}"
            )))
        }
    }
}

/// Checks that `array` is a C-contiguous numpy array of `T` with `columns` columns (or 1-D when
/// `columns` is `None`) and copies it out. Says exactly what was wrong otherwise.
fn read_array<T: Element + Copy>(
    name: &str,
    array: &Bound<'_, PyAny>,
    columns: Option<usize>,
) -> PyResult<Vec<T>> {
    let py = array.py();
    let expected_dtype = numpy::dtype::<T>(py);
    let expected_shape = match columns {
        Some(columns) => format!("(N, {columns})"),
        None => "(N,)".to_owned(),
    };
    let expectation = format!(
        "{name} must be a C-contiguous numpy array of dtype {expected_dtype} and shape {expected_shape}"
    );
    let Ok(untyped) = array.cast::<PyUntypedArray>() else {
        let type_name = array.get_type().name()?;
        return Err(ArrayError::new_err(format!(
            "{expectation}, got a {type_name}"
        )));
    };
    let dtype = untyped.dtype();
    if !dtype.is_equiv_to(&expected_dtype) {
        return Err(ArrayError::new_err(format!(
            "{expectation}, got dtype {dtype} (convert with .astype(numpy.{expected_dtype}))"
        )));
    }
    let shape = untyped.shape();
    let shape_ok = match columns {
        Some(columns) => shape.len() == 2 && shape[1] == columns,
        None => shape.len() == 1,
    };
    if !shape_ok {
        return Err(ArrayError::new_err(format!(
            "{expectation}, got shape {shape:?}"
        )));
    }
    if !untyped.is_c_contiguous() {
        return Err(ArrayError::new_err(format!(
            "{expectation}, got a non-contiguous array (use numpy.ascontiguousarray)"
        )));
    }
    let values: Vec<T> = if columns.is_some() {
        let typed = untyped.cast::<PyArray2<T>>()?.readonly();
        typed.as_slice()?.to_vec()
    } else {
        let typed = untyped.cast::<PyArray1<T>>()?.readonly();
        typed.as_slice()?.to_vec()
    };
    Ok(values)
}

fn read_positions(name: &str, array: &Bound<'_, PyAny>) -> PyResult<Vec<Vec3>> {
    let flat = read_array::<f32>(name, array, Some(3))?;
    Ok(flat
        .chunks_exact(3)
        .map(|row| Vec3::new(row[0], row[1], row[2]))
        .collect())
}

fn rows_array<'py, T: Element>(
    py: Python<'py>,
    flat: Vec<T>,
    columns: usize,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let rows = flat.len() / columns;
    PyArray1::from_vec(py, flat).reshape([rows, columns])
}

type SurfaceArrays<'py> = (
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
);

fn surface_arrays<'py>(
    py: Python<'py>,
    hits: &[Option<SurfaceHit>],
) -> PyResult<SurfaceArrays<'py>> {
    let mut triangles = Vec::with_capacity(hits.len());
    let mut barycentrics = Vec::with_capacity(hits.len() * 3);
    let mut positions = Vec::with_capacity(hits.len() * 3);
    let mut distances = Vec::with_capacity(hits.len());
    for hit in hits {
        match hit {
            Some(hit) => {
                triangles.push(hit.face_point.triangle as i32);
                barycentrics.extend(hit.face_point.barycentric.to_array());
                positions.extend(hit.position.to_array());
                distances.push(hit.distance);
            }
            None => {
                triangles.push(-1);
                barycentrics.extend([0.0; 3]);
                positions.extend([f32::NAN; 3]);
                distances.push(f32::NAN);
            }
        }
    }
    Ok((
        PyArray1::from_vec(py, triangles),
        rows_array(py, barycentrics, 3)?,
        rows_array(py, positions, 3)?,
        PyArray1::from_vec(py, distances),
    ))
}

type VertexArrays<'py> = (
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
);

fn vertex_arrays<'py>(py: Python<'py>, hits: &[Option<VertexHit>]) -> PyResult<VertexArrays<'py>> {
    let vertices = hits
        .iter()
        .map(|hit| hit.map_or(-1, |hit| hit.vertex as i32))
        .collect();
    let surface: Vec<Option<SurfaceHit>> = hits
        .iter()
        .map(|hit| {
            hit.map(|hit| SurfaceHit {
                face_point: hit.face_point,
                position: hit.position,
                distance: hit.distance,
            })
        })
        .collect();
    let (triangles, barycentrics, positions, distances) = surface_arrays(py, &surface)?;
    Ok((
        PyArray1::from_vec(py, vertices),
        triangles,
        barycentrics,
        positions,
        distances,
    ))
}

/// A triangle mesh prepared for queries (BVH over triangles, vertex tree, adjacency, normals).
#[pyclass(name = "TargetMesh", module = "springwrap_kernel", frozen, subclass)]
struct PyTargetMesh {
    mesh: Arc<TargetMesh>,
}

#[pymethods]
impl PyTargetMesh {
    #[new]
    #[pyo3(signature = (vertices, triangles, *, reject_degenerate = false))]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        reject_degenerate: bool,
    ) -> PyResult<Self> {
        let vertices = read_positions("vertices", vertices)?;
        let flat_triangles = read_array::<u32>("triangles", triangles, Some(3))?;
        let triangles = flat_triangles
            .chunks_exact(3)
            .map(|row| [row[0], row[1], row[2]])
            .collect();
        let options = TargetMeshOptions { reject_degenerate };
        let mesh = run_kernel(py, || TargetMesh::new(vertices, triangles, options))?;
        Ok(Self {
            mesh: Arc::new(mesh),
        })
    }

    /// Builds now what is otherwise built on first use: the vertex tree, adjacency, normals.
    fn prepare_all(&self, py: Python<'_>) -> PyResult<()> {
        run_kernel(py, || {
            self.mesh.prepare_all();
            Ok(())
        })
    }

    /// Number of vertices.
    #[getter]
    fn vertex_count(&self) -> usize {
        self.mesh.vertices().len()
    }

    /// Number of triangles.
    #[getter]
    fn triangle_count(&self) -> usize {
        self.mesh.triangles().len()
    }

    /// Number of zero-area triangles (kept, but inert).
    #[getter]
    fn degenerate_triangle_count(&self) -> usize {
        self.mesh.degenerate_triangle_count()
    }

    /// Number of edges with a single triangle (holes and open borders).
    #[getter]
    fn boundary_edge_count(&self) -> usize {
        self.mesh.boundary_edges().len()
    }

    /// Number of edges shared by three or more triangles.
    #[getter]
    fn non_manifold_edge_count(&self) -> usize {
        self.mesh.non_manifold_edge_count()
    }

    /// `((min_x, min_y, min_z), (max_x, max_y, max_z))`.
    fn bounding_box(&self) -> ((f32, f32, f32), (f32, f32, f32)) {
        let (min, max) = self.mesh.bounding_box();
        ((min.x, min.y, min.z), (max.x, max.y, max.z))
    }

    /// (N, 3) float32 vertex positions.
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat = self
            .mesh
            .vertices()
            .iter()
            .flat_map(|v| v.to_array())
            .collect();
        rows_array(py, flat, 3)
    }

    /// (M, 3) uint32 triangles.
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let flat = self.mesh.triangles().iter().flatten().copied().collect();
        rows_array(py, flat, 3)
    }

    /// (M, 3) float32 unit face normals, zero for degenerate triangles.
    fn face_normals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat = self
            .mesh
            .face_normals()
            .iter()
            .flat_map(|v| v.to_array())
            .collect();
        rows_array(py, flat, 3)
    }

    /// (N, 3) float32 angle-weighted unit vertex normals.
    fn vertex_normals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat = self
            .mesh
            .vertex_normals()
            .iter()
            .flat_map(|v| v.to_array())
            .collect();
        rows_array(py, flat, 3)
    }

    /// (M, 3) int32: the triangle across each edge, -1 on boundary and non-manifold edges.
    fn triangle_neighbors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        let flat = self
            .mesh
            .triangle_neighbors()
            .iter()
            .flatten()
            .map(|&neighbor| {
                if neighbor == NO_TRIANGLE {
                    -1
                } else {
                    neighbor as i32
                }
            })
            .collect();
        rows_array(py, flat, 3)
    }

    /// (B, 2) uint32 rows of (triangle, edge) for every boundary edge.
    fn boundary_edges<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let flat = self
            .mesh
            .boundary_edges()
            .iter()
            .flat_map(|edge| [edge.triangle, u32::from(edge.edge)])
            .collect();
        rows_array(py, flat, 2)
    }

    /// Point-to-plane ICP of `source` onto this mesh from `initial` (a (4, 4) float64 matrix,
    /// identity when `None`): (matrix, iterations, converged, rms_before, rms_after, pairs_used).
    /// With `anchor_source` / `anchor_target` ((K, 3) float32 each) the anchors stay in the fit,
    /// all together weighing `anchor_weight` times the surface pairs.
    #[pyo3(signature = (
        source,
        initial = None,
        *,
        update = "RIGID",
        max_iterations = 50,
        trim_fraction = 0.1,
        max_distance = f32::INFINITY,
        tolerance = 1e-7,
        ignore_boundary = true,
        anchor_source = None,
        anchor_target = None,
        anchor_weight = 1.0,
    ))]
    #[allow(clippy::too_many_arguments)] // keyword arguments of one Python method
    fn icp<'py>(
        &self,
        py: Python<'py>,
        source: &Bound<'py, PyAny>,
        initial: Option<&Bound<'py, PyAny>>,
        update: &str,
        max_iterations: u32,
        trim_fraction: f32,
        max_distance: f32,
        tolerance: f64,
        ignore_boundary: bool,
        anchor_source: Option<&Bound<'py, PyAny>>,
        anchor_target: Option<&Bound<'py, PyAny>>,
        anchor_weight: f64,
    ) -> PyResult<IcpTuple<'py>> {
        let source = read_positions("source", source)?;
        let (anchor_source, anchor_target) = match (anchor_source, anchor_target) {
            (Some(source), Some(target)) => (
                read_positions("anchor_source", source)?,
                read_positions("anchor_target", target)?,
            ),
            (None, None) => (Vec::new(), Vec::new()),
            _ => {
                return Err(InvalidArgumentError::new_err(
                    "anchor_source and anchor_target come together: give both or neither",
                ));
            }
        };
        let initial = match initial {
            Some(array) => read_transform("initial", array)?,
            None => Transform::IDENTITY,
        };
        let update = match update {
            "RIGID" => IcpUpdate::Rigid,
            "SIMILARITY" => IcpUpdate::Similarity,
            other => {
                return Err(InvalidArgumentError::new_err(format!(
                    "invalid update: {other:?} (use 'RIGID' or 'SIMILARITY')"
                )));
            }
        };
        let settings = IcpSettings {
            update,
            max_iterations,
            trim_fraction,
            max_distance,
            tolerance,
            ignore_boundary,
        };
        let anchors = IcpAnchors {
            source: &anchor_source,
            target: &anchor_target,
            weight: anchor_weight,
        };
        let report = run_kernel(py, || {
            icp_anchored(&self.mesh, &source, anchors, initial, settings)
        })?;
        Ok((
            transform_array(py, &report.transform)?,
            report.iterations,
            report.converged,
            report.rms_before,
            report.rms_after,
            report.pairs_used,
        ))
    }

    /// Exact closest surface point of each query: (triangles, barycentrics, positions, distances).
    #[pyo3(signature = (points, *, max_distance = f32::INFINITY))]
    fn closest_points<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        max_distance: f32,
    ) -> PyResult<SurfaceArrays<'py>> {
        let points = read_positions("points", points)?;
        let hits = run_kernel(py, || self.mesh.closest_points(&points, max_distance))?;
        surface_arrays(py, &hits)
    }

    /// Nearest vertex of each query: (vertices, triangles, barycentrics, positions, distances).
    #[pyo3(signature = (points, *, max_distance = f32::INFINITY))]
    fn nearest_vertices<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        max_distance: f32,
    ) -> PyResult<VertexArrays<'py>> {
        let points = read_positions("points", points)?;
        let hits = run_kernel(py, || self.mesh.nearest_vertices(&points, max_distance))?;
        vertex_arrays(py, &hits)
    }

    /// First hit along each ray: (triangles, barycentrics, positions, signed distances).
    #[pyo3(signature = (origins, directions, *, max_distance = f32::INFINITY, both_directions = false))]
    fn ray_cast<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        max_distance: f32,
        both_directions: bool,
    ) -> PyResult<SurfaceArrays<'py>> {
        let origins = read_positions("origins", origins)?;
        let directions = read_positions("directions", directions)?;
        let hits = run_kernel(py, || {
            self.mesh
                .ray_casts(&origins, &directions, max_distance, both_directions)
        })?;
        surface_arrays(py, &hits)
    }

    /// (K, 3) float32 positions of face-points given as triangles (K,) uint32 and barycentrics (K, 3).
    fn face_point_positions<'py>(
        &self,
        py: Python<'py>,
        triangles: &Bound<'py, PyAny>,
        barycentrics: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let triangles = read_array::<u32>("triangles", triangles, None)?;
        let barycentrics = read_positions("barycentrics", barycentrics)?;
        if triangles.len() != barycentrics.len() {
            return Err(to_python_error(&KernelError::LengthMismatch {
                what: "triangles and barycentrics",
                first: triangles.len(),
                second: barycentrics.len(),
            }));
        }
        let face_points: Vec<FacePoint> = triangles
            .iter()
            .zip(&barycentrics)
            .map(|(&triangle, &barycentric)| FacePoint {
                triangle,
                barycentric,
            })
            .collect();
        let positions = run_kernel(py, || self.mesh.face_point_positions(&face_points))?;
        let flat = positions.iter().flat_map(|p| p.to_array()).collect();
        rows_array(py, flat, 3)
    }

    fn __repr__(&self) -> String {
        format!(
            "TargetMesh({} vertices, {} triangles, {} degenerate, {} boundary edges)",
            self.mesh.vertices().len(),
            self.mesh.triangles().len(),
            self.mesh.degenerate_triangle_count(),
            self.mesh.boundary_edges().len()
        )
    }
}

fn read_pairs(name: &str, array: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<[u32; 2]>> {
    let Some(array) = array else {
        return Ok(Vec::new());
    };
    let flat = read_array::<u32>(name, array, Some(2))?;
    Ok(flat
        .chunks_exact(2)
        .map(|pair| [pair[0], pair[1]])
        .collect())
}

/// The structure of a layout mesh for the wrap: grid lines, corners, extraordinary vertices, curves.
#[pyclass(name = "LayoutStructure", module = "springwrap_kernel", frozen)]
struct PyLayoutStructure {
    structure: LayoutStructure,
}

#[pymethods]
impl PyLayoutStructure {
    #[new]
    #[pyo3(signature = (vertex_count, face_corners, face_sizes, *, edges = None, seams = None))]
    fn new(
        py: Python<'_>,
        vertex_count: usize,
        face_corners: &Bound<'_, PyAny>,
        face_sizes: &Bound<'_, PyAny>,
        edges: Option<&Bound<'_, PyAny>>,
        seams: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let face_corners = read_array::<u32>("face_corners", face_corners, None)?;
        let face_sizes = read_array::<u32>("face_sizes", face_sizes, None)?;
        let edges = read_pairs("edges", edges)?;
        let seams = read_pairs("seams", seams)?;
        let structure = run_kernel(py, || {
            LayoutStructure::new(vertex_count, &face_corners, &face_sizes, &edges, &seams)
        })?;
        Ok(Self { structure })
    }

    /// Number of layout vertices.
    #[getter]
    fn vertex_count(&self) -> usize {
        self.structure.vertex_count
    }

    /// (T, 3) uint32 grid-line triples (previous, vertex, next).
    fn line_triples<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let flat = self
            .structure
            .line_triples
            .iter()
            .flat_map(|triple| [triple.previous, triple.vertex, triple.next])
            .collect();
        rows_array(py, flat, 3)
    }

    /// Vertices on no grid line (umbrella fallback), uint32.
    fn extraordinary<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        PyArray1::from_vec(py, self.structure.extraordinary.clone())
    }

    /// Patch corners (border vertices of one face), uint32.
    fn corners<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        PyArray1::from_vec(py, self.structure.corners.clone())
    }

    /// The curves as a list of (kind, vertices uint32, closed); kind is "BORDER", "SEAM" or "LOOSE".
    fn curves<'py>(&self, py: Python<'py>) -> Vec<(&'static str, Bound<'py, PyArray1<u32>>, bool)> {
        self.structure
            .curves
            .iter()
            .map(|curve| {
                let kind = match curve.kind {
                    CurveKind::Border => "BORDER",
                    CurveKind::Seam => "SEAM",
                    CurveKind::Loose => "LOOSE",
                };
                (
                    kind,
                    PyArray1::from_vec(py, curve.vertices.clone()),
                    curve.closed,
                )
            })
            .collect()
    }
}

/// Per-vertex state arrays: (states, triangles, barycentrics).
type StateArrays<'py> = (
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray2<f32>>,
);

/// A wrap in progress: call `step(n)` repeatedly, read `positions()` and `states()`.
#[pyclass(name = "WrapSolver", module = "springwrap_kernel", subclass)]
struct PyWrapSolver {
    solver: WrapSolver,
}

#[pymethods]
impl PyWrapSolver {
    #[new]
    #[pyo3(signature = (
        target, structure, states, triangles, barycentrics, positions, *,
        anchor_vertices = None, anchor_triangles = None, anchor_barycentrics = None,
        anchor_positions = None, unreliable_triangles = None, curve_vertices = None,
        curve_vertex_counts = None, curve_points = None, curve_point_counts = None, fairness = 0.5, arc_length = 0.5, thin_plate = 0.2,
        constraint = 0.5, folding = 0.3, tolerance = 1e-5, landing_distance = 0.25,
        fold_tolerance = 0.17453292, momentum = 0.9, rest = "TEMPLATE", rest_positions = None,
        plane_vertices = None, plane_point = None, plane_normal = None, plane_slide = true,
        solver = "SPRINGS"
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        target: &Bound<'_, PyTargetMesh>,
        structure: &Bound<'_, PyLayoutStructure>,
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
        fairness: f32,
        arc_length: f32,
        thin_plate: f32,
        constraint: f32,
        folding: f32,
        tolerance: f32,
        landing_distance: f32,
        fold_tolerance: f32,
        momentum: f32,
        rest: &str,
        rest_positions: Option<&Bound<'_, PyAny>>,
        plane_vertices: Option<&Bound<'_, PyAny>>,
        plane_point: Option<[f32; 3]>,
        plane_normal: Option<[f32; 3]>,
        plane_slide: bool,
        solver: &str,
    ) -> PyResult<Self> {
        let solver_kind = match solver {
            "SPRINGS" => SolverKind::Springs,
            "ENERGY" => SolverKind::Energy,
            other => {
                return Err(InvalidArgumentError::new_err(format!(
                    "invalid solver: {other:?} is not 'SPRINGS' or 'ENERGY'"
                )));
            }
        };
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
        let rest = match rest {
            "TEMPLATE" => SpringRest::Template,
            "EVEN" => SpringRest::Even,
            other => {
                return Err(InvalidArgumentError::new_err(format!(
                    "invalid rest: {other:?} is not 'TEMPLATE' or 'EVEN'"
                )));
            }
        };
        let rest_positions = rest_positions
            .map(|array| read_positions("rest_positions", array))
            .transpose()?;
        let anchors = read_anchors(
            anchor_vertices,
            anchor_triangles,
            anchor_barycentrics,
            anchor_positions,
        )?;
        let settings = WrapSettings {
            weights: WrapWeights {
                fairness,
                arc_length,
                thin_plate,
                constraint,
                folding,
            },
            tolerance,
            landing_distance,
            fold_tolerance,
            momentum,
            rest,
            solver: solver_kind,
        };
        let curves = read_curve_constraints(
            curve_vertices,
            curve_vertex_counts,
            curve_points,
            curve_point_counts,
        )?;
        let unreliable = unreliable_triangles
            .map(|flags| read_array::<bool>("unreliable_triangles", flags, None))
            .transpose()?;
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
            .with_curve_constraints(&curves)?;
            let solver = match &plane {
                Some(plane) => solver.with_plane_constraint(plane)?,
                None => solver,
            };
            match unreliable {
                Some(flags) => solver.with_unreliable_triangles(flags),
                None => Ok(solver),
            }
        })?;
        Ok(Self { solver })
    }

    /// Runs up to `iterations` iterations (fewer once converged); returns the progress as
    /// ((iterations, total_iterations, max_displacement, converged, face_points, space_points,
    /// landed, folded, lifted, fold_tolerance, mean_displacement), energy, held_back).
    #[allow(clippy::type_complexity)]
    fn step(
        &mut self,
        py: Python<'_>,
        iterations: usize,
    ) -> PyResult<(
        (
            usize,
            usize,
            f32,
            bool,
            usize,
            usize,
            usize,
            usize,
            usize,
            f32,
            f32,
        ),
        f64,
        usize,
    )> {
        let solver = &mut self.solver;
        let report = run_kernel(py, || solver.step(iterations))?;
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
                report.lifted,
                report.fold_tolerance,
                report.mean_displacement,
            ),
            report.energy,
            report.held_back,
        ))
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
/// `curve_vertices`, its target polyline the next `curve_point_counts[c]` rows of `curve_points`.
fn read_curve_constraints(
    vertices: Option<&Bound<'_, PyAny>>,
    vertex_counts: Option<&Bound<'_, PyAny>>,
    points: Option<&Bound<'_, PyAny>>,
    point_counts: Option<&Bound<'_, PyAny>>,
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
    let vertex_total: usize = vertex_counts.iter().map(|&count| count as usize).sum();
    let point_total: usize = point_counts.iter().map(|&count| count as usize).sum();
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
            let constraint = CurveConstraint {
                layout_vertices: vertices[vertex_offset..vertex_offset + vertex_count].to_vec(),
                target: points[point_offset..point_offset + point_count].to_vec(),
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

/// ICP results as returned to Python (the package names them `IcpReport`).
type IcpTuple<'py> = (Bound<'py, PyArray2<f64>>, u32, bool, f64, f64, usize);

/// Reads a (4, 4) float64 affine matrix whose last row is `0 0 0 1`.
fn read_transform(name: &str, array: &Bound<'_, PyAny>) -> PyResult<Transform> {
    let flat = read_array::<f64>(name, array, Some(4))?;
    if flat.len() != 16 {
        return Err(ArrayError::new_err(format!(
            "{name} must be a (4, 4) float64 matrix, got {} rows",
            flat.len() / 4
        )));
    }
    if flat[12..] != [0.0, 0.0, 0.0, 1.0] {
        return Err(InvalidArgumentError::new_err(format!(
            "invalid {name}: the last row must be 0 0 0 1 (an affine matrix), got {:?}",
            &flat[12..]
        )));
    }
    Ok(Transform {
        rows: std::array::from_fn(|row| std::array::from_fn(|column| flat[row * 4 + column])),
    })
}

/// A transform as a (4, 4) float64 homogeneous matrix.
fn transform_array<'py>(
    py: Python<'py>,
    transform: &Transform,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat = transform
        .to_homogeneous()
        .iter()
        .flatten()
        .copied()
        .collect();
    rows_array(py, flat, 4)
}

/// Least-squares transform taking `source[i]` to `target[i]` (float32 (N, 3) anchors), as a
/// (4, 4) float64 matrix; `method` is `'RIGID'`, `'SIMILARITY'` or `'AFFINE'`.
#[pyfunction(name = "fit_transform")]
#[pyo3(signature = (source, target, method = "SIMILARITY", *, weights = None))]
fn fit_transform_py<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    target: &Bound<'py, PyAny>,
    method: &str,
    weights: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let method = match method {
        "RIGID" => AlignMethod::Rigid,
        "SIMILARITY" => AlignMethod::Similarity,
        "AFFINE" => AlignMethod::Affine,
        other => {
            return Err(InvalidArgumentError::new_err(format!(
                "invalid method: {other:?} (use 'RIGID', 'SIMILARITY' or 'AFFINE')"
            )));
        }
    };
    let source = read_positions("source", source)?;
    let target = read_positions("target", target)?;
    let weights = weights
        .map(|array| read_array::<f32>("weights", array, None))
        .transpose()?;
    let transform = run_kernel(py, || {
        fit_transform(&source, &target, method, weights.as_deref())
    })?;
    transform_array(py, &transform)
}

/// The native part of `springwrap_kernel`.
#[pymodule(gil_used = false)]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<PyTargetMesh>()?;
    m.add_class::<PyLayoutStructure>()?;
    m.add_class::<PyWrapSolver>()?;
    m.add_function(wrap_pyfunction!(fit_transform_py, m)?)?;
    m.add("SpringwrapError", py.get_type::<SpringwrapError>())?;
    m.add("ArrayError", py.get_type::<ArrayError>())?;
    m.add("EmptyMeshError", py.get_type::<EmptyMeshError>())?;
    m.add("NonFiniteError", py.get_type::<NonFiniteError>())?;
    m.add(
        "IndexOutOfRangeError",
        py.get_type::<IndexOutOfRangeError>(),
    )?;
    m.add("DegenerateMeshError", py.get_type::<DegenerateMeshError>())?;
    m.add(
        "DegenerateTriangleError",
        py.get_type::<DegenerateTriangleError>(),
    )?;
    m.add(
        "InvalidArgumentError",
        py.get_type::<InvalidArgumentError>(),
    )?;
    m.add("InternalError", py.get_type::<InternalError>())?;
    features::register(m)?;
    Ok(())
}
