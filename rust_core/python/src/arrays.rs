//! numpy arrays in and out: the array contract checked (dtype, shape, C order) and copied.

use glam::{DVec3, Vec3};
use numpy::{
    Element, PyArray1, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::errors::ArrayError;

/// Checks that `array` is a C-contiguous numpy array of `T` with `columns` columns (or 1-D when
/// `columns` is `None`) and copies it out. Says exactly what was wrong otherwise.
pub(crate) fn read_array<T: Element + Copy>(
    name: &str,
    array: &Bound<'_, PyAny>,
    columns: Option<usize>,
) -> PyResult<Vec<T>> {
    read_with(name, array, columns, <[T]>::to_vec)
}

/// As [`read_array`], handing the checked array's values to `read` instead of copying them (one
/// copy fewer for a caller that converts them anyway).
pub(crate) fn read_with<T: Element + Copy, R>(
    name: &str,
    array: &Bound<'_, PyAny>,
    columns: Option<usize>,
    read: impl FnOnce(&[T]) -> R,
) -> PyResult<R> {
    let py = array.py();
    let expected_dtype = numpy::dtype::<T>(py);
    let expected_shape = match columns {
        Some(columns) => format!("(N, {columns})"),
        None => "(N,)".to_owned(),
    };
    let expectation = format!(
        "{name} must be a C-contiguous numpy array of dtype {expected_dtype} and shape {expected_shape}"
    );
    let Ok(untyped) = array.cast::<PyUntypedArray>() else {
        let type_name = array.get_type().name()?;
        return Err(ArrayError::new_err(format!(
            "{expectation}, got a {type_name}"
        )));
    };
    let dtype = untyped.dtype();
    if !dtype.is_equiv_to(&expected_dtype) {
        return Err(ArrayError::new_err(format!(
            "{expectation}, got dtype {dtype} (convert with .astype(numpy.{expected_dtype}))"
        )));
    }
    let shape = untyped.shape();
    let shape_ok = match columns {
        Some(columns) => shape.len() == 2 && shape[1] == columns,
        None => shape.len() == 1,
    };
    if !shape_ok {
        return Err(ArrayError::new_err(format!(
            "{expectation}, got shape {shape:?}"
        )));
    }
    if !untyped.is_c_contiguous() {
        return Err(ArrayError::new_err(format!(
            "{expectation}, got a non-contiguous array (use numpy.ascontiguousarray)"
        )));
    }
    if columns.is_some() {
        let typed = untyped.cast::<PyArray2<T>>()?.readonly();
        Ok(read(typed.as_slice()?))
    } else {
        let typed = untyped.cast::<PyArray1<T>>()?.readonly();
        Ok(read(typed.as_slice()?))
    }
}

pub(crate) fn read_positions(name: &str, array: &Bound<'_, PyAny>) -> PyResult<Vec<Vec3>> {
    read_with(name, array, Some(3), |flat: &[f32]| {
        flat.chunks_exact(3)
            .map(|row| Vec3::new(row[0], row[1], row[2]))
            .collect()
    })
}

pub(crate) fn rows_array<'py, T: Element>(
    py: Python<'py>,
    flat: Vec<T>,
    columns: usize,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let rows = flat.len() / columns;
    PyArray1::from_vec(py, flat).reshape([rows, columns])
}

/// Optional (K, 2) uint32 rows as pairs; none when `array` is `None`.
pub(crate) fn read_pairs(name: &str, array: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<[u32; 2]>> {
    let Some(array) = array else {
        return Ok(Vec::new());
    };
    read_with(name, array, Some(2), |flat: &[u32]| {
        flat.chunks_exact(2)
            .map(|pair| [pair[0], pair[1]])
            .collect()
    })
}

/// (N, 3) float64 rows as f64 points (the quality read-out's world positions).
pub(crate) fn read_points64(name: &str, array: &Bound<'_, PyAny>) -> PyResult<Vec<DVec3>> {
    read_with(name, array, Some(3), |flat: &[f64]| {
        flat.chunks_exact(3)
            .map(|row| DVec3::new(row[0], row[1], row[2]))
            .collect()
    })
}

/// A layout's faces, flat: `face_corners` (every face's vertices, face after face) and `face_sizes`
/// (each face's corner count), both 1-D uint32.
pub(crate) fn read_faces(
    face_corners: &Bound<'_, PyAny>,
    face_sizes: &Bound<'_, PyAny>,
) -> PyResult<(Vec<u32>, Vec<u32>)> {
    Ok((
        read_array::<u32>("face_corners", face_corners, None)?,
        read_array::<u32>("face_sizes", face_sizes, None)?,
    ))
}
