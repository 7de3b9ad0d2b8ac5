//! `layout_pieces` and `SurfaceFollower`: parts that follow the layout's surface. Positions cross
//! as float64.

use std::sync::Arc;

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use springwrap_kernel::{FollowSettings, SurfaceFollower, connected_pieces};

use crate::arguments::{count, flag};
use crate::arrays::{read_array, read_pairs, read_points64, rows_array};
use crate::errors::run_kernel;

/// (N,) uint32 piece number of each layout vertex: the connected components of `edges` ((E, 2)
/// uint32), numbered in the order of each piece's lowest vertex.
#[pyfunction(name = "layout_pieces")]
fn layout_pieces_py<'py>(
    py: Python<'py>,
    vertex_count: &Bound<'py, PyAny>,
    edges: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<u32>>> {
    let vertex_count = count(
        "vertex_count",
        vertex_count,
        springwrap_kernel::mesh::MAX_ELEMENTS,
    )?;
    let edges = read_pairs("edges", Some(edges))?;
    let pieces = run_kernel(py, || connected_pieces(vertex_count, &edges))?;
    Ok(PyArray1::from_vec(py, pieces))
}

/// Parts bound to the layout's surface at rest, moved by the surface's motion (rigid pieces by
/// the best similarity of the surface around them, soft vertices by their own neighbourhood's).
#[pyclass(name = "SurfaceFollower", module = "springwrap_kernel", frozen)]
pub(crate) struct PySurfaceFollower {
    follower: Arc<SurfaceFollower>,
}

#[pymethods]
impl PySurfaceFollower {
    #[new]
    #[allow(clippy::too_many_arguments)] // keyword arguments of one Python constructor
    #[pyo3(signature = (surface_rest, part_rest, pieces, rigid, *, neighbours = None, soft_neighbours = None, scale = None, robust_rounds = None))]
    fn new(
        py: Python<'_>,
        surface_rest: &Bound<'_, PyAny>,
        part_rest: &Bound<'_, PyAny>,
        pieces: &Bound<'_, PyAny>,
        rigid: &Bound<'_, PyAny>,
        neighbours: Option<&Bound<'_, PyAny>>,
        soft_neighbours: Option<&Bound<'_, PyAny>>,
        scale: Option<&Bound<'_, PyAny>>,
        robust_rounds: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let defaults = FollowSettings::default();
        let settings = FollowSettings {
            neighbours: neighbours.map_or(Ok(defaults.neighbours), |value| {
                count("neighbours", value, 1 << 20)
            })?,
            soft_neighbours: soft_neighbours.map_or(Ok(defaults.soft_neighbours), |value| {
                count("soft_neighbours", value, 1 << 20)
            })?,
            scale: flag("scale", scale, defaults.scale)?,
            robust_rounds: robust_rounds.map_or(Ok(defaults.robust_rounds), |value| {
                count("robust_rounds", value, 1 << 20)
            })?,
        };
        let surface_rest = read_points64("surface_rest", surface_rest)?;
        let part_rest = read_points64("part_rest", part_rest)?;
        let pieces = read_array::<u32>("pieces", pieces, None)?;
        let rigid = read_array::<bool>("rigid", rigid, None)?;
        let follower = run_kernel(py, || {
            SurfaceFollower::new(&surface_rest, &part_rest, &pieces, &rigid, settings)
        })?;
        Ok(Self {
            follower: Arc::new(follower),
        })
    }

    /// Number of part vertices.
    #[getter]
    fn part_count(&self) -> usize {
        self.follower.part_count()
    }

    /// (P, 3) float64 part positions for the surface at `surface_now` ((S, 3) float64).
    fn apply<'py>(
        &self,
        py: Python<'py>,
        surface_now: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let surface_now = read_points64("surface_now", surface_now)?;
        let follower = Arc::clone(&self.follower);
        let moved = run_kernel(py, || follower.apply(&surface_now))?;
        rows_array(
            py,
            moved.iter().flat_map(|point| point.to_array()).collect(),
            3,
        )
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(layout_pieces_py, m)?)?;
    m.add_class::<PySurfaceFollower>()?;
    Ok(())
}
