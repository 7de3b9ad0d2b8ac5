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
    assert arguments.schedule == "global-to-local" and KERNEL.schedule == "AUTO"


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


def test_the_energy_solver_reads_none_of_the_spring_settings():
    """What the warning below says: with the energy solver, the spring solver's weights and tolerance change
    nothing (the same positions bit for bit), while the same change does move the spring solver's result."""
    from springwrap.core.wrap_inputs import ENERGY_IGNORED

    changed = {"fairness": 0.9, "arc_length": 0.1, "thin_plate": 0.45, "constraint": 0.9, "folding": 0.9}
    changed["tolerance"] = 1e-3
    assert set(changed) == set(ENERGY_IGNORED)
    results = {}
    for solver in ("ENERGY", "SPRINGS"):
        for label, settings in (("default", {}), ("changed", changed)):
            _target, layout, _normal = plane_scene(hole=True)
            bpy.ops.springwrap.anchors_auto(spacing=0.5)
            assert bpy.ops.springwrap.wrap(solver=solver, max_iterations=300, **settings) == {"FINISHED"}
            results[solver, label] = np.array([vertex.co[:] for vertex in layout.data.vertices])
            for obj in list(bpy.data.objects):
                bpy.data.objects.remove(obj)
    assert np.array_equal(results["ENERGY", "default"], results["ENERGY", "changed"])
    assert not np.allclose(results["SPRINGS", "default"], results["SPRINGS", "changed"])


def test_a_setting_the_energy_solver_ignores_is_warned_about(capfd):
    plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    capfd.readouterr()
    assert bpy.ops.springwrap.wrap(fairness=0.8, tolerance=1e-3) == {"FINISHED"}
    output = capfd.readouterr().out
    assert (
        "The Energy solver ignores Fairness, Tolerance: only the Springs solver reads them "
        "(the result is what the default would give)" in output
    )
    bpy.ops.springwrap.wrap()  # the defaults: nothing to warn about
    assert "ignores" not in capfd.readouterr().out
    bpy.ops.springwrap.wrap(solver="SPRINGS", fairness=0.8, max_iterations=50)
    assert "ignores" not in capfd.readouterr().out


@pytest.mark.parametrize(
    "script, options, warned",
    [
        ("retarget.py", ["--template", "t.obj", "--target", "m.obj", "--fairness", "0.8"], "--fairness"),
        (
            "retarget.py",
            ["--template", "t.obj", "--target", "m.obj", "--thin-plate", "0.3", "--tolerance", "1e-3"],
            "--thin-plate, --tolerance",
        ),
        ("retarget.py", ["--template", "t.obj", "--target", "m.obj", "--fairness", "0.8", "--solver", "springs"], None),
        ("retarget.py", ["--template", "t.obj", "--target", "m.obj"], None),
    ],
)
def test_the_command_line_warns_about_options_the_energy_solver_ignores(script, options, warned):
    """retarget.py's report (and its printed warnings) carry the warning; mirror.py's does the same for --tolerance."""
    retarget = _script(script)
    arguments = retarget["parse_arguments"](["--", *options])
    warnings = []
    retarget["warn_energy_ignored"](retarget["wrap_settings"](arguments), warnings)
    if warned is None:
        assert warnings == []
    else:
        assert warnings == [
            f"The Energy solver ignores {warned}: only the Springs solver reads "
            f"{'them' if ',' in warned else 'it'} (the result is what the default would give)"
        ]


def test_the_mirror_warns_about_a_tolerance_its_energy_wrap_ignores(capfd):
    from bpy_helpers import head_scene

    head_scene()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.springwrap.mirror(axis="X", tolerance=1e-3) == {"FINISHED"}
    assert "The Energy solver ignores Tolerance: only the Springs solver reads it" in capfd.readouterr().out
