//! Binding of the kernel's feature detection: principal curvatures, regions and feature curves.
//!
//! Module-level functions taking a `TargetMesh`; the pure-Python package hangs them on its
//! `TargetMesh` as methods and names the results.

use std::sync::Arc;

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use springwrap_kernel::features::{detect, scale};
use springwrap_kernel::{
    FeatureCurveKind, FeatureSettings, PrincipalCurvatures, automatic_scale, detect_features,
    principal_curvatures,
};

use crate::arguments;
use crate::arrays::rows_array;
use crate::errors::run_kernel;
use crate::target_mesh::PyTargetMesh;

type CurvatureArrays<'py> = (
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
);

type CurveTuple<'py> = (&'static str, bool, Bound<'py, PyArray2<f32>>);

fn curvature_arrays<'py>(
    py: Python<'py>,
    curvatures: PrincipalCurvatures,
) -> PyResult<CurvatureArrays<'py>> {
    let flat = |vectors: &[glam::Vec3]| vectors.iter().flat_map(|v| v.to_array()).collect();
    Ok((
        PyArray1::from_vec(py, curvatures.k1),
        PyArray1::from_vec(py, curvatures.k2),
        rows_array(py, flat(&curvatures.d1), 3)?,
        rows_array(py, flat(&curvatures.d2), 3)?,
    ))
}

/// Principal curvatures of every vertex fitted over `scale`: (k1, k2, d1, d2); convex positive.
#[pyfunction(name = "principal_curvatures")]
fn principal_curvatures_py<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    scale: &Bound<'py, PyAny>,
) -> PyResult<CurvatureArrays<'py>> {
    let mesh = arguments::instance::<PyTargetMesh>("mesh", "TargetMesh", mesh)?;
    let mesh = Arc::clone(&mesh.get().mesh);
    let scale = arguments::float32("scale", scale)?;
    let curvatures = run_kernel(py, || principal_curvatures(&mesh, scale))?;
    curvature_arrays(py, curvatures)
}

/// Curvatures, regions and ridge / valley curves: (scale used, k1, k2, d1, d2, regions uint8,
/// curves), each curve a (kind, closed, (P, 3) float32 points) tuple. `scale` None or 0: the
/// automatic scale (from the target and `layout_edge_length`).
#[pyfunction(name = "detect_features")]
#[pyo3(signature = (
    mesh,
    scale = None,
    *,
    layout_edge_length = None,
    flat_threshold = None,
    ridge_threshold = None,
    hysteresis = None,
    min_length = None,
    join_distance = None,
))]
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
fn detect_features_py<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    scale: Option<&Bound<'py, PyAny>>,
    layout_edge_length: Option<&Bound<'py, PyAny>>,
    flat_threshold: Option<&Bound<'py, PyAny>>,
    ridge_threshold: Option<&Bound<'py, PyAny>>,
    hysteresis: Option<&Bound<'py, PyAny>>,
    min_length: Option<&Bound<'py, PyAny>>,
    join_distance: Option<&Bound<'py, PyAny>>,
) -> PyResult<(
    f32,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<u8>>,
    Vec<CurveTuple<'py>>,
)> {
    let mesh = arguments::instance::<PyTargetMesh>("mesh", "TargetMesh", mesh)?;
    let mesh = Arc::clone(&mesh.get().mesh);
    let defaults = FeatureSettings::default();
    let optional = |name, value: Option<&Bound<'py, PyAny>>| -> PyResult<Option<f32>> {
        match value {
            Some(value) if !value.is_none() => Ok(Some(arguments::float32(name, value)?)),
            _ => Ok(None),
        }
    };
    let settings = FeatureSettings {
        scale: optional("scale", scale)?.unwrap_or(defaults.scale),
        layout_edge_length: optional("layout_edge_length", layout_edge_length)?
            .unwrap_or(defaults.layout_edge_length),
        flat_threshold: arguments::float32_or(
            "flat_threshold",
            flat_threshold,
            defaults.flat_threshold,
        )?,
        ridge_threshold: arguments::float32_or(
            "ridge_threshold",
            ridge_threshold,
            defaults.ridge_threshold,
        )?,
        hysteresis: arguments::float32_or("hysteresis", hysteresis, defaults.hysteresis)?,
        min_length: optional("min_length", min_length)?,
        join_distance: optional("join_distance", join_distance)?,
    };
    let features = run_kernel(py, || detect_features(&mesh, &settings))?;
    let regions = features.regions.iter().map(|&r| r as u8).collect();
    let curves = features
        .curves
        .into_iter()
        .map(|curve| {
            let kind = match curve.kind {
                FeatureCurveKind::Ridge => "RIDGE",
                FeatureCurveKind::Valley => "VALLEY",
            };
            let flat = curve.points.iter().flat_map(|p| p.to_array()).collect();
            Ok((kind, curve.closed, rows_array(py, flat, 3)?))
        })
        .collect::<PyResult<Vec<_>>>()?;
    let (k1, k2, d1, d2) = curvature_arrays(py, features.curvatures)?;
    Ok((
        features.scale,
        k1,
        k2,
        d1,
        d2,
        PyArray1::from_vec(py, regions),
        curves,
    ))
}

/// The automatic feature scale of a mesh (see the kernel's `features::scale`): with
/// `layout_edge_length` > 0 that length, else a tenth of the diagonal, within 3 and 30 mean edges.
#[pyfunction(name = "automatic_feature_scale")]
#[pyo3(signature = (mesh, layout_edge_length = None))]
fn automatic_feature_scale_py<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    layout_edge_length: Option<&Bound<'py, PyAny>>,
) -> PyResult<f32> {
    let mesh = arguments::instance::<PyTargetMesh>("mesh", "TargetMesh", mesh)?;
    let mesh = Arc::clone(&mesh.get().mesh);
    let layout_edge_length = arguments::float32_or("layout_edge_length", layout_edge_length, 0.0)?;
    run_kernel(py, || automatic_scale(&mesh, layout_edge_length))
}

/// Feature detection's default settings: {"scale" (0: automatic), "flat_threshold",
/// "ridge_threshold", "hysteresis", "min_length_scales", "join_distance_scales",
/// "scale_diagonal_fraction", "scale_min_edges", "scale_max_edges"}.
#[pyfunction(name = "feature_defaults")]
fn feature_defaults_py(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let defaults = FeatureSettings::default();
    let dict = PyDict::new(py);
    dict.set_item("scale", defaults.scale)?;
    dict.set_item("flat_threshold", defaults.flat_threshold)?;
    dict.set_item("ridge_threshold", defaults.ridge_threshold)?;
    dict.set_item("hysteresis", defaults.hysteresis)?;
    dict.set_item("min_length_scales", detect::MIN_LENGTH_SCALES)?;
    dict.set_item("join_distance_scales", detect::JOIN_DISTANCE_SCALES)?;
    dict.set_item(
        "scale_diagonal_fraction",
        scale::AUTOMATIC_SCALE_DIAGONAL_FRACTION,
    )?;
    dict.set_item("scale_min_edges", scale::AUTOMATIC_SCALE_MIN_EDGES)?;
    dict.set_item("scale_max_edges", scale::AUTOMATIC_SCALE_MAX_EDGES)?;
    Ok(dict)
}

/// Adds the feature functions to the native module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(principal_curvatures_py, m)?)?;
    m.add_function(wrap_pyfunction!(detect_features_py, m)?)?;
    m.add_function(wrap_pyfunction!(automatic_feature_scale_py, m)?)?;
    m.add_function(wrap_pyfunction!(feature_defaults_py, m)?)?;
    Ok(())
}
