//! The quality read-out's stretch, face normals and flips (`TargetMesh.surface_distances` is its
//! distance): f64 positions in, numpy arrays out.

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use springwrap_kernel::{LayoutFaces, face_normals, flipped_faces, vertex_stretch};

use crate::arrays::{read_array, read_pairs, read_points64, rows_array};
use crate::errors::run_kernel;

/// (N,) float64 mean incident edge length now over the same at rest (1 where nothing is measured).
#[pyfunction(name = "vertex_stretch")]
fn vertex_stretch_py<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    rest: &Bound<'py, PyAny>,
    edges: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let points = read_points64("points", points)?;
    let rest = read_points64("rest", rest)?;
    let edges = read_pairs("edges", Some(edges))?;
    let stretch = run_kernel(py, || vertex_stretch(&points, &rest, &edges))?;
    Ok(PyArray1::from_vec(py, stretch))
}

/// (F, 3) float64 Newell normals (twice the area vector; zero for a degenerate face).
#[pyfunction(name = "face_normals")]
fn face_normals_py<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    face_corners: &Bound<'py, PyAny>,
    face_sizes: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let points = read_points64("points", points)?;
    let corners = read_array::<u32>("face_corners", face_corners, None)?;
    let sizes = read_array::<u32>("face_sizes", face_sizes, None)?;
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    let normals = run_kernel(py, || face_normals(&points, faces))?;
    rows_array(py, normals.iter().flat_map(|n| n.to_array()).collect(), 3)
}

/// (F,) bool: each face turned over against its rest shape (its neighbourhood's best rotation).
#[pyfunction(name = "flipped_faces")]
fn flipped_faces_py<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    rest: &Bound<'py, PyAny>,
    face_corners: &Bound<'py, PyAny>,
    face_sizes: &Bound<'py, PyAny>,
    edges: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let points = read_points64("points", points)?;
    let rest = read_points64("rest", rest)?;
    let corners = read_array::<u32>("face_corners", face_corners, None)?;
    let sizes = read_array::<u32>("face_sizes", face_sizes, None)?;
    let edges = read_pairs("edges", Some(edges))?;
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    let flipped = run_kernel(py, || flipped_faces(&points, &rest, faces, &edges))?;
    Ok(PyArray1::from_vec(py, flipped))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(vertex_stretch_py, m)?)?;
    m.add_function(wrap_pyfunction!(face_normals_py, m)?)?;
    m.add_function(wrap_pyfunction!(flipped_faces_py, m)?)?;
    Ok(())
}
