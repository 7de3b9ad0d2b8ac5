"""The GUI lane's script, run inside a real Blender *with its interface* (``tests/gui/run_gui_lane.py`` starts it):

    blender --factory-startup --enable-event-simulate --python tests/gui/gui_workflow.py -- \
        --package dist/springwrap-X-legacy.zip --output out/gui [--hide-numpy]

It installs the legacy zip the way a user does (Install Add-on, then enable it), builds the demo scene
(``blender_scripts/demo.py``: a displaced, holed Suzanne and Suzanne's quads as the layout), opens the
sidebar's Springwrap tab, and runs the workflow through the panel's operators with ``INVOKE_DEFAULT`` in
the 3D view (undo steps pushed as the buttons do): detach, the cage display, automatic anchors, the
live wrap (its wall time against its solver time measured), undo and redo (the layout compared bit
for bit), a long live wrap cancelled with a simulated Esc (the layout must be back exactly),
feature detection (one curve object per kind), then the anchor list on a layout of 160 801 vertices at the
sidebar's default width (5- and 6-digit vertices, symmetric pairs, a missing vertex; a click on a row selects and
centres its vertex), then the pair tool on the body (``gui_pair_tool.py``). Each step is a ``bpy.app.timers`` callback, so that
Blender redraws in between as it does for a user; a screenshot of each step goes to the output folder.

With ``--hide-numpy`` it plays Debian's Blender without python3-numpy instead: numpy cannot be imported,
enabling the add-on must not fail, and the Preferences and the panel must say what to install.

It writes ``result.json`` (every step's outcome and the measurements) and quits; the runner checks it
and the console. Nothing here asserts on pixels: the screenshots are for people (and the user guide).
"""

import argparse
import importlib.abc
import json
import sys
import time
import traceback
from pathlib import Path

import bpy

import addon_utils
from mathutils import Vector

REPOSITORY = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPOSITORY / "blender_scripts"))
sys.path.insert(0, str(REPOSITORY))
sys.path.insert(0, str(REPOSITORY / "tests" / "gui"))

STEP_SECONDS = 0.3
"""Pause between steps (the interface redraws in between)."""
ANCHOR_SPACING = 0.3
"""The demo's anchor spacing (``demo.WRAP_ANCHOR_SPACING``)."""
MIN_SOLVER_SHARE = 0.5
"""The live wrap of the demo layout must spend at least this share of its wall time solving."""
SEVERAL_FRAMES_WRAP = {"spring_resolution": 8, "tolerance": 1e-9, "max_iterations": 6000}
"""A live wrap of several frames (the demo layout's quads cut 8 x 8: about 5 s of solving on 2 quiet cores, where
a first frame solves up to about 1 s under the software-drawn viewport), run to the end: its share of solving is
reported."""
LONG_WRAP = {"spring_resolution": 8, "tolerance": 1e-9, "max_iterations": 50_000}
"""A live wrap long enough to be cancelled mid-way on any machine (the quads cut 8 x 8: about 5 s of solving)."""
LIST_GRID = 400
"""Subdivisions of the anchor list step's grid layout (a little more than 100 000 vertices)."""
ANCHOR_LIST_CROP = 620
"""Top of the sidebar kept in the anchor list's screenshots (the Springwrap, Place and Anchors panels)."""
TAB_TRIES = 8
"""Mouse-wheel steps over the sidebar's tabs before giving up finding the Springwrap tab."""


def parse_arguments() -> argparse.Namespace:
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="gui_workflow.py")
    parser.add_argument("--package", type=Path, required=True, help="the legacy add-on zip to install")
    parser.add_argument("--output", type=Path, required=True, help="folder of result.json and the screenshots")
    parser.add_argument("--hide-numpy", action="store_true", help="play a Blender without numpy")
    parser.add_argument("--body", type=Path, help="the body and scan for the pair tool's steps (body.npz)")
    parser.add_argument("--pair-tool-only", action="store_true", help="only the pair tool's steps (to work on them)")
    return parser.parse_args(argv)


class HideNumpy(importlib.abc.MetaPathFinder):
    """numpy cannot be imported (Debian's Blender without python3-numpy)."""

    def find_spec(self, name, path=None, target=None):
        if name == "numpy" or name.startswith("numpy."):
            raise ModuleNotFoundError(f"No module named '{name}'", name=name)
        return None


# ---------------------------------------------------------------- the window


