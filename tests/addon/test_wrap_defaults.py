"""The wrap's defaults and ranges have one source: the kernel's ``springwrap_kernel.WrapSettings()`` and
``WrapSettings.ranges()``, and the add-on's own in ``core.defaults``; and every setting shown acts.

The wrap and mirror operators' properties, the add-on's own parameters and the command lines
(``retarget.py``, ``mirror.py``, ``wrap.py``) read them; these tests fail when any of them holds a
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


def test_the_mirror_operators_tolerance_and_the_panels_schedule_are_the_kernels():
    from springwrap.operators import mirror as mirror_operator

    defaults = operator_defaults(bpy.ops.springwrap.mirror)
    assert same(defaults.tolerance, KERNEL.tolerance)
    assert mirror_operator.SPRINGWRAP_OT_mirror.parameters(defaults).settings == KERNEL
    panel = bpy.types.Object.bl_rna.properties["springwrap"].fixed_type
    assert panel.properties["wrap_schedule"].default == KERNEL.schedule
    assert "wrap_solver" not in panel.properties


def test_the_properties_ranges_are_the_kernels_and_the_iteration_limit_is_one_number():
    from springwrap.core import defaults

    ranges = sk.WrapSettings.ranges()
    for operator in (bpy.ops.springwrap.wrap, bpy.ops.springwrap.mirror):
        properties = operator.get_rna_type().properties
        for name in ("tolerance", "fairness", "arc_length", "thin_plate", "constraint", "folding"):
            if name not in properties:
                continue
            _label, low, high, _low_open, _high_open = ranges[name]
            assert (properties[name].hard_min, properties[name].hard_max) == (
                pytest.approx(low),
                pytest.approx(high),
            ), name
        assert properties["max_iterations"].default == defaults.MAX_ITERATIONS
    sequence = bpy.ops.springwrap.wrap_sequence.get_rna_type().properties
    assert sequence["max_iterations"].default == defaults.MAX_ITERATIONS
    assert bpy.ops.springwrap.wrap.get_rna_type().properties["spring_resolution"].default == defaults.SPRING_RESOLUTION
    for script, options in (
        ("retarget.py", ["--template", "t.obj", "--target", "m.obj"]),
        ("mirror.py", ["--layout", "l.obj", "--target", "m.obj"]),
        ("wrap.py", []),
    ):
        arguments = _script(script)["parse_arguments"](["--", *options])
        assert arguments.max_iterations == defaults.MAX_ITERATIONS, script


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
    for name in ("tolerance", "fairness", "arc_length", "thin_plate", "constraint", "folding"):
        assert getattr(arguments, name) == getattr(KERNEL, name), name


def test_the_retarget_command_line_takes_the_schedule():
    retarget = _script("retarget.py")
    arguments = retarget["parse_arguments"](
        ["--", "--template", "t.obj", "--target", "t.obj", "--schedule", "global-to-local"]
    )
    assert retarget["wrap_settings"](arguments) == KERNEL.replace(schedule="GLOBAL_TO_LOCAL")
    assert arguments.schedule == "global-to-local" and KERNEL.schedule == "AUTO"


def test_the_mirror_command_lines_tolerance_is_the_kernels_and_its_weld_distance_the_operators():
    mirror = _script("mirror.py")
    arguments = mirror["parse_arguments"](["--", "--layout", "layout.obj", "--target", "target.obj"])
    assert arguments.tolerance == KERNEL.tolerance
    weld = operator_defaults(bpy.ops.springwrap.mirror).weld_distance
    assert np.float32(arguments.weld_distance) == np.float32(weld)


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


SHOWN_SETTINGS = {
    "fairness": 1.0,
    "arc_length": 0.1,
    "thin_plate": 0.5,
    "constraint": 0.05,
    "folding": 0.0,
    "tolerance": 0.5,
    "schedule": "LOCAL",  # the automatic choice for these 8 anchors is global to local
    "max_iterations": 3,
    "spring_resolution": 2,
}
"""Every setting the wrap's redo panel shows that changes the wrap itself, each with a value away from its
default (the groups and Hold on Plane have their own tests)."""


def _wrapped(**properties) -> np.ndarray:
    """The world positions after a wrap of the sphere scene (one of its quads cut into two triangles, so that two
    vertices have no grid line through them) with ``properties``."""
    import bmesh

    from bpy_helpers import sphere_scene, world_positions

    bpy.ops.wm.read_homefile(use_empty=True)
    _target, layout = sphere_scene()
    editable = bmesh.new()
    editable.from_mesh(layout.data)
    editable.faces.ensure_lookup_table()
    bmesh.ops.triangulate(editable, faces=[editable.faces[44]])
    editable.to_mesh(layout.data)
    editable.free()
    layout.data.update()
    assert bpy.ops.springwrap.anchors_auto(spacing=0.9) == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(**properties) == {"FINISHED"}
    return world_positions(bpy.data.objects[layout.name])


def test_each_setting_the_redo_panel_shows_changes_the_wrap():
    shown = {prop.identifier for prop in bpy.ops.springwrap.wrap.get_rna_type().properties if not prop.is_hidden}
    assert set(WRAP_OPERATOR_SETTINGS) <= shown and "solver" not in shown and "rest" not in shown
    assert set(SHOWN_SETTINGS) == set(WRAP_OPERATOR_SETTINGS) | {"max_iterations", "spring_resolution"}
    reference = _wrapped()
    assert np.array_equal(_wrapped(), reference)  # deterministic
    defaults = operator_defaults(bpy.ops.springwrap.wrap)
    for name, value in SHOWN_SETTINGS.items():
        assert getattr(defaults, name) != value, name
        moved = np.abs(_wrapped(**{name: value}) - reference).max()
        assert moved > 1e-5, f"{name}={value} moved no vertex more than {moved}"  # float noise: 1e-7


def test_each_wrap_option_of_the_command_line_reaches_the_kernels_settings():
    retarget = _script("retarget.py")
    base = ["--", "--template", "t.obj", "--target", "m.obj"]
    for name, value in SHOWN_SETTINGS.items():
        if name in ("max_iterations", "spring_resolution"):
            continue
        option = "--" + name.replace("_", "-")
        text = value.lower().replace("_", "-") if isinstance(value, str) else str(value)
        arguments = retarget["parse_arguments"]([*base, option, text])
        settings = retarget["wrap_settings"](arguments)
        assert settings == KERNEL.replace(**{name: value}), option


def test_the_retired_spring_solver_is_mapped_with_a_warning(capfd):
    """Scripts and presets that name ``solver='SPRINGS'`` wrap with the energy solver and say so."""
    from springwrap.core import defaults

    results = {}
    for solver in ("SPRINGS", "ENERGY"):
        bpy.ops.wm.read_homefile(use_empty=True)
        _target, layout, _normal = plane_scene()
        bpy.ops.springwrap.anchors_auto(spacing=0.5)
        capfd.readouterr()
        assert bpy.ops.springwrap.wrap(solver=solver) == {"FINISHED"}
        assert (defaults.RETIRED_SOLVER_WARNING in capfd.readouterr().out) == (solver == "SPRINGS")
        results[solver] = snapshot_positions(layout)
    assert np.array_equal(results["SPRINGS"], results["ENERGY"])
    retarget = _script("retarget.py")
    arguments = retarget["parse_arguments"](["--", "--template", "t.obj", "--target", "m.obj", "--solver", "springs"])
    assert retarget["wrap_settings"](arguments) == KERNEL
    with pytest.raises(sk.InvalidArgumentError, match="the spring solver was retired"):
        sk.WrapSettings(solver="SPRINGS")


@pytest.mark.parametrize("stored", [0, "SPRINGS", 1])
def test_an_old_file_s_stored_spring_solver_is_said_once_and_removed(capfd, stored):
    """A layout saved with the panel's Solver set to Springs (an old ``.blend`` keeps the enum's index, 0, as a bare
    ID property) wraps with the energy solver: the first wrap says so naming the layout and removes the stored
    choice, the next says nothing; the result is the one without it. A stored Energy (1) is removed silently."""
    from springwrap.core import defaults

    results = {}
    for stored_value in (stored, None):
        bpy.ops.wm.read_homefile(use_empty=True)
        _target, layout, _normal = plane_scene()
        if stored_value is not None:
            layout.springwrap["wrap_solver"] = stored_value
        bpy.ops.springwrap.anchors_auto(spacing=0.5)
        capfd.readouterr()
        assert bpy.ops.springwrap.wrap() == {"FINISHED"}
        said = capfd.readouterr().out
        expected = stored_value is not None and stored != 1
        assert (defaults.retired_stored_solver_warning(layout.name) in said) == expected, said
        assert "wrap_solver" not in layout.springwrap.keys()
        results[stored_value] = snapshot_positions(layout)
        if stored_value is not None:
            assert bpy.ops.springwrap.wrap() == {"FINISHED"}
            assert "Springs" not in capfd.readouterr().out  # said once
    assert np.array_equal(results[stored], results[None])


def snapshot_positions(layout) -> np.ndarray:
    return np.array([vertex.co[:] for vertex in layout.data.vertices])


def _mirrored(**properties) -> np.ndarray:
    """The world positions after a mirror of the half head (snapped, with anchors) with ``properties``."""
    from bpy_helpers import head_scene, world_positions

    bpy.ops.wm.read_homefile(use_empty=True)
    _target, layout = head_scene()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.6) == {"FINISHED"}
    assert bpy.ops.springwrap.mirror(axis="X", surfaced_half="FREE", **properties) == {"FINISHED"}
    return world_positions(bpy.data.objects[layout.name])


def test_each_wrap_setting_the_mirrors_redo_panel_shows_changes_the_mirror():
    shown = {prop.identifier for prop in bpy.ops.springwrap.mirror.get_rna_type().properties if not prop.is_hidden}
    assert {"tolerance", "max_iterations"} <= shown and "solver" not in shown
    reference = _mirrored()
    assert np.array_equal(_mirrored(), reference)  # deterministic
    defaults = operator_defaults(bpy.ops.springwrap.mirror)
    for name, value in {"tolerance": 0.5, "max_iterations": 2}.items():
        assert getattr(defaults, name) != value, name
        moved = np.abs(_mirrored(**{name: value}) - reference).max()
        assert moved > 1e-5, f"{name}={value} moved no vertex more than {moved}"
