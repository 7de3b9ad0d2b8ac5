"""Mirroring (paper, section 3): ``springwrap.mirror`` under Blender (PyPI ``bpy``).

Targets are generated and **exactly** symmetric: half of a deformed sphere (a nose on the midline,
ears, a flattened top) is built on x >= 0 with its midline vertices at x = 0 exactly, and the other
half is its reflection (negating x is exact in floating point), triangles reversed. The layout is
the same kind of half, coarser. Everything is moved by one rotation and translation, so the mirror
plane is not a world axis plane. Results are checked against the plane in world space with numpy:
each new vertex against the reflection of the vertex it was copied from, seam vertices against the
plane, the target surface with ``mathutils`` BVHTree.
"""

import bpy

import numpy as np
import pytest
from mathutils import Matrix, Vector
from mathutils.bvhtree import BVHTree

from bpy_helpers import (
    PLACEMENT,
    activate,
    head_scene,
    local_positions,
    midline_drift,
    mirror_outcome,
    read_state,
    snapshot,
    symmetric_head_scene,
    world_plane,
    world_positions,
)

SYMMETRY_TOLERANCE = 1e-5
"""Symmetric target: every new vertex within this (world units; the layout is ~2.6 across) of its partner's mirror."""
FREE_SYMMETRY_TOLERANCE = 2e-3
"""Both halves wrapped together from a symmetric start: every new vertex within this of its partner's mirror."""


def symmetry_errors(layout, outcome):
    """(copies' distance from their partner's reflection, seam vertices' distance from the plane), world units."""
    from springwrap.core import mirroring

    positions = world_positions(layout)
    point, normal = world_plane()
    plane = mirroring.Plane(point, normal)
    partners = mirroring.partner_errors(positions, outcome.source, outcome.is_copy, plane)
    seam = np.abs(mirroring.signed_distances(positions[outcome.seam], plane))
    return partners, seam


# ---------------------------------------------------------------- mirror only


def test_mirror_only_reflects_welds_and_reverses_winding():
    target, layout = head_scene()
    layout.data.attributes.new("tag", "FLOAT", "POINT")
    tags = np.arange(len(layout.data.vertices), dtype=np.float32)
    layout.data.attributes["tag"].data.foreach_set("value", tags)
    count, face_count = len(layout.data.vertices), len(layout.data.polygons)
    assert bpy.ops.springwrap.mirror(axis="X", wrap=False) == {"FINISHED"}
    outcome = mirror_outcome()
    assert outcome.seam_vertices == 2 * 11 + 2  # the two meridians at x = 0 (11 rings each) and the poles
    assert len(layout.data.vertices) == 2 * count - outcome.seam_vertices
    assert len(layout.data.polygons) == 2 * face_count
    partners, seam = symmetry_errors(layout, outcome)
    assert partners.max() < 1e-6 and seam.max() < 1e-6
    # The layout's own vertices keep their indices and positions; attributes follow to the copies.
    assert np.array_equal(outcome.source[:count], np.arange(count))
    copied = np.empty(len(layout.data.vertices), dtype=np.float32)
    layout.data.attributes["tag"].data.foreach_get("value", copied)
    assert np.array_equal(copied, tags[outcome.source])
    # Reversed winding: every face normal (world) of a copy is the reflection of its source face's normal.
    normals = np.array([layout.matrix_world.to_3x3() @ polygon.normal for polygon in layout.data.polygons])
    point, normal = world_plane()
    reflected = normals[:face_count] - 2.0 * np.outer(normals[:face_count] @ normal, normal)
    centres = np.array([layout.matrix_world @ polygon.center for polygon in layout.data.polygons])
    mirrored_centres = centres[:face_count] - 2.0 * np.outer((centres[:face_count] - point) @ normal, normal)
    for index in range(face_count):
        partner = face_count + int(np.argmin(np.linalg.norm(centres[face_count:] - mirrored_centres[index], axis=1)))
        assert np.dot(normals[partner], reflected[index]) > 0.999
    # Copies are space-points to be wrapped.
    states = read_state(layout)[0]
    assert (states[outcome.is_copy] == 0).all()


