"""The GUI lane's pair-tool steps (``gui_workflow.py`` runs them last): the pair tool driven with simulated mouse
events on the 13,380-vertex MakeHuman body and a scan-like target (the ``heavy`` body voxel-remeshed, prepared by
``run_gui_lane.py`` from the benchmark's data into ``body.npz``).

The references are Blender's own: ``bpy_extras.view3d_utils`` projects points to the region and casts the ray
under a pixel, ``mathutils.bvhtree`` finds what the ray hits (the layout's surface in front of a vertex, the
target's surface under the mouse). Checks: a move highlights the vertex under the mouse, two clicks make a pair on
that vertex and on the clicked surface point, a drag leaves the target end exactly on the surface (its triangle and
barycentric weights give its location), Live re-settles from a drag's first move, Ctrl+Z steps back through the re-settle and
the edit (bit for bit to before it), Esc cancels a running re-settle bit for bit, a pair dragged while the Wrap
button's live wrap runs goes to it (``gui_wrap_drag.py``), X removes the pair under the mouse, Esc leaves
the tool; redraws per second while dragging are counted.
"""

import sys
import time

import bpy

import gui_wrap_drag
import numpy as np
from bpy_extras import view3d_utils
from gui_layout_data import anchors_of, snapshot, world_of
from mathutils import Matrix, Vector
from mathutils.bvhtree import BVHTree

from benchmarks.retarget.baselines import mesh_object  # the repository is on the path (gui_workflow.py)

STEP = 0.3
"""Seconds between steps."""
MOVE = 0.05
"""Seconds after a simulated mouse move (Blender handles it and redraws)."""
ANCHORS = 6
"""Landmark anchors the body is wrapped with before the tool is used."""
TARGET_OFFSET = (40, -30)
"""Pixels from the clicked layout vertex to the clicked target point."""
SURFACE_PRECISION = 1e-5
"""Metres: how far a pair's target point may be from the mouse ray, and from its own triangle and weights' point
(float32 on a 2 m body)."""
DRAG_JUMP = 0.05
"""Metres a drag's move may take its surface point (a move's few pixels are millimetres on the torso)."""
HIT_PRECISION = 1e-4
"""Metres: how far a pair's target point may be from Blender's own hit along the mouse ray (two float32 ray casts
from a few metres away; where the ray meets the surface at a slant, their depths differ most)."""


