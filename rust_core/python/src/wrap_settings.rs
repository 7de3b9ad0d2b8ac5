//! `WrapSettings`: the kernel's `WrapSettings` as one immutable Python object.
//!
//! Every default is the kernel's `WrapSettings::default()` (the signature's defaults are Rust
//! expressions reading it, never numbers typed again), and every check is the kernel's
//! `WrapSettings::validate()`, so the add-on, the scripts and the stubs read them from here.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat};
use springwrap_kernel::{WrapSchedule, WrapSettings, WrapWeights};

use crate::arguments;
use crate::errors::{InvalidArgumentError, to_python_error};

/// The kernel's defaults, read by the constructor's signature.
fn defaults() -> WrapSettings {
    WrapSettings::default()
}

/// The binding's name of a stiffness schedule.
fn schedule_name(schedule: WrapSchedule) -> &'static str {
    match schedule {
        WrapSchedule::Auto => "AUTO",
        WrapSchedule::Local => "LOCAL",
        WrapSchedule::GlobalToLocal => "GLOBAL_TO_LOCAL",
    }
}

fn parse_schedule(name: &str) -> PyResult<WrapSchedule> {
    [
        WrapSchedule::Auto,
        WrapSchedule::Local,
        WrapSchedule::GlobalToLocal,
    ]
    .into_iter()
    .find(|&schedule| schedule_name(schedule) == name)
    .ok_or_else(|| {
        InvalidArgumentError::new_err(format!(
            "invalid schedule: {name:?} is not 'AUTO', 'LOCAL' or 'GLOBAL_TO_LOCAL'"
        ))
    })
}

/// Refuses a keyword of the retired spring solver with what to do instead; `'ENERGY'` (the one
/// solver) and `'TEMPLATE'` (the one rest shape) are taken as the defaults they are.
fn check_retired(
    solver: Option<&Bound<'_, PyAny>>,
    rest: Option<&Bound<'_, PyAny>>,
    momentum: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    let retired = |name: &str, what: String| {
        InvalidArgumentError::new_err(format!(
            "invalid {name}: {what}; the spring solver was retired, the energy solver is the \
             wrap's only solver (leave {name} out)"
        ))
    };
    if let Some(solver) = solver {
        let name = arguments::text("solver", Some(solver), "ENERGY")?;
        if name != "ENERGY" {
            return Err(retired("solver", format!("{name:?} is not 'ENERGY'")));
        }
    }
    if let Some(rest) = rest {
        let name = arguments::text("rest", Some(rest), "TEMPLATE")?;
        if name != "TEMPLATE" {
            return Err(retired(
                "rest",
                format!("{name:?}: the energy keeps the template's shape"),
            ));
        }
    }
    if momentum.is_some() {
        return Err(retired(
            "momentum",
            "the energy solver has no momentum".to_owned(),
        ));
    }
    Ok(())
}

/// A float32 setting as the Python float of its shortest decimal (`0.2`, not
/// `0.20000000298023224`); it converts back to the same float32.
fn decimal(value: f32) -> f64 {
    value.to_string().parse().unwrap_or(f64::from(value))
}

/// Everything that controls a wrap besides the layout, the target and the constraints: the
/// energy's weights, the tolerance that ends each stiffness level, landing, the fold tolerance and
/// the schedule. Immutable; `WrapSettings()` holds the kernel's defaults. The retired spring
/// solver's keywords (`solver`, `rest`, `momentum`) are refused with a message, except
/// `solver='ENERGY'` and `rest='TEMPLATE'`, which are what every wrap does.
#[pyclass(
    name = "WrapSettings",
    module = "springwrap_kernel",
    frozen,
    eq,
    subclass
)]
#[derive(Clone, PartialEq)]
pub(crate) struct PyWrapSettings {
    pub(crate) settings: WrapSettings,
}

