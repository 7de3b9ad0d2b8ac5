"""Feature detection on a target mesh (paper, section 3.2 and Figure 9): ``springwrap.detect_features``.

The kernel fits the principal curvatures over a scale (by default chosen from the target and, run from a layout,
the layout's median edge length), classifies each vertex as flat, convex, concave or saddle, and traces ridge and
valley curves (the centre-lines of blends), joined where they continue each other and extended along their crease
to where it ends. The operator
writes the regions as a point colour attribute and the curves as one poly-curve object per kind (``<target>
Ridges``, ``<target> Valleys``, a spline per curve, replaced by a new run), which the curve-constraint
operators take as target curves (the spline nearest the chain). It computes everything first and writes only
when that succeeded: a target with no curvature (a plane) is reported and the scene is left as it
was.
"""

import contextlib
import time

import bpy

import numpy as np

from .. import property_kinds as props
from ..blender import features as feature_data
from ..blender.edit_mode import object_mode
from ..core.errors import ERRORS
from ..core.features import feature_defaults, region_colors
from .base import SpringwrapOperator

_DEFAULTS = feature_defaults()


def scale_layout(context, source, name: str = ""):
    """The layout whose edge length sets the automatic scale: the mesh object called ``name``, else the active
    object when it is a layout whose Springwrap target is ``source``; None when there is none."""
    if name:
        obj = bpy.data.objects.get(name)
        return obj if obj is not None and obj.type == "MESH" else None
    obj = context.active_object
    if obj is not None and obj.type == "MESH" and obj != source and obj.springwrap.target == source:
        return obj
    return None


def feature_object(context, name: str = ""):
    """The object to detect features on: the one called ``name``, else the active object's Springwrap
    target when it has one, else the active object. None when there is no such mesh."""
    if name:
        obj = bpy.data.objects.get(name)
    else:
        obj = context.active_object
        if obj is not None and obj.type == "MESH" and obj.springwrap.target is not None:
            obj = obj.springwrap.target
    return obj if obj is not None and obj.type == "MESH" else None


