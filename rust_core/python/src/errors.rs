//! The binding's exception classes and the one place kernel errors and panics become them.

use std::panic::{AssertUnwindSafe, catch_unwind};

use pyo3::create_exception;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};
use springwrap_kernel::KernelError;

create_exception!(
    springwrap_kernel,
    SpringwrapError,
    PyValueError,
    "Base class of every error the Springwrap kernel raises."
);
create_exception!(
    springwrap_kernel,
    ArrayError,
    SpringwrapError,
    "An input array has the wrong dtype, shape or memory layout."
);
create_exception!(
    springwrap_kernel,
    EmptyMeshError,
    SpringwrapError,
    "The mesh has no vertices or no triangles."
);
create_exception!(
    springwrap_kernel,
    NonFiniteError,
    SpringwrapError,
    "A coordinate is NaN or infinite."
);
create_exception!(
    springwrap_kernel,
    IndexOutOfRangeError,
    SpringwrapError,
    "An index refers to a vertex or triangle that does not exist."
);
create_exception!(
    springwrap_kernel,
    DegenerateMeshError,
    SpringwrapError,
    "Every triangle has zero area: there is no surface."
);
create_exception!(
    springwrap_kernel,
    DegenerateTriangleError,
    SpringwrapError,
    "A triangle has zero area (raised only with reject_degenerate=True)."
);
create_exception!(
    springwrap_kernel,
    InvalidArgumentError,
    SpringwrapError,
    "A scalar argument is out of its domain."
);
create_exception!(
    springwrap_kernel,
    TooLargeError,
    InvalidArgumentError,
    "A count is larger than the kernel supports (32-bit indices)."
);
create_exception!(
    springwrap_kernel,
    CoordinateRangeError,
    SpringwrapError,
    "A coordinate is finite but beyond the kernel's bound (|x| <= 1e8), or a wrap constraint \
     lies beyond the region the wrap can reach."
);
create_exception!(
    springwrap_kernel,
    DivergedError,
    SpringwrapError,
    "The wrap diverged (a point stopped being finite or left the region it can reach); the layout \
     was rolled back to before the failing step."
);
create_exception!(
    springwrap_kernel,
    CancelledError,
    SpringwrapError,
    "A long computation stopped because its cancellation flag was set (``CancelFlag.cancel()``)."
);
create_exception!(
    springwrap_kernel,
    InternalError,
    SpringwrapError,
    "A bug in the kernel (a caught Rust panic). Please report it."
);

create_exception!(
    springwrap_kernel,
    FlatSurfaceError,
    SpringwrapError,
    "Feature detection found no curvature at the scale given (a plane): nothing to detect."
);

/// `springwrap_kernel.ArgumentTypeError`: both a `SpringwrapError` and a `TypeError`.
static ARGUMENT_TYPE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// The class `ArgumentTypeError(SpringwrapError, TypeError)`, made on first use (PyO3's
/// `create_exception!` takes one base class only).
pub(crate) fn argument_type_error_class(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    ARGUMENT_TYPE_ERROR
        .get_or_try_init(py, || {
            let bases = PyTuple::new(
                py,
                [
                    py.get_type::<SpringwrapError>(),
                    py.get_type::<PyTypeError>(),
                ],
            )?;
            let namespace = PyDict::new(py);
            namespace.set_item("__module__", "springwrap_kernel")?;
            namespace.set_item(
                "__doc__",
                "An argument has the wrong Python type (the message names it). Both a \
                 SpringwrapError and a TypeError.",
            )?;
            let class = py
                .get_type::<PyType>()
                .call1(("ArgumentTypeError", bases, namespace))?
                .cast_into::<PyType>()?;
            Ok(class.unbind())
        })
        .map(|class| class.bind(py))
}

/// An `ArgumentTypeError` with `message`.
pub(crate) fn argument_type_error(py: Python<'_>, message: String) -> PyErr {
    match argument_type_error_class(py) {
        Ok(class) => PyErr::from_type(class.clone(), message),
        Err(error) => error,
    }
}

