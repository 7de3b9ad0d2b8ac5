//! The quality read-out's stretch, face normals and flips (`TargetMesh.surface_distances` is its
//! distance): f64 positions in, numpy arrays out. `layout_readout` is the read-out's one call: the
//! stretch, the flips and the layout's size at once.

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use springwrap_kernel::{LayoutFaces, face_normals, flipped_faces, layout_readout, vertex_stretch};

use crate::arrays::{read_faces, read_pairs, read_points64, rows_array};
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
    let (corners, sizes) = read_faces(face_corners, face_sizes)?;
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
    let (corners, sizes) = read_faces(face_corners, face_sizes)?;
    let edges = read_pairs("edges", Some(edges))?;
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    let flipped = run_kernel(py, || flipped_faces(&points, &rest, faces, &edges))?;
    Ok(PyArray1::from_vec(py, flipped))
}

/// (stretch (N,) float64, flipped (F,) bool, diagonal float): the stretch and flips of
/// `vertex_stretch` and `flipped_faces` and the finite points' bounding-box diagonal in one pass;
/// `rest` None: no usable rest shape (the stretch reads 1, no face is flipped).
#[pyfunction(name = "layout_readout")]
#[pyo3(signature = (points, rest, face_corners, face_sizes, edges))]
#[allow(clippy::type_complexity)]
fn layout_readout_py<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    rest: Option<&Bound<'py, PyAny>>,
    face_corners: &Bound<'py, PyAny>,
    face_sizes: &Bound<'py, PyAny>,
    edges: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<bool>>, f64)> {
    let points = read_points64("points", points)?;
    let rest = rest
        .filter(|rest| !rest.is_none())
        .map(|rest| read_points64("rest", rest))
        .transpose()?;
    let (corners, sizes) = read_faces(face_corners, face_sizes)?;
    let edges = read_pairs("edges", Some(edges))?;
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    let readout = run_kernel(py, || {
        layout_readout(&points, rest.as_deref(), faces, &edges)
    })?;
    Ok((
        PyArray1::from_vec(py, readout.stretch),
        PyArray1::from_vec(py, readout.flipped),
        readout.diagonal,
    ))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(vertex_stretch_py, m)?)?;
    m.add_function(wrap_pyfunction!(face_normals_py, m)?)?;
    m.add_function(wrap_pyfunction!(flipped_faces_py, m)?)?;
    m.add_function(wrap_pyfunction!(layout_readout_py, m)?)?;
    Ok(())
}
