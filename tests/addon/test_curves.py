"""Curve constraints under Blender (PyPI ``bpy``): the operators, storage, drawing data and the wrap.

Scenes come from ``test_wrap``: the tilted plane target (a 40 x 40 quad grid) with a grid layout
0.3 above it, or a quad strip with a seam and a loose chain. Target curves are a poly curve object
drawn on the plane, or rows of the target grid, so their answers are known: a row of target
vertices is the shortest edge chain between its ends, and after a wrap every constrained chain
vertex lies on its curve (checked against the curve's own evaluated polyline).
"""

import bpy

import bmesh
import numpy as np
import pytest
from mathutils import Vector

from bpy_helpers import (
    anchor_snapshot,
    chain_pairs,
    curves_layout,
    distance_to_polyline,
    plane_scene,
    plane_target,
    quad_normals,
    quads_of,
    select_edges,
    snapshot,
    world_positions,
)

ROW = 13  # vertices per row of the test_wrap grid layout (12 subdivisions)


# ---------------------------------------------------------------- helpers


def curve_rows(layout):
    """The stored constraints as plain tuples (for identity checks)."""
    return [
        (
            item.layout_vertices,
            item.source_kind,
            None if item.curve_object is None else item.curve_object.name,
            item.target_vertices,
            tuple(tuple(point.co) for point in item.points),
        )
        for item in layout.springwrap.curve_constraints
    ]


def poly_curve(name, world_points):
    """A poly curve object (identity transform) through the given world points."""
    data = bpy.data.curves.new(name, "CURVE")
    data.dimensions = "3D"
    spline = data.splines.new("POLY")
    spline.points.add(len(world_points) - 1)
    for point, location in zip(spline.points, world_points):
        point.co = (*location, 1.0)
    curve = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(curve)
    return curve


def bent_curve_under_row(layout, normal):
    """A poly curve on the plane target under the layout's first row, bent 0.1 sideways in the plane."""
    row = world_positions(layout)[:ROW]
    on_plane = row - 0.3 * normal
    along = on_plane[-1] - on_plane[0]
    side = np.cross(normal, along / np.linalg.norm(along))
    t = np.linspace(0.0, 1.0, 9)
    points = on_plane[0] + t[:, None] * along + 0.1 * np.sin(np.pi * t)[:, None] * side
    return poly_curve("Curve", points), points


def activate(layout):
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout


# ---------------------------------------------------------------- registration


def test_operators_panel_and_settings_are_registered():
    for name in (
        "curve_constraint_add",
        "curve_constraints_auto",
        "curve_constraint_remove",
        "curve_constraints_clear",
    ):
        operator = getattr(bpy.ops.springwrap, name)
        assert operator.get_rna_type().identifier == f"SPRINGWRAP_OT_{name}"
        assert operator.get_rna_type().description
        assert getattr(bpy.types, f"SPRINGWRAP_OT_{name}").bl_options == {"REGISTER", "UNDO"}
    assert hasattr(bpy.types, "SPRINGWRAP_PT_curve_constraints")
    assert hasattr(bpy.types, "SPRINGWRAP_UL_curve_constraints")
    settings = bpy.types.Object.bl_rna.properties["springwrap"].fixed_type
    for name in ("curve_constraints", "active_curve_constraint_index", "show_curve_constraints", "curve_source"):
        assert name in settings.properties


# ---------------------------------------------------------------- add