def test_mirror_across_an_empty_uses_its_local_plane():
    target, layout = head_scene()
    layout.matrix_world = Matrix.Identity(4)  # the layout's own X plane is no longer the head's
    layout.data.transform(PLACEMENT)
    empty = bpy.data.objects.new("Mirror", None)
    empty.matrix_world = PLACEMENT @ Matrix.Diagonal((2.0, 0.5, 1.0, 1.0))  # scale does not tilt the YZ plane
    bpy.context.scene.collection.objects.link(empty)
    activate(layout)
    assert bpy.ops.springwrap.mirror(axis="X", mirror_object="Mirror", wrap=False) == {"FINISHED"}
    partners, seam = symmetry_errors(layout, mirror_outcome())
    assert partners.max() < 1e-5 and seam.max() < 1e-5


# ---------------------------------------------------------------- mirror and wrap


def test_a_snapped_half_pinned_gets_its_own_reflection():
    """A half snapped from a sphere (its shape is not the template's, its rest shape never set) and pinned:
    the new half keeps the surfaced half's shape, not the template's, so on a symmetric target it comes out
    as its reflection. Only the seam moves: the snap left it up to 1.4e-3 off the plane, the wrap walks it
    onto the cross-section, and the new half's points next to it follow where the pinned ones cannot
    (measured: 2.3e-4 ENERGY, 3.1e-4 SPRINGS, on a layout 2.6 across; with the template as the new half's
    rest shape 6.0e-2 and 2.3e-2)."""
    target, layout = head_scene()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.mirror(axis="X", seam="SLIDE", surfaced_half="PIN", max_iterations=3000) == {"FINISHED"}
    outcome = mirror_outcome()
    assert outcome.wrap is not None and outcome.wrap.converged
    partners, seam = symmetry_errors(layout, outcome)
    assert partners.max() < 5e-4, f"max asymmetry {partners.max():.3g}"
    assert np.median(partners) < 2e-5, f"median asymmetry {np.median(partners):.3g}"
    assert seam.max() < SYMMETRY_TOLERANCE, f"seam {seam.max():.3g} off the plane"


@pytest.mark.parametrize("seam_mode", ["SLIDE", "HOLD"])
@pytest.mark.parametrize("surfaced_half", ["PIN", "FREE"])
def test_mirror_and_wrap_on_a_symmetric_target_is_symmetric(seam_mode, surfaced_half):
    """PIN: the surfaced half must be what the springs want for the result to be symmetric: the half layout
    put on the target's own vertices (its grid is a subset of the target's), its rest shape set there. FREE:
    both halves are wrapped from the snapped template (a sphere: far from the head's shape) and must stay
    symmetric all the way."""
    if surfaced_half == "PIN":
        target, layout = head_scene(on_target=True)
        assert bpy.ops.springwrap.snap() == {"FINISHED"}
        assert bpy.ops.springwrap.rest_set() == {"FINISHED"}
    else:
        target, layout = head_scene()
        assert bpy.ops.springwrap.snap() == {"FINISHED"}
    start = world_positions(layout).copy()
    assert bpy.ops.springwrap.mirror(axis="X", seam=seam_mode, surfaced_half=surfaced_half, max_iterations=3000) == {
        "FINISHED"
    }
    outcome = mirror_outcome()
    assert outcome.wrap is not None and outcome.wrap.converged
    moved = np.linalg.norm(world_positions(layout)[: len(start)] - start, axis=1)
    partners, seam = symmetry_errors(layout, outcome)
    if surfaced_half == "FREE":
        assert moved.max() > 0.02  # the wrap did real work
        # Symmetric in exact arithmetic; rounding differences between the halves tip a few discrete
        # choices (a point's rocking, momentum restarts) one way on one side only. Measured: 8.6e-4
        # (SLIDE, 1,038 iterations) on a layout 2.6 across.
        assert partners.max() < FREE_SYMMETRY_TOLERANCE, f"max asymmetry {partners.max():.3g}"
    else:
        assert partners.max() < SYMMETRY_TOLERANCE, f"max asymmetry {partners.max():.3g}"
    assert seam.max() < SYMMETRY_TOLERANCE, f"seam {seam.max():.3g} off the plane"
    # All on the target: face-points, on its surface.
    states = read_state(layout)[0]
    assert (states == 1).all()
    mesh = target.data
    tree = BVHTree.FromPolygons(
        [PLACEMENT @ vertex.co for vertex in mesh.vertices], [list(polygon.vertices) for polygon in mesh.polygons]
    )
    distances = [tree.find_nearest(Vector(point))[3] for point in world_positions(layout)]
    assert max(distances) < 1e-5


