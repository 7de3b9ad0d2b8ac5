//! Binding of the layout's feature lines and their pairing with target feature curves.

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use springwrap_kernel::features::pairing::{
    FreeReason, PairSettings, TargetCurve, TargetCurveKind, pair_lines,
};
use springwrap_kernel::layout::{FeatureLine, LineKind, LineSettings, LineSource, feature_lines};

use crate::arguments;
use crate::arrays::{read_array, read_faces, read_pairs, read_positions, rows_array};
use crate::errors::{InvalidArgumentError, run_kernel};

/// (kind, source, vertices uint32, closed, mean signed dihedral in degrees).
type LineTuple<'py> = (
    &'static str,
    &'static str,
    Bound<'py, PyArray1<u32>>,
    bool,
    f32,
);

/// (curve index or None, why free or None, confidence, chain uint32, target (P, 3) float32).
type PairTuple<'py> = (
    Option<usize>,
    Option<&'static str>,
    f32,
    Bound<'py, PyArray1<u32>>,
    Bound<'py, PyArray2<f32>>,
);

fn kind_name(kind: LineKind) -> &'static str {
    match kind {
        LineKind::Ridge => "RIDGE",
        LineKind::Valley => "VALLEY",
        LineKind::Border => "BORDER",
        LineKind::Any => "ANY",
    }
}

fn line_kind(name: &str) -> PyResult<LineKind> {
    Ok(match name {
        "RIDGE" => LineKind::Ridge,
        "VALLEY" => LineKind::Valley,
        "BORDER" => LineKind::Border,
        "ANY" => LineKind::Any,
        other => {
            return Err(InvalidArgumentError::new_err(format!(
                "invalid line kind {other:?}: RIDGE, VALLEY, BORDER or ANY"
            )));
        }
    })
}

fn curve_kind(name: &str) -> PyResult<TargetCurveKind> {
    Ok(match name {
        "RIDGE" => TargetCurveKind::Ridge,
        "VALLEY" => TargetCurveKind::Valley,
        "BORDER" => TargetCurveKind::Border,
        other => {
            return Err(InvalidArgumentError::new_err(format!(
                "invalid curve kind {other:?}: RIDGE, VALLEY or BORDER"
            )));
        }
    })
}

/// The feature lines of a layout: `positions` (N, 3) float32 (its rest shape), faces as
/// `face_corners`/`face_sizes` (uint32), `marked` (K, 2) uint32 edges the artist marked. A list of
/// (kind "RIDGE"/"VALLEY"/"BORDER"/"ANY", source "MARKED"/"CREASE"/"BORDER", vertices, closed,
/// mean signed dihedral in degrees).
#[pyfunction(name = "layout_feature_lines")]
#[pyo3(signature = (
    positions, face_corners, face_sizes, *, marked = None, crease_degrees = None, borders = None,
    min_edges = None,
))]
#[allow(clippy::too_many_arguments)]
fn layout_feature_lines_py<'py>(
    py: Python<'py>,
    positions: &Bound<'py, PyAny>,
    face_corners: &Bound<'py, PyAny>,
    face_sizes: &Bound<'py, PyAny>,
    marked: Option<&Bound<'py, PyAny>>,
    crease_degrees: Option<&Bound<'py, PyAny>>,
    borders: Option<&Bound<'py, PyAny>>,
    min_edges: Option<&Bound<'py, PyAny>>,
) -> PyResult<Vec<LineTuple<'py>>> {
    let positions = read_positions("positions", positions)?;
    let (face_corners, face_sizes) = read_faces(face_corners, face_sizes)?;
    let marked = read_pairs("marked", marked.filter(|value| !value.is_none()))?;
    let defaults = LineSettings::default();
    let min_edges = match min_edges.filter(|value| !value.is_none()) {
        Some(value) => arguments::count("min_edges", value, usize::MAX)?,
        None => defaults.min_edges,
    };
    let settings = LineSettings {
        crease_degrees: arguments::float32_or(
            "crease_degrees",
            crease_degrees,
            defaults.crease_degrees,
        )?,
        borders: arguments::flag("borders", borders, defaults.borders)?,
        min_edges,
    };
    let lines = run_kernel(py, || {
        feature_lines(&positions, &face_corners, &face_sizes, &marked, &settings)
    })?;
    Ok(lines
        .into_iter()
        .map(|line| {
            let source = match line.source {
                LineSource::Marked => "MARKED",
                LineSource::Crease => "CREASE",
                LineSource::Border => "BORDER",
            };
            (
                kind_name(line.kind),
                source,
                PyArray1::from_vec(py, line.vertices),
                line.closed,
                line.dihedral,
            )
        })
        .collect())
}

