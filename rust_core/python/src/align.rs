//! Alignment: `fit_transform` and the (4, 4) matrices of `TargetMesh.icp`.

use numpy::PyArray2;
use pyo3::prelude::*;
use springwrap_kernel::{AlignMethod, Transform, fit_transform};

use crate::arguments;
use crate::arrays::{read_array, read_positions, rows_array};
use crate::errors::{ArrayError, InvalidArgumentError, run_kernel};

/// ICP results as returned to Python (the package names them `IcpReport`).
pub(crate) type IcpTuple<'py> = (Bound<'py, PyArray2<f64>>, u32, bool, f64, f64, usize);

/// Reads a (4, 4) float64 affine matrix whose last row is `0 0 0 1`.
pub(crate) fn read_transform(name: &str, array: &Bound<'_, PyAny>) -> PyResult<Transform> {
    let flat = read_array::<f64>(name, array, Some(4))?;
    if flat.len() != 16 {
        return Err(ArrayError::new_err(format!(
            "{name} must be a (4, 4) float64 matrix, got {} rows",
            flat.len() / 4
        )));
    }
    if flat[12..] != [0.0, 0.0, 0.0, 1.0] {
        return Err(InvalidArgumentError::new_err(format!(
            "invalid {name}: the last row must be 0 0 0 1 (an affine matrix), got {:?}",
            &flat[12..]
        )));
    }
    Ok(Transform {
        rows: std::array::from_fn(|row| std::array::from_fn(|column| flat[row * 4 + column])),
    })
}

/// A transform as a (4, 4) float64 homogeneous matrix.
pub(crate) fn transform_array<'py>(
    py: Python<'py>,
    transform: &Transform,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat = transform
        .to_homogeneous()
        .iter()
        .flatten()
        .copied()
        .collect();
    rows_array(py, flat, 4)
}

/// Least-squares transform taking `source[i]` to `target[i]` (float32 (N, 3) anchors), as a
/// (4, 4) float64 matrix; `method` is `'RIGID'`, `'SIMILARITY'` or `'AFFINE'`.
#[pyfunction(name = "fit_transform")]
#[pyo3(signature = (source, target, method = None, *, weights = None))]
pub(crate) fn fit_transform_py<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    target: &Bound<'py, PyAny>,
    method: Option<&Bound<'py, PyAny>>,
    weights: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let method = arguments::text("method", method, "SIMILARITY")?;
    let method = match method.as_str() {
        "RIGID" => AlignMethod::Rigid,
        "SIMILARITY" => AlignMethod::Similarity,
        "AFFINE" => AlignMethod::Affine,
        other => {
            return Err(InvalidArgumentError::new_err(format!(
                "invalid method: {other:?} (use 'RIGID', 'SIMILARITY' or 'AFFINE')"
            )));
        }
    };
    let source = read_positions("source", source)?;
    let target = read_positions("target", target)?;
    let weights = weights
        .map(|array| read_array::<f32>("weights", array, None))
        .transpose()?;
    let transform = run_kernel(py, || {
        fit_transform(&source, &target, method, weights.as_deref())
    })?;
    transform_array(py, &transform)
}