/// The one place where kernel errors become Python exceptions.
pub(crate) fn to_python_error(error: &KernelError) -> PyErr {
    let message = error.to_string();
    match error {
        KernelError::EmptyMesh { .. } => EmptyMeshError::new_err(message),
        KernelError::NonFinite { .. } => NonFiniteError::new_err(message),
        KernelError::VertexIndexOutOfRange { .. }
        | KernelError::LayoutIndexOutOfRange { .. }
        | KernelError::TriangleIndexOutOfRange { .. } => IndexOutOfRangeError::new_err(message),
        KernelError::DegenerateMesh { .. } => DegenerateMeshError::new_err(message),
        KernelError::DegenerateTriangle { .. } => DegenerateTriangleError::new_err(message),
        KernelError::ZeroDirection { .. }
        | KernelError::LengthMismatch { .. }
        | KernelError::InvalidArgument { .. }
        | KernelError::TooFewPairs { .. }
        | KernelError::CoincidentAnchors { .. }
        | KernelError::CollinearAnchors { .. }
        | KernelError::CoplanarAnchors { .. } => InvalidArgumentError::new_err(message),
        KernelError::InvalidScale { .. } => InvalidArgumentError::new_err(message),
        KernelError::TooLarge { .. } => TooLargeError::new_err(message),
        KernelError::CoordinateOutOfRange { .. } | KernelError::BeyondReach { .. } => {
            CoordinateRangeError::new_err(message)
        }
        KernelError::FlatSurface { .. } => FlatSurfaceError::new_err(message),
        KernelError::Diverged { .. } => DivergedError::new_err(message),
        KernelError::Cancelled { .. } => CancelledError::new_err(message),
    }
}

/// Runs kernel work without the GIL, turning kernel errors and panics into Python exceptions.
pub(crate) fn run_kernel<T: Send>(
    py: Python<'_>,
    work: impl FnOnce() -> Result<T, KernelError> + Send,
) -> PyResult<T> {
    let outcome = py.detach(|| catch_unwind(AssertUnwindSafe(work)));
    match outcome {
        Ok(Ok(value)) => Ok(value),
        Ok(Err(error)) => Err(to_python_error(&error)),
        Err(panic) => {
            let reason = panic
                .downcast_ref::<&str>()
                .map(ToString::to_string)
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_owned());
            Err(InternalError::new_err(format!(
                "internal error in the Springwrap kernel: {reason}"
            )))
        }
    }
}

/// Adds every exception class of this module to the native module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("SpringwrapError", py.get_type::<SpringwrapError>())?;
    m.add("ArrayError", py.get_type::<ArrayError>())?;
    m.add("EmptyMeshError", py.get_type::<EmptyMeshError>())?;
    m.add("NonFiniteError", py.get_type::<NonFiniteError>())?;
    m.add(
        "IndexOutOfRangeError",
        py.get_type::<IndexOutOfRangeError>(),
    )?;
    m.add("DegenerateMeshError", py.get_type::<DegenerateMeshError>())?;
    m.add(
        "DegenerateTriangleError",
        py.get_type::<DegenerateTriangleError>(),
    )?;
    m.add(
        "InvalidArgumentError",
        py.get_type::<InvalidArgumentError>(),
    )?;
    m.add("TooLargeError", py.get_type::<TooLargeError>())?;
    m.add("CancelledError", py.get_type::<CancelledError>())?;
    m.add(
        "CoordinateRangeError",
        py.get_type::<CoordinateRangeError>(),
    )?;
    m.add("ArgumentTypeError", argument_type_error_class(py)?)?;
    m.add("DivergedError", py.get_type::<DivergedError>())?;
    m.add("InternalError", py.get_type::<InternalError>())?;
    m.add("FlatSurfaceError", py.get_type::<FlatSurfaceError>())?;
    Ok(())
}
