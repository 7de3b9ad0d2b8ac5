"""The subdivision cage fit: ``springwrap.fit_subdivision`` moves the layout so that its Catmull–Clark
subdivision, as Blender's Subdivision Surface modifier computes it, lies on the target.

Everything is computed first (``blender.cage_fit`` and ``core.cage_fit``); the layout is written only when
the fit succeeded, and any problem is reported with the layout left exactly as it was.
"""

import time

import bpy

from .. import property_kinds as props
from ..blender import cage_fit as cage_fit_data
from ..blender import last_run
from ..blender import target as target_data
from ..blender.edit_mode import object_mode
from ..core import cage_fit
from ..core.errors import ERRORS
from ..properties import max_distance_property
from .base import LayoutOperator, check_inputs, open_layout, operator_values, report_storage_precision

_DEFAULTS = cage_fit.fit_defaults()


class SPRINGWRAP_OT_fit_subdivision(LayoutOperator, bpy.types.Operator):
    """Move the layout (the cage) so that its subdivided surface, as the Subdivision Surface modifier computes it, lies on the target instead of shrinking inside it"""

    bl_label = "Fit Subdivision Surface"

    last_outcome = None
    """The last successful fit's ``core.cage_fit.CageFitOutcome`` (for scripts: the distances before and after)."""

    levels: props.integer(
        "Levels",
        "Subdivision level whose surface is fitted (use the same on the Subdivision Surface modifier)",
        cage_fit.DEFAULT_LEVELS,
        min=1,
        max=int(_DEFAULTS["max_levels"]),
    )
    rounds: props.integer(
        "Rounds",
        "Gauss-Newton rounds: each matches the subdivided surface to the target and solves for the cage",
        cage_fit.DEFAULT_ROUNDS,
        min=1,
        max=50,
    )
    boundary_smooth: props.choice(
        "Boundary Smooth",
        "The modifier's Boundary Smooth: how the corners of open borders are subdivided",
        cage_fit.BOUNDARY_ITEMS,
        "ALL",
    )
    smoothness: props.number(
        "Smoothness",
        "How strongly each round's move of the cage is kept smooth (it also carries the fit over holes)",
        float(_DEFAULTS["smoothness"]),
        min=0.0,
        soft_max=10.0,
    )
    max_distance: max_distance_property(
        "Subdivided points farther than this from the target are not pulled to it (0 = unlimited)"
    )
    only_selected: props.flag(
        "Only Selected", "Move the selected vertices only (the others are held, as anchored vertices always are)", False
    )

    def execute(self, context):
        layout = open_layout(self, context, moves_vertices=True)
        if layout is None:
            return {"CANCELLED"}
        start = time.perf_counter()
        parameters = operator_values(self, cage_fit_data.CageFitParameters, boundary="boundary_smooth")
        try:
            with object_mode(layout):
                extent = check_inputs(context, layout, frozenset({"positions", "anchors"}))
                target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
                outcome = cage_fit_data.fit_subdivision(context, layout, target, parameters)
                report_storage_precision(self, layout, extent)
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        milliseconds = (time.perf_counter() - start) * 1000.0
        type(self).last_outcome = outcome
        last_run.remember_fit(layout.name, self.levels, outcome)
        self.report({"INFO"}, cage_fit.summary(outcome, self.levels, milliseconds))
        return {"FINISHED"}


classes = (SPRINGWRAP_OT_fit_subdivision,)