class Window:
    """The first window, its 3D view and the regions the steps use."""

    def __init__(self):
        self.window = bpy.context.window_manager.windows[0]
        self.area = next(area for area in self.window.screen.areas if area.type == "VIEW_3D")
        self.space = self.area.spaces.active

    def region(self, kind: str):
        return next(region for region in self.area.regions if region.type == kind)

    def override(self):
        """The context of a button press in the 3D view's sidebar."""
        return bpy.context.temp_override(window=self.window, area=self.area, region=self.region("UI"))

    def call(self, operator, *args, **kwargs):
        """``operator('INVOKE_DEFAULT', True, ...)`` in the 3D view: as a button does, with an undo step."""
        with self.override():
            return operator("INVOKE_DEFAULT", True, *args, **kwargs)

    def redraw(self) -> None:
        """Draw the window now, every area (a button press redraws the sidebar; a timer's call does not)."""
        for area in self.window.screen.areas:
            area.tag_redraw()
        with bpy.context.temp_override(window=self.window, area=self.area):
            bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)

    def screenshot(self, path: Path) -> None:
        """The window as it is now, redrawn first."""
        self.redraw()
        with bpy.context.temp_override(window=self.window, area=self.area):
            bpy.ops.screen.screenshot(filepath=str(path))

    def simulate(self, kind: str, value: str, region=None, **modifiers) -> None:
        region = region or self.region("WINDOW")
        x, y = region.x + region.width // 2, region.y + region.height // 2
        self.window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=x, y=y)
        self.window.event_simulate(type=kind, value=value, x=x, y=y, **modifiers)


