"""``springwrap.feature_lines_pair``: the layout's feature lines paired with the target's features as curve
constraints.

The layout's feature lines are the edges the artist marked (sharp edges, seams, a vertex group, a boolean edge
attribute) and, on its rest shape, its creases (dihedral angle) and open borders; the target's features are its
sharp creases (its own edges, exact), the creases a re-tessellation rounded (where the planes of their flanks meet,
on the surface: ``core.rounded_creases``), ridges and valleys (Detect Features at the automatic scale for the layout's
edge length: crests known to within their scale) and the borders of its holes. Each line is paired with a feature
close to it under the current fit, parallel, of its kind and about as long, unless it already lies within the
feature's accuracy; the pair becomes a curve constraint (source Feature Pair, with its confidence) that the next wrap follows.
With Junctions, the corners where the layout's lines end are matched with those where the target's sharp or
rounded creases end, and a line between two matched corners follows its feature between them, shared out by its rest length.
Placement Anchors puts each vertex of a paired line where a smooth map through the anchors and the matched corners
takes its rest point, projected onto the feature.
Lines without a partner stay free and are listed in the report. Everything is computed first and written only
when it succeeded; a bad input (a marked line that crosses itself, an empty group) changes nothing.
"""

import time

import bpy

from .. import property_kinds as props
from ..blender import anchors as anchor_data
from ..blender import curves as curve_data
from ..blender import feature_lines as line_data
from ..blender.target import check_target, read_target
from ..core import anchors, curves, feature_lines, line_placement, openings
from .base import LayoutCollectionOperator

PLACEMENT_ITEMS = (
    (
        "MAPPED",
        "Anchors",
        "Each vertex where a smooth map through the anchors (and the matched corners) takes its rest point, "
        "projected onto the feature: the anchors, not the fit's sliding, decide where along it each vertex lies",
    ),
    ("SPACED", "As Spaced", "Each vertex at the fraction of the line's length it has when the wrap starts"),
)
"""Pair Feature Lines' placements of a line's vertices along its feature."""


