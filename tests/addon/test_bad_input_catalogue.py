"""The bad-input catalogue thrown at every operator of ``bpy.ops.springwrap``.

One scene holds everything an operator may read: a target, a hybrid layout (face- and space-points, a rest
shape), anchors, a curve constraint, a curve object, and (for ``align_armature``) two armatures. Each case of
:data:`CATALOGUE` breaks it one way: NaN / infinite / 1e30 / FLT_MAX coordinates (written with ``foreach_set``
and typed into Blender properties), an anchor on a vertex the layout no longer has, an empty layout, shape
keys, a target without faces... Every operator that reads what a case breaks (:data:`READS`) must report an
ERROR and leave the layout, its attributes, its anchors, its constraints and its transform bit-identical;
the others must finish or refuse, never crash, and leave the scene as it was when they refuse.
"""

import math
import tempfile
from pathlib import Path

import bpy

import numpy as np
import pytest

from benchmarks.retarget import rig_scene, rigging
from bpy_helpers import make_grid_layout, make_target, set_selection, target_without_faces

FLT_MAX = float(np.finfo(np.float32).max)
ROW = 11  # the grid layout: 11 x 11 vertices
CONSTRAINED_ROW = list(range(2 * ROW, 3 * ROW))  # the chain of the scene's curve constraint
SELECTED_ROW = list(range(6 * ROW, 7 * ROW))  # the chain curve_constraint_add pairs in the catalogue


# ---------------------------------------------------------------- the scene


def _select_chain(layout, chain):
    """Select exactly the edges of the chain (object mode data), and its vertices."""
    mesh = layout.data
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edges)
    pairs = {frozenset(pair) for pair in zip(chain, chain[1:])}
    mesh.edges.foreach_set("select", np.array([frozenset(edge) in pairs for edge in edges.reshape(-1, 2).tolist()]))
    set_selection(layout, np.isin(np.arange(len(mesh.vertices)), chain))


def _curve_object(points):
    """A poly curve object called 'Curve' through ``points`` (world space)."""
    data = bpy.data.curves.new("Curve", "CURVE")
    data.dimensions = "3D"
    spline = data.splines.new("POLY")
    spline.points.add(len(points) - 1)
    spline.points.foreach_set("co", np.c_[np.asarray(points), np.ones(len(points))].astype(np.float32).ravel())
    curve = bpy.data.objects.new("Curve", data)
    bpy.context.scene.collection.objects.link(curve)
    return curve


def _armatures(layout):
    """A one-bone template armature skinning the whole layout, and a target armature whose bone is turned."""
    count = len(layout.data.vertices)
    weights = {"bone": (np.arange(count), np.ones(count))}

    def rig(tail):
        return rigging.RigData(
            names=("bone",),
            parents=("",),
            heads=np.array([[0.0, 0.0, 2.0]]),
            tails=np.array([tail]),
            rolls=np.zeros(1),
            weights=weights,
        )

    template = rig_scene.build_armature("Template Rig", rig((0.0, 0.0, 3.0)))
    rig_scene.skin(layout, template, rig((0.0, 0.0, 3.0)))
    rig_scene.build_armature("Target Rig", rig((0.0, 0.3, 2.9)))


def catalogue_scene(with_armatures=False):
    """Target, hybrid layout with a rest shape, anchors, a curve constraint and a curve object; the layout active."""
    target = make_target()
    layout = make_grid_layout(target)
    set_selection(layout, np.arange(len(layout.data.vertices)) % 2 == 0)
    assert bpy.ops.springwrap.snap(only_selected=True) == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.7) == {"FINISHED"}
    assert bpy.ops.springwrap.anchor_add(vertex_index=5, location=(2, 2, 2), use_location=True, on_surface=False) == {
        "FINISHED"
    }
    _select_chain(layout, CONSTRAINED_ROW)
    assert bpy.ops.springwrap.curve_constraint_add() == {"FINISHED"}
    _select_chain(layout, SELECTED_ROW)
    matrix = np.array(layout.matrix_world)
    row = np.array([tuple(layout.data.vertices[index].co) + (1.0,) for index in SELECTED_ROW]) @ matrix.T
    _curve_object(row[:, :3] - [0.0, 0.0, 0.3])
    if with_armatures:
        _armatures(layout)
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    bpy.context.view_layer.update()
    return target, layout


# ---------------------------------------------------------------- what must not change


