//! Binding of the kernel's correspondence proposals: further layout-vertex → target-point pairs
//! from the anchors given and the current fit.

use std::sync::Arc;

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use springwrap_kernel::{
    GivenPair, KernelError, LayoutFaces, ProposalLayout, ProposalSettings, propose_correspondences,
};

use crate::arguments;
use crate::arrays::{read_array, read_positions, rows_array};
use crate::errors::{run_kernel, to_python_error};
use crate::target_mesh::PyTargetMesh;

type ProposalArrays<'py> = (
    Bound<'py, PyArray1<u32>>,
    Bound<'py, PyArray1<u32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
);

/// Proposed pairs, most confident first: (vertices uint32 (P,), triangles uint32 (P,),
/// barycentric float32 (P, 3), positions float32 (P, 3), confidences float32 (P,)).
#[pyfunction(name = "propose_correspondences")]
#[pyo3(signature = (
    mesh,
    rest,
    current,
    face_corners,
    face_sizes,
    anchor_vertices,
    anchor_targets,
    *,
    max_count = None,
    min_confidence = None,
    search_radius = None,
    feature_scale = None,
))]
#[allow(clippy::too_many_arguments)]
fn propose_correspondences_py<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    rest: &Bound<'py, PyAny>,
    current: &Bound<'py, PyAny>,
    face_corners: &Bound<'py, PyAny>,
    face_sizes: &Bound<'py, PyAny>,
    anchor_vertices: &Bound<'py, PyAny>,
    anchor_targets: &Bound<'py, PyAny>,
    max_count: Option<&Bound<'py, PyAny>>,
    min_confidence: Option<&Bound<'py, PyAny>>,
    search_radius: Option<&Bound<'py, PyAny>>,
    feature_scale: Option<&Bound<'py, PyAny>>,
) -> PyResult<ProposalArrays<'py>> {
    let mesh = arguments::instance::<PyTargetMesh>("mesh", "TargetMesh", mesh)?;
    let mesh = Arc::clone(&mesh.get().mesh);
    let rest = read_positions("rest", rest)?;
    let current = read_positions("current", current)?;
    let corners = read_array::<u32>("face_corners", face_corners, None)?;
    let sizes = read_array::<u32>("face_sizes", face_sizes, None)?;
    let vertices = read_array::<u32>("anchor_vertices", anchor_vertices, None)?;
    let targets = read_positions("anchor_targets", anchor_targets)?;
    if vertices.len() != targets.len() {
        return Err(to_python_error(&KernelError::LengthMismatch {
            what: "anchor_vertices and anchor_targets",
            first: vertices.len(),
            second: targets.len(),
        }));
    }
    let defaults = ProposalSettings::default();
    let max_count = match max_count {
        Some(value) if !value.is_none() => {
            u32::try_from(arguments::count("max_count", value, u32::MAX as usize)?)
                .unwrap_or(u32::MAX)
        }
        _ => defaults.max_count,
    };
    let settings = ProposalSettings {
        max_count,
        min_confidence: arguments::float32_or(
            "min_confidence",
            min_confidence,
            defaults.min_confidence,
        )?,
        search_radius: arguments::float32_or(
            "search_radius",
            search_radius,
            defaults.search_radius,
        )?,
        feature_scale: arguments::float32_or(
            "feature_scale",
            feature_scale,
            defaults.feature_scale,
        )?,
    };
    let given: Vec<GivenPair> = vertices
        .iter()
        .zip(&targets)
        .map(|(&vertex, &target)| GivenPair { vertex, target })
        .collect();
    let proposals = run_kernel(py, || {
        let layout = ProposalLayout {
            rest: &rest,
            current: &current,
            faces: LayoutFaces {
                corners: &corners,
                sizes: &sizes,
            },
        };
        propose_correspondences(&mesh, layout, &given, &settings)
    })?;
    Ok((
        PyArray1::from_vec(py, proposals.iter().map(|p| p.vertex).collect()),
        PyArray1::from_vec(
            py,
            proposals.iter().map(|p| p.face_point.triangle).collect(),
        ),
        rows_array(
            py,
            proposals
                .iter()
                .flat_map(|p| p.face_point.barycentric.to_array())
                .collect(),
            3,
        )?,
        rows_array(
            py,
            proposals
                .iter()
                .flat_map(|p| p.position.to_array())
                .collect(),
            3,
        )?,
        PyArray1::from_vec(py, proposals.iter().map(|p| p.confidence).collect()),
    ))
}

/// The proposals' default settings: {"max_count", "min_confidence", "search_radius",
/// "feature_scale", "min_anchors"}.
#[pyfunction(name = "proposal_defaults")]
fn proposal_defaults_py(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let defaults = ProposalSettings::default();
    let dict = PyDict::new(py);
    dict.set_item("max_count", defaults.max_count)?;
    dict.set_item("min_confidence", defaults.min_confidence)?;
    dict.set_item("search_radius", defaults.search_radius)?;
    dict.set_item("feature_scale", defaults.feature_scale)?;
    dict.set_item(
        "min_anchors",
        springwrap_kernel::correspond::MIN_GIVEN_PAIRS,
    )?;
    Ok(dict)
}

/// Adds the proposal functions to the native module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(propose_correspondences_py, m)?)?;
    m.add_function(wrap_pyfunction!(proposal_defaults_py, m)?)?;
    Ok(())
}