/// Pairs feature lines with target curves under the current fit: `positions` (N, 3) float32 the
/// layout where the fit has it, `lines` a list of (vertices uint32, closed, kind), `curves` a list
/// of (kind "RIDGE"/"VALLEY"/"BORDER", points (P, 3) float32, closed[, accuracy: how far the curve
/// may lie from its feature, 0 when left out]). One tuple per line: (curve index or None, why it
/// stays free ("NONE_NEARBY", "NOT_PARALLEL", "LENGTH_DIFFERS", "LOW_CONFIDENCE", "TAKEN",
/// "WITHIN_ACCURACY") or None, confidence, chain uint32, target (P, 3) float32).
#[pyfunction(name = "pair_feature_lines")]
#[pyo3(signature = (positions, lines, curves, *, max_distance, max_angle = None, min_confidence = None))]
fn pair_feature_lines_py<'py>(
    py: Python<'py>,
    positions: &Bound<'py, PyAny>,
    lines: Vec<(Bound<'py, PyAny>, bool, String)>,
    curves: Vec<Bound<'py, PyAny>>,
    max_distance: &Bound<'py, PyAny>,
    max_angle: Option<&Bound<'py, PyAny>>,
    min_confidence: Option<&Bound<'py, PyAny>>,
) -> PyResult<Vec<PairTuple<'py>>> {
    let positions = read_positions("positions", positions)?;
    let lines = lines
        .into_iter()
        .map(|(vertices, closed, kind)| {
            Ok(FeatureLine {
                vertices: read_array::<u32>("line vertices", &vertices, None)?,
                closed,
                kind: line_kind(&kind)?,
                source: LineSource::Marked,
                dihedral: 0.0,
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let curves = curves
        .into_iter()
        .map(|curve| {
            // (kind, points, closed) or (kind, points, closed, accuracy).
            let (kind, points, closed, accuracy) =
                match curve.extract::<(String, Bound<'py, PyAny>, bool, f32)>() {
                    Ok(full) => full,
                    Err(_) => {
                        let (kind, points, closed) =
                            curve.extract::<(String, Bound<'py, PyAny>, bool)>()?;
                        (kind, points, closed, 0.0)
                    }
                };
            Ok(TargetCurve {
                kind: curve_kind(&kind)?,
                points: read_positions("curve points", &points)?,
                closed,
                accuracy,
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let defaults = PairSettings::with_distance(1.0);
    let settings = PairSettings {
        max_distance: arguments::float32("max_distance", max_distance)?,
        max_angle: arguments::float32_or("max_angle", max_angle, defaults.max_angle)?,
        min_confidence: arguments::float32_or(
            "min_confidence",
            min_confidence,
            defaults.min_confidence,
        )?,
    };
    let outcomes = run_kernel(py, || pair_lines(&positions, &lines, &curves, &settings))?;
    outcomes
        .into_iter()
        .map(|outcome| {
            let (curve, reason) = match outcome.result {
                Ok(curve) => (Some(curve), None),
                Err(reason) => (
                    None,
                    Some(match reason {
                        FreeReason::NoneNearby => "NONE_NEARBY",
                        FreeReason::NotParallel => "NOT_PARALLEL",
                        FreeReason::LengthDiffers => "LENGTH_DIFFERS",
                        FreeReason::LowConfidence => "LOW_CONFIDENCE",
                        FreeReason::Taken => "TAKEN",
                        FreeReason::WithinAccuracy => "WITHIN_ACCURACY",
                    }),
                ),
            };
            let flat = outcome.target.iter().flat_map(|p| p.to_array()).collect();
            Ok((
                curve,
                reason,
                outcome.confidence,
                PyArray1::from_vec(py, outcome.chain),
                rows_array(py, flat, 3)?,
            ))
        })
        .collect()
}

/// Adds the feature-line functions to the native module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(layout_feature_lines_py, m)?)?;
    m.add_function(wrap_pyfunction!(pair_feature_lines_py, m)?)?;
    Ok(())
}
