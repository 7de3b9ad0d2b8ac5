"""The lists of the sidebar's sub-panels: the layout's anchors and its curve constraints."""

from typing import NamedTuple

import bpy

import numpy as np
from mathutils import Vector

from . import anchor_focus


class Cell(NamedTuple):
    """One label of a list row: its text and icon."""

    text: str
    icon: str = "NONE"


class AnchorRow(NamedTuple):
    """What a row of the anchor list can show, most important first: the pair number (as in the viewport), how
    far the vertex is from its target point ("missing" when the vertex is gone), its symmetric twin (the twin
    anchor's pair number, or "mid" on the plane), the layout vertex."""

    number: Cell
    distance: Cell
    twin: Cell | None
    vertex: Cell
    missing: bool


def anchor_row(
    index: int, vertex: int, twin_vertex: int, twin_index: int, distance: str | None, kind: str
) -> AnchorRow:
    """The row of the anchor at ``index`` of the list: on layout vertex ``vertex``, paired with the anchor at
    ``twin_index`` on ``twin_vertex`` (-1: no twin; ``twin_vertex == vertex``: on the symmetry plane; ``twin_index``
    -1 with a twin vertex: the twin's vertex is shown), ``distance`` the text of its vertex's distance to its target
    point (None: the vertex is gone), ``kind`` ``'FACE'`` or ``'SPACE'`` (the distance's icon)."""
    missing = distance is None
    if twin_vertex < 0:
        twin = None
    elif twin_vertex == vertex:
        twin = Cell("mid", "MOD_MIRROR")
    elif twin_index >= 0:
        twin = Cell(str(anchor_focus.pair_number(twin_index)), "MOD_MIRROR")
    else:
        twin = Cell(f"v{twin_vertex}", "MOD_MIRROR")
    return AnchorRow(
        number=Cell(str(anchor_focus.pair_number(index))),
        distance=Cell("missing", "ERROR")
        if missing
        else Cell(distance, "SNAP_FACE" if kind == "FACE" else "EMPTY_AXIS"),
        twin=twin,
        vertex=Cell(f"v{vertex}"),
        missing=missing,
    )


CHARACTER_WIDTH = 7.0
"""Width of a digit of Blender's interface font at UI scale 1, in pixels (rounded up: letters are narrower)."""
ICON_WIDTH = 20.0
"""Width of a label's icon, with its padding, at UI scale 1."""
LABEL_PADDING = 10.0
"""Space a row gives each label beyond its text and icon, at UI scale 1."""
ROW_OVERHEAD = 110.0
"""The sidebar's width less the width of the anchor list's rows' text, at UI scale 1: the tabs, the margins, the
row's own padding, the list's scroll bar and the column of buttons beside it (measured in the GUI lane)."""


def cell_width(cell: Cell) -> float:
    """The width ``cell`` needs in a row, at UI scale 1 (an estimate on the large side)."""
    return len(cell.text) * CHARACTER_WIDTH + (ICON_WIDTH if cell.icon != "NONE" else 0.0) + LABEL_PADDING


def row_cells(row: AnchorRow, width: float | None, widest: AnchorRow | None = None) -> list[Cell]:
    """The cells of ``row`` in their order (number, vertex, twin, distance) that fit ``width`` (pixels at UI scale 1;
    None: unlimited) whole, never cut: the vertex goes first, then the twin, when they do not all fit. The choice
    is made on ``widest`` (the list's widest row; default ``row``) so that every row shows the same columns."""
    widest = widest or row
    optional = [("vertex", widest.vertex), ("twin", widest.twin)]
    shown = {"vertex", "twin"}
    needed = cell_width(widest.number) + cell_width(widest.distance)
    needed += sum(cell_width(cell) for _name, cell in optional if cell is not None)
    for name, cell in optional:
        if width is None or needed <= width:
            break
        shown.discard(name)
        needed -= cell_width(cell) if cell is not None else 0.0
    cells = [row.number]
    cells += [row.vertex] if "vertex" in shown else []
    cells += [row.twin] if "twin" in shown and row.twin is not None else []
    return cells + [row.distance]


