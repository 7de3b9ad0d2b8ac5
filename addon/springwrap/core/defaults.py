"""The wrap's defaults and ranges, in one place: the add-on's own (the iteration limit, the spring resolution) and
the kernel's (``springwrap_kernel.WrapSettings()`` and ``WrapSettings.ranges()``, written once in the kernel), and
the mirror's weld distance.

The operators' and panel's properties (``properties``), the scripts in ``blender_scripts/`` and the benchmarks read
them from here. No ``bpy``.
"""

from typing import NamedTuple

MAX_ITERATIONS = 2000
"""The wrap's iteration limit: the energy solver's schedule ends long before it (a body in a few dozen iterations);
it bounds a wrap that would not end."""

SPRING_RESOLUTION = 1
"""Quads cut k x k for the fine stage of a wrap: 1, no fine stage."""

WELD_FRACTION = 0.1
"""The mirror's default weld distance: a vertex this close to the mirror plane, as a fraction of the mean length of
its edges, is snapped onto it and shared by both halves (the seam)."""

RETIRED_SOLVER = "SPRINGS"
"""The spring solver's name in old ``.blend`` files, operator calls and scripts: the wrap maps it to the energy
solver, with :data:`RETIRED_SOLVER_WARNING`."""

RETIRED_SOLVER_WARNING = (
    "The Springs solver was retired: wrapped with the Energy solver (Fairness, Arc Length, Thin Plate, Constraint, "
    "Folding and Tolerance weigh its terms)"
)

RETIRED_SOLVER_INDEX = 0
"""The retired solver's number in an old ``.blend``: Blender stores an enum setting as its item's index, and
``SPRINGS`` was the first item of the panel's Solver (``wrap_solver``)."""


def is_retired_solver(value) -> bool:
    """Whether a stored or given solver choice (an old file's enum index, or its name) is the retired spring
    solver."""
    if isinstance(value, str):
        return value.upper() == RETIRED_SOLVER
    return isinstance(value, int) and not isinstance(value, bool) and value == RETIRED_SOLVER_INDEX


def retired_stored_solver_warning(layout_name: str) -> str:
    """What a wrap says once when ``layout_name``'s settings, saved in an old ``.blend``, chose the Springs
    solver (the choice is then removed from the layout)."""
    return f"Layout '{layout_name}' was saved with the Springs solver chosen. {RETIRED_SOLVER_WARNING}; the old choice was removed"


class SettingRange(NamedTuple):
    """One kernel setting's range (``springwrap_kernel.WrapSettings.ranges()``)."""

    label: str
    low: float
    high: float
    low_open: bool
    high_open: bool


def kernel():
    """The ``springwrap_kernel`` module, with a message saying what is missing when it is not installed."""
    try:
        import springwrap_kernel
    except ImportError as error:
        raise ImportError(
            f"The Springwrap kernel is not available ({error}): the add-on needs its springwrap_kernel package "
            "(bundled in the extension and in the legacy zip; `make setup` in a checkout)"
        ) from error
    return springwrap_kernel


def wrap_defaults():
    """``springwrap_kernel.WrapSettings()``: the kernel's default wrap settings."""
    return kernel().WrapSettings()


def wrap_ranges() -> dict[str, SettingRange]:
    """The kernel's range of every numeric wrap setting, by keyword."""
    return {name: SettingRange(*row) for name, row in kernel().WrapSettings.ranges().items()}