def test_mirror_keeps_the_surfaced_half_where_it_is():
    target, layout = head_scene()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.6) == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(max_iterations=3000) == {"FINISHED"}
    count = len(layout.data.vertices)
    before = world_positions(layout).copy()
    anchors_before = len(layout.springwrap.anchors)
    assert bpy.ops.springwrap.mirror(axis="X", max_iterations=3000) == {"FINISHED"}
    outcome = mirror_outcome()
    after = world_positions(layout)[:count]
    off_seam = ~outcome.seam[:count]
    assert np.array_equal(after[off_seam], before[off_seam].astype(after.dtype))
    assert outcome.seam_max_distance < 1e-5
    # The anchors of the surfaced half are mirrored onto the new half (those on the seam dropped).
    assert outcome.mirrored_anchors > 0
    kept = anchors_before - outcome.dropped_anchors
    assert outcome.mirrored_anchors == kept
    assert len(layout.springwrap.anchors) == kept + outcome.mirrored_anchors


# ---------------------------------------------------------------- bad input and reports


def test_a_plane_that_misses_the_layout_is_refused_and_changes_nothing(capfd):
    target, layout = head_scene()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.6) == {"FINISHED"}
    far = bpy.data.objects.new("Far", None)
    far.location = (5.0, 0.0, 0.0)
    bpy.context.scene.collection.objects.link(far)
    activate(layout)
    before = snapshot(layout)
    faces_before = len(layout.data.polygons)
    anchors_before = [tuple(item.location) for item in layout.springwrap.anchors]
    with pytest.raises(RuntimeError, match="misses layout 'Layout'"):
        bpy.ops.springwrap.mirror(axis="X", mirror_object="Far")
    assert snapshot(layout) == before
    assert len(layout.data.polygons) == faces_before
    assert [tuple(item.location) for item in layout.springwrap.anchors] == anchors_before
    with pytest.raises(RuntimeError, match="no object named 'Nowhere'"):
        bpy.ops.springwrap.mirror(axis="X", mirror_object="Nowhere")
    assert snapshot(layout) == before


def test_a_failing_wrap_puts_the_mesh_back():
    target, layout = head_scene()
    before = snapshot(layout)
    faces_before = len(layout.data.polygons)
    with pytest.raises(RuntimeError, match="Max Iterations|tolerance|must be"):
        bpy.ops.springwrap.mirror(axis="X", tolerance=0.0)
    assert snapshot(layout) == before and len(layout.data.polygons) == faces_before


def test_faces_crossing_the_plane_are_reported_and_selected():
    # A 10 x 10 grid from x = 0 to 1; a vertex next to the midline pulled to the other side: its four faces cross.
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=11, y_subdivisions=11, size=1.0, location=(0.5, 0.5, 0.0))
    layout = bpy.context.active_object
    layout.name = "Layout"
    positions = local_positions(layout).astype(np.float64)
    columns = np.unique(positions[:, 0])
    next_to_midline = np.flatnonzero(positions[:, 0] == columns[1])
    pulled = next_to_midline[np.argsort(positions[next_to_midline, 1])[5]]
    positions[pulled, 0] = columns[0] - 0.5 * (columns[1] - columns[0])
    layout.data.vertices.foreach_set("co", positions.astype(np.float32).ravel())
    layout.data.update()
    empty = bpy.data.objects.new("Mirror", None)
    bpy.context.scene.collection.objects.link(empty)
    activate(layout)
    assert bpy.ops.springwrap.mirror(axis="X", mirror_object="Mirror", wrap=False) == {"FINISHED"}
    outcome = mirror_outcome()
    assert outcome.crossing_faces.size == 4
    selected = np.array([polygon.select for polygon in layout.data.polygons])
    assert np.array_equal(np.flatnonzero(selected), np.sort(outcome.crossing_faces))


def open_border_vertices(layout) -> int:
    """How many vertices of the layout lie on an open border (an edge of one face)."""
    import bmesh

    mesh = bmesh.new()
    try:
        mesh.from_mesh(layout.data)
        return sum(vertex.is_boundary for vertex in mesh.verts)
    finally:
        mesh.free()