class SPRINGWRAP_UL_anchors(bpy.types.UIList):
    """The layout's anchors: the pair number (as the viewport shows it), the layout vertex, the symmetric twin's
        pair number ("mid" on the plane) and how far the vertex is from its target point (its icon: on the surface or
        in space), the columns that fit the sidebar's width whole. While the pair tool's mouse is over an anchor, the
    other rows are dimmed."""

    bl_idname = "SPRINGWRAP_UL_anchors"

    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        obj = data.id_data
        vertex_count = len(obj.data.vertices) if obj.type == "MESH" else 0
        rows = _anchor_rows(context, obj, data.anchors, vertex_count, index)
        region = getattr(context, "region", None)
        width = None if region is None else region.width / max(context.preferences.system.ui_scale, 1e-3)
        row = layout.row(align=True)
        row.alert = rows[0].missing
        hovered = anchor_focus.hovered_anchor(obj)
        row.active = hovered in (anchor_focus.NO_ANCHOR, index)  # the pair tool's mouse is over another anchor
        for cell in row_cells(rows[0], None if width is None else width - ROW_OVERHEAD, rows[1]):
            row.label(text=cell.text, icon=cell.icon)


def _anchor_rows(context, obj, items, vertex_count: int, index: int) -> tuple[AnchorRow, AnchorRow]:
    """The row of the anchor at ``index`` and the widest row the list can have (the largest pair number, vertex
    and distance text, a twin when any anchor has one)."""
    vertices, twins = np.empty(len(items), dtype=np.int32), np.empty(len(items), dtype=np.int32)
    items.foreach_get("vertex_index", vertices)
    items.foreach_get("twin_vertex", twins)
    item = items[index]
    twin_index = -1
    if item.twin_vertex >= 0 and item.twin_vertex != item.vertex_index:
        found = np.flatnonzero(vertices == item.twin_vertex)
        twin_index = int(found[0]) if found.size else -1
    distance = None
    if 0 <= item.vertex_index < vertex_count:
        # Object-mode data (in edit mode, as of the last switch): one vertex per visible row, read as drawn.
        world = obj.matrix_world @ obj.data.vertices[item.vertex_index].co
        distance = _length_text(context, (Vector(item.location) - world).length)
    row = anchor_row(index, item.vertex_index, item.twin_vertex, twin_index, distance, item.target_kind)
    last = len(items) - 1
    widest_vertex = max(int(vertices.max(initial=0)), vertex_count - 1, 0)
    has_twin = bool((twins >= 0).any())
    widest = anchor_row(last, widest_vertex, widest_vertex + 1 if has_twin else -1, last, WIDEST_DISTANCE, "FACE")
    return row, widest


def _length_text(context, value: float) -> str:
    """A distance in the scene's units, three significant digits ("0.0312 m", "3.12 cm", "1.2 ft")."""
    units = context.scene.unit_settings if context.scene is not None else None
    if units is None or units.system == "NONE":
        return f"{value:.3g}"
    return bpy.utils.units.to_string(
        units.system, "LENGTH", value * units.scale_length, precision=3, split_unit=units.use_separate
    )


WIDEST_DISTANCE = "0.000 mm"
"""As wide as a distance's text gets (three significant digits and a unit)."""


class SPRINGWRAP_UL_curve_constraints(bpy.types.UIList):
    """The layout's curve constraints: the chain's end vertices and the target curve's source"""

    bl_idname = "SPRINGWRAP_UL_curve_constraints"

    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        vertices = item.layout_vertices.split()
        chain = f"{vertices[0]}..{vertices[-1]} ({len(vertices)})" if vertices else "(empty)"
        row = layout.row(align=True)
        row.label(text=chain, icon="EDGESEL")
        if item.source_kind == "CURVE_OBJECT":
            name = item.curve_object.name if item.curve_object is not None else "(missing curve)"
            row.alert = item.curve_object is None
            row.label(text=name, icon="CURVE_DATA")
        else:
            row.label(text=f"{len(item.points)} target vertices", icon="MESH_DATA")


classes = (SPRINGWRAP_UL_anchors, SPRINGWRAP_UL_curve_constraints)
