//! `LayoutStructure`: the layout mesh's grid lines, corners, extraordinary vertices and curves.

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use springwrap_kernel::mesh::MAX_ELEMENTS;
use springwrap_kernel::{CurveKind, LayoutStructure};

use crate::arguments;
use crate::arrays::{read_faces, read_pairs, rows_array};
use crate::errors::run_kernel;

/// The structure of a layout mesh for the wrap: grid lines, corners, extraordinary vertices, curves.
#[pyclass(name = "LayoutStructure", module = "springwrap_kernel", frozen)]
pub(crate) struct PyLayoutStructure {
    pub(crate) structure: LayoutStructure,
}

#[pymethods]
impl PyLayoutStructure {
    #[new]
    #[pyo3(signature = (vertex_count, face_corners, face_sizes, *, edges = None, seams = None))]
    fn new(
        py: Python<'_>,
        vertex_count: &Bound<'_, PyAny>,
        face_corners: &Bound<'_, PyAny>,
        face_sizes: &Bound<'_, PyAny>,
        edges: Option<&Bound<'_, PyAny>>,
        seams: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let vertex_count = arguments::count("vertex_count", vertex_count, MAX_ELEMENTS)?;
        let (face_corners, face_sizes) = read_faces(face_corners, face_sizes)?;
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