def test_mirror_after_a_wrap_without_hold_welds_the_drifted_midline(capfd):
    """A half wrapped without Hold on Plane has its midline (its open border) off the plane; Mirror with its
    defaults finds it as the seam, brings it back onto the plane, re-settles the border and welds a closed head
    with the template's vertex count. The wrap says what Hold on Plane is for."""
    target, layout = head_scene()
    vertices = local_positions(target).astype(np.float64)  # the nose bent 0.1 to one side: an asymmetric head
    vertices[:, 0] += 0.1 * np.exp(-((vertices[:, 1] - 0.9) ** 2 + (vertices[:, 2] - 0.1) ** 2) / 0.2)
    target.data.vertices.foreach_set("co", vertices.astype(np.float32).ravel())
    target.data.update()
    midline = np.flatnonzero(local_positions(layout)[:, 0] == 0.0)
    count = len(layout.data.vertices)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.6) == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.springwrap.wrap(max_iterations=3000) == {"FINISHED"}
    assert f"open border lies on its X plane ({midline.size} vertices" in capfd.readouterr().out
    point, normal = world_plane()
    assert bpy.ops.springwrap.mirror(axis="X", max_iterations=3000) == {"FINISHED"}
    outcome = mirror_outcome()
    assert outcome.seam_vertices == midline.size
    assert outcome.drifted_seam > 0  # beyond their weld distance: found only as the open border
    assert len(layout.data.vertices) == 2 * count - midline.size
    assert outcome.crossing_faces.size == 0 and open_border_vertices(layout) == 0
    assert np.abs((world_positions(layout)[outcome.seam] - point) @ normal).max() < 1e-5
    assert "brought back onto it and the border re-settled" in capfd.readouterr().out


def test_mirror_on_a_layout_that_covers_both_sides_is_refused_and_changes_nothing():
    target, layout, _twins = symmetric_head_scene()
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="already covers both sides.*Delete the other half"):
        bpy.ops.springwrap.mirror(axis="X")
    assert snapshot(layout) == before and mirror_outcome() is None


def test_undo_restores_the_half_layout():
    target, layout = head_scene()
    bpy.ops.ed.undo_push(message="Before mirror")
    before = snapshot(layout)
    vertex_count = len(layout.data.vertices)
    bpy.ops.springwrap.mirror("EXEC_DEFAULT", True, axis="X", wrap=False)
    assert len(bpy.data.objects["Layout"].data.vertices) > vertex_count
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]
    assert len(layout.data.vertices) == vertex_count
    assert snapshot(layout) == before


# ---------------------------------------------------------------- a lone half, wrapped with its midline held


def test_hold_on_plane_keeps_a_lone_half_s_midline_on_the_plane_for_the_mirror():
    """A half wrapped alone has a free border where its midline is: it drifts off the plane, and the mirror
    then finds faces crossing it. Held on the plane, the midline stays there and the mirror is clean."""
    drifts = {}
    for hold in ("NONE", "X"):
        bpy.ops.wm.read_homefile(use_empty=True)
        target, layout = head_scene()
        midline = np.flatnonzero(local_positions(layout)[:, 0] == 0.0)
        assert midline.size >= 10
        assert bpy.ops.springwrap.snap() == {"FINISHED"}
        assert bpy.ops.springwrap.anchors_auto(spacing=0.6) == {"FINISHED"}
        assert bpy.ops.springwrap.wrap(max_iterations=3000, hold_plane=hold) == {"FINISHED"}
        drifts[hold] = midline_drift(layout, midline)
        if hold == "X":
            assert bpy.ops.springwrap.mirror(axis="X", max_iterations=3000) == {"FINISHED"}
            outcome = mirror_outcome()
            assert outcome.crossing_faces.size == 0
            assert outcome.seam_max_distance < 1e-5
    assert drifts["NONE"] > 1e-3, drifts  # the problem is real
    assert drifts["X"] < 1e-5, drifts


def test_hold_on_a_plane_that_misses_the_layout_is_refused_and_changes_nothing():
    target, layout = head_scene()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    bpy.ops.object.empty_add(location=(40.0, 0.0, 0.0))
    empty = bpy.context.active_object
    activate(layout)
    layout.springwrap.mirror_object = empty
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="No layout vertex lies on the hold plane"):
        bpy.ops.springwrap.wrap(hold_plane="X")
    assert snapshot(layout) == before
