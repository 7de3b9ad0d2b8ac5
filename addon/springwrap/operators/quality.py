"""``springwrap.select_problems``: select what the quality read-out flags, in Edit Mode, so it can be fixed.

The read-out (``blender.quality``: distance, stretch, flipped) is written by Snap, Project, Wrap and Mirror;
this operator only reads it. Flipped faces are selected in face select mode, stretched and off-surface
vertices in vertex select mode; everything else is deselected.
"""

import bpy

from .. import property_kinds as props
from ..blender import mirror as mirror_data
from ..blender import quality as quality_data
from ..blender.edit_mode import object_mode
from ..core import quality
from ..core.errors import ERRORS
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
                    self.report({"ERROR"}, quality_data.MISSING_READOUT.format(name=layout.name))
                    return {"CANCELLED"}
                values = {"FLIPPED": readout.flipped, "STRETCHED": readout.stretch, "OFF_SURFACE": readout.distances}
                mask = quality.problem_mask(self.kind, values[self.kind], self.threshold, readout.diagonal)
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
        self.report({"INFO"}, text)
        return {"FINISHED"}

    def _what(self) -> str:
        if self.kind == "FLIPPED":
            return "turned over against the rest shape"
        if self.kind == "STRETCHED":
            factor = quality.stretch_factor(self.threshold)
            return f"stretch above {factor:.3g} or below {1.0 / factor:.3g}"
        return "farther from the target than " + (
            f"{self.threshold:.4g}" if self.threshold > 0.0 else f"{100 * quality.OFF_SURFACE_FRACTION:g} % of its size"
        )


classes = (SPRINGWRAP_OT_select_problems,)