def _attribute_bytes(mesh):
    result = {}
    for attribute in mesh.attributes:
        if attribute.name.startswith("."):
            continue
        field = {"FLOAT_VECTOR": "vector", "FLOAT_COLOR": "color", "BYTE_COLOR": "color", "FLOAT2": "vector"}.get(
            attribute.data_type, "value"
        )
        width = {"vector": 3 if attribute.data_type == "FLOAT_VECTOR" else 2, "color": 4}.get(field, 1)
        values = np.empty(len(attribute.data) * width, dtype=np.float64)
        attribute.data.foreach_get(field, values)
        result[(attribute.name, attribute.domain, attribute.data_type)] = values.tobytes()
    return result


def _key_bytes(block):
    values = np.empty(len(block.data) * 3, dtype=np.float32)
    block.data.foreach_get("co", values)
    return (block.name, block.relative_key.name, block.value, block.slider_min, block.slider_max, values.tobytes())


def full_snapshot(layout):
    """Everything an operator may write on the layout, as comparable values (NaN compares as itself)."""
    settings = layout.springwrap
    mesh = layout.data
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    anchors = [
        (
            item.vertex_index,
            item.target_kind,
            item.triangle,
            tuple(item.barycentric),
            tuple(item.location),
            item.twin_vertex,
        )
        for item in settings.anchors
    ]
    constraints = [
        (
            item.layout_vertices,
            item.source_kind,
            item.target_vertices,
            tuple(tuple(point.co) for point in item.points),
            tuple(entry.value for entry in item.fractions),
        )
        for item in settings.curve_constraints
    ]
    return {
        "positions": positions.tobytes(),
        "counts": (len(mesh.vertices), len(mesh.edges), len(mesh.polygons)),
        "attributes": _attribute_bytes(mesh),
        "anchors": repr(anchors),
        "anchor settings": (settings.active_anchor_index, settings.anchors_signature),
        "constraints": repr(constraints),
        "target signature": settings.target_signature,
        "matrix": repr([tuple(row) for row in layout.matrix_world]),
        "modifiers": [modifier.name for modifier in layout.modifiers],
        "shape keys": None if mesh.shape_keys is None else [_key_bytes(block) for block in mesh.shape_keys.key_blocks],
    }


# ---------------------------------------------------------------- the catalogue


def _layout_vertex(value):
    def breaks(target, layout):
        positions = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
        layout.data.vertices.foreach_get("co", positions)
        positions[7 * 3] = value  # vertex 7, x
        layout.data.vertices.foreach_set("co", positions)
        layout.data.update()

    return breaks


def _typed_layout_vertex(target, layout):
    layout.data.vertices[7].co.x = math.inf  # through the property: whatever Blender stores
    layout.data.update()


def _anchor_location(value, typed=False):
    def breaks(target, layout):
        anchors = layout.springwrap.anchors
        if typed:
            anchors[0].location[0] = value  # through the property: inf is stored as 3.4e38
        else:
            locations = np.empty(len(anchors) * 3, dtype=np.float32)
            anchors.foreach_get("location", locations)
            locations[0] = value
            anchors.foreach_set("location", locations)

    return breaks


def _anchor_on_a_missing_vertex(target, layout):
    layout.springwrap.anchors[0].vertex_index = 5000


def _curve_point(value):
    def breaks(target, layout):
        layout.springwrap.curve_constraints[0].points[3].co[1] = value

    return breaks


def _new_curve_point(value):
    def breaks(target, layout):
        points = bpy.data.objects["Curve"].data.splines[0].points
        points[4].co[2] = value

    return breaks


def _empty_layout(target, layout):
    layout.data.clear_geometry()


def _shape_keys(target, layout):
    layout.shape_key_add(name="Basis")


def _shape_key_nan(target, layout):
    layout.shape_key_add(name="Basis")
    smile = layout.shape_key_add(name="Smile", from_mix=False)
    smile.data[7].co.y = math.nan


def _shape_key_far(target, layout):
    layout.shape_key_add(name="Basis")
    smile = layout.shape_key_add(name="Smile", from_mix=False)
    smile.data[7].co.y = FLT_MAX  # an inf typed into the key's field


def _layout_transform(target, layout):
    layout.location.x = math.nan


def _target_vertex(value):
    def breaks(target, layout):
        target.data.vertices[5].co.y = value
        target.data.update()

    return breaks