#[pymethods]
impl PyWrapSettings {
    #[new]
    #[pyo3(signature = (
        *,
        fairness = None,
        arc_length = None,
        thin_plate = None,
        constraint = None,
        folding = None,
        tolerance = None,
        landing_distance = None,
        fold_tolerance = None,
        momentum = None,
        rest = None,
        solver = None,
        schedule = None,
    ))]
    #[allow(clippy::too_many_arguments)] // keyword arguments of one Python constructor
    fn new(
        fairness: Option<&Bound<'_, PyAny>>,
        arc_length: Option<&Bound<'_, PyAny>>,
        thin_plate: Option<&Bound<'_, PyAny>>,
        constraint: Option<&Bound<'_, PyAny>>,
        folding: Option<&Bound<'_, PyAny>>,
        tolerance: Option<&Bound<'_, PyAny>>,
        landing_distance: Option<&Bound<'_, PyAny>>,
        fold_tolerance: Option<&Bound<'_, PyAny>>,
        momentum: Option<&Bound<'_, PyAny>>,
        rest: Option<&Bound<'_, PyAny>>,
        solver: Option<&Bound<'_, PyAny>>,
        schedule: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        check_retired(solver, rest, momentum)?;
        // Absent keywords take the kernel's defaults (`WrapSettings::default()`, never a number
        // typed again); every value is converted by `arguments` (naming the keyword) and then
        // checked by the kernel's `validate()`.
        let defaults = defaults();
        let number = |name: &str, value, default| arguments::float32_or(name, value, default);
        let fairness = number("fairness", fairness, defaults.weights.fairness)?;
        let arc_length = number("arc_length", arc_length, defaults.weights.arc_length)?;
        let thin_plate = number("thin_plate", thin_plate, defaults.weights.thin_plate)?;
        let constraint = number("constraint", constraint, defaults.weights.constraint)?;
        let folding = number("folding", folding, defaults.weights.folding)?;
        let tolerance = number("tolerance", tolerance, defaults.tolerance)?;
        let landing_distance = number(
            "landing_distance",
            landing_distance,
            defaults.landing_distance,
        )?;
        let fold_tolerance = number("fold_tolerance", fold_tolerance, defaults.fold_tolerance)?;
        let schedule = arguments::text("schedule", schedule, schedule_name(defaults.schedule))?;
        let settings = WrapSettings {
            weights: WrapWeights {
                fairness,
                arc_length,
                thin_plate,
                constraint,
                folding,
            },
            tolerance,
            landing_distance,
            fold_tolerance,
            schedule: parse_schedule(&schedule)?,
        };
        settings
            .validate()
            .map_err(|error| to_python_error(&error))?;
        Ok(Self { settings })
    }

    /// α: fairness, the weight of the second differences along the grid lines, 0 to 1.
    #[getter]
    fn fairness(&self) -> f64 {
        decimal(self.settings.weights.fairness)
    }

    /// β: arc length, the weight of the edge terms (the spacing along the grid lines), 0 to 1.
    #[getter]
    fn arc_length(&self) -> f64 {
        decimal(self.settings.weights.arc_length)
    }

    /// γ_tp: thin plate, the weight of the umbrella terms at points no grid line runs straight
    /// through (poles), 0 to 0.5.
    #[getter]
    fn thin_plate(&self) -> f64 {
        decimal(self.settings.weights.thin_plate)
    }

    /// γ_con: the pull of the layout onto the target (the data term's weight), 0 to 1.
    #[getter]
    fn constraint(&self) -> f64 {
        decimal(self.settings.weights.constraint)
    }

    /// γ_fold: how far off the surface the layout is still drawn onto it (the data term's
    /// reach), 0 (nothing is) to 1.
    #[getter]
    fn folding(&self) -> f64 {
        decimal(self.settings.weights.folding)
    }

    /// A stiffness level ends once an iteration lowers the energy by less than this fraction,
    /// (0, 1].
    #[getter]
    fn tolerance(&self) -> f64 {
        decimal(self.settings.tolerance)
    }

    /// An anchored space-point lands on its face-point target within this fraction of the mean
    /// edge length, 0 to 10.
    #[getter]
    fn landing_distance(&self) -> f64 {
        decimal(self.settings.landing_distance)
    }

    /// A free point lands on the surface at the end only where the layout faces it within this
    /// angle, in radians, 0 to pi / 2.
    #[getter]
    fn fold_tolerance(&self) -> f64 {
        decimal(self.settings.fold_tolerance)
    }

    /// The stiffness schedule: `'AUTO'` (chosen from the anchors when the wrap
    /// starts: global to local for 3 to 11 anchors, or more on a change of proportions),
    /// `'LOCAL'` or `'GLOBAL_TO_LOCAL'` (stiff, nearly affine levels first: for few anchors on a
    /// large change of shape).
    #[getter]
    fn schedule(&self) -> &'static str {
        schedule_name(self.settings.schedule)
    }

    /// The range of every numeric setting, from the kernel's one table: `{keyword: (label, low,
    /// high, low_open, high_open)}`, in the constructor's order.
    #[staticmethod]
    fn ranges(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let dict = PyDict::new(py);
        for (name, label, range) in WrapSettings::RANGES {
            dict.set_item(
                name,
                (
                    label,
                    range.low,
                    range.high,
                    range.low_open,
                    range.high_open,
                ),
            )?;
        }
        Ok(dict)
    }

    /// Every setting by its keyword, in the constructor's order.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for (name, value) in self.numbers() {
            dict.set_item(name, decimal(value))?;
        }
        dict.set_item("schedule", self.schedule())?;
        Ok(dict)
    }

    /// A copy with the given settings changed (checked like the constructor).
    #[pyo3(signature = (**changes))]
    fn replace<'py>(
        slf: &Bound<'py, Self>,
        changes: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let arguments = slf.get().to_dict(slf.py())?;
        if let Some(changes) = changes {
            arguments.update(changes.as_mapping())?;
        }
        slf.get_type().call((), Some(&arguments))
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let mut parts = Vec::new();
        for (name, value) in self.numbers() {
            let value = PyFloat::new(py, decimal(value)).repr()?;
            parts.push(format!("{name}={value}"));
        }
        Ok(format!(
            "WrapSettings({}, schedule='{}')",
            parts.join(", "),
            self.schedule()
        ))
    }
}

impl PyWrapSettings {
    /// The numeric settings by keyword, in the constructor's order.
    fn numbers(&self) -> [(&'static str, f32); 8] {
        let settings = &self.settings;
        let weights = &settings.weights;
        [
            ("fairness", weights.fairness),
            ("arc_length", weights.arc_length),
            ("thin_plate", weights.thin_plate),
            ("constraint", weights.constraint),
            ("folding", weights.folding),
            ("tolerance", settings.tolerance),
            ("landing_distance", settings.landing_distance),
            ("fold_tolerance", settings.fold_tolerance),
        ]
    }
}