def crop(path: Path, rectangle: tuple[int, int, int, int], output: Path, halve: bool = False) -> None:
    """Save the ``(x, y, width, height)`` part of a window screenshot (window coordinates, from the bottom left,
    as Blender's regions and images count), at half size with ``halve`` (2 x 2 pixels averaged)."""
    import numpy as np

    x, y, width, height = rectangle
    image = bpy.data.images.load(str(path))
    pixels = np.empty(image.size[0] * image.size[1] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    part = pixels.reshape(image.size[1], image.size[0], 4)[y : y + height, x : x + width]
    if halve:
        height, width = height // 2, width // 2
        part = part[: 2 * height, : 2 * width].reshape(height, 2, width, 2, 4).mean(axis=(1, 3))
    cropped = bpy.data.images.new(output.stem, width, height)
    cropped.pixels.foreach_set(np.ascontiguousarray(part, dtype=np.float32).reshape(-1))
    cropped.filepath_raw = str(output)
    cropped.file_format = "PNG"
    cropped.save()
    bpy.data.images.remove(cropped)
    bpy.data.images.remove(image)


# ---------------------------------------------------------------- the layout, read independently


def layout_snapshot(layout) -> dict:
    """Positions and every Springwrap attribute of the layout mesh, as bytes (object mode)."""
    import numpy as np

    mesh = layout.data
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    snapshot = {"co": positions.tobytes()}
    fields = {"INT": "value", "FLOAT": "value", "FLOAT_VECTOR": "vector", "FLOAT2": "vector", "BOOLEAN": "value"}
    for attribute in mesh.attributes:
        if attribute.name.startswith("springwrap_"):
            field = fields[attribute.data_type]
            width = 3 if attribute.data_type == "FLOAT_VECTOR" else 2 if attribute.data_type == "FLOAT2" else 1
            dtype = (
                np.int32 if attribute.data_type == "INT" else bool if attribute.data_type == "BOOLEAN" else np.float32
            )
            values = np.empty(len(attribute.data) * width, dtype=dtype)
            attribute.data.foreach_get(field, values)
            snapshot[attribute.name] = values.tobytes()
    return snapshot


def point_counts(layout) -> tuple[int, int]:
    """(face-points, space-points) from the state attribute."""
    import numpy as np

    attribute = layout.data.attributes.get("springwrap_state")
    if attribute is None:
        return 0, len(layout.data.vertices)
    states = np.empty(len(attribute.data), dtype=np.int32)
    attribute.data.foreach_get("value", states)
    return int((states == 1).sum()), int((states == 0).sum())


# ---------------------------------------------------------------- the steps


def wrap_timings(outcome: set, wrapped, seconds_until_seen: float) -> dict:
    """What a step records of a live wrap: how it returned, its iterations and frames, its seconds and how
    much of them were solving, and the seconds until its end was seen."""
    return {
        "outcome": sorted(outcome),
        "iterations": wrapped.iterations,
        "frames": wrapped.frames,
        "wrap_seconds": round(wrapped.seconds, 4),
        "solver_seconds": round(wrapped.kernel_seconds, 4),
        "solver_share": round(wrapped.kernel_seconds / wrapped.seconds, 3),
        "seconds_until_seen": round(seconds_until_seen, 3),
    }


class Workflow:
    """The steps, run one per timer call; each returns the seconds until the next one, or None when done."""

    def __init__(self, arguments):
        self.output = arguments.output
        self.package = arguments.package
        self.hide_numpy = arguments.hide_numpy
        self.body = arguments.body
        self.pair_tool_only = arguments.pair_tool_only
        self.result = {"steps": [], "failures": [], "screenshots": [], "blender": bpy.app.version_string}
        self.ui = Window()
        self.tab_drawn = 0.0
        self.steps = self.missing_numpy_steps() if self.hide_numpy else self.workflow_steps()
        self.started = time.perf_counter()

    # --- bookkeeping

    def check(self, condition: bool, message: str) -> None:
        if not condition:
            raise AssertionError(message)

    def shot(self, name: str, view: bool = False, sidebar_height: int | None = None) -> None:
        """A screenshot of the window, the sidebar cropped from it (its top ``sidebar_height`` pixels when given),
        and with ``view`` the 3D view at half size."""
        path = self.output / f"{name}.png"
        self.ui.screenshot(path)
        self.result["screenshots"].append(path.name)
        sidebar = self.ui.region("UI")
        height = min(sidebar_height or sidebar.height, sidebar.height)
        crops = {"sidebar": ((sidebar.x, sidebar.y + sidebar.height - height, sidebar.width, height), False)}
        if view:
            crops["view"] = ((self.ui.area.x, self.ui.area.y, self.ui.area.width, self.ui.area.height), True)
        for suffix, (rectangle, halve) in crops.items():
            cropped = self.output / f"{name}-{suffix}.png"
            crop(path, rectangle, cropped, halve)
            self.result["screenshots"].append(cropped.name)

    def run(self):
        """The timer: the next step (a generator yields the seconds to wait), its failure recorded."""
        try:
            wait = next(self.steps)
            return wait
        except StopIteration:
            self.finish()
            return None
        except Exception:  # noqa: BLE001 - record it, stop, let the runner fail
            self.result["failures"].append(traceback.format_exc())
            self.finish()
            return None

    def finish(self) -> None:
        self.result["seconds"] = time.perf_counter() - self.started
        (self.output / "result.json").write_text(json.dumps(self.result, indent=2))
        print(f"gui_workflow: {len(self.result['steps'])} steps, {len(self.result['failures'])} failures")
        bpy.app.timers.register(lambda: bpy.ops.wm.quit_blender() and None, first_interval=0.2)

    def step(self, name: str, **details) -> None:
        self.result["steps"].append({"name": name, **details})
        print(f"gui_workflow: {name} {json.dumps(details)}")

    # --- common

    def install(self) -> None:
        """Install the legacy zip and enable it, as Preferences > Add-ons > Install does."""
        result = bpy.ops.preferences.addon_install(filepath=str(self.package))
        self.check(result == {"FINISHED"}, f"addon_install: {result}")
        addon_utils.modules_refresh()
        result = bpy.ops.preferences.addon_enable(module="springwrap")
        self.check(result == {"FINISHED"}, f"addon_enable: {result}")
        module = sys.modules["springwrap"]
        scripts = Path(bpy.utils.user_resource("SCRIPTS")).resolve()
        self.check(scripts in Path(module.__file__).resolve().parents, f"{module.__file__} is not in {scripts}")
        self.step("install", module=module.__file__)

    def open_tab(self):
        """Open the sidebar and wheel over its tabs until the Springwrap tab shows (a probe panel there draws)."""
        workflow = self

        class SPRINGWRAP_PT_gui_probe(bpy.types.Panel):
            bl_space_type, bl_region_type, bl_category, bl_label = "VIEW_3D", "UI", "Springwrap", "GUI probe"
            bl_options = {"HIDE_HEADER"}

            def draw(self, context):
                workflow.tab_drawn = time.perf_counter()

        bpy.utils.register_class(SPRINGWRAP_PT_gui_probe)
        self.ui.space.show_region_ui = True
        yield STEP_SECONDS
        for _ in range(TAB_TRIES):
            asked = time.perf_counter()
            yield STEP_SECONDS
            if self.tab_drawn > asked:
                break
            sidebar = self.ui.region("UI")
            x, y = sidebar.x + sidebar.width - 8, sidebar.y + sidebar.height // 2  # over the tabs
            self.ui.window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=x, y=y)
            self.ui.window.event_simulate(type="WHEELDOWNMOUSE", value="PRESS", x=x, y=y)
        self.check(self.tab_drawn > 0.0, "the Springwrap tab never showed")
        bpy.utils.unregister_class(SPRINGWRAP_PT_gui_probe)
        self.step("open_tab", sidebar_width=self.ui.region("UI").width)
        yield STEP_SECONDS

    # --- the workflow

    def workflow_steps(self):
        import demo

        self.install()
        if self.pair_tool_only:
            yield from self.open_tab()
            yield from self.pair_tool_steps()
            return
        wrap_session = sys.modules["springwrap.blender.wrap_session"]
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
        target, _hole, _cut = demo.build_target()
        layout = demo.build_layout(target)
        demo.attach_and_activate(layout, target)
        with bpy.context.temp_override(window=self.ui.window, area=self.ui.area, region=self.ui.region("WINDOW")):
            bpy.ops.view3d.view_selected()
        yield from self.open_tab()
        self.shot("01-target")

        self.check(self.ui.call(bpy.ops.springwrap.detach) == {"FINISHED"}, "detach")
        self.check(point_counts(layout) == (0, len(layout.data.vertices)), "detach: all space-points")
        yield STEP_SECONDS

        layout.springwrap.show_cage = True  # the panel's Show Cage checkbox
        self.check(layout.show_in_front and layout.display_type == "WIRE", "the cage: In Front and Wire")
        yield STEP_SECONDS

        result = self.ui.call(bpy.ops.springwrap.anchors_auto, spacing=ANCHOR_SPACING)
        self.check(result == {"FINISHED"} and len(layout.springwrap.anchors) > 10, f"anchors_auto: {result}")
        self.step("anchors", count=len(layout.springwrap.anchors))
        yield STEP_SECONDS
        self.shot("02-anchors")

        # The live wrap of the demo layout, as the Wrap button runs it.
        before = layout_snapshot(layout)
        start = time.perf_counter()
        outcome = self.ui.call(bpy.ops.springwrap.wrap)
        returned = time.perf_counter() - start
        self.check(outcome in ({"FINISHED"}, {"RUNNING_MODAL"}), f"wrap: {outcome}")
        while wrap_session.running_session(layout) is not None:
            yield 0.05
        wall = time.perf_counter() - start
        wrapped = wrap_session.last_result(layout)
        self.check(wrapped is not None and wrapped.converged, f"the wrap did not converge: {wrapped}")
        share = wrapped.kernel_seconds / wrapped.seconds
        self.step(
            "wrap",
            **wrap_timings(outcome, wrapped, wall),
            invoke_seconds=round(returned, 3),
            face_points=wrapped.face_points,
        )
        self.check(
            share >= MIN_SOLVER_SHARE,
            f"the live wrap spent {share:.1%} of its {wrapped.seconds:.2f} s solving (at least 50 % expected)",
        )
        after = layout_snapshot(layout)
        self.check(after != before, "the wrap changed nothing")
        yield STEP_SECONDS
        self.shot("03-wrapped", view=True)

        # Undo and redo, as Ctrl+Z and Shift+Ctrl+Z.
        with self.ui.override():
            bpy.ops.ed.undo()
        yield STEP_SECONDS
        layout = bpy.data.objects["Layout"]  # undo replaced the data blocks
        self.check(layout_snapshot(layout) == before, "undo did not bring the layout back bit for bit")
        with self.ui.override():
            bpy.ops.ed.redo()
        yield STEP_SECONDS
        layout = bpy.data.objects["Layout"]
        self.check(layout_snapshot(layout) == after, "redo did not bring the wrap back bit for bit")
        self.step("undo_redo")

        # A live wrap of several frames, to the end: how much of its time was solving.
        start = time.perf_counter()
        outcome = self.ui.call(bpy.ops.springwrap.wrap, **SEVERAL_FRAMES_WRAP)
        self.check(outcome in ({"FINISHED"}, {"RUNNING_MODAL"}), f"wrap: {outcome}")
        while wrap_session.running_session(layout) is not None:
            yield 0.05
        several = wrap_session.last_result(layout)
        self.check(several is not None and several is not wrapped, "the wrap of several frames left no result")
        self.check(several.frames > 1, f"the wrap of several frames ran in {several.frames}")
        self.step("live_wrap", **wrap_timings(outcome, several, time.perf_counter() - start))
        yield STEP_SECONDS

        # A long live wrap, cancelled with Esc after it has written a few frames.
        before = layout_snapshot(layout)
        outcome = self.ui.call(bpy.ops.springwrap.wrap, **LONG_WRAP)
        self.check(outcome == {"RUNNING_MODAL"}, f"the long wrap did not go modal: {outcome}")
        session = wrap_session.running_session(layout)
        self.check(session is not None, "no live wrap in progress")
        while session.frames < 2:  # the first frame (in invoke) and one of the modal's
            yield 0.05
        self.check(layout_snapshot(layout) != before, "the live wrap's frames are not written")
        self.shot("04-live-wrap")
        frames = session.frames
        self.ui.simulate("ESC", "PRESS")
        self.ui.simulate("ESC", "RELEASE")
        waited = time.perf_counter()
        while wrap_session.running_session(layout) is not None:
            self.check(time.perf_counter() - waited < 30.0, "Esc did not end the live wrap")
            yield 0.05
        self.check(layout_snapshot(layout) == before, "Esc did not restore the layout bit for bit")
        self.step(
            "escape",
            frames=frames,
            iterations=session.total_iterations,
            live_seconds=round(time.perf_counter() - session.start_time, 3),
            solver_seconds=round(session.kernel_seconds, 3),
            display_seconds=round(session.pacer.display_seconds or 0.0, 3),
            answered_seconds=round(time.perf_counter() - waited, 3),
            worker_stop_seconds=round(session.stop_seconds, 3),  # of which stopping the solve
        )
        yield STEP_SECONDS

        # The quality read-out's heat-map, drawn by the add-on's overlay in this 3D view for each kind: the draw
        # callback fills the heat-map's cache (proof it ran) and never gives up.
        heatmap = sys.modules["springwrap.ui.heatmap"]
        self.check(heatmap.is_installed(), "the heat-map's draw handlers are not installed")
        self.check("springwrap_distance" in layout.data.attributes, "the wrap wrote no quality read-out")
        drawn = {}
        for kind in ("DISTANCE", "STRETCH", "FLIPPED"):
            layout.springwrap.heatmap_kind = kind
            layout.springwrap.show_heatmap = True
            heatmap._cache.update(key=None, batch=None, scale=None)
            self.ui.redraw()
            yield STEP_SECONDS
            self.check(not heatmap._failed, f"the heat-map gave up drawing {kind} (see the console)")
            key, scale = heatmap._cache["key"], heatmap._cache["scale"]
            self.check(key is not None and key[-1] == kind and scale is not None, f"the heat-map did not draw {kind}")
            drawn[kind] = scale.title
            if kind == "STRETCH":
                self.shot("05-heatmap", view=True)
        layout.springwrap.show_heatmap = False
        self.step("heatmap", drawn=drawn)
        yield STEP_SECONDS

        # Features: one curve object per kind, named after the target; a second run replaces them.
        bpy.context.view_layer.objects.active = layout
        for _ in range(2):
            self.check(self.ui.call(bpy.ops.springwrap.detect_features) == {"FINISHED"}, "detect_features")
            yield STEP_SECONDS
        features = bpy.data.collections["Springwrap Features"].objects
        names = sorted(obj.name for obj in features)
        self.check(names and set(names) <= {"Target Ridges", "Target Valleys"}, f"feature objects: {names}")
        self.step("features", objects=names, splines=[len(obj.data.splines) for obj in features])
        bpy.context.view_layer.objects.active = layout
        yield STEP_SECONDS
        self.shot("06-check")

        layout.springwrap.show_cage = False
        self.check(not layout.show_in_front and layout.display_type == "TEXTURED", "the cage: display not restored")
        self.step("cage_off")
        yield STEP_SECONDS

        yield from self.follow_steps(layout, target)
        yield from self.anchor_list_steps(target)
        yield from self.pair_tool_steps()

    def anchor_list_steps(self, target):
        """The anchor list on a layout of more than 100 000 vertices at the sidebar's default width: 5- and
        6-digit vertices, symmetric pairs, a vertex on the plane, a missing vertex; then a click on a row (the
        active anchor set from the sidebar, as the list's row does) selects the vertex and centres the view on it,
        in Object and Edit Mode, and an anchor operator's new active anchor moves nothing."""
        import numpy as np

        started = time.perf_counter()
        in_view = {"window": self.ui.window, "area": self.ui.area, "region": self.ui.region("WINDOW")}
        with bpy.context.temp_override(**in_view):
            bpy.ops.mesh.primitive_grid_add(x_subdivisions=LIST_GRID, y_subdivisions=LIST_GRID, size=2.0)
        big = bpy.context.active_object
        big.name = "Big Layout"
        big.location = target.location
        count = len(big.data.vertices)
        self.check(count > 100_000, f"the big layout has {count} vertices")
        big.springwrap.target = target
        rows = [(123456, 123789), (123789, 123456), (52960, 52960), (5296, -1), (count - 1, -1), (count + 7, -1)]
        bpy.context.view_layer.update()
        for vertex, twin in rows:
            item = big.springwrap.anchors.add()
            item.vertex_index, item.twin_vertex, item.target_kind = vertex, twin, "SPACE"
            if vertex < count:
                item.location = big.matrix_world @ big.data.vertices[vertex].co + Vector((0.0, 0.0, 0.0312))
            if vertex == count - 1:  # every vertex there
                yield STEP_SECONDS
                self.shot("07-anchor-list", sidebar_height=ANCHOR_LIST_CROP)
                anchor_focus = sys.modules["springwrap.ui.anchor_focus"]
                anchor_focus.set_hovered_anchor(big, 2)  # the pair tool's mouse over pair 3: the others dimmed
                yield STEP_SECONDS
                self.shot("08-anchor-list-hovered", sidebar_height=ANCHOR_LIST_CROP)
                anchor_focus.set_hovered_anchor(big, anchor_focus.NO_ANCHOR)
        big.springwrap.anchors.move(len(rows) - 1, 0)  # the missing vertex first: in view
        yield STEP_SECONDS
        self.shot("09-anchor-list-missing", sidebar_height=ANCHOR_LIST_CROP)

        region_3d = self.ui.space.region_3d
        clicked = {}
        for mode, index in (("OBJECT", 1), ("EDIT", 4)):
            if mode == "EDIT":
                with bpy.context.temp_override(**in_view):
                    bpy.ops.object.mode_set(mode="EDIT")
            with self.ui.override():
                big.springwrap.active_anchor_index = index  # what a click on the row does
            yield STEP_SECONDS
            vertex = big.springwrap.anchors[index].vertex_index
            world = big.matrix_world @ big.data.vertices[vertex].co
            centred = (Vector(region_3d.view_location) - world).length
            self.check(centred < 1e-5, f"{mode}: the view is not centred on vertex {vertex} ({centred})")
            if mode == "EDIT":
                with bpy.context.temp_override(**in_view):
                    bpy.ops.object.mode_set(mode="OBJECT")  # the selection is written into the mesh
            selection = np.empty(count, dtype=bool)
            big.data.vertices.foreach_get("select", selection)
            selected = np.flatnonzero(selection).tolist()
            self.check(selected == [vertex], f"{mode}: row {index} selected {selected[:5]}, not [{vertex}]")
            clicked[mode] = vertex
        view = Vector(region_3d.view_location)
        with self.ui.override():
            big.springwrap.active_anchor_index = 0
            added = bpy.ops.springwrap.anchor_add(vertex_index=7, location=(0.0, 0.0, 0.0), use_location=True)
        self.check(added == {"FINISHED"}, f"anchor_add: {added}")
        yield STEP_SECONDS
        self.check(Vector(region_3d.view_location) == view, "the view moved on an anchor operator")
        system = bpy.context.preferences.system
        self.step(
            "anchor_list",
            vertices=count,
            clicked=clicked,
            sidebar_width=self.ui.region("UI").width,
            ui_scale=round(system.ui_scale, 3),
            pixel_size=system.pixel_size,
            seconds=round(time.perf_counter() - started, 1),
        )

    def follow_steps(self, layout, target):
        """Follow on, then part of the target moved as an edit would: the layout re-settles by itself (the add-on's
        timer), there and nowhere else; Follow shows in the 3D view's header."""
        import numpy as np

        indicator = sys.modules["springwrap.ui.follow_indicator"]
        self.check(indicator.draw_header in bpy.types.VIEW3D_HT_header._dyn_ui_initialize(), "no Follow in the header")
        bpy.context.view_layer.objects.active = layout
        layout.springwrap.follow = True  # the panel's Follow toggle (its update measures the layout)
        self.ui.redraw()
        yield STEP_SECONDS
        self.shot("07-follow", view=True)

        def world(obj, evaluated=False):
            """World positions of ``obj``'s vertices (``evaluated``: its modifiers applied)."""
            source = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()) if evaluated else obj
            data = source.to_mesh() if evaluated else obj.data
            points = np.empty(len(data.vertices) * 3)
            data.vertices.foreach_get("co", points)
            if evaluated:
                source.to_mesh_clear()
            matrix = np.array(obj.matrix_world)
            return points.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]

        before = world(layout)
        mesh = target.data
        rest = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", rest)
        local = rest.reshape(-1, 3)
        low, high = local.min(axis=0), local.max(axis=0)
        cap = local[:, 2] > high[2] - 0.15 * (high[2] - low[2])  # the top of the target (its own z), pushed up
        moved = local.copy()
        moved[cap, 2] += 0.05 * (high[2] - low[2])
        target_before = world(target, evaluated=True)  # the surface the layout follows: modifiers applied
        mesh.vertices.foreach_set("co", moved.ravel())
        mesh.update()
        target_after = world(target, evaluated=True)
        size = float(np.linalg.norm(target_after.max(axis=0) - target_after.min(axis=0)))
        started = time.perf_counter()
        while np.array_equal(world(layout), before):
            self.check(time.perf_counter() - started < 30.0, "the layout did not follow the edit within 30 s")
            yield 0.1
        yield STEP_SECONDS
        after = world(layout)
        shift = np.linalg.norm(after - before, axis=1)
        where = np.linalg.norm(target_after - target_before, axis=1) > 1e-6  # where the surface moved
        changed = np.concatenate([target_before[where], target_after[where]])[::5]
        near = np.array([np.linalg.norm(changed - point, axis=1).min() for point in before])
        far = near > 0.2 * size  # beyond the change and the rings the layout eases in by
        self.check(far.sum() > 10, f"only {far.sum()} layout vertices far from the edit")
        self.check(float(shift[far].max()) < 1e-6, f"vertices far from the edit moved {shift[far].max():.3g}")
        self.check(float(shift.max()) > 0.005 * size, "the layout did not re-settle where the target moved")
        self.step(
            "follow",
            moved=int((shift > 1e-6).sum()),
            far=int(far.sum()),
            far_max=float(shift[far].max()),
            seconds=round(time.perf_counter() - started, 3),
        )
        layout.springwrap.follow = False
        mesh.vertices.foreach_set("co", rest)  # put the target back (Follow is off: the layout stays)
        mesh.update()
        yield STEP_SECONDS

    def pair_tool_steps(self):
        import gui_pair_tool

        self.check(self.body is not None and self.body.is_file(), f"no body for the pair tool at {self.body}")
        yield from gui_pair_tool.PairToolSteps(self, self.body).steps()

    def missing_numpy_steps(self):
        sys.modules.pop("numpy", None)
        sys.meta_path.insert(0, HideNumpy())
        self.install()
        module = sys.modules["springwrap"]
        self.check(hasattr(bpy.types, "SPRINGWRAP_PT_missing"), "no message panel without numpy")
        self.check(not hasattr(bpy.types, "SPRINGWRAP_OT_wrap"), "operators registered without numpy")
        lines = module.missing_dependency_lines(ModuleNotFoundError("No module named 'numpy'", name="numpy"))
        self.check(module.NUMPY_FIX in " ".join(lines), f"the message does not say how to fix it: {lines}")
        self.step("missing_numpy", lines=lines)
        bpy.ops.mesh.primitive_cube_add()
        yield from self.open_tab()
        sys.meta_path[:] = [finder for finder in sys.meta_path if not isinstance(finder, HideNumpy)]  # to crop
        self.shot("06-missing-numpy", sidebar_height=240)


def main() -> None:
    arguments = parse_arguments()
    arguments.output.mkdir(parents=True, exist_ok=True)
    bpy.context.preferences.view.show_splash = False

    def start():  # once the window is up
        bpy.app.timers.register(Workflow(arguments).run, first_interval=STEP_SECONDS)

    bpy.app.timers.register(start, first_interval=1.0)


main()
