//! PyO3 binding of the Springwrap kernel: the only crate that knows Python.
//!
//! Thin by design: check and copy the numpy inputs into owned Rust data, run the kernel with the
//! GIL released (`py.detach`) and any panic caught, and wrap the results as numpy arrays. The
//! pure-Python package `springwrap_kernel` re-exports this module and adds named results.

mod align;
mod arguments;
mod arrays;
mod correspond;
mod errors;
mod feature_lines;
mod features;
mod fit;
mod layout;
mod parts;
mod quality;
mod target_mesh;
mod wrap;
mod wrap_settings;

use pyo3::prelude::*;

/// The native part of `springwrap_kernel`.
#[pymodule(gil_used = false)]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MAX_COORDINATE", springwrap_kernel::MAX_COORDINATE)?;
    m.add("MAX_ELEMENTS", springwrap_kernel::mesh::MAX_ELEMENTS)?;
    m.add_class::<target_mesh::PyTargetMesh>()?;
    m.add_class::<layout::PyLayoutStructure>()?;
    m.add_class::<wrap_settings::PyWrapSettings>()?;
    m.add_class::<wrap::PyWrapSolver>()?;
    m.add_function(wrap_pyfunction!(align::fit_transform_py, m)?)?;
    correspond::register(m)?;
    errors::register(m)?;
    features::register(m)?;
    feature_lines::register(m)?;
    fit::register(m)?;
    quality::register(m)?;
    parts::register(m)?;
    Ok(())
}