class SPRINGWRAP_OT_feature_lines_pair(LayoutCollectionOperator, bpy.types.Operator):
    """Pair the layout's feature lines (marked edges, creases, open borders) with the target's ridges, valleys and hole borders nearby, as curve constraints"""

    bl_label = "Pair Feature Lines"

    collection = "curve_constraints"
    active_index = "active_curve_constraint_index"

    use_sharp: props.flag("Sharp Edges", "The layout's edges marked sharp are feature lines", True)
    use_seams: props.flag("Seams", "The layout's edges marked as seams are feature lines", False)
    vertex_group: props.text(
        "Vertex Group", "Edges both of whose vertices are in this layout vertex group are feature lines; empty: none"
    )
    edge_attribute: props.text(
        "Edge Attribute", "Edges whose boolean edge attribute of this name is set are feature lines; empty: none"
    )
    crease_angle: props.number(
        "Crease Angle",
        "Edges of the layout's rest shape whose two faces' normals differ by more than this (degrees) are "
        "creases, feature lines too; the target's sharp creases and the creases a re-tessellation rounded "
        "(flanks meeting at more than this) are features to pair with; 0: no creases",
        30.0,
        min=0.0,
        max=180.0,
    )
    use_borders: props.flag("Open Borders", "The layout's open borders (rims of holes) are feature lines", True)
    use_openings: props.flag(
        "Openings",
        "The layout's closed slits (lips that meet: a closed edge loop whose halves touch) are paired with the rim "
        "of the opening the target has there (an open mouth), found by casting rays across the slit",
        True,
    )
    feature_scale: props.distance(
        "Feature Scale",
        "Scale at which the target's ridges and valleys are detected (see Detect Features); 0 = automatic, from "
        "the layout's median edge length",
    )
    max_distance: props.distance(
        "Max Distance",
        "Farthest a line may lie from its feature (mean, under the current fit); 0 = "
        f"{feature_lines.DISTANCE_EDGES:g} median layout edge lengths",
    )
    max_angle: props.number(
        "Max Angle", "Largest angle (degrees) between a line and its feature", 30.0, min=0.0, max=90.0
    )
    min_confidence: props.number(
        "Min Confidence",
        "Pairs less sure than this (closeness x parallelism x length agreement, 0 to 1) are not made",
        0.5,
        min=0.0,
        max=1.0,
        subtype="FACTOR",
    )
    use_junctions: props.flag(
        "Junctions",
        "Match the corners where the layout's creases meet with the target's (mutual nearest, within the max "
        "distance) and share out each crease between two matched corners by the layout's rest spacing, so that "
        "the corners, not the fit's sliding, decide where along a crease each vertex lies",
        True,
    )
    placement: props.choice(
        "Placement",
        "Where along its feature each vertex of a paired line goes",
        PLACEMENT_ITEMS,
        "MAPPED",
    )
    replace: props.flag(
        "Replace", "Remove the feature pairs made before (other curve constraints stay) before pairing again", True
    )

    def run(self, context, layout):
        start = time.perf_counter()
        depsgraph = context.evaluated_depsgraph_get()
        lines_read = line_data.read_layout_lines(
            layout, self.use_sharp, self.use_seams, self.vertex_group, self.edge_attribute
        )
        lines = feature_lines.find_lines(
            lines_read.rest,
            lines_read.face_corners,
            lines_read.face_sizes,
            lines_read.marked,
            self.crease_angle,
            self.use_borders,
        )
        existing = curve_data.read_curve_constraints(layout)
        if self.replace:
            existing = [item for item in existing if item.source_kind != curves.FEATURE_LINE]
        median_edge = line_data.median_layout_edge(lines_read)
        distance = self.max_distance or feature_lines.automatic_distance(median_edge)
        found_curves, target_junctions, scale = line_data.read_target_features(
            depsgraph, check_target(layout), median_edge, self.crease_angle, scale=self.feature_scale
        )
        anchor_list = anchor_data.read_anchors(layout)
        anchored = anchors.anchored_mask(anchor_list, lines_read.current.shape[0])
        junctions = {}
        if self.use_junctions:
            junctions = feature_lines.match_junctions(
                feature_lines.line_junctions(lines), lines_read.current, target_junctions, distance
            )
        rest = feature_lines.cornered_rest(
            lines_read.rest, lines_read.face_corners, lines_read.face_sizes, junctions, self.crease_angle
        )
        maps = []
        if self.placement == "MAPPED":
            kept = anchors.valid_vertex_mask(anchor_list, lines_read.current.shape[0]) & ~anchor_list.proposed
            maps = line_placement.placement_maps(
                rest, anchor_list.vertex_indices[kept], anchor_list.locations[kept], junctions
            )
        pairing = feature_lines.pair_lines(
            lines,
            lines_read.current,
            found_curves,
            anchored,
            existing,
            distance,
            rest=rest,
            junctions=junctions,
            maps=maps,
            max_angle=self.max_angle,
            min_confidence=self.min_confidence,
        )
        opened = []
        if self.use_openings:
            opened = self.pair_openings(
                depsgraph, layout, lines_read, existing + pairing.constraints, anchored, pairing.mapping
            )
        curve_data.write_curve_constraints(
            layout, existing + pairing.constraints + [item for pair in opened for item in pair.constraints], -1
        )
        line_data.remember_free(
            layout.name,
            [(feature_lines.line_label(line), feature_lines.FREE_REASONS[reason]) for line, reason in pairing.free],
        )
        level, text = feature_lines.pairing_report(len(lines), pairing)
        if opened:
            level = "INFO"
            text += "; " + openings.report_text(opened)
        text += f"; {len(junctions)} corners matched, {pairing.between_junctions} pairs between two"
        if pairing.mapping is not None:
            shape = "quadratic" if pairing.mapping.degree == 2 else "affine"
            text += f", placed by a map through {pairing.mapping.centres.shape[0]} anchors and corners ({shape})"
        text += (
            f"; {len(found_curves)} target features at scale {scale:.4g}, max distance {distance:.4g} "
            f"({time.perf_counter() - start:.2f} s)"
        )
        return [({level}, text)]

    @staticmethod
    def pair_openings(depsgraph, layout, lines_read, held_constraints, anchored, mapping) -> list:
        """The layout's slits paired with the target's openings (``core.openings.OpeningPair`` each), those
        whose vertices another constraint holds left out; ``mapping``: see ``core.openings.pair_slit``."""
        slits = openings.layout_slits(lines_read.rest, lines_read.face_corners, lines_read.face_sizes)
        if not slits:
            return []
        mesh = read_target(depsgraph, layout).mesh
        held = curves.constrained_vertices(held_constraints, anchored)
        found = []
        if mapping is not None and mapping.centres.shape[0] < line_placement.MIN_MAP_POINTS:
            mapping = None  # too coarse to place a lip along its rim: as the fit spaces it
        for slit, direction in slits:
            pair = openings.pair_slit(mesh, slit, lines_read.rest, lines_read.current, direction, mapping)
            if pair is not None and not held & set(slit.loop.tolist()):
                found.append(pair)
        return found


classes = (SPRINGWRAP_OT_feature_lines_pair,)
