"""Everything else on a layout survives every operator.

The layout is the half head of ``test_mirror`` (101 vertices, 96 faces) snapped onto its symmetric target, with
anchors and a curve constraint, and dressed by ``bpy_helpers.dress_layout`` with what an artist's layout
carries: two UV maps, weighted vertex groups (``.L`` / ``_R`` pairs), an attribute of every type on every domain,
creases, seams, sharp edges, flat and smooth faces, three materials, a vertex colour layer, custom split normals,
a Subdivision Surface and a Mirror modifier, a parent, custom properties, a selection and hidden elements (no
shape keys). Every operator of ``bpy.ops.springwrap`` that can change the layout runs on it, and every datum of
``bpy_helpers.layout_data`` must come out bit-identical: vertex, edge, face and corner counts and order, every
attribute's raw values, the vertex group weights... Only what the operator exists to change may change: the
positions and the face-point state always, plus what :data:`CHANGES` names. A failure names the operator and
the data that changed.

The mirror adds the other half (:func:`test_mirror_keeps_the_half_and_copies_everything_onto_the_new_half`):
the original half's data must be kept, and each new vertex, edge, face and corner must carry the data of its
original, bit for bit, with vertex group weights moved to the group of the mirrored name (as Blender's Mirror
modifier does).
"""

import tempfile
from pathlib import Path

import bpy

import numpy as np
import pytest

from bpy_helpers import (
    activate,
    attribute_values,
    dress_layout,
    head_scene,
    layout_data,
    mirror_outcome,
    read_creases,
    repair_edge_selection,
    select_edges,
    wrap_session,
)

CHAIN = [1 + 5 * 9 + column for column in range(1, 8)]
"""A ring of the half head's layout (ring 5, its 7 columns off the midline): the scene's curve constraint."""
SELECTED_CHAIN = [1 + 7 * 9 + column for column in range(1, 8)]
"""Ring 7's: the chain ``curve_constraint_add`` pairs in its case."""


def layout_scene(creases=True, armatures=False):
    """The dressed half-head layout, snapped, with anchors and a curve constraint; the layout active."""
    target, layout = head_scene()
    repair_edge_selection(layout.data)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.8) == {"FINISHED"}
    select_edges(layout, list(zip(CHAIN, CHAIN[1:])))
    assert bpy.ops.springwrap.curve_constraint_add() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    if armatures:
        _armatures(layout)
    dress_layout(layout, creases=creases)
    activate(layout)
    bpy.context.view_layer.update()
    return target, layout


def _armatures(layout):
    """A one-bone template armature skinning the whole layout (group ``bone``), a target armature turned a little."""
    from benchmarks.retarget import rig_scene, rigging

    count = len(layout.data.vertices)

    def rig(tail):
        return rigging.RigData(
            names=("bone",),
            parents=("",),
            heads=np.array([[0.3, -0.2, -0.8]]),
            tails=np.array([tail]),
            rolls=np.zeros(1),
            weights={"bone": (np.arange(count), np.ones(count))},
        )

    template = rig_scene.build_armature("Template Rig", rig((0.3, -0.2, 1.2)))
    rig_scene.skin(layout, template, rig((0.3, -0.2, 1.2)))
    rig_scene.build_armature("Target Rig", rig((0.35, -0.1, 1.2)))


def _edit_mode(operator, **arguments):
    """Run the operator from edit mode (what the edit-mode buttons do), then leave edit mode. Compared from after a
    first trip into edit mode and back: Blender's own (it flushes the selection and adds UV selection layers)."""

    def in_edit_mode():
        bpy.ops.object.mode_set(mode="EDIT")
        try:
            return getattr(bpy.ops.springwrap, operator)(**arguments)
        finally:
            bpy.ops.object.mode_set(mode="OBJECT")

    def run():
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.object.mode_set(mode="OBJECT")
        return "SNAPSHOT", in_edit_mode

    return run