def test_add_orders_the_selected_chain_and_orients_the_curve_object():
    _target, layout, normal = plane_scene()
    curve, points = bent_curve_under_row(layout, normal)
    chain = list(range(ROW))
    activate(layout)
    select_edges(layout, chain_pairs(chain)[::-1])  # selection order does not matter
    # The curve drawn backwards must be turned round so it starts at the chain's first vertex.
    curve.data.splines[0].points.foreach_set("co", np.c_[points[::-1], np.ones(len(points))].ravel())
    assert bpy.ops.springwrap.curve_constraint_add(curve_object="Curve") == {"FINISHED"}
    assert layout.mode == "EDIT"
    bpy.ops.object.mode_set(mode="OBJECT")
    (item,) = layout.springwrap.curve_constraints
    assert item.layout_vertices == " ".join(str(vertex) for vertex in chain)
    assert item.source_kind == "CURVE_OBJECT" and item.curve_object == curve
    stored = np.array([tuple(point.co) for point in item.points])
    np.testing.assert_allclose(stored, points, atol=1e-5)


@pytest.mark.parametrize(
    "pairs, reason",
    [
        ([(0, 1), (1, 2), (1, ROW + 1)], "branch at vertex 1"),
        ([(0, 1), (1, ROW + 1), (ROW + 1, ROW), (ROW, 0)], "closed loop"),
        ([(0, 1), (3, 4)], "more than one piece"),
    ],
)
def test_add_refuses_branches_loops_and_pieces_and_leaves_the_scene_untouched(pairs, reason):
    _target, layout, normal = plane_scene()
    bent_curve_under_row(layout, normal)
    activate(layout)
    select_edges(layout, pairs)
    bpy.ops.object.mode_set(mode="OBJECT")  # the edit-mesh round trip itself may rewrite positions
    before = snapshot(layout), curve_rows(layout), anchor_snapshot(layout)
    bpy.ops.object.mode_set(mode="EDIT")
    with pytest.raises(RuntimeError, match=reason):
        bpy.ops.springwrap.curve_constraint_add(curve_object="Curve")
    bpy.ops.object.mode_set(mode="OBJECT")
    assert (snapshot(layout), curve_rows(layout), anchor_snapshot(layout)) == before


def test_add_from_target_edges_follows_the_target_row_between_the_end_anchors():
    target, layout, _normal = plane_scene()
    target_points = world_positions(target)
    target_row = np.flatnonzero(np.isclose(target.data.vertices[0].co.y, [v.co.y for v in target.data.vertices]))
    target_row = target_row[np.argsort([target.data.vertices[int(i)].co.x for i in target_row])]
    start, end = target_row[5], target_row[30]
    chain = list(range(ROW))
    for vertex, target_vertex in ((chain[0], start), (chain[-1], end)):
        location = Vector(target_points[target_vertex] + np.array([0.003, -0.002, 0.001]))
        assert bpy.ops.springwrap.anchor_add(vertex_index=vertex, location=location, use_location=True) == {"FINISHED"}
    select_edges(layout, chain_pairs(chain))
    assert bpy.ops.springwrap.curve_constraint_add() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    (item,) = layout.springwrap.curve_constraints
    assert item.source_kind == "TARGET_EDGES"
    np.testing.assert_array_equal([int(index) for index in item.target_vertices.split()], target_row[5:31])
    stored = np.array([tuple(point.co) for point in item.points])
    np.testing.assert_allclose(stored, target_points[target_row[5:31]], atol=1e-5)

    # The same chain again: its vertices are taken (non-manifold), refused with the reason.
    before = curve_rows(layout)
    select_edges(layout, chain_pairs(chain[2:6]))
    with pytest.raises(RuntimeError, match="already belongs to another curve constraint"):
        bpy.ops.springwrap.curve_constraint_add()
    bpy.ops.object.mode_set(mode="OBJECT")
    assert curve_rows(layout) == before


def test_add_needs_a_target_and_a_real_curve_object():
    _target, layout, normal = plane_scene()
    bent_curve_under_row(layout, normal)
    select_edges(layout, chain_pairs(list(range(4))))
    with pytest.raises(RuntimeError, match="no curve object called 'Nothing'"):
        bpy.ops.springwrap.curve_constraint_add(curve_object="Nothing")
    bpy.ops.object.mode_set(mode="OBJECT")
    layout.springwrap.target = None
    assert not bpy.ops.springwrap.curve_constraint_add.poll()
    assert not layout.springwrap.curve_constraints