def _no_readout(target, layout):
    for name in ("springwrap_distance", "springwrap_stretch", "springwrap_flipped"):
        layout.data.attributes.remove(layout.data.attributes[name])


def _foreign_readout(target, layout):
    """A ``springwrap_distance`` of another type and domain (a user's own attribute of that name)."""
    layout.data.attributes.remove(layout.data.attributes["springwrap_distance"])
    layout.data.attributes.new("springwrap_distance", "INT", "FACE")


CATALOGUE = {
    # case: (how it breaks the scene, what it breaks, what the error names)
    "layout vertex NaN": (_layout_vertex(math.nan), "positions", "Layout vertex 7 has a NaN"),
    "layout vertex inf (foreach_set)": (_layout_vertex(math.inf), "positions", "Layout vertex 7 has a NaN or infinite"),
    "layout vertex inf (typed)": (_typed_layout_vertex, "positions", "Layout vertex 7"),
    "layout vertex FLT_MAX": (_layout_vertex(FLT_MAX), "positions", "Layout vertex 7 is at .*beyond 1e\\+09"),
    "layout vertex 1e30": (_layout_vertex(1e30), "positions", "Layout vertex 7 is at"),
    "layout vertex 1e5 away": (_layout_vertex(1e5), "positions far", "more than 1000 times the target's size"),
    "layout transform NaN": (_layout_transform, "positions", "NaN or infinite transform"),
    "empty layout": (_empty_layout, "positions", "has no vertices"),
    "anchor NaN": (_anchor_location(math.nan), "anchors", r"Anchor 0 \(vertex \d+\) has a NaN"),
    "anchor inf (typed, stored as 3.4e38)": (
        _anchor_location(math.inf, typed=True),
        "anchors",
        r"Anchor 0 \(vertex \d+\) is at \(3.403e\+38",
    ),
    "anchor 1e30": (_anchor_location(1e30), "anchors", r"Anchor 0 \(vertex \d+\) is at"),
    "anchor on a missing vertex": (_anchor_on_a_missing_vertex, "anchor vertices", "no longer has"),
    "curve point NaN": (_curve_point(math.nan), "curves", "Curve constraint 0's target point 3 has a NaN"),
    "curve point 1e30": (_curve_point(1e30), "curves", "Curve constraint 0's target point 3 is at"),
    "new curve NaN": (_new_curve_point(math.nan), "new curve", "Curve 'Curve': point 4 has a NaN"),
    "new curve FLT_MAX": (_new_curve_point(FLT_MAX), "new curve", "Curve 'Curve': point 4 is at"),
    "shape keys": (_shape_keys, "shape keys", "has shape keys; Fit Subdivision and Align Armature evaluate"),
    "shape key NaN": (
        _shape_key_nan,
        "shape key data",
        "shape key 'Smile' has a NaN or infinite coordinate at vertex 7",
    ),
    "shape key FLT_MAX": (
        _shape_key_far,
        "shape key data",
        r"shape key 'Smile' has a coordinate beyond 1e\+09 at vertex 7",
    ),
    "target without faces": (target_without_faces, "target", "'Target' has no faces"),
    "target vertex NaN": (_target_vertex(math.nan), "target", "'Target'"),
    "target vertex 1e30": (_target_vertex(1e30), "target", "'Target'"),
    "no read-out": (_no_readout, "read-out", "has no quality read-out: Snap, Project, Wrap or Mirror"),
    "read-out of another type": (_foreign_readout, "read-out", "has no quality read-out"),
}
"""Bad inputs: each breaks the scene one way."""

BROKEN_LISTS = ("anchor NaN", "anchor 1e30", "curve point NaN", "curve point 1e30")