def _select_chain_then(operator, **arguments):
    def run():
        layout = bpy.context.active_object
        for vertex in SELECTED_CHAIN:  # a chain hidden in part would not be one piece in edit mode
            layout.data.vertices[vertex].hide = False
        for edge in layout.data.edges:
            edge.hide = edge.hide and not set(edge.vertices) <= set(SELECTED_CHAIN)
        select_edges(layout, list(zip(SELECTED_CHAIN, SELECTED_CHAIN[1:])))  # and enters edit mode
        bpy.ops.object.mode_set(mode="OBJECT")  # the data compared is object mode data
        return "SNAPSHOT", lambda: getattr(bpy.ops.springwrap, operator)(**arguments)

    return run


def _live_wrap(cancel):
    """The live wrap's path (``WrapSession``, as the modal operator runs it): frames written, then finished or
    cancelled."""

    def run():
        session = wrap_session(bpy.context.active_object, max_iterations=60)
        for _frame in range(5):
            session.advance()
        if cancel:
            session.cancel()
        else:
            session.run()
            session.finish()
        return {"FINISHED"}

    return run


def _select_problems():
    """Select Problems (it leaves the layout in edit mode, with a new selection), then back to object mode."""
    result = bpy.ops.springwrap.select_problems(kind="STRETCHED", threshold=1.05)
    bpy.ops.object.mode_set(mode="OBJECT")
    return result


def _proposed_then(operator):
    """Propose pairs (any confidence, searched widely, features of the small scene's size), then accept or reject
    them all."""

    def run():
        assert bpy.ops.springwrap.anchors_propose(min_confidence=0.0, search_radius=0.5, feature_scale=0.015) == {
            "FINISHED"
        }
        assert any(item.proposed for item in bpy.context.active_object.springwrap.anchors)
        return {"FINISHED"}, _call(operator, all=True)

    return run


def _sequence_then_export():
    """Wrap two frames (the layout gets its sequence keys), then export them as a point cache."""
    if not (bpy.app.build_options.alembic or bpy.app.build_options.usd):
        pytest.skip("this Blender was built without Alembic and USD (Debian's 3.4): Export Point Cache refuses")
    assert bpy.ops.springwrap.wrap_sequence(use_scene_range=False, frame_start=1, frame_end=2) == {"FINISHED"}
    path = str(Path(tempfile.gettempdir()) / "springwrap-survives")
    file_format = "ALEMBIC" if bpy.app.build_options.alembic else "USD"
    return {"FINISHED"}, _call("export_sequence", filepath=path, file_format=file_format)


def _call(operator, **arguments):
    return lambda: getattr(bpy.ops.springwrap, operator)(**arguments)


ANCHORS, CONSTRAINTS, REST = "Springwrap anchors", "Springwrap curve constraints", "attribute springwrap_rest"
READOUT = {"attribute springwrap_distance", "attribute springwrap_stretch", "attribute springwrap_flipped"}
"""The quality read-out: written by snap, project, the wrap and the mirror (``blender.quality``)."""
SELECTION = {"selected vertices", "selected edges", "selected faces"}
SELECTION |= {"attribute .select_vert", "attribute .select_edge", "attribute .select_poly"}  # Blender 4+