# ---------------------------------------------------------------- automatic pairing


def test_auto_pairs_the_anchored_loose_chain_and_seam_and_reports_the_rest(capfd):
    target, _normal = plane_target()
    layout = curves_layout(target, shift=0.037)
    # Anchor both ends of the loose chain (27..35) and of the seam (9..17); one end of nothing else.
    for vertex in (27, 35, 9, 17):
        assert bpy.ops.springwrap.anchor_add(
            vertex_index=vertex, location=world_positions(layout)[vertex], use_location=True
        ) == {"FINISHED"}
    assert bpy.ops.springwrap.curve_constraints_auto() == {"FINISHED"}
    rows = curve_rows(layout)
    chains = sorted(row[0] for row in rows)
    assert chains == sorted([" ".join(map(str, range(9, 18))), " ".join(map(str, range(27, 36)))])
    assert all(row[1] == "TARGET_EDGES" for row in rows)
    output = capfd.readouterr().out
    # The strip's border comes in 6 pieces (its corners and the seam's ends split it), none anchored at both ends.
    assert "Paired 2 layout curves" in output and "6 an end of the layout curve has no anchor" in output

    # Again: both are constrained already (non-manifold), nothing is added.
    assert bpy.ops.springwrap.curve_constraints_auto() == {"FINISHED"}
    assert curve_rows(layout) == rows
    assert "already constrained" in capfd.readouterr().out


def test_auto_refuses_ends_anchored_to_the_same_target_vertex(capfd):
    target, _normal = plane_target()
    layout = curves_layout(target, shift=0.037)
    spot = Vector(world_positions(target)[100])
    for vertex in (27, 35):
        bpy.ops.springwrap.anchor_add(vertex_index=vertex, location=spot, use_location=True)
    assert bpy.ops.springwrap.curve_constraints_auto() == {"FINISHED"}
    assert not layout.springwrap.curve_constraints
    assert "1 both ends anchor to the same target vertex" in capfd.readouterr().out


def test_auto_on_a_layout_without_curves_says_why_and_what_to_do(capfd):
    """A closed layout has no open border, seam or loose chain: nothing to pair, and the report says so (a
    warning) and what to do; a layout whose curves are all unanchored is told to anchor their ends."""
    from bpy_helpers import symmetric_head_scene

    symmetric_head_scene()  # a closed sphere layout
    assert bpy.ops.springwrap.curve_constraints_auto() == {"FINISHED"}
    output = capfd.readouterr().out
    assert output.startswith("Warning: Paired 0 layout curves with target edge chains: the layout has no curve")
    assert "Mark Seam along the edges to follow" in output
    bpy.ops.wm.read_homefile(use_empty=True)
    target, _normal = plane_target()
    curves_layout(target, shift=0.037)
    assert bpy.ops.springwrap.curve_constraints_auto() == {"FINISHED"}
    output = capfd.readouterr().out
    assert "Warning: Paired 0 layout curves with target edge chains of its 8:" in output
    assert "Anchor both ends of each curve to pair" in output


def test_the_panel_header_counts_the_constraints():
    from springwrap.ui.panels import SPRINGWRAP_PT_curve_constraints

    _target, layout, normal = plane_scene()
    curve, _points = bent_curve_under_row(layout, normal)

    def header():
        recorder = _Recorder()
        SPRINGWRAP_PT_curve_constraints.draw_header_preset(type("Panel", (), {"layout": recorder})(), bpy.context)
        return recorder.labels

    assert header() == ["0"]
    select_edges(layout, chain_pairs(list(range(4))))
    assert bpy.ops.springwrap.curve_constraint_add(curve_object=curve.name) == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    assert header() == ["1"]


