"""The wrap's defaults have one source, the kernel's ``springwrap_kernel.WrapSettings()``.

The wrap and mirror operators' properties, the panel's solver, the add-on's own parameters and the
command lines (``retarget.py``, ``mirror.py``) read it; these tests fail when any of them holds a
number of its own. Blender's float properties are float32, as the kernel's settings are, so values
are compared as float32, and the settings an operator hands to the kernel are compared exactly.
"""

import runpy
from pathlib import Path
from types import SimpleNamespace

import bpy

import numpy as np
import pytest

import springwrap_kernel as sk
from bpy_helpers import plane_scene
from helpers import REPOSITORY

KERNEL = sk.WrapSettings()
WRAP_OPERATOR_SETTINGS = (
    "tolerance",
    "fairness",
    "arc_length",
    "thin_plate",
    "constraint",
    "folding",
    "rest",
    "solver",
    "schedule",
)
"""The kernel settings ``springwrap.wrap`` has a property for."""


def same(value, kernel_value) -> bool:
    """Equal as the kernel holds it: strings as they are, numbers as float32."""
    if isinstance(kernel_value, str):
        return value == kernel_value
    return np.float32(value) == np.float32(kernel_value)


def operator_defaults(operator) -> SimpleNamespace:
    """Every property's default of ``operator`` (a ``bpy.ops`` function), as attributes."""
    rna = operator.get_rna_type()
    return SimpleNamespace(
        **{prop.identifier: prop.default for prop in rna.properties if prop.identifier != "rna_type"}
    )


def test_the_wrap_operators_defaults_are_the_kernels():
    from springwrap.operators import wrap as wrap_operator

    defaults = operator_defaults(bpy.ops.springwrap.wrap)
    for name in WRAP_OPERATOR_SETTINGS:
        assert same(getattr(defaults, name), getattr(KERNEL, name)), name
    assert wrap_operator.SPRINGWRAP_OT_wrap.parameters(defaults).settings == KERNEL


def test_the_mirror_operators_tolerance_and_the_panels_solver_are_the_kernels():
    from springwrap.operators import mirror as mirror_operator

    defaults = operator_defaults(bpy.ops.springwrap.mirror)
    assert same(defaults.tolerance, KERNEL.tolerance)
    assert mirror_operator.SPRINGWRAP_OT_mirror.parameters(defaults).settings == KERNEL
    panel = bpy.types.Object.bl_rna.properties["springwrap"].fixed_type
    assert panel.properties["wrap_solver"].default == KERNEL.solver


def test_the_add_ons_parameters_default_to_the_kernels_settings():
    from springwrap import properties
    from springwrap.blender.wrap_session import WrapSession
    from springwrap.core.wrap_inputs import WrapParameters

    assert properties.WRAP_DEFAULTS == KERNEL
    _target, layout, _normal = plane_scene()
    session = WrapSession(bpy.context, layout, WrapParameters())
    assert session.solver.settings == KERNEL


def test_a_bad_setting_is_refused_by_the_kernel_naming_it():
    from springwrap.operators import wrap as wrap_operator

    defaults = operator_defaults(bpy.ops.springwrap.wrap)
    defaults.thin_plate = 0.7
    with pytest.raises(sk.InvalidArgumentError, match=r"invalid thin_plate: .* within \[0, 0.5\], not 0.7"):
        wrap_operator.SPRINGWRAP_OT_wrap.parameters(defaults)


def _script(name: str) -> dict:
    return runpy.run_path(str(REPOSITORY / "blender_scripts" / name), run_name=f"springwrap_test_{Path(name).stem}")


def test_the_retarget_command_lines_defaults_are_the_kernels():
    retarget = _script("retarget.py")
    arguments = retarget["parse_arguments"](["--", "--template", "template.obj", "--target", "target.obj"])
    assert retarget["wrap_settings"](arguments) == KERNEL
    for name in ("tolerance", "fairness", "arc_length", "thin_plate"):
        assert getattr(arguments, name) == getattr(KERNEL, name), name
    assert arguments.solver.upper() == KERNEL.solver


def test_the_retarget_command_line_takes_the_schedule():
    retarget = _script("retarget.py")
    arguments = retarget["parse_arguments"](
        ["--", "--template", "t.obj", "--target", "t.obj", "--schedule", "global-to-local"]
    )
    assert retarget["wrap_settings"](arguments) == KERNEL.replace(schedule="GLOBAL_TO_LOCAL")


def test_the_mirror_command_lines_tolerance_is_the_kernels():
    mirror = _script("mirror.py")
    arguments = mirror["parse_arguments"](["--", "--layout", "layout.obj", "--target", "target.obj"])
    assert arguments.tolerance == KERNEL.tolerance


@pytest.mark.parametrize(
    "script, options, message",
    [
        (
            "retarget.py",
            ["--template", "t.obj", "--target", "m.obj", "--thin-plate", "0.7"],
            r"invalid thin_plate: the thin plate weight must be within [0, 0.5], not 0.7",
        ),
        (
            "retarget.py",
            ["--template", "t.obj", "--target", "m.obj", "--tolerance", "0"],
            r"invalid tolerance: the tolerance must be within (0, 1], not 0",
        ),
        (
            "mirror.py",
            ["--layout", "l.obj", "--target", "m.obj", "--tolerance", "2"],
            r"invalid tolerance: the tolerance must be within (0, 1], not 2",
        ),
    ],
)
def test_a_bad_setting_on_the_command_line_is_a_usage_error_naming_it(script, options, message, capsys):
    parse_arguments = _script(script)["parse_arguments"]
    with pytest.raises(SystemExit) as exit_info:
        parse_arguments(["--", *options])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