CASES = {
    # case: (how to run it, the data it exists to change besides positions and the face-point state)
    "detach": (_call("detach"), set()),
    "detach only selected": (_call("detach", only_selected=True), set()),
    "snap": (_call("snap"), READOUT),
    "snap VERTEX": (_call("snap", mode="VERTEX"), READOUT),
    "snap from edit mode": (_edit_mode("snap", only_selected=True), READOUT),
    "project NORMAL": (_call("project", direction="NORMAL"), READOUT),
    "project -Z": (_call("project", direction="-Z"), READOUT),
    "rest_set": (_call("rest_set"), {REST}),
    "align to the object": (_call("align", icp_iterations=5), set()),
    "align baked": (_call("align", icp_iterations=5, apply="BAKE"), set()),
    "align_armature": (_call("align_armature", target_armature="Target Rig"), {REST}),
    "anchor_add": (_call("anchor_add", vertex_index=3, location=(0.5, 0.1, 1.0), use_location=True), {ANCHORS}),
    "anchors_auto": (_call("anchors_auto", spacing=0.5), {ANCHORS}),
    "anchors_update": (_call("anchors_update"), {ANCHORS}),
    "anchor_remove": (_call("anchor_remove"), {ANCHORS}),
    "anchors_clear": (_call("anchors_clear"), {ANCHORS}),
    "anchors_propose": (_call("anchors_propose", min_confidence=0.0, search_radius=0.5), {ANCHORS}),
    "anchor_accept": (_proposed_then("anchor_accept"), {ANCHORS}),
    "anchor_reject": (_proposed_then("anchor_reject"), {ANCHORS}),
    "curve_constraint_add": (_select_chain_then("curve_constraint_add"), {CONSTRAINTS}),
    "curve_constraints_auto": (_call("curve_constraints_auto"), {CONSTRAINTS}),
    "curve_constraint_remove": (_call("curve_constraint_remove"), {CONSTRAINTS}),
    "curve_constraints_clear": (_call("curve_constraints_clear"), {CONSTRAINTS}),
    "wrap": (_call("wrap", max_iterations=60), READOUT),
    "wrap SPRINGS coarse to fine": (_call("wrap", solver="SPRINGS", spring_resolution=2, max_iterations=60), READOUT),
    "wrap holding the X plane": (_call("wrap", hold_plane="X", max_iterations=60), READOUT),
    "wrap from edit mode": (_edit_mode("wrap", max_iterations=60), READOUT),
    "wrap live, finished": (_live_wrap(cancel=False), READOUT),
    "wrap live, cancelled": (_live_wrap(cancel=True), set()),
    "wrap_sequence": (_call("wrap_sequence", use_scene_range=False, frame_start=1, frame_end=2), READOUT),
    "export_sequence": (_sequence_then_export, set()),
    "detect_features": (_call("detect_features", scale=0.3), set()),
    "feature_lines_pair": (_call("feature_lines_pair", use_sharp=False, min_confidence=0.0), {CONSTRAINTS}),
    "fit_subdivision": (_call("fit_subdivision", rounds=2), set()),
    "select_problems": (_select_problems, SELECTION),
}
"""Every operator that can change the layout, in the ways it can be run (the mirror has its own tests; the pair
tool runs only in a 3D view: its Live re-settle is a ``WrapSession`` as the wrap's, ``test_pair_tool.py``)."""


def test_every_operator_is_covered():
    registered = {name for name in dir(bpy.ops.springwrap) if not name.startswith("_")}
    covered = {name for name in registered if any(case.startswith(name) for case in CASES)}
    assert registered - covered == {"mirror", "pair_tool"}


def changed_data(before, after):
    return sorted(name for name in before.keys() | after.keys() if before.get(name) != after.get(name))


@pytest.mark.parametrize("case", list(CASES))
def test_operator_keeps_everything_else_on_the_layout(case):
    run, changes = CASES[case]
    # The subdivision fit refuses creased layouts (its model has no creases): its layout has zero creases.
    target, layout = layout_scene(creases=case != "fit_subdivision", armatures=case == "align_armature")
    if case == "fit_subdivision":
        assert not np.any(read_creases(layout.data, "EDGE")) and not np.any(read_creases(layout.data, "POINT"))
    before = layout_data(layout)
    result = run()
    if isinstance(result, tuple):  # the case set something up first (a selection): compare from there
        before = layout_data(layout)
        result = result[1]()
    assert result == {"FINISHED"}, case
    after = layout_data(layout)
    if case == "align_armature":  # its Armature modifier is released by design
        assert "ARMATURE" in before.pop("modifiers") and "ARMATURE" not in after.pop("modifiers")
    changed = changed_data(before, after)
    assert set(changed) <= changes, f"{case} changed {sorted(set(changed) - changes)}"


# ---------------------------------------------------------------- the mirror


def _faces(mesh):
    starts = np.empty(len(mesh.polygons), dtype=np.int64)
    totals = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", totals)
    corner_vertices = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", corner_vertices)
    return [list(range(start, start + total)) for start, total in zip(starts, totals)], corner_vertices


