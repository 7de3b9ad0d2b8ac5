//! Binding of the kernel's feature detection: principal curvatures, regions and feature curves.
//!
//! Module-level functions taking a `TargetMesh`; the pure-Python package hangs them on its
//! `TargetMesh` as methods and names the results.

use std::sync::Arc;

use numpy::{PyArray1, PyArray2};
use pyo3::create_exception;
use pyo3::prelude::*;
use springwrap_kernel::{
    FeatureCurveKind, FeatureSettings, PrincipalCurvatures, detect_features, principal_curvatures,
};

use crate::arguments;
use crate::arrays::rows_array;
use crate::errors::{SpringwrapError, run_kernel};
use crate::target_mesh::PyTargetMesh;

create_exception!(
    springwrap_kernel,
    FlatSurfaceError,
    SpringwrapError,
    "Feature detection found no curvature at the scale given (a plane): nothing to detect."
);

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

/// Curvatures, regions and ridge / valley curves: (k1, k2, d1, d2, regions uint8, curves), each
/// curve a (kind, closed, (P, 3) float32 points) tuple.
#[pyfunction(name = "detect_features")]
#[pyo3(signature = (
    mesh,
    scale,
    *,
    flat_threshold = None,
    ridge_threshold = None,
    min_length = None,
    join_distance = None,
))]
#[allow(clippy::type_complexity)]
fn detect_features_py<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    scale: &Bound<'py, PyAny>,
    flat_threshold: Option<&Bound<'py, PyAny>>,
    ridge_threshold: Option<&Bound<'py, PyAny>>,
    min_length: Option<&Bound<'py, PyAny>>,
    join_distance: Option<&Bound<'py, PyAny>>,
) -> PyResult<(
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<u8>>,
    Vec<CurveTuple<'py>>,
)> {
    let mesh = arguments::instance::<PyTargetMesh>("mesh", "TargetMesh", mesh)?;
    let mesh = Arc::clone(&mesh.get().mesh);
    let scale = arguments::float32("scale", scale)?;
    let defaults = FeatureSettings::with_scale(scale);
    let settings = FeatureSettings {
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
        min_length: arguments::float32_or("min_length", min_length, defaults.min_length)?,
        join_distance: arguments::float32_or(
            "join_distance",
            join_distance,
            defaults.join_distance,
        )?,
        ..defaults
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
    Ok((k1, k2, d1, d2, PyArray1::from_vec(py, regions), curves))
}

/// Adds the feature functions and their exception to the native module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(principal_curvatures_py, m)?)?;
    m.add_function(wrap_pyfunction!(detect_features_py, m)?)?;
    m.add("FlatSurfaceError", m.py().get_type::<FlatSurfaceError>())?;
    Ok(())
}
