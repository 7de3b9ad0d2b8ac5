"""``springwrap.select_problems``: select what the quality read-out flags, in Edit Mode, so it can be fixed.

The read-out (``blender.quality``: distance, stretch, flipped) is written by Snap, Project, Wrap and Mirror;
this operator only reads it. Flipped faces are selected in face select mode, stretched and off-surface
vertices in vertex select mode; everything else is deselected. Vertices whose read-out value is not a number
(an attribute edited by hand or by another tool) are selected too and reported; a read-out without a single
number is refused. The selection is framed in the 3D view (``view3d.view_selected``) when there is one.
"""

import bpy

import numpy as np

from .. import property_kinds as props
from ..blender import mirror as mirror_data
from ..blender import parts as part_data
from ..blender import quality as quality_data
from ..blender.edit_mode import object_mode
from ..core import quality
from ..core.errors import ERRORS
from ..core.wrap_inputs import POINTS_ONLY
from ..properties import PROBLEM_KIND_ITEMS
from .base import LayoutOperator, open_layout


class SPRINGWRAP_OT_select_problems(LayoutOperator, bpy.types.Operator):
    """Select the faces or vertices the quality read-out flags (flipped, stretched, off the surface) in Edit Mode"""

    bl_label = "Select Problems"

    requires_target = False

    kind: props.choice("Kind", "What to select", PROBLEM_KIND_ITEMS, "FLIPPED")
    threshold: props.number(
        "Threshold",
        "Off Surface: a distance in world units; Stretched: a factor, above it or below its inverse; "
        f"0 = the default ({100 * quality.OFF_SURFACE_FRACTION:g} % of the layout's size; "
        f"{quality.STRETCH_FACTOR:g}); Flipped: not used",
        0.0,
        min=0.0,
        soft_max=10.0,
    )

    def execute(self, context):
        layout = open_layout(self, context, require_target=False)
        if layout is None:
            return {"CANCELLED"}
        try:
            with object_mode(layout):
                readout = quality_data.read_readout(layout)
                if readout is None:
                    if not (layout.data.polygons or layout.data.edges):  # points alone: never measured
                        self.report({"ERROR"}, f"Layout '{layout.name}' has no faces and no edges: {POINTS_ONLY}")
                        return {"CANCELLED"}
                    self.report({"ERROR"}, quality_data.MISSING_READOUT.format(name=layout.name))
                    return {"CANCELLED"}
                values = {"FLIPPED": readout.flipped, "STRETCHED": readout.stretch, "OFF_SURFACE": readout.distances}
                values = np.asarray(values[self.kind])
                unmeasured = ~np.isfinite(values) if values.dtype.kind == "f" else np.zeros(values.shape, bool)
                if unmeasured.size and unmeasured.all():
                    self.report({"ERROR"}, NO_NUMBERS.format(what=self._what_values(), name=layout.name))
                    return {"CANCELLED"}
                with np.errstate(invalid="ignore"):
                    mask = quality.problem_mask(self.kind, values, self.threshold, readout.diagonal)
                mask = mask | unmeasured
                followed = part_data.read_parts(layout) if self.kind == "OFF_SURFACE" else None
                parts_left = 0 if followed is None else int((mask & followed).sum())
                if followed is not None:
                    mask &= ~followed  # a part is off the target by design (it follows the surface)
                hidden = quality_data.hidden(layout, "FACE" if self.kind == "FLIPPED" else "POINT")
                skipped = int((mask & hidden).sum())
                mask &= ~hidden  # hidden elements stay unselected, as Blender's own selection leaves them
                if self.kind == "FLIPPED":
                    mirror_data.select_faces(layout, mask.nonzero()[0])
                else:
                    quality_data.select_vertices(layout, mask)
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        if layout.mode != "EDIT":
            bpy.ops.object.mode_set(mode="EDIT")
        faces = self.kind == "FLIPPED"
        context.tool_settings.mesh_select_mode = (not faces, False, faces)
        count, total = int(mask.sum()), mask.size
        text = f"Selected {count} of {total} {'faces' if faces else 'vertices'} ({self._what()})"
        if skipped:
            text += f"; {skipped} more are hidden and were left unselected (Alt+H reveals them)"
        if parts_left:
            text += (
                f"; {parts_left} part vertices are off the target by design (they follow the surface) and not judged"
            )
        if count and frame_selected(context):
            text += "; framed in the 3D view"
        self.report({"INFO"}, text)
        missing = int((unmeasured & ~hidden).sum())
        if missing:
            self.report(
                {"WARNING"},
                f"{missing} vertices of '{layout.name}' have no {self._what_values()} in the read-out (not a number: "
                "the attribute was changed by hand or by another tool); they are selected too. Snap, Wrap or "
                "Mirror again to measure them",
            )
        return {"FINISHED"}

    def _what_values(self) -> str:
        return {"STRETCHED": "stretch", "OFF_SURFACE": "distance to the target"}.get(self.kind, "flip flag")

    def _what(self) -> str:
        if self.kind == "FLIPPED":
            return "turned over against the rest shape"
        if self.kind == "STRETCHED":
            factor = quality.stretch_factor(self.threshold)
            return f"stretch above {factor:.3g} or below {1.0 / factor:.3g}"
        return "farther from the target than " + (
            f"{self.threshold:.4g}" if self.threshold > 0.0 else f"{100 * quality.OFF_SURFACE_FRACTION:g} % of its size"
        )


NO_NUMBERS = (
    "The read-out's {what} of '{name}' is not a number anywhere (the attribute was changed by hand or by another "
    "tool): there is nothing to select by. Snap, Wrap or Mirror again to measure the layout"
)


def frame_selected(context) -> bool:
    """Frame the edit-mode selection in the first 3D view of the window (``view3d.view_selected``); False without
    one (a script in the background)."""
    screen = getattr(context, "screen", None)
    if context.window is None or screen is None:
        return False
    for area in screen.areas:
        if area.type != "VIEW_3D":
            continue
        region = next((region for region in area.regions if region.type == "WINDOW"), None)
        if region is None:
            continue
        with context.temp_override(window=context.window, area=area, region=region):
            bpy.ops.view3d.view_selected()
        return True
    return False


classes = (SPRINGWRAP_OT_select_problems,)