def element_sources(layout, source, count, edge_count, face_count):
    """Each element's original after a mirror, per domain: (POINT, EDGE, FACE, CORNER) index arrays.

    Found from the vertex sources alone: a new edge stands for the original edge between its ends' sources, a
    new face for the original face on its corners' sources (winding reversed), a new corner for the corner of
    that face at its vertex's source. Original elements must be where they were.
    """
    mesh = layout.data
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edges)
    edges = edges.reshape(-1, 2)
    edge_of = {frozenset(pair): index for index, pair in enumerate(edges[:edge_count].tolist())}
    edge_source = np.array([edge_of[frozenset(source[pair].tolist())] for pair in edges])
    faces, corner_vertices = _faces(mesh)
    face_of = {frozenset(corner_vertices[corners].tolist()): index for index, corners in enumerate(faces[:face_count])}
    face_source, corner_source = np.empty(len(faces), dtype=np.int64), np.empty(len(mesh.loops), dtype=np.int64)
    for index, corners in enumerate(faces):
        sources = source[corner_vertices[corners]]
        original = face_of[frozenset(sources.tolist())]
        face_source[index] = original
        original_corners = dict(zip(corner_vertices[faces[original]].tolist(), faces[original]))
        corner_source[corners] = [original_corners[vertex] for vertex in sources.tolist()]
        if index >= face_count:
            assert _reversed_cycle(sources.tolist(), corner_vertices[faces[original]].tolist()), index
    assert np.array_equal(edge_source[:edge_count], np.arange(edge_count))
    assert np.array_equal(face_source[:face_count], np.arange(face_count))
    return {"POINT": source, "EDGE": edge_source, "FACE": face_source, "CORNER": corner_source}


OBJECT_LEVEL = ("UV maps", "vertex groups", "materials", "material slots", "colour attributes", "active attribute")
OBJECT_LEVEL += ("custom normals", "modifiers", "parent", "object custom properties", "mesh custom properties")
OBJECT_LEVEL += ("Springwrap target",)
"""The data of ``bpy_helpers.layout_data`` that are the object's or the whole mesh's: the mirror keeps them."""
NOT_COPIED = {"position", "springwrap_state", "springwrap_face", "springwrap_bary", "springwrap_rest"}
NOT_COPIED |= {"springwrap_distance", "springwrap_stretch", "springwrap_flipped"}
"""Attributes the mirror computes for the copies instead: positions reflected, the state, the rest shape reflected,
the quality read-out measured again on the whole layout."""
COPIED_AS_STORED = {"custom_normal"}
"""Stored per corner relative to the corner's own frame: the copy keeps the stored values (see the guide)."""