def test_remove_and_clear():
    target, _normal = plane_target()
    layout = curves_layout(target, shift=0.037)
    for vertex in (27, 35, 9, 17):
        bpy.ops.springwrap.anchor_add(vertex_index=vertex, location=world_positions(layout)[vertex], use_location=True)
    bpy.ops.springwrap.curve_constraints_auto()
    first, second = curve_rows(layout)
    layout.springwrap.active_curve_constraint_index = 0
    assert bpy.ops.springwrap.curve_constraint_remove() == {"FINISHED"}
    assert curve_rows(layout) == [second]
    assert bpy.ops.springwrap.curve_constraints_clear() == {"FINISHED"}
    assert not layout.springwrap.curve_constraints
    assert not bpy.ops.springwrap.curve_constraints_clear.poll()


# ---------------------------------------------------------------- the wrap


def test_wrap_puts_the_chain_on_the_target_curve():
    _target, layout, normal = plane_scene()
    curve, _points = bent_curve_under_row(layout, normal)
    chain = list(range(ROW))
    select_edges(layout, chain_pairs(chain))
    assert bpy.ops.springwrap.curve_constraint_add(curve_object="Curve") == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    # Slide the curve along the plane after pairing: the wrap reads it again (evaluated, world space).
    row = world_positions(layout)[:ROW]
    along = (row[-1] - row[0]) / np.linalg.norm(row[-1] - row[0])
    curve.location = Vector(0.08 * np.cross(normal, along) + 0.05 * along)
    bpy.context.view_layer.update()
    evaluated = curve.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    polyline = np.array([tuple(curve.matrix_world @ vertex.co) for vertex in evaluated.vertices])
    curve.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh_clear()
    before = distance_to_polyline(world_positions(layout)[chain], polyline)
    assert before.min() > 0.2
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    after = distance_to_polyline(world_positions(layout)[chain], polyline)
    assert after.max() < 1e-3, after


def test_wrap_refuses_a_constraint_on_missing_vertices_and_leaves_the_layout_untouched():
    _target, layout, normal = plane_scene()
    bent_curve_under_row(layout, normal)
    select_edges(layout, chain_pairs(list(range(5))))
    assert bpy.ops.springwrap.curve_constraint_add(curve_object="Curve") == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    layout.springwrap.curve_constraints[0].layout_vertices = "0 1 99999"
    before = snapshot(layout), curve_rows(layout)
    with pytest.raises(RuntimeError, match="99999"):
        bpy.ops.springwrap.wrap()
    assert (snapshot(layout), curve_rows(layout)) == before


def test_wrap_refuses_a_deleted_curve_object():
    _target, layout, normal = plane_scene()
    curve, _points = bent_curve_under_row(layout, normal)
    select_edges(layout, chain_pairs(list(range(5))))
    bpy.ops.springwrap.curve_constraint_add(curve_object="Curve")
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.data.objects.remove(curve)
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="Curve constraint 0"):
        bpy.ops.springwrap.wrap()
    assert snapshot(layout) == before


# ---------------------------------------------------------------- storage and drawing


