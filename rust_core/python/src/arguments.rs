//! Python scalars in: every argument that is not an array is converted here, so that a wrong
//! value or type raises the module's own exception naming the argument.
//!
//! PyO3's own conversions raise a bare `OverflowError` for a negative or huge int given where a
//! count is expected (not naming the argument) and a bare `TypeError` for a wrong type. The
//! binding takes such arguments as Python objects and converts them with these functions:
//!
//! - a value of the right type outside its range: [`InvalidArgumentError`] (a `ValueError`), or
//!   [`TooLargeError`] for a count above what the kernel supports;
//! - a value of the wrong Python type: `springwrap_kernel.ArgumentTypeError`, which is both a
//!   `SpringwrapError` and a `TypeError` (so `except TypeError` and `except SpringwrapError` both
//!   catch it).
//!
//! Only a call that does not match the signature at all (a missing argument, an unknown keyword)
//! raises Python's own `TypeError`, as for any Python function.

use pyo3::exceptions::PyOverflowError;
use pyo3::prelude::*;
use pyo3::types::PyBool;

use crate::errors::{ArrayError, InvalidArgumentError, TooLargeError, argument_type_error};

/// The name of `value`'s Python type, for messages.
fn type_name(value: &Bound<'_, PyAny>) -> String {
    value
        .get_type()
        .name()
        .map_or_else(|_| "object".to_owned(), |name| name.to_string())
}

/// A whole number from 0 to `max` (a Python int, or anything with `__index__` such as a numpy
/// integer; not a bool, not a float).
pub(crate) fn count(name: &str, value: &Bound<'_, PyAny>, max: usize) -> PyResult<usize> {
    let py = value.py();
    if value.is_instance_of::<PyBool>() {
        return Err(argument_type_error(
            py,
            format!("{name} must be an int, got a bool"),
        ));
    }
    match value.extract::<i64>() {
        Ok(number) if number < 0 => Err(InvalidArgumentError::new_err(format!(
            "invalid {name}: it must be 0 or more, not {number}"
        ))),
        Ok(number) => match usize::try_from(number) {
            Ok(number) if number <= max => Ok(number),
            _ => Err(TooLargeError::new_err(format!(
                "invalid {name}: {number} is more than the {max} supported"
            ))),
        },
        Err(error) if error.is_instance_of::<PyOverflowError>(py) => {
            let shown = value
                .repr()
                .map_or_else(|_| "it".to_owned(), |r| r.to_string());
            if value.lt(0).unwrap_or(false) {
                Err(InvalidArgumentError::new_err(format!(
                    "invalid {name}: it must be 0 or more, not {shown}"
                )))
            } else {
                Err(TooLargeError::new_err(format!(
                    "invalid {name}: {shown} is more than the {max} supported"
                )))
            }
        }
        Err(_) => Err(argument_type_error(
            py,
            format!("{name} must be an int, got {}", type_name(value)),
        )),
    }
}

/// A real number as float64 (a Python float or int, a numpy scalar; not a bool).
pub(crate) fn float64(name: &str, value: &Bound<'_, PyAny>) -> PyResult<f64> {
    let py = value.py();
    if value.is_instance_of::<PyBool>() {
        return Err(argument_type_error(
            py,
            format!("{name} must be a number, got a bool"),
        ));
    }
    match value.extract::<f64>() {
        Ok(number) => Ok(number),
        Err(error) if error.is_instance_of::<PyOverflowError>(py) => {
            Err(InvalidArgumentError::new_err(format!(
                "invalid {name}: it is beyond the range of a float"
            )))
        }
        Err(_) => Err(argument_type_error(
            py,
            format!("{name} must be a number, got {}", type_name(value)),
        )),
    }
}

/// A real number as float32: [`float64`], and a finite value beyond float32's range is refused
/// (it would silently become infinite). NaN and infinities pass: the kernel's checks name them.
pub(crate) fn float32(name: &str, value: &Bound<'_, PyAny>) -> PyResult<f32> {
    let number = float64(name, value)?;
    if number.is_finite() && number.abs() > f64::from(f32::MAX) {
        return Err(InvalidArgumentError::new_err(format!(
            "invalid {name}: {number:e} is beyond the range of a float32 (±{:e})",
            f32::MAX
        )));
    }
    Ok(number as f32)
}