@pytest.mark.parametrize("wrap", [False, True], ids=["mirror only", "mirror and wrap"])
def test_mirror_keeps_the_half_and_copies_everything_onto_the_new_half(wrap):
    target, layout = layout_scene()
    mesh = layout.data
    count, edge_count, face_count, corner_count = (
        len(mesh.vertices),
        len(mesh.edges),
        len(mesh.polygons),
        len(mesh.loops),
    )
    before = layout_data(layout)
    values_before = {attribute.name: attribute_values(attribute) for attribute in mesh.attributes}
    domains = {attribute.name: attribute.domain for attribute in mesh.attributes}
    groups_before = [{item.group: item.weight for item in vertex.groups} for vertex in mesh.vertices]
    uvs_before = {layer.name: _uvs(layer) for layer in mesh.uv_layers}
    flags_before = {
        (collection, name): _read(getattr(mesh, collection), name, dtype) for collection, name, dtype in FLAGS
    }
    assert bpy.ops.springwrap.mirror(axis="X", wrap=wrap, max_iterations=60) == {"FINISHED"}
    outcome = mirror_outcome()
    assert outcome.crossing_faces.size == 0 and outcome.copies > 0
    sources = element_sources(layout, outcome.source, count, edge_count, face_count)
    after = layout_data(layout)
    # Object and mesh level: nothing changes.
    for name in OBJECT_LEVEL:
        assert after[name] == before[name], name
    assert after[CONSTRAINTS] == before[CONSTRAINTS]
    names_before = {entry for entry in before["attribute names"] if not entry[0].startswith(".uv_select")}
    names_after = {entry for entry in after["attribute names"] if not entry[0].startswith(".uv_select")}
    assert names_after == names_before
    # Every attribute: the originals keep their values, each copy has its original's.
    sizes = {"POINT": count, "EDGE": edge_count, "FACE": face_count, "CORNER": corner_count}
    topology = {".edge_verts", ".corner_vert", ".corner_edge"}
    for attribute in mesh.attributes:
        name = attribute.name
        if name in NOT_COPIED or name in topology or name.startswith(".uv_select"):
            continue
        values, old = attribute_values(attribute), values_before[name]
        domain = domains[name]
        assert _same(values[: sizes[domain]], old), f"the mirror changed '{name}' on the original half"
        if name in COPIED_AS_STORED:
            continue
        assert _same(values, old[sources[domain]]), f"the mirror's copies do not carry '{name}'"
    for collection, name, dtype in FLAGS:  # Blender 3.4 keeps these outside the attributes
        values = _read(getattr(mesh, collection), name, dtype)
        domain = {"vertices": "POINT", "edges": "EDGE", "polygons": "FACE"}[collection]
        assert np.array_equal(values, flags_before[collection, name][sources[domain]]), (collection, name)
    for name, uvs in uvs_before.items():
        assert np.array_equal(_uvs(mesh.uv_layers[name]), uvs[sources["CORNER"]]), f"UV map {name}"
    for name, domain in (("vertex creases", "POINT"), ("edge creases", "EDGE")):
        creases = read_creases(mesh, domain)
        assert np.array_equal(creases, read_creases_before(before, name)[sources[domain]]), name
    # Vertex groups: the originals keep their weights; a copy's weights go to the mirrored group where it exists.
    names = [group.name for group in layout.vertex_groups]
    flipped = {
        index: names.index(bpy.utils.flip_name(name))
        for index, name in enumerate(names)
        if bpy.utils.flip_name(name) in names
    }
    for vertex in mesh.vertices:
        weights = {item.group: item.weight for item in vertex.groups}
        original = groups_before[outcome.source[vertex.index]]
        if vertex.index < count:
            assert weights == original, f"vertex {vertex.index}'s weights changed"
        else:
            mirrored = {flipped.get(group, group): weight for group, weight in original.items()}
            assert weights == mirrored, f"copy {vertex.index} does not have its original's weights, groups mirrored"
    assert any(
        flipped.get(group, group) != group
        for vertex in mesh.vertices[count:]
        for group in [item.group for item in vertex.groups]
    )
    if not wrap:  # custom normals: the copies' are the reflections of their originals' (the wrap then moves them)
        from springwrap.blender import compat

        normals = compat.read_corner_normals(mesh).astype(np.float64)
        reflected = normals[sources["CORNER"]] * [-1.0, 1.0, 1.0]  # the layout's local x = 0 plane, no scale
        angles = np.degrees(np.arccos(np.clip((normals * reflected).sum(axis=1), -1.0, 1.0)))[corner_count:]
        on_seam = outcome.seam[corner_vertices(mesh)][corner_count:]
        assert angles[~on_seam].max() < 1.0 and angles.mean() < 0.1, (angles[~on_seam].max(), angles.mean())


FLAGS = (
    ("edges", "use_seam", bool),
    ("edges", "use_edge_sharp", bool),
    ("polygons", "use_smooth", bool),
    ("polygons", "material_index", np.int32),
    ("vertices", "select", bool),
    ("vertices", "hide", bool),
    ("edges", "select", bool),
    ("edges", "hide", bool),
    ("polygons", "select", bool),
    ("polygons", "hide", bool),
)
"""Per-element data read through the elements' own properties: (collection, property, dtype)."""