ALL_LAYOUT = {"positions", "positions far", "anchors", "curves", "target"}
"""``positions far``: farther from the target than 1e3 of its sizes (judged only by operators that read a target)."""
OPERATORS = {
    # operator: (keyword arguments of a call that finishes on the healthy scene, what it reads and refuses)
    "detach": ({}, {"positions", "positions far", "target"}),
    "snap": ({}, {"positions", "positions far", "target", "shape key data"}),
    "project": ({"direction": "-Z"}, {"positions", "positions far", "target", "shape key data"}),
    "rest_set": ({}, {"positions", "positions far"}),
    "align": ({"icp_iterations": 5}, {"positions", "positions far", "anchors", "anchor vertices", "target"}),
    "anchor_add": ({"vertex_index": 3, "location": (0.1, 0.2, 1.0), "use_location": True}, {"anchors", "target"}),
    "anchors_auto": ({"spacing": 0.7, "replace": False}, {"positions", "positions far", "anchors", "target"}),
    "anchors_update": ({}, {"anchors", "target"}),
    "anchor_remove": ({}, set()),
    "anchors_propose": ({}, {"positions", "positions far", "anchors", "target"}),
    "anchor_accept": ({"all": True}, set()),
    "anchor_reject": ({"all": True}, set()),
    "anchors_clear": ({}, set()),
    "curve_constraint_add": ({"curve_object": "Curve"}, ALL_LAYOUT | {"new curve"}),
    "curve_constraints_auto": ({}, ALL_LAYOUT),
    "curve_constraint_remove": ({}, set()),
    "curve_constraints_clear": ({}, set()),
    "feature_lines_pair": ({}, ALL_LAYOUT),
    "wrap": ({"max_iterations": 30}, ALL_LAYOUT | {"anchor vertices", "shape key data"}),
    "mirror": ({"axis": "Y", "max_iterations": 30}, ALL_LAYOUT | {"anchor vertices", "shape key data"}),
    "wrap_sequence": (
        {"use_scene_range": False, "frame_start": 1, "frame_end": 2, "max_iterations": 30},
        ALL_LAYOUT | {"anchor vertices"},
    ),
    "export_sequence": (
        {
            "filepath": str(Path(tempfile.gettempdir()) / "springwrap-catalogue"),
            "file_format": "ALEMBIC" if bpy.app.build_options.alembic else "USD",
        },
        set(),
    ),
    "align_armature": ({"target_armature": "Target Rig"}, {"positions", "shape keys"}),
    "detect_features": ({"scale": 0.5, "write_curves": False}, {"target"}),
    "select_problems": ({"kind": "STRETCHED", "threshold": 1.2}, {"read-out"}),
    "fit_subdivision": (
        {"rounds": 2},
        {"positions", "positions far", "anchors", "anchor vertices", "target", "shape keys"},
    ),
}
"""Every operator, a call of it that works, and the kinds of input it reads (so refuses when broken)."""

PAIRS = [
    (operator, case) for operator in OPERATORS for case in CATALOGUE if CATALOGUE[case][1] in OPERATORS[operator][1]
]
OTHER_PAIRS = [
    (operator, case) for operator in OPERATORS for case in CATALOGUE if CATALOGUE[case][1] not in OPERATORS[operator][1]
]


def _call(operator, arguments):
    return getattr(bpy.ops.springwrap, operator)(**arguments)


NEEDS_A_PROPOSAL = {"anchor_accept", "anchor_reject"}
NEEDS_SEQUENCE_KEYS = {"export_sequence"}


def _scene_for(operator):
    """The catalogue's healthy scene for ``operator`` (target, layout): with the rigs for Align Armature, and the
    last anchor (the scene's space anchor) a proposed pair for the operators that accept or reject one."""
    target, layout = catalogue_scene(with_armatures=operator == "align_armature")
    if operator in NEEDS_A_PROPOSAL:
        layout.springwrap.anchors[-1].proposed = True
    if operator in NEEDS_SEQUENCE_KEYS:  # two frames of a sequence, as Wrap Sequence writes them
        layout.shape_key_add(name="Basis", from_mix=False)
        for frame in (1, 2):
            layout.shape_key_add(name=f"Wrap {frame:04d}", from_mix=False).keyframe_insert("value", frame=frame)
    return target, layout


INTERACTIVE = {"pair_tool"}
"""Operators that run only in a 3D view (called from a script they refuse, saying so); their bad input is checked
on the functions they call (``test_pair_tool.py``)."""


def test_every_operator_is_in_the_catalogue():
    registered = {name for name in dir(bpy.ops.springwrap) if not name.startswith("_")}
    assert registered - INTERACTIVE == set(OPERATORS)


@pytest.mark.parametrize("operator", list(OPERATORS))
def test_each_catalogue_call_finishes_on_the_healthy_scene(operator):
    if operator == "export_sequence" and not (bpy.app.build_options.alembic or bpy.app.build_options.usd):
        pytest.skip("this Blender was built without Alembic and USD (Debian's 3.4): Export Point Cache refuses")
    arguments, _reads = OPERATORS[operator]
    _scene_for(operator)
    assert _call(operator, arguments) == {"FINISHED"}


