//! `TargetMesh`: the kernel's target mesh and its queries (closest point, nearest vertex, rays, ICP).

use std::sync::Arc;

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use springwrap_kernel::{
    FacePoint, IcpAnchors, IcpSettings, IcpUpdate, KernelError, NO_TRIANGLE, SurfaceHit,
    TargetMesh, TargetMeshOptions, Transform, VertexHit, icp_anchored,
};

use crate::align::{IcpTuple, read_transform, transform_array};
use crate::arguments;
use crate::arrays::{read_array, read_points64, read_positions, read_with, rows_array};
use crate::errors::{InvalidArgumentError, run_kernel, to_python_error};

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
pub(crate) struct PyTargetMesh {
    pub(crate) mesh: Arc<TargetMesh>,
}

#[pymethods]
impl PyTargetMesh {
    #[new]
    #[pyo3(signature = (vertices, triangles, *, reject_degenerate = None))]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        reject_degenerate: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let reject_degenerate = arguments::flag("reject_degenerate", reject_degenerate, false)?;
        let vertices = read_positions("vertices", vertices)?;
        // Rows straight out of the array: a flat copy first would hold 12 bytes per triangle more.
        let triangles = read_with("triangles", triangles, Some(3), |flat: &[u32]| {
            flat.chunks_exact(3)
                .map(|row| [row[0], row[1], row[2]])
                .collect()
        })?;
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
        update = None,
        max_iterations = None,
        trim_fraction = None,
        max_distance = None,
        tolerance = None,
        ignore_boundary = None,
        anchor_source = None,
        anchor_target = None,
        anchor_weight = None,
    ))]
    #[allow(clippy::too_many_arguments)] // keyword arguments of one Python method
    fn icp<'py>(
        &self,
        py: Python<'py>,
        source: &Bound<'py, PyAny>,
        initial: Option<&Bound<'py, PyAny>>,
        update: Option<&Bound<'py, PyAny>>,
        max_iterations: Option<&Bound<'py, PyAny>>,
        trim_fraction: Option<&Bound<'py, PyAny>>,
        max_distance: Option<&Bound<'py, PyAny>>,
        tolerance: Option<&Bound<'py, PyAny>>,
        ignore_boundary: Option<&Bound<'py, PyAny>>,
        anchor_source: Option<&Bound<'py, PyAny>>,
        anchor_target: Option<&Bound<'py, PyAny>>,
        anchor_weight: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<IcpTuple<'py>> {
        let defaults = IcpSettings::default();
        let update = arguments::text("update", update, "RIGID")?;
        let max_iterations = match max_iterations.filter(|value| !value.is_none()) {
            Some(value) => arguments::count("max_iterations", value, u32::MAX as usize)? as u32,
            None => defaults.max_iterations,
        };
        let trim_fraction =
            arguments::float32_or("trim_fraction", trim_fraction, defaults.trim_fraction)?;
        let max_distance =
            arguments::float32_or("max_distance", max_distance, defaults.max_distance)?;
        let tolerance = arguments::float64_or("tolerance", tolerance, defaults.tolerance)?;
        let ignore_boundary =
            arguments::flag("ignore_boundary", ignore_boundary, defaults.ignore_boundary)?;
        let anchor_weight = arguments::float64_or("anchor_weight", anchor_weight, 1.0)?;
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
        let update = match update.as_str() {
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
    #[pyo3(signature = (points, *, max_distance = None))]
    fn closest_points<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        max_distance: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<SurfaceArrays<'py>> {
        let max_distance = arguments::float32_or("max_distance", max_distance, f32::INFINITY)?;
        let points = read_positions("points", points)?;
        let hits = run_kernel(py, || self.mesh.closest_points(&points, max_distance))?;
        surface_arrays(py, &hits)
    }

    /// Nearest vertex of each query: (vertices, triangles, barycentrics, positions, distances).
    #[pyo3(signature = (points, *, max_distance = None))]
    fn nearest_vertices<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        max_distance: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<VertexArrays<'py>> {
        let max_distance = arguments::float32_or("max_distance", max_distance, f32::INFINITY)?;
        let points = read_positions("points", points)?;
        let hits = run_kernel(py, || self.mesh.nearest_vertices(&points, max_distance))?;
        vertex_arrays(py, &hits)
    }

    /// First hit along each ray: (triangles, barycentrics, positions, signed distances).
    #[pyo3(signature = (origins, directions, *, max_distance = None, both_directions = None))]
    fn ray_cast<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        max_distance: Option<&Bound<'py, PyAny>>,
        both_directions: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<SurfaceArrays<'py>> {
        let max_distance = arguments::float32_or("max_distance", max_distance, f32::INFINITY)?;
        let both_directions = arguments::flag("both_directions", both_directions, false)?;
        let origins = read_positions("origins", origins)?;
        let directions = read_positions("directions", directions)?;
        let hits = run_kernel(py, || {
            self.mesh
                .ray_casts(&origins, &directions, max_distance, both_directions)
        })?;
        surface_arrays(py, &hits)
    }

    /// (N,) float64 distance of each point (float64, in the mesh's coordinates) to the closest
    /// surface point; ``near`` (N,) uint32: the triangle each point lies on (a face-point's,
    /// 0xFFFFFFFF for none): within ``on_surface`` of it, the distance to it, else the search
    /// starts there. A non-finite point's distance is infinite.
    #[pyo3(signature = (points, *, near = None, on_surface = None))]
    fn surface_distances<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        near: Option<&Bound<'py, PyAny>>,
        on_surface: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let on_surface = arguments::on_surface(on_surface)?;
        let points = read_points64("points", points)?;
        let near = near
            .map(|near| read_array::<u32>("near", near, None))
            .transpose()?;
        let distances = run_kernel(py, || {
            self.mesh
                .surface_distances(&points, near.as_deref(), on_surface)
        })?;
        Ok(PyArray1::from_vec(py, distances))
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