def _read(collection, name, dtype):
    values = np.empty(len(collection), dtype=dtype)
    collection.foreach_get(name, values)
    return values


def corner_vertices(mesh):
    values = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", values)
    return values


def test_a_mirror_that_fails_after_changing_the_mesh_puts_everything_back(monkeypatch):
    from springwrap.core.errors import LayoutError
    from springwrap.operators import mirror

    def failing_session(*_arguments, **_keywords):
        raise LayoutError("a wrap that fails after the mesh was mirrored")

    monkeypatch.setattr(mirror, "WrapSession", failing_session)
    target, layout = layout_scene()
    before = layout_data(layout)
    values_before = {attribute.name: attribute_values(attribute) for attribute in layout.data.attributes}
    with pytest.raises(RuntimeError, match="Mirroring failed and was undone: a wrap that fails"):
        bpy.ops.springwrap.mirror(axis="X", max_iterations=60)
    after = layout_data(layout)
    assert changed_data(before, after) == []
    values_after = {attribute.name: attribute_values(attribute) for attribute in layout.data.attributes}
    for name, values in values_before.items():  # positions and the face-point state too
        assert _same(values_after[name], values), name


def _reversed_cycle(cycle, original):
    """Whether ``cycle`` runs through the vertices of ``original`` the other way round (the copy's winding)."""
    backwards = original[::-1]
    return any(cycle == backwards[shift:] + backwards[:shift] for shift in range(len(backwards)))


def _uvs(layer):
    values = np.empty(len(layer.data) * 2, dtype=np.float32)
    layer.data.foreach_get("uv", values)
    return values.reshape(-1, 2)


def read_creases_before(before, name):
    return np.frombuffer(before[name], dtype=np.float32)


def _same(a, b):
    if a.dtype == object:
        return a.tolist() == b.tolist()
    return a.shape == b.shape and a.tobytes() == b.tobytes()


# ---------------------------------------------------------------- the command line


@pytest.mark.parametrize("wrap", [False, True], ids=["mirror only", "mirror and wrap"])
def test_the_mirror_script_keeps_the_layout_s_data(tmp_path, wrap):
    """``blender_scripts/mirror.py`` on a .blend (its own process): the same operator, the same data. With the
    wrap, the target is the same file's Target, which the layout's pointer brought along already."""
    import subprocess

    from helpers import REPOSITORY, TIMEOUT_SECONDS, script_command

    target, layout = layout_scene()
    mesh = layout.data
    count, face_count = len(mesh.vertices), len(mesh.polygons)
    before = layout_data(layout)
    values_before = {attribute.name: attribute_values(attribute) for attribute in mesh.attributes}
    path = tmp_path / "dressed.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    output = tmp_path / "mirrored.blend"
    process = subprocess.run(
        [*script_command(REPOSITORY / "blender_scripts" / "mirror.py")]
        + ["--layout", str(path), "--layout-object", "Layout", "--output-blend", str(output)]
        + (["--target", str(path), "--target-object", "Target"] if wrap else ["--no-wrap"]),
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SECONDS,
        cwd=REPOSITORY,
    )
    assert process.returncode == 0, process.stderr
    bpy.ops.wm.open_mainfile(filepath=str(output))
    layout = bpy.data.objects["Layout"]
    mesh = layout.data
    assert len(mesh.vertices) > count and len(mesh.polygons) == 2 * face_count
    after = layout_data(layout)
    for name in ("UV maps", "vertex groups", "materials", "colour attributes", "custom normals", "modifiers"):
        assert after[name] == before[name], name
    for name in ("parent", "object custom properties", "mesh custom properties", CONSTRAINTS):
        assert after[name] == before[name], name
    sizes = {"POINT": count, "FACE": face_count}
    for attribute in mesh.attributes:  # the original half's points and faces keep every value
        if attribute.domain in sizes and attribute.name in values_before.keys() - NOT_COPIED:
            values = attribute_values(attribute)[: sizes[attribute.domain]]
            assert _same(values, values_before[attribute.name]), attribute.name