def _broken_scene(operator, case):
    """The catalogue's scene for ``operator`` broken by ``case``: (the operator's arguments, the layout, the message
    expected, the layout's full snapshot)."""
    arguments, _reads = OPERATORS[operator]
    target, layout = _scene_for(operator)
    breaks, _kind, message = CATALOGUE[case]
    breaks(target, layout)
    bpy.context.view_layer.update()
    return arguments, layout, message, full_snapshot(layout)


@pytest.mark.parametrize("operator, case", PAIRS, ids=[f"{operator}-{case}" for operator, case in PAIRS])
def test_bad_input_is_an_error_and_changes_nothing(operator, case):
    arguments, layout, message, before = _broken_scene(operator, case)
    with pytest.raises(RuntimeError, match=message):
        _call(operator, arguments)
    assert bpy.context.active_object == layout
    assert layout.mode == "OBJECT"
    assert full_snapshot(layout) == before


@pytest.mark.parametrize("operator, case", OTHER_PAIRS, ids=[f"{operator}-{case}" for operator, case in OTHER_PAIRS])
def test_bad_input_an_operator_does_not_read_never_crashes_it(operator, case):
    """It finishes (the input is not its business) or refuses for a reason of its own, leaving the scene as it was."""
    arguments, layout, _message, before = _broken_scene(operator, case)
    try:
        result = _call(operator, arguments)
    except RuntimeError as error:
        assert str(error).startswith("Error: ") or "poll()" in str(error), error
        assert full_snapshot(layout) == before
    else:
        assert result == {"FINISHED"}


@pytest.mark.parametrize("case", BROKEN_LISTS)
def test_a_broken_anchor_or_constraint_can_be_removed(case):
    """The way out: the remove and clear operators read nothing of the items they remove."""
    target, layout = catalogue_scene()
    CATALOGUE[case][0](target, layout)
    if case.startswith("anchor"):
        count = len(layout.springwrap.anchors)
        layout.springwrap.active_anchor_index = 0
        assert bpy.ops.springwrap.anchor_remove() == {"FINISHED"}
        assert len(layout.springwrap.anchors) == count - 1
        assert bpy.ops.springwrap.anchors_update() == {"FINISHED"}  # the rest is healthy again
    else:
        assert bpy.ops.springwrap.curve_constraints_clear() == {"FINISHED"}
        assert len(layout.springwrap.curve_constraints) == 0
    assert bpy.ops.springwrap.wrap(max_iterations=30) == {"FINISHED"}


@pytest.mark.parametrize("value", [math.nan, math.inf, 1e30], ids=["NaN", "inf", "1e30"])
@pytest.mark.parametrize("source", ["location", "cursor"])
def test_anchor_add_refuses_a_bad_location_or_cursor(value, source):
    target, layout = catalogue_scene()
    before = full_snapshot(layout)
    arguments = {"vertex_index": 3}
    if source == "location":
        arguments |= {"location": (value, 0.0, 0.0), "use_location": True}
        message = "Location must be a finite number" if math.isnan(value) else "The anchor location"  # inf: 3.4e38
    else:
        bpy.context.scene.cursor.location.x = value
        message = "The 3D cursor"
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.springwrap.anchor_add(**arguments)
    assert full_snapshot(layout) == before


@pytest.mark.parametrize("value", [math.nan, 1e30], ids=["NaN", "1e30"])
def test_a_bad_mirror_plane_is_refused(value):
    target, layout = catalogue_scene()
    bpy.ops.object.empty_add(location=(0.0, 0.0, 0.0))
    mirror = bpy.context.active_object
    mirror.name = "Mirror"
    mirror.location.x = value
    bpy.context.view_layer.objects.active = layout
    bpy.context.view_layer.update()
    before = full_snapshot(layout)
    with pytest.raises(RuntimeError, match="The plane of 'Mirror'|The mirror plane's object has a NaN"):
        bpy.ops.springwrap.mirror(axis="X", mirror_object="Mirror", max_iterations=30)
    assert full_snapshot(layout) == before
    layout.springwrap.mirror_object = mirror
    with pytest.raises(RuntimeError, match="The plane of 'Mirror'|The mirror plane's object has a NaN"):
        bpy.ops.springwrap.wrap(hold_plane="X", max_iterations=30)
    assert full_snapshot(layout) == before


# ---------------------------------------------------------------- symmetric anchors

