//! The quality read-out's stretch, face normals and flips (`TargetMesh.surface_distances` is its
//! distance): f64 positions in, numpy arrays out. `layout_readout` is the read-out's one call: the
//! stretch, the flips and the layout's size at once; `placed_readout` the whole read-out of a
//! layout as its object stores it (local float32 positions and the object's matrix), distances
//! included.

use std::sync::Arc;

use glam::DVec3;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use springwrap_kernel::{
    DistanceTarget, LayoutFaces, PlacedLayout, face_normals, flipped_faces, layout_readout,
    placed_readout, vertex_stretch,
};

use crate::align::read_transform;
use crate::arguments;
use crate::arrays::{
    read_array, read_faces, read_pairs, read_points64, read_positions, rows_array,
};
use crate::errors::{ArrayError, run_kernel};
use crate::target_mesh::PyTargetMesh;

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

/// (distances (N,) float64, stretch (N,) float64, flipped (F,) bool, diagonal float): the whole
/// read-out of a layout as its object stores it. `positions` and `rest` (N, 3) float32 are in the
/// object's space (`rest` None: no rest shape; one with a point not finite in the world is not
/// used either), `matrix` (4, 4) float64 (affine) takes them to the world; `mesh`'s coordinates
/// are the world's less `origin` ((3,) float64, default zero); `near` and `on_surface` as in
/// `TargetMesh.surface_distances`. The same numbers as `layout_readout` of the world positions
/// and rest shape and `surface_distances` of the positions, in one call.
#[pyfunction(name = "placed_readout")]
#[pyo3(signature = (
    mesh,
    positions,
    rest,
    matrix,
    face_corners,
    face_sizes,
    edges,
    *,
    origin = None,
    near = None,
    on_surface = None,
))]
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
fn placed_readout_py<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    positions: &Bound<'py, PyAny>,
    rest: Option<&Bound<'py, PyAny>>,
    matrix: &Bound<'py, PyAny>,
    face_corners: &Bound<'py, PyAny>,
    face_sizes: &Bound<'py, PyAny>,
    edges: &Bound<'py, PyAny>,
    origin: Option<&Bound<'py, PyAny>>,
    near: Option<&Bound<'py, PyAny>>,
    on_surface: Option<&Bound<'py, PyAny>>,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<bool>>,
    f64,
)> {
    let mesh = arguments::instance::<PyTargetMesh>("mesh", "TargetMesh", mesh)?;
    let mesh = Arc::clone(&mesh.get().mesh);
    let positions = read_positions("positions", positions)?;
    let rest = rest
        .filter(|rest| !rest.is_none())
        .map(|rest| read_positions("rest", rest))
        .transpose()?;
    let to_world = read_transform("matrix", matrix)?;
    let (corners, sizes) = read_faces(face_corners, face_sizes)?;
    let edges = read_pairs("edges", Some(edges))?;
    let origin = match origin.filter(|origin| !origin.is_none()) {
        None => DVec3::ZERO,
        Some(origin) => match read_array::<f64>("origin", origin, None)?[..] {
            [x, y, z] => DVec3::new(x, y, z),
            ref other => {
                return Err(ArrayError::new_err(format!(
                    "origin must be a (3,) float64 array, got {} values",
                    other.len()
                )));
            }
        },
    };
    let near = near
        .filter(|near| !near.is_none())
        .map(|near| read_array::<u32>("near", near, None))
        .transpose()?;
    let on_surface = arguments::on_surface(on_surface)?;
    let layout = PlacedLayout {
        positions: &positions,
        rest: rest.as_deref(),
        to_world: &to_world,
        faces: LayoutFaces {
            corners: &corners,
            sizes: &sizes,
        },
        edges: &edges,
    };
    let target = DistanceTarget {
        mesh: &mesh,
        origin,
        near: near.as_deref(),
        on_surface,
    };
    let readout = run_kernel(py, || placed_readout(layout, target))?;
    Ok((
        PyArray1::from_vec(py, readout.distances),
        PyArray1::from_vec(py, readout.layout.stretch),
        PyArray1::from_vec(py, readout.layout.flipped),
        readout.layout.diagonal,
    ))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(vertex_stretch_py, m)?)?;
    m.add_function(wrap_pyfunction!(face_normals_py, m)?)?;
    m.add_function(wrap_pyfunction!(flipped_faces_py, m)?)?;
    m.add_function(wrap_pyfunction!(layout_readout_py, m)?)?;
    m.add_function(wrap_pyfunction!(placed_readout_py, m)?)?;
    Ok(())
}