/// [`float32`], or `default` when the argument is absent or `None`.
pub(crate) fn float32_or(
    name: &str,
    value: Option<&Bound<'_, PyAny>>,
    default: f32,
) -> PyResult<f32> {
    match value {
        Some(value) if !value.is_none() => float32(name, value),
        _ => Ok(default),
    }
}

/// [`float64`], or `default` when the argument is absent or `None`.
pub(crate) fn float64_or(
    name: &str,
    value: Option<&Bound<'_, PyAny>>,
    default: f64,
) -> PyResult<f64> {
    match value {
        Some(value) if !value.is_none() => float64(name, value),
        _ => Ok(default),
    }
}

/// `on_surface` of the distance queries: a finite distance of zero or more (0 when absent or
/// `None`).
pub(crate) fn on_surface(value: Option<&Bound<'_, PyAny>>) -> PyResult<f64> {
    let on_surface = float64_or("on_surface", value, 0.0)?;
    if on_surface >= 0.0 && on_surface.is_finite() {
        Ok(on_surface)
    } else {
        Err(InvalidArgumentError::new_err(format!(
            "on_surface must be a finite distance of zero or more, not {on_surface}"
        )))
    }
}

/// A bool (Python's, or numpy's `bool_`), or `default` when absent or `None`.
pub(crate) fn flag(name: &str, value: Option<&Bound<'_, PyAny>>, default: bool) -> PyResult<bool> {
    let Some(value) = value.filter(|value| !value.is_none()) else {
        return Ok(default);
    };
    value.extract::<bool>().map_err(|_| {
        argument_type_error(
            value.py(),
            format!("{name} must be a bool, got {}", type_name(value)),
        )
    })
}

/// A str, or `default` when absent or `None`.
pub(crate) fn text(
    name: &str,
    value: Option<&Bound<'_, PyAny>>,
    default: &str,
) -> PyResult<String> {
    let Some(value) = value.filter(|value| !value.is_none()) else {
        return Ok(default.to_owned());
    };
    value.extract::<String>().map_err(|_| {
        argument_type_error(
            value.py(),
            format!("{name} must be a str, got {}", type_name(value)),
        )
    })
}

/// Three numbers (a tuple, a list, a numpy array) as float32, or `None` when absent or `None`.
pub(crate) fn vector3(name: &str, value: Option<&Bound<'_, PyAny>>) -> PyResult<Option<[f32; 3]>> {
    let Some(value) = value.filter(|value| !value.is_none()) else {
        return Ok(None);
    };
    let py = value.py();
    let items: Vec<Bound<'_, PyAny>> = if value.is_instance_of::<pyo3::types::PyString>() {
        return Err(argument_type_error(
            py,
            format!("{name} must be three numbers, got a str"),
        ));
    } else {
        match value.try_iter() {
            Ok(items) => items.collect::<PyResult<_>>()?,
            Err(_) => {
                return Err(argument_type_error(
                    py,
                    format!("{name} must be three numbers, got {}", type_name(value)),
                ));
            }
        }
    };
    if items.len() != 3 {
        return Err(ArrayError::new_err(format!(
            "{name} must be three numbers (x, y, z), got {}",
            items.len()
        )));
    }
    let mut vector = [0.0f32; 3];
    for (slot, item) in vector.iter_mut().zip(&items) {
        *slot = float32(name, item)?;
    }
    Ok(Some(vector))
}

/// An instance of the binding's class `T` (or a subclass), named `class_name` in messages.
pub(crate) fn instance<'py, T: pyo3::PyClass>(
    name: &str,
    class_name: &str,
    value: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, T>> {
    value.cast::<T>().cloned().map_err(|_| {
        argument_type_error(
            value.py(),
            format!(
                "{name} must be a springwrap_kernel.{class_name}, got {}",
                type_name(value)
            ),
        )
    })
}