class PairToolSteps:
    """The steps, as a generator of waits (``gui_workflow.Workflow.run`` calls it from a timer)."""

    def __init__(self, workflow, body_path):
        self.workflow, self.ui, self.body_path = workflow, workflow.ui, body_path
        self.draws = 0
        self.clicks = 0

    # --- the mouse

    @property
    def region(self):
        return self.ui.region("WINDOW")

    def pixel(self, point) -> Vector:
        """Region pixel of a world point (Blender's projection)."""
        return view3d_utils.location_3d_to_region_2d(self.region, self.ui.space.region_3d, Vector(point))

    def ray(self, pixel):
        """(origin, direction) of the view ray under a region pixel (Blender's)."""
        region, region_3d = self.region, self.ui.space.region_3d
        return (
            view3d_utils.region_2d_to_origin_3d(region, region_3d, pixel),
            view3d_utils.region_2d_to_vector_3d(region, region_3d, pixel),
        )

    def snapped(self, pixel) -> Vector:
        """``pixel`` on the whole pixel an event there reports (events have integer window coordinates)."""
        return Vector(
            (round(self.region.x + pixel[0]) - self.region.x, round(self.region.y + pixel[1]) - self.region.y)
        )

    def event(self, kind: str, value: str, pixel, **modifiers) -> None:
        x, y = int(round(self.region.x + pixel[0])), int(round(self.region.y + pixel[1]))
        self.ui.window.event_simulate(type=kind, value=value, x=x, y=y, **modifiers)

    def move(self, pixel):
        self.event("MOUSEMOVE", "NOTHING", pixel)
        yield MOVE

    def click(self, pixel, **modifiers):
        yield from self.move(pixel)
        self.event("LEFTMOUSE", "PRESS", pixel, **modifiers)
        self.event("LEFTMOUSE", "RELEASE", pixel, **modifiers)
        self.clicks += 1
        yield MOVE

    def drag(self, start, steps, step=(4.0, -3.0), pause=MOVE):
        yield from self.move(start)
        self.event("LEFTMOUSE", "PRESS", start)
        yield MOVE
        pixel = Vector(start)
        for _ in range(steps):
            pixel = self.snapped(pixel + Vector(step))
            yield from self.move_by(pixel, pause)
        self.event("LEFTMOUSE", "RELEASE", pixel)
        yield MOVE
        self.last_mouse = pixel

    def move_by(self, pixel, pause):
        self.event("MOUSEMOVE", "NOTHING", pixel)
        yield pause

    def key(self, kind: str, pixel, **modifiers):
        self.event(kind, "PRESS", pixel, **modifiers)
        self.event(kind, "RELEASE", pixel, **modifiers)
        yield STEP

    # --- the steps

    def steps(self):
        wf, check = self.workflow, self.workflow.check
        wrap_session = sys.modules["springwrap.blender.wrap_session"]
        pair_module = sys.modules["springwrap.operators.pair_tool"]
        overlays = sys.modules["springwrap.ui.overlays"]
        target_data = sys.modules["springwrap.blender.target"]

        # The body, wrapped with a few landmark anchors through the panel's operators.
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
        body = np.load(self.body_path)
        target = mesh_object("Scan", body["target_vertices"], body["target_triangles"])
        layout = mesh_object("Body", body["layout_vertices"], body["layout_quads"])
        layout.springwrap.target = target
        bpy.context.view_layer.update()
        for obj in bpy.context.view_layer.objects:
            if obj is not None:
                obj.select_set(obj == layout)
        bpy.context.view_layer.objects.active = layout
        check(self.ui.call(bpy.ops.springwrap.detach) == {"FINISHED"}, "detach the body")
        for vertex, location in zip(body["anchor_vertices"][:ANCHORS].tolist(), body["anchor_positions"].tolist()):
            result = self.ui.call(
                bpy.ops.springwrap.anchor_add, vertex_index=vertex, location=location, use_location=True
            )
            check(result == {"FINISHED"}, f"anchor_add: {result}")
        # The Wrap button's defaults: Blender remembers the properties of the workflow's earlier wraps.
        properties = bpy.ops.springwrap.wrap.get_rna_type().properties
        defaults = {
            name: properties[name].default for name in ("solver", "spring_resolution", "tolerance", "max_iterations")
        }
        outcome = self.ui.call(bpy.ops.springwrap.wrap, **defaults)
        check(outcome in ({"FINISHED"}, {"RUNNING_MODAL"}), f"wrap the body: {outcome}")
        while wrap_session.running_session(layout) is not None:
            yield 0.1
        with bpy.context.temp_override(window=self.ui.window, area=self.ui.area, region=self.region):
            bpy.ops.view3d.view_axis(type="FRONT")
            bpy.ops.view3d.view_selected()
        region_3d = self.ui.space.region_3d
        region_3d.view_distance *= 0.45  # the torso fills the view
        region_3d.view_location = Vector(world_of(layout).mean(axis=0)) + Vector((0.0, 0.0, 0.25))
        wf.step(
            "pair_tool_scene",
            layout_vertices=len(layout.data.vertices),
            target_triangles=len(body["target_triangles"]),
            anchors=len(layout.springwrap.anchors),
        )
        yield STEP

        # The toolbar's tool; the first move in the view starts it.
        with bpy.context.temp_override(window=self.ui.window, area=self.ui.area, region=self.region):
            bpy.ops.wm.tool_set_by_id(name="springwrap.pair_tool")
        vertex, vertex_pixel = self.front_vertex(layout)
        yield from self.move(vertex_pixel)
        yield STEP
        check(pair_module.running(), "the pair tool did not start on a mouse move in the view")
        hovered = overlays.tool_points(layout)[0]
        world = world_of(layout)
        check(
            hovered is not None and np.linalg.norm(np.asarray(hovered) - world[vertex]) < 1e-6,
            f"the hover does not highlight vertex {vertex} under the mouse: {hovered}",
        )
        wf.shot("07-pair-hover", view=True)

        # Two clicks: the layout vertex, then the target point.
        count = len(layout.springwrap.anchors)
        self.clicks = 0
        yield from self.click(vertex_pixel)
        target_pixel = self.snapped(vertex_pixel + Vector(TARGET_OFFSET))
        yield from self.move(target_pixel)
        hovered_target = overlays.tool_points(layout)[1]
        yield from self.click(target_pixel)
        yield STEP
        items = layout.springwrap.anchors
        check(len(items) == count + 1, f"two clicks made {len(items) - count} pairs")
        pair = len(items) - 1
        expected = self.surface_hit(target, target_pixel)
        location = np.array(items[pair].location)
        check(items[pair].vertex_index == vertex, f"the pair is on vertex {items[pair].vertex_index}, not {vertex}")
        check(
            self.under_mouse(location, expected, target_pixel),
            f"the pair's target {location} (at pixel {tuple(self.pixel(location))}) is not the clicked surface point "
            f"{expected} (at pixel {tuple(target_pixel)})",
        )
        check(
            hovered_target is not None and np.linalg.norm(np.asarray(hovered_target) - location) < SURFACE_PRECISION,
            "the hovered target point is not the one the click took",
        )
        self.check_on_surface(layout, pair, target_data)
        wf.step(
            "pair_click",
            vertex=vertex,
            clicks=self.clicks,
            off_blender_hit_m=float(np.linalg.norm(location - expected)),
        )
        wf.shot("08-pair-made", view=True)

        # A drag of the pair's target end along the surface; the redraws while dragging counted.
        handle = bpy.types.SpaceView3D.draw_handler_add(self.count_draw, (), "WINDOW", "POST_PIXEL")
        try:
            self.draws, started = 0, time.perf_counter()
            start = self.pixel(location)
            step = self.drag_on_target(target, start, (4.0, -3.0), 12, 5.0)
            yield from self.drag(start, steps=12, step=step, pause=0.0)
            seconds = time.perf_counter() - started
        finally:
            bpy.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")
        yield STEP
        dragged = np.array(items[pair].location)
        expected = self.surface_hit(target, self.last_mouse)
        check(np.linalg.norm(dragged - location) > 1e-3, "the drag did not move the target end")
        check(
            self.under_mouse(dragged, expected, self.last_mouse),
            f"the dragged end {dragged} is not the surface point under the mouse {expected}",
        )
        self.check_on_surface(layout, pair, target_data)
        check(items[pair].vertex_index == vertex, "the drag of the target end changed the layout vertex")
        wf.step(
            "pair_drag",
            moves=12,
            redraws=self.draws,
            seconds=round(seconds, 3),
            redraws_per_second=round(self.draws / seconds, 2),
        )
        wf.shot("09-pair-dragged", view=True)

        # Live: the next drag re-settles the layout, from its first move (the layout follows the drag).
        layout.springwrap.pair_live = True
        before_drag = snapshot(layout)
        start = self.pixel(dragged)
        yield from self.drag(start, steps=4, step=self.drag_on_target(target, start, (-8.0, 8.0), 4, 8.0 * 2**0.5))
        released = time.perf_counter()
        after_drag_anchors = anchors_of(layout)
        check(wrap_session.running_session(layout) is not None, "Live did not start a re-settle with the drag")
        first_frame = None
        while wrap_session.running_session(layout) is not None:
            if first_frame is None and snapshot(layout)[0] != before_drag[0]:
                first_frame = time.perf_counter() - released
            check(time.perf_counter() - released < 120.0, "the Live re-settle did not end")
            yield 0.02
        settled = time.perf_counter() - released
        result = wrap_session.last_result(layout)
        after_settle = snapshot(layout)
        check(after_settle[0] != before_drag[0], "Live did not move the layout")
        wf.step(
            "pair_live",
            first_frame_seconds=round(first_frame or settled, 3),
            settled_seconds=round(settled, 3),
            iterations=result.iterations,
            converged=result.converged,
            frames=result.frames,
        )
        wf.shot("10-pair-live", view=True)

        # Ctrl+Z: back over the re-settle (to the layout as it was at the drag's release), then over the drag, bit
        # for bit.
        mouse = self.last_mouse
        yield from self.key("Z", mouse, ctrl=True)
        layout = bpy.data.objects["Body"]
        check(anchors_of(layout) == after_drag_anchors, "Ctrl+Z undid more than the re-settle")
        yield from self.key("Z", mouse, ctrl=True)
        layout = bpy.data.objects["Body"]
        check(snapshot(layout) == before_drag, "a second Ctrl+Z did not undo the drag bit for bit")
        check(pair_module.running(), "undo ended the pair tool")
        wf.step("pair_undo")

        # Esc while a re-settle runs: the layout back bit for bit.
        layout.springwrap.pair_live = True  # the undo went back to before Live was switched on
        items = layout.springwrap.anchors
        before_drag = snapshot(layout)
        start = self.pixel(items[pair].location)
        yield from self.drag(start, steps=3, step=self.drag_on_target(target, start, (12.0, 4.0), 3, 40.0**0.5 * 2))
        edited_anchors = anchors_of(layout)
        check(wrap_session.running_session(layout) is not None, "no re-settle to cancel")
        yield from self.key("ESC", self.last_mouse)
        check(wrap_session.running_session(layout) is None, "Esc did not stop the re-settle")
        check(snapshot(layout)[:2] == before_drag[:2], "Esc did not put the layout back bit for bit")
        check(anchors_of(layout) == edited_anchors, "Esc on the re-settle undid the drag too")
        check(pair_module.running(), "the first Esc (a re-settle running) left the tool")
        wf.step("pair_escape")

        # The Wrap button's live wrap, a pair dragged while it runs, then Ctrl+Z (gui_wrap_drag.py).
        yield from gui_wrap_drag.steps(self, pair)
        layout = bpy.data.objects["Body"]

        # X over the pair removes it.
        layout.springwrap.pair_live = False
        count = len(layout.springwrap.anchors)
        end = self.pixel(layout.springwrap.anchors[pair].location)
        yield from self.move(end)
        yield from self.key("X", end)
        check(len(layout.springwrap.anchors) == count - 1, "X did not remove the pair under the mouse")
        wf.step("pair_remove", anchors=len(layout.springwrap.anchors))

        # Esc leaves the tool; the select tool is back.
        yield from self.key("ESC", end)
        check(not pair_module.running(), "Esc did not leave the pair tool")
        tool = bpy.context.workspace.tools.from_space_view3d_mode("OBJECT", create=False)
        check(tool is None or tool.idname != "springwrap.pair_tool", "the pair tool is still the active tool")
        wf.step("pair_leave")
        yield STEP

    # --- references

    def count_draw(self):
        self.draws += 1

    def front_vertex(self, layout):
        """A layout vertex near the view's centre that nothing of the layout hides, and its pixel."""
        world = world_of(layout)
        tree = BVHTree.FromPolygons([Vector(p) for p in world], [tuple(p.vertices) for p in layout.data.polygons])
        centre = Vector((self.region.width / 2, self.region.height / 2))
        pixels = [self.pixel(point) for point in world]
        order = sorted(
            (index for index, pixel in enumerate(pixels) if pixel is not None),
            key=lambda index: (pixels[index] - centre).length,
        )
        for index in order[:200]:
            origin, direction = self.ray(pixels[index])
            hit = tree.ray_cast(origin, direction)
            if hit[0] is not None and (hit[0] - Vector(world[index])).length < 1e-3:
                return index, pixels[index]
        raise AssertionError("no layout vertex in view")

    def under_mouse(self, point, hit, pixel) -> bool:
        """Whether ``point`` is on the mouse ray at ``pixel`` and at Blender's own ``hit`` on the target."""
        if hit is None:
            return False
        origin, direction = self.ray(pixel)
        offset = Vector(point) - origin
        off_ray = (offset - offset.dot(direction) * direction).length
        return off_ray < SURFACE_PRECISION and np.linalg.norm(np.asarray(point) - hit) < HIT_PRECISION

    def surface_hit(self, target, pixel, tree=None):
        """Blender's own hit of the ray under ``pixel`` on the evaluated target, or None (``tree``: the target's
        :meth:`target_tree`, built here when not given)."""
        tree = self.target_tree(target) if tree is None else tree
        origin, direction = self.ray(pixel)
        matrix = target.matrix_world
        inverse = matrix.inverted()
        hit = tree.ray_cast(inverse @ origin, (inverse.to_3x3() @ direction).normalized())
        return None if hit[0] is None else np.array(matrix @ hit[0])

    @staticmethod
    def target_tree(target) -> BVHTree:
        """Blender's own tree of the evaluated target (in its local space)."""
        depsgraph = bpy.context.evaluated_depsgraph_get()
        return BVHTree.FromObject(target.evaluated_get(depsgraph), depsgraph)

    def drag_on_target(self, target, start, preferred, moves: int, pixels: float, turn: int = 180) -> Vector:
        """A drag's step (a pixel vector of length ``pixels``) from the pixel ``start`` whose ``moves`` moves all stay
        over the target (a drag off it leaves the pair's end where it last was): ``preferred``'s direction when it
        does, else the nearest turn of it, up to ``turn`` degrees either way; one whose moves stay on one stretch of
        the surface (no move's point :data:`DRAG_JUMP` from the last, as across an outline onto the surface behind)
        first. Where the pairs sit on the screen depends on the wrap before (the pair tool's vertex is the one
        nearest the view's centre), so a fixed direction may leave the body's outline."""
        tree = self.target_tree(target)
        preferred = Vector(preferred).normalized()
        angles = sorted(range(-turn, turn + 1, 15), key=abs)
        steps = [Matrix.Rotation(np.radians(angle), 2) @ preferred * pixels for angle in angles]
        jumps = {}  # step index: the largest move of a surface point along it (None: it leaves the target)
        for index, step in enumerate(steps):
            pixel, last, largest = Vector(start), self.surface_hit(target, start, tree), 0.0
            for _ in range(moves):
                pixel = self.snapped(pixel + step)
                hit = self.surface_hit(target, pixel, tree)
                if hit is None:
                    largest = None
                    break
                largest = max(largest, np.inf if last is None else float(np.linalg.norm(hit - last)))
                last = hit
            if largest is not None and largest <= DRAG_JUMP:
                return step
            jumps[index] = largest
        on_target = [index for index, largest in jumps.items() if largest is not None]
        if on_target:
            return steps[on_target[0]]
        raise AssertionError(f"no drag of {moves} x {pixels} px from {tuple(start)} stays on the target")

    def check_on_surface(self, layout, index, target_data):
        """The pair's end is a face anchor whose triangle and weights give its location."""
        item = layout.springwrap.anchors[index]
        self.workflow.check(item.target_kind == "FACE" and item.triangle >= 0, "the pair's end is not on a face")
        mesh = target_data.read_target(bpy.context.evaluated_depsgraph_get(), layout).mesh
        surface = mesh.face_point_positions(
            np.array([item.triangle], dtype=np.uint32), np.array([item.barycentric], dtype=np.float32)
        )[0]
        self.workflow.check(
            np.linalg.norm(surface - np.array(item.location)) < SURFACE_PRECISION,
            "the pair's location is not its triangle and weights' point",
        )