class SPRINGWRAP_OT_detect_features(SpringwrapOperator, bpy.types.Operator):
    """Colour the target's concave, convex and flat regions and trace its ridge and valley curves (blend centre-lines) for curve constraints"""

    bl_label = "Detect Features"

    object_name: props.text(
        "Object", "Mesh object to analyse; empty: the active object's Springwrap target, or the active mesh"
    )
    layout_name: props.text(
        "Layout",
        "Layout whose median edge length sets the automatic scale; empty: the active object when it "
        "is a layout of this target, else none (the scale then comes from the target alone)",
    )
    scale: props.distance(
        "Scale",
        "Radius over which the surface is fitted: bumps and noise smaller than this are ignored; for blend "
        "centre-lines about the blend radius. 0 = automatic: the layout's median edge length, or without a "
        f"layout {_DEFAULTS['scale_diagonal_fraction']:g} of the target's diagonal (within "
        f"{_DEFAULTS['scale_min_edges']:g} and {_DEFAULTS['scale_max_edges']:g} mean edge lengths)",
        _DEFAULTS["scale"],
    )
    flat_threshold: props.number(
        "Flat Threshold",
        "A curvature k counts as flat while |k| x scale is below this",
        _DEFAULTS["flat_threshold"],
        min=0.0,
        soft_max=1.0,
    )
    ridge_threshold: props.number(
        "Ridge Threshold",
        "k x scale a ridge or valley must reach somewhere along it to be traced",
        _DEFAULTS["ridge_threshold"],
        min=0.0,
        soft_max=2.0,
    )
    hysteresis: props.number(
        "Hysteresis",
        "Fraction of the ridge threshold a curve keeps along the rest of its length and while its ends "
        "are extended along the crease, to where the crease ends (1 = the full threshold everywhere)",
        _DEFAULTS["hysteresis"],
        min=0.0,
        max=1.0,
        subtype="FACTOR",
    )
    min_length: props.distance(
        "Min Length", f"Curves shorter than this are dropped (0 = {_DEFAULTS['min_length_scales']:g} times the scale)"
    )
    write_colors: props.flag(
        "Region Colours",
        "Write the regions as the colour attribute 'springwrap_curvature' (grey flat, red convex, "
        "blue concave, yellow saddle) and make it the active colour (Solid shading > Color > Attribute)",
        True,
    )
    write_curves: props.flag(
        "Feature Curves",
        "Write the ridge and valley curves as two curve objects, '<target> Ridges' and '<target> Valleys' "
        "(a spline per curve, replacing the previous ones), in the 'Springwrap Features' collection",
        True,
    )

    @classmethod
    def poll(cls, context):
        if feature_object(context) is None:
            cls.poll_message_set("No active mesh object (the target, or a layout with a target)")
            return False
        return True

    def execute(self, context):
        source = feature_object(context, self.object_name)
        if source is None:
            where = f"'{self.object_name}'" if self.object_name else "the active object (or its target)"
            self.report({"ERROR"}, f"No mesh object to detect features on: {where}")
            return {"CANCELLED"}
        if not (self.write_colors or self.write_curves):
            self.report({"ERROR"}, "Nothing to write: enable Region Colours or Feature Curves")
            return {"CANCELLED"}
        window_manager = context.window_manager
        show_progress = not bpy.app.background
        if show_progress:
            window_manager.progress_begin(0, 3)
        start = time.perf_counter()
        layout = scale_layout(context, source, self.layout_name)
        if self.layout_name and layout is None:
            self.report({"ERROR"}, f"No mesh object called '{self.layout_name}' to take the layout edge length from")
            return {"CANCELLED"}
        try:
            feature_mesh = feature_data.read_feature_mesh(context.evaluated_depsgraph_get(), source)
            edge_length = feature_data.layout_edge_length(layout) if layout is not None and not self.scale else 0.0
            if show_progress:
                window_manager.progress_update(1)
            settings = {
                "flat_threshold": self.flat_threshold,
                "ridge_threshold": self.ridge_threshold,
                "hysteresis": self.hysteresis,
                "layout_edge_length": edge_length,
            }
            if self.min_length > 0.0:
                settings["min_length"] = self.min_length
            features = feature_data.detect_features(feature_mesh, self.scale, **settings)
            if show_progress:
                window_manager.progress_update(2)
            colors_fit = feature_mesh.vertices.shape[0] == feature_mesh.base_vertex_count
            if self.write_colors and colors_fit:
                with object_mode(source) if source == context.active_object else contextlib.nullcontext():
                    feature_data.write_feature_colors(source, region_colors(features.regions))
            curve_objects = (
                feature_data.write_feature_curves(context, source, features.curves) if self.write_curves else []
            )
        except ERRORS as error:
            self.report({"ERROR"}, f"'{source.name}': {error}")
            return {"CANCELLED"}
        finally:
            if show_progress:
                window_manager.progress_end()
        counts = np.bincount(np.asarray(features.regions, dtype=np.int64), minlength=4)
        kinds = [curve.kind for curve in features.curves]
        if self.scale:
            chosen = "given"
        elif edge_length > 0.0:
            chosen = f"automatic, from the edges of '{layout.name}' (median {edge_length:.4g})"
        else:
            chosen = "automatic, from the target"
        self.report(
            {"INFO"},
            f"'{source.name}' at scale {features.scale:.4g} ({chosen}): {counts[0]} flat, {counts[1]} convex, "
            f"{counts[2]} concave, "
            f"{counts[3]} saddle vertices; {kinds.count('RIDGE')} ridges and {kinds.count('VALLEY')} valleys"
            + (f" in {', '.join(repr(obj.name) for obj in curve_objects)}" if curve_objects else "")
            + f" ({time.perf_counter() - start:.2f} s)",
        )
        if self.write_colors and not colors_fit:
            self.report(
                {"WARNING"},
                f"Region colours not written: the modifiers of '{source.name}' change its vertex count "
                f"({feature_mesh.base_vertex_count} -> {feature_mesh.vertices.shape[0]}); apply them to see the colours",
            )
        return {"FINISHED"}


classes = (SPRINGWRAP_OT_detect_features,)