SYMMETRIC_CALLS = {
    "anchor_add": {"vertex_index": 3, "location": (0.1, 0.2, 1.0), "use_location": True, "symmetric": True},
    "anchors_auto": {"spacing": 0.7, "replace": False, "symmetric": True},
}
"""The symmetric anchor operators: a call that finishes on the healthy scene (its layout's own X plane)."""
SYMMETRIC_READS = {"positions", "positions far", "anchors", "target"}
SYMMETRIC_PAIRS = [
    (operator, case) for operator in SYMMETRIC_CALLS for case in CATALOGUE if CATALOGUE[case][1] in SYMMETRIC_READS
]


def _symmetry_object(kind):
    """A scene object 'Symmetry' that cannot give a symmetry plane: deleted, a mesh, or with a NaN transform."""
    if kind == "not an Empty":
        bpy.ops.mesh.primitive_cube_add(size=0.2)
        bpy.context.active_object.name = "Symmetry"
        return
    empty = bpy.data.objects.new("Symmetry", None)
    bpy.context.scene.collection.objects.link(empty)
    if kind == "deleted":
        bpy.data.objects.remove(empty)
    else:
        empty.location.x = math.nan


SYMMETRY_OBJECTS = {
    "deleted": "There is no object named 'Symmetry' for the symmetry plane",
    "not an Empty": "The symmetry object 'Symmetry' is a mesh, not an Empty",
    "NaN transform": "'Symmetry' has a NaN or infinite transform",
}


@pytest.mark.parametrize("operator", list(SYMMETRIC_CALLS))
def test_symmetric_anchor_calls_finish_on_the_healthy_scene(operator):
    catalogue_scene()
    assert _call(operator, SYMMETRIC_CALLS[operator]) == {"FINISHED"}


@pytest.mark.parametrize(
    "operator, case", SYMMETRIC_PAIRS, ids=[f"{operator}-{case}" for operator, case in SYMMETRIC_PAIRS]
)
def test_symmetric_anchor_calls_refuse_bad_input_and_change_nothing(operator, case):
    target, layout = catalogue_scene()
    breaks, _kind, message = CATALOGUE[case]
    breaks(target, layout)
    bpy.context.view_layer.update()
    before = full_snapshot(layout)
    with pytest.raises(RuntimeError, match=message):
        _call(operator, SYMMETRIC_CALLS[operator])
    assert full_snapshot(layout) == before


SYMMETRIC_OTHER_PAIRS = [
    (operator, case) for operator in SYMMETRIC_CALLS for case in CATALOGUE if CATALOGUE[case][1] not in SYMMETRIC_READS
]


@pytest.mark.parametrize(
    "operator, case", SYMMETRIC_OTHER_PAIRS, ids=[f"{operator}-{case}" for operator, case in SYMMETRIC_OTHER_PAIRS]
)
def test_symmetric_anchor_calls_never_crash_on_other_bad_input(operator, case):
    """They finish or refuse for a reason of their own, leaving the scene as it was when they refuse."""
    target, layout = catalogue_scene()
    CATALOGUE[case][0](target, layout)
    bpy.context.view_layer.update()
    before = full_snapshot(layout)
    try:
        result = _call(operator, SYMMETRIC_CALLS[operator])
    except RuntimeError as error:
        assert str(error).startswith("Error: ") or "poll()" in str(error), error
        assert full_snapshot(layout) == before
    else:
        assert result == {"FINISHED"}


@pytest.mark.parametrize("kind", list(SYMMETRY_OBJECTS))
@pytest.mark.parametrize("operator", list(SYMMETRIC_CALLS))
def test_a_bad_symmetry_object_is_refused(operator, kind):
    target, layout = catalogue_scene()
    _symmetry_object(kind)
    bpy.context.view_layer.objects.active = layout
    bpy.context.view_layer.update()
    before = full_snapshot(layout)
    with pytest.raises(RuntimeError, match=SYMMETRY_OBJECTS[kind]):
        _call(operator, SYMMETRIC_CALLS[operator] | {"symmetry_object": "Symmetry"})
    assert full_snapshot(layout) == before


def test_project_along_normals_refuses_an_infinite_vertex_instead_of_skipping_it():
    """A real inf written with foreach_set was skipped by project(NORMAL) (its normal is not finite)."""
    target, layout = catalogue_scene()
    _layout_vertex(math.inf)(target, layout)
    before = full_snapshot(layout)
    with pytest.raises(RuntimeError, match="Layout vertex 7 has a NaN or infinite coordinate"):
        bpy.ops.springwrap.project(direction="NORMAL")
    assert full_snapshot(layout) == before