def test_save_and_reload_keep_the_constraints(tmp_path):
    _target, layout, normal = plane_scene()
    bent_curve_under_row(layout, normal)
    select_edges(layout, chain_pairs(list(range(ROW))))
    bpy.ops.springwrap.curve_constraint_add(curve_object="Curve")
    bpy.ops.object.mode_set(mode="OBJECT")
    rows = curve_rows(layout)
    path = str(tmp_path / "curves.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    assert "Layout" not in bpy.data.objects
    bpy.ops.wm.open_mainfile(filepath=path)
    reloaded = bpy.data.objects["Layout"]
    assert curve_rows(reloaded) == rows
    assert reloaded.springwrap.curve_constraints[0].curve_object == bpy.data.objects["Curve"]


def test_drawing_data_joins_each_chain_vertex_to_its_curve_point():
    from springwrap.ui import overlays as anchor_drawing

    _target, layout, normal = plane_scene()
    bent_curve_under_row(layout, normal)
    select_edges(layout, chain_pairs(list(range(ROW))))
    bpy.ops.springwrap.curve_constraint_add(curve_object="Curve")
    bpy.ops.object.mode_set(mode="OBJECT")
    starts, ends = anchor_drawing.curve_segments(layout)
    assert starts.shape == ends.shape == (ROW * anchor_drawing.CURVE_DASH_COUNT, 3)
    assert starts.dtype == np.float32
    np.testing.assert_allclose(starts[0], world_positions(layout)[0], atol=1e-5)  # first dash starts at vertex 0
    layout.springwrap.show_curve_constraints = False
    assert anchor_drawing.curve_segments(layout)[0].shape == (0, 3)
    anchor_drawing.draw_anchors()  # background mode: draws nothing, raises nothing


class _Recorder:
    """Stands in for ``UILayout``: records operator buttons (with their settings), props, lists and labels."""

    def __init__(self):
        self.operators, self.props, self.lists, self.labels = [], [], [], []
        self.alert = False

    def row(self, *args, **kwargs):
        return self

    column = split = row

    def separator(self, *args, **kwargs):
        pass

    def label(self, text="", **kwargs):
        self.labels.append(text)

    def prop(self, data, name, **kwargs):
        self.props.append(name)

    def template_list(self, list_type, _list_id, _data, collection, _active_data, active, **kwargs):
        self.lists.append((list_type, collection, active))

    def operator(self, idname, **kwargs):
        button = type("Button", (), {})()
        self.operators.append((idname, button))
        return button


def test_panel_lists_the_constraints_with_their_buttons():
    from springwrap.ui.lists import SPRINGWRAP_UL_curve_constraints
    from springwrap.ui.panels import SPRINGWRAP_PT_curve_constraints

    _target, layout, normal = plane_scene()
    curve, _points = bent_curve_under_row(layout, normal)
    layout.springwrap.curve_source = curve
    assert SPRINGWRAP_PT_curve_constraints.bl_parent_id == "SPRINGWRAP_PT_anchors"
    assert SPRINGWRAP_PT_curve_constraints.poll(bpy.context)
    recorder = _Recorder()
    SPRINGWRAP_PT_curve_constraints.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    names = [name for name, _button in recorder.operators]
    assert names == [
        "springwrap.curve_constraint_add",
        "springwrap.curve_constraint_remove",
        "springwrap.curve_constraints_clear",
        "springwrap.curve_constraints_auto",
        "springwrap.feature_lines_pair",
    ]
    assert recorder.operators[0][1].curve_object == "Curve"
    assert recorder.lists == [("SPRINGWRAP_UL_curve_constraints", "curve_constraints", "active_curve_constraint_index")]
    assert "curve_source" in recorder.props

    select_edges(layout, chain_pairs(list(range(4))))
    bpy.ops.springwrap.curve_constraint_add(curve_object="Curve")
    bpy.ops.object.mode_set(mode="OBJECT")
    row = _Recorder()
    item = layout.springwrap.curve_constraints[0]
    SPRINGWRAP_UL_curve_constraints.draw_item(None, bpy.context, row, layout.springwrap, item, 0, None, "")
    assert row.labels == ["0..3 (4)", "Curve"]


# ---------------------------------------------------------------- regressions (rings and tubes)
#
# Two defects of v1 on rings, reproduced on a tube: which way a target curve runs was decided by
# its ends alone (an opened ring's two ends are next to each other), and a chain of target edges
# was the shortest one between the anchors, wherever the layout chain ran.

TUBE_SEGMENTS = 48  # target vertices around the tube (7.5 degrees apart)
TUBE_RINGS = 21  # z from -1 to 1 in steps of 0.1
RING_STEP = 2.0 * np.pi / 16  # a 16-vertex layout ring: 22.5 degrees, three target edges
BAND_ROWS = (-0.3, -0.15, 0.0, 0.15, 0.3)  # z of the band's rows; row 2 runs round the tube's ring 10


def quad_mesh(name, vertices, faces):
    """A mesh made by bmesh (bpy 5.0.1's ``from_pydata`` leaves selection layers that crash
    ``edges.foreach_set("select", ...)``)."""
    editable = bmesh.new()
    made = [editable.verts.new(vertex) for vertex in vertices]
    for face in faces:
        editable.faces.new([made[index] for index in face])
    mesh = bpy.data.meshes.new(name)
    editable.to_mesh(mesh)
    editable.free()
    return mesh


def tube_target():
    """An open tube along z (radius 1, z from -1 to 1, 48 x 20 quads): the target of the ring cases."""
    angles = 2.0 * np.pi * np.arange(TUBE_SEGMENTS) / TUBE_SEGMENTS
    vertices = [(np.cos(a), np.sin(a), z) for z in np.linspace(-1.0, 1.0, TUBE_RINGS) for a in angles]
    faces = [
        (
            ring * TUBE_SEGMENTS + s,
            ring * TUBE_SEGMENTS + (s + 1) % TUBE_SEGMENTS,
            (ring + 1) * TUBE_SEGMENTS + (s + 1) % TUBE_SEGMENTS,
            (ring + 1) * TUBE_SEGMENTS + s,
        )
        for ring in range(TUBE_RINGS - 1)
        for s in range(TUBE_SEGMENTS)
    ]
    mesh = quad_mesh("Tube", vertices, faces)
    target = bpy.data.objects.new("Target", mesh)
    bpy.context.scene.collection.objects.link(target)
    return target


def tube_vertex(ring, segment):
    """Index of the tube target's vertex at ring ``ring`` (z = -1 + 0.1 ring) and angle 7.5 degrees x ``segment``."""
    return ring * TUBE_SEGMENTS + segment % TUBE_SEGMENTS


def ring_band(target, angles, closed, radius=1.06):
    """A quad layout band round the tube's axis, a little outside it: a row per ``BAND_ROWS`` z, a
    column per angle (vertex row * columns + column); ``closed``: the last column joins the first."""
    columns = len(angles)
    vertices = [(radius * np.cos(a), radius * np.sin(a), z) for z in BAND_ROWS for a in angles]
    faces = [
        (
            row * columns + c,
            row * columns + (c + 1) % columns,
            (row + 1) * columns + (c + 1) % columns,
            (row + 1) * columns + c,
        )
        for row in range(len(BAND_ROWS) - 1)
        for c in range(columns if closed else columns - 1)
    ]
    mesh = quad_mesh("Band", vertices, faces)
    layout = bpy.data.objects.new("Layout", mesh)
    bpy.context.scene.collection.objects.link(layout)
    layout.springwrap.target = target
    activate(layout)
    return layout


def flipped_quads(layout):
    """How many of the band's quads face into the tube (their outward normal is radial)."""
    world = world_positions(layout)
    quads = quads_of(layout)
    centres = world[quads].mean(axis=1) * np.array([1.0, 1.0, 0.0])
    outward = centres / np.linalg.norm(centres, axis=1)[:, None]
    return int((np.einsum("kx,kx->k", quad_normals(world, quads), outward) <= 0.0).sum())


def chain_errors(layout, chain, truth):
    """(mean, max) distance of the chain's vertices from where they belong."""
    distances = np.linalg.norm(world_positions(layout)[chain] - truth, axis=1)
    return distances.mean(), distances.max()


def test_an_opened_ring_follows_its_curve_the_right_way_round_on_a_turned_template():
    """v1 oriented the curve by its end nearer the chain's first vertex: an opened ring on a
    template turned by 0.6 of an edge (its first vertex 0.4 of an edge from the curve's *last*
    point) got the curve reversed, 90 degrees of mean error. The whole chain decides now."""
    target = tube_target()
    layout = ring_band(target, RING_STEP * (np.arange(16) - 0.6), closed=True)
    chain = [2 * 16 + k for k in range(16)]  # the row at z = 0, opened between its last and first vertex
    truth = np.array([(np.cos(RING_STEP * k), np.sin(RING_STEP * k), 0.0) for k in range(16)])
    poly_curve("Ring", truth)  # the ring on the tube, opened the same way: no segment from the last point back
    select_edges(layout, chain_pairs(chain))
    assert bpy.ops.springwrap.curve_constraint_add(curve_object="Ring") == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    stored = np.array([tuple(point.co) for point in layout.springwrap.curve_constraints[0].points])
    assert np.allclose(stored, truth, atol=1e-5), "the curve was turned round"
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    mean, largest = chain_errors(layout, chain, truth)
    assert largest < 1e-3, (mean, largest)
    assert flipped_quads(layout) == 0


def test_a_curve_turned_after_pairing_keeps_its_direction_at_the_wrap():
    """The wrap reads a curve object again; v1 kept the direction whose start was nearer the cached
    start point, so an opened ring turned by over half an edge after pairing ran backwards (turned
    by two thirds of an edge here: two tube edges, so that its points stay on the tube)."""
    target = tube_target()
    layout = ring_band(target, RING_STEP * np.arange(16), closed=True)
    chain = [2 * 16 + k for k in range(16)]
    points = np.array([(np.cos(RING_STEP * k), np.sin(RING_STEP * k), 0.0) for k in range(16)])
    curve = poly_curve("Ring", points)
    select_edges(layout, chain_pairs(chain))
    assert bpy.ops.springwrap.curve_constraint_add(curve_object="Ring") == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    curve.rotation_euler = (0.0, 0.0, RING_STEP * 2 / 3)
    bpy.context.view_layer.update()
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    turned = np.array([(np.cos(RING_STEP * (k + 2 / 3)), np.sin(RING_STEP * (k + 2 / 3)), 0.0) for k in range(16)])
    mean, largest = chain_errors(layout, chain, turned)
    assert largest < 1e-3, (mean, largest)
    assert flipped_quads(layout) == 0


@pytest.mark.parametrize("pairing", ["by hand", "automatic"])
def test_a_target_edge_chain_follows_the_layout_chain_the_long_way_round(pairing):
    """v1 joined the anchored ends by the shortest chain of target edges wherever the layout chain
    ran: a chain round 225 degrees of the tube was paired with the 135 degrees the other way. The
    target edges follow the chain's own course now."""
    target = tube_target()
    layout = ring_band(target, RING_STEP * np.arange(11), closed=False)  # 0 to 225 degrees
    row, ring = (2, 10) if pairing == "by hand" else (0, 7)  # the middle row, or the bottom border (z = -0.3)
    chain = [row * 11 + k for k in range(11)]
    for vertex, segment in ((chain[0], 0), (chain[-1], 30)):
        location = Vector(world_positions(target)[tube_vertex(ring, segment)])
        assert bpy.ops.springwrap.anchor_add(vertex_index=vertex, location=location, use_location=True) == {"FINISHED"}
    if pairing == "by hand":
        select_edges(layout, chain_pairs(chain))
        assert bpy.ops.springwrap.curve_constraint_add() == {"FINISHED"}
        bpy.ops.object.mode_set(mode="OBJECT")
    else:
        assert bpy.ops.springwrap.curve_constraints_auto() == {"FINISHED"}
    (item,) = layout.springwrap.curve_constraints
    assert item.layout_vertices == " ".join(map(str, chain))
    followed = [int(index) for index in item.target_vertices.split()]
    assert followed == [tube_vertex(ring, segment) for segment in range(31)], followed
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    z = -1.0 + 0.1 * ring
    truth = np.array([(np.cos(RING_STEP * k), np.sin(RING_STEP * k), z) for k in range(11)])
    mean, largest = chain_errors(layout, chain, truth)
    assert largest < 1e-3, (mean, largest)
    assert flipped_quads(layout) == 0