def test_set_rest_shape_does_not_need_a_usable_target():
    """Set Rest Shape reads the target only to judge the vertices against it: a target that lost its faces is
    not its problem (it finishes), while the wrap refuses it."""
    target, layout = catalogue_scene()
    target_without_faces(target, layout)
    assert bpy.ops.springwrap.rest_set() == {"FINISHED"}
    with pytest.raises(RuntimeError, match="'Target' has no faces"):
        bpy.ops.springwrap.wrap(max_iterations=30)


LAYOUT_CASES = ("layout vertex NaN", "layout vertex 1e30", "layout transform NaN", "empty layout")


@pytest.mark.parametrize("case", LAYOUT_CASES)
def test_detect_features_at_the_automatic_scale_survives_a_broken_layout(case, capfd):
    """Run from the layout at the automatic scale, Detect Features reads the layout's edge lengths: a broken
    layout never crashes it and is never changed; what cannot be measured (no finite edge) leaves the scale to
    the target alone."""
    target, layout = catalogue_scene()
    breaks, _kind, _message = CATALOGUE[case]
    breaks(target, layout)
    bpy.context.view_layer.update()
    before = full_snapshot(layout)
    capfd.readouterr()
    assert bpy.ops.springwrap.detect_features(write_curves=False) == {"FINISHED"}
    output = capfd.readouterr().out
    assert "at scale " in output and "nan" not in output.lower(), output
    assert full_snapshot(layout) == before


@pytest.mark.parametrize("name", ["Nowhere", "Curve"])  # missing; a curve object
def test_detect_features_refuses_a_layout_that_is_not_a_mesh(name):
    target, layout = catalogue_scene()
    before = full_snapshot(layout)
    with pytest.raises(RuntimeError, match=f"No mesh object called '{name}'"):
        bpy.ops.springwrap.detect_features(layout_name=name, write_curves=False)
    assert full_snapshot(layout) == before


def _float_settings(operator):
    """The operator's float settings: (identifier, a non-finite value of its shape)."""
    properties = getattr(bpy.ops.springwrap, operator).get_rna_type().properties
    return [
        (prop.identifier, (math.nan,) * prop.array_length if prop.is_array else math.nan)
        for prop in properties
        if prop.type == "FLOAT"
    ]


@pytest.mark.parametrize("operator", list(OPERATORS))
def test_every_float_setting_of_every_operator_refuses_nan_and_changes_nothing(operator):
    """One policy for the numbers a user sets: NaN is never "unlimited", "automatic" or "not free" (Auto Anchors'
    spacing, the max distance of snap, project and the subdivision fit, Detect Features' minimum length, ...)."""
    arguments, _reads = OPERATORS[operator]
    target, layout = catalogue_scene(with_armatures=operator == "align_armature")
    before = full_snapshot(layout)
    anchors = len(layout.springwrap.anchors)
    for name, value in _float_settings(operator):
        with pytest.raises(RuntimeError, match="must be a finite number, not nan"):
            _call(operator, arguments | {name: value})
        assert full_snapshot(layout) == before, name
        assert len(layout.springwrap.anchors) == anchors, name


def test_the_operators_named_for_nan_have_the_settings_checked():
    """The settings found taking NaN as a value are among those checked."""
    for operator, name in [
        ("anchors_auto", "spacing"),
        ("snap", "max_distance"),
        ("project", "max_distance"),
        ("fit_subdivision", "max_distance"),
        ("detect_features", "min_length"),
    ]:
        assert name in dict(_float_settings(operator)), (operator, name)


@pytest.mark.parametrize("group", ["Free", "Stiffness"])
def test_a_nan_weight_in_the_free_or_stiffness_group_is_refused_naming_the_group(group):
    target, layout = catalogue_scene()
    vertex_group = layout.vertex_groups.new(name=group)
    vertex_group.add([3, 4], 0.5, "REPLACE")
    vertex_group.add([5], math.nan, "REPLACE")
    before = full_snapshot(layout)
    keyword = {"Free": "free_group", "Stiffness": "stiffness_group"}[group]
    with pytest.raises(RuntimeError, match=f"vertex group '{group}': vertex 5's weight must be a finite number"):
        bpy.ops.springwrap.wrap(max_iterations=30, solver="ENERGY", **{keyword: group})
    assert full_snapshot(layout) == before
