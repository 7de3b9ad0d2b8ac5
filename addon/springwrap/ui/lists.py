"""The lists of the sidebar's sub-panels: the layout's anchors and its curve constraints.

An anchor row is built by pure helpers (:func:`anchor_row`, :func:`widest_row`, :func:`columns`): the pair number,
the vertex, the twin and the distance, in columns as wide as the list's widest row needs, those that do not fit the
sidebar left out rather than cut (text widths estimated per character on the large side, calibrated in the GUI lane).
"""

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
    """What a row of the anchor list shows, in its order: the pair number (as the viewport numbers the pairs), the
    layout vertex, the symmetric twin (``None``: no twin) and how far the vertex is from its target point
    ("missing" when the layout has no such vertex)."""

    number: Cell
    vertex: Cell
    twin: Cell | None
    distance: Cell

    @property
    def missing(self) -> bool:
        return self.distance.icon == "ERROR"


TWIN_MARK = "\u2194"
"""Before a twin's pair number: the two anchors of a symmetric pair ("↔12")."""
MISSING = Cell("missing", "ERROR")
"""The distance cell of an anchor whose vertex the layout does not have (any more)."""


def anchor_row(index: int, vertex: int, twin_vertex: int, twin_index: int, distance: str | None) -> AnchorRow:
    """The row of the anchor at ``index`` of the list, on layout vertex ``vertex``; ``twin_vertex``: its symmetric
    twin's vertex (-1: none; ``vertex`` itself: on the symmetry plane, "mid"), the twin anchor at ``twin_index``
    (shown by its pair number; -1: not in the list, the twin's vertex is shown); ``distance``: the text of the
    vertex's distance to its target point (None: the layout has no such vertex)."""
    if twin_vertex < 0:
        twin = None
    elif twin_vertex == vertex:
        twin = Cell(f"{TWIN_MARK}mid")
    elif twin_index >= 0:
        twin = Cell(f"{TWIN_MARK}{anchor_focus.pair_number(twin_index)}")
    else:
        twin = Cell(f"{TWIN_MARK}v{twin_vertex}")
    distance_cell = MISSING if distance is None else Cell(distance)
    return AnchorRow(Cell(str(anchor_focus.pair_number(index))), Cell(f"v{vertex}"), twin, distance_cell)


def vertex_text(vertex: int, twin_vertex: int, vertex_count: int) -> str:
    """The active anchor's vertex under the list, with its twin's ("123456 ↔ 123789", "52960 ↔ mid"), or that it is
    missing: the vertex numbers whole, whatever the sidebar's width leaves for the list's columns."""
    text = str(vertex) if 0 <= vertex < vertex_count else f"{vertex} missing"
    if twin_vertex < 0:
        return text
    return f"{text} {TWIN_MARK} {'mid' if twin_vertex == vertex else twin_vertex}"


def widest_row(count: int, largest_vertex: int, twins: list[Cell], distances: list[Cell]) -> AnchorRow:
    """A row as wide as any of a list of ``count`` anchors: the largest pair number and vertex, the widest of the
    ``twins`` and ``distances`` cells the list has (no twin cell: no anchor has a twin)."""
    number, vertex = Cell(str(anchor_focus.pair_number(max(count - 1, 0)))), Cell(f"v{max(largest_vertex, 0)}")
    twin = max(twins, key=cell_width, default=None)
    return AnchorRow(number, vertex, twin, max(distances, key=cell_width, default=Cell("0 m")))


def distance_samples(distances: np.ndarray) -> np.ndarray:
    """The distances whose texts are the widest of ``distances`` (three significant digits and a unit): the largest
    of each power of ten present (a handful, whatever the list's length)."""
    distances = np.asarray(distances, dtype=np.float64)
    distances = distances[np.isfinite(distances)]
    if not distances.size:
        return distances
    decades = np.floor(np.log10(np.maximum(distances, 1e-30)))
    order = np.lexsort((distances, decades))
    last_of_decade = np.append(decades[order][1:] != decades[order][:-1], True)
    return distances[order][last_of_decade]


CHARACTER_WIDTHS = {
    **dict.fromkeys(" .,'", 3.5),
    **dict.fromkeys('ilfjt"', 4.3),
    **dict.fromkeys("cs", 6.2),
    **dict.fromkeys("mM\u2194", 10.7),
}
"""Widths of the narrow and wide characters of Blender's interface font at UI scale 1, in pixels (DejaVu Sans of
Blender 3.x, a little wider than the Inter of 4.x)."""
CHARACTER_WIDTH = 7.0
"""Width of any other character (a digit's)."""
ICON_WIDTH = 22.0
"""Width of a label's icon and the gap after it, at UI scale 1."""
LABEL_PADDING = 6.0
"""Width a label takes beyond its text and icon, at UI scale 1."""
ROW_OVERHEAD = 110.0
"""The sidebar's width less the width of a row of the anchor list, at UI scale 1: the tabs, the margins, the
list's scroll bar and the column of buttons beside it (measured in the GUI lane: a 229 px sidebar at UI scale 1.042
has rows of 115 px)."""


def cell_width(cell: Cell | None) -> float:
    """The width ``cell`` needs in a row (0 for ``None``), at UI scale 1 (an estimate on the large side)."""
    if cell is None:
        return 0.0
    characters = sum(CHARACTER_WIDTHS.get(character, CHARACTER_WIDTH) for character in cell.text)
    return characters + (ICON_WIDTH if cell.icon != "NONE" else 0.0) + LABEL_PADDING


def columns(widest: AnchorRow, width: float | None) -> list[tuple[str, float]]:
    """The columns of the list's rows and their widths (UI scale 1): those of ``widest`` that fit ``width`` whole
    (None: unlimited), never a cut one. The number and the distance always; the twin and then the vertex as room
    allows."""
    chosen = [("number", cell_width(widest.number)), ("distance", cell_width(widest.distance))]
    for name in ("twin", "vertex"):
        cell = getattr(widest, name)
        if cell is None:
            continue
        if width is None or sum(size for _name, size in chosen) + cell_width(cell) <= width:
            chosen.append((name, cell_width(cell)))
    order = ("number", "vertex", "twin", "distance")
    return sorted(chosen, key=lambda column: order.index(column[0]))


def row_cells(row: AnchorRow, shown: list[tuple[str, float]]) -> list[tuple[Cell, float]]:
    """The cells of ``row`` in the columns ``shown`` (an empty cell where the row has no twin), with their widths."""
    return [(getattr(row, name) or Cell(""), size) for name, size in shown]


class SPRINGWRAP_UL_anchors(bpy.types.UIList):
    """The layout's anchors: the pair number (as the viewport numbers the pairs), the layout vertex, the symmetric
    twin's pair number ("↔mid" on the plane) and how far the vertex is from its target point: the columns that fit
    the sidebar's width whole, the vertex and then the twin left out when the sidebar is narrow. While the pair
    tool's mouse is over an anchor, the other rows are dimmed."""

    bl_idname = "SPRINGWRAP_UL_anchors"

    def filter_items(self, context, data, propname):
        """No filtering nor sorting; measures the list's widest row, once per redraw, for :meth:`draw_item`."""
        items = getattr(data, propname)
        _widest_rows.clear()
        _widest_rows[data.id_data.name_full, len(items)] = _widest_row(context, data.id_data, items)
        return [], []

    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        obj = data.id_data
        row = _anchor_row(context, obj, data.anchors, index)
        widest = _widest_rows.get((obj.name_full, len(data.anchors))) or _widest_row(context, obj, data.anchors)
        region = getattr(context, "region", None)
        shown = columns(widest, None if region is None else region.width / _ui_scale(context) - ROW_OVERHEAD)
        line = layout.row(align=True)
        line.alert = row.missing
        line.active = anchor_focus.hovered_anchor(obj) in (anchor_focus.NO_ANCHOR, index)
        cells = row_cells(row, shown)
        for number, (cell, size) in enumerate(cells):
            box = line.row(align=True)
            if number < len(cells) - 1:  # fixed widths: the columns line up; the last takes the rest
                box.ui_units_x = size / UI_UNIT
            else:
                box.alignment = "RIGHT"
            box.label(text=cell.text, icon=cell.icon)
        if item.proposed:  # a proposed pair, not used by the wrap until accepted: marked with its confidence
            line.label(text=f"proposed {item.confidence:.2f}", icon="LIGHT")


def _ui_scale(context) -> float:
    """Pixels per pixel at UI scale 1: the interface's effective scale (the Resolution Scale preference without a
    window, as in background mode)."""
    preferences = context.preferences
    return preferences.system.ui_scale if preferences.system.ui_scale > 0.0 else max(preferences.view.ui_scale, 0.25)


UI_UNIT = 20.0
"""Pixels of one of Blender's UI units at UI scale 1 (``ui_units_x``)."""


def _anchor_row(context, obj, items, index: int) -> AnchorRow:
    """The row of the anchor at ``index`` of ``items`` (the list of ``obj``)."""
    vertex_count = len(obj.data.vertices) if obj.type == "MESH" else 0
    item = items[index]
    twin_index = -1
    if item.twin_vertex >= 0 and item.twin_vertex != item.vertex_index:
        vertices = np.empty(len(items), dtype=np.int32)
        items.foreach_get("vertex_index", vertices)
        found = np.flatnonzero(vertices == item.twin_vertex)
        twin_index = int(found[0]) if found.size else -1
    distance = None
    if 0 <= item.vertex_index < vertex_count:
        # Object-mode data (in edit mode, as of the last switch): one vertex per visible row, read as drawn.
        world = obj.matrix_world @ obj.data.vertices[item.vertex_index].co
        distance = _length_text(context, (Vector(item.location) - world).length)
    return anchor_row(index, item.vertex_index, item.twin_vertex, twin_index, distance)


def _widest_row(context, obj, items) -> AnchorRow:
    """The widest row of the list ``items`` of ``obj``: its pair numbers, vertices, twins and distances (those of
    every anchor, read at once; the distance texts of a handful of samples)."""
    count = len(items)
    vertex_count = len(obj.data.vertices) if obj.type == "MESH" else 0
    vertices, twins = np.empty(count, dtype=np.int64), np.empty(count, dtype=np.int64)
    locations = np.empty(count * 3, dtype=np.float64)
    if count:
        items.foreach_get("vertex_index", vertices)
        items.foreach_get("twin_vertex", twins)
        items.foreach_get("location", locations)
    twin_cells = [Cell(f"{TWIN_MARK}mid")] if np.any((twins >= 0) & (twins == vertices)) else []
    other = twins[(twins >= 0) & (twins != vertices)]
    in_list = np.isin(other, vertices)
    if in_list.any():
        twin_cells.append(Cell(f"{TWIN_MARK}{anchor_focus.pair_number(count - 1)}"))
    if not in_list.all():
        twin_cells.append(Cell(f"{TWIN_MARK}v{int(other[~in_list].max())}"))
    present = (vertices >= 0) & (vertices < vertex_count)
    distance_cells = [] if present.all() else [MISSING]
    if present.any():
        positions = np.empty(vertex_count * 3, dtype=np.float32)
        obj.data.vertices.foreach_get("co", positions)
        matrix = np.array(obj.matrix_world, dtype=np.float64)
        world = positions.reshape(-1, 3)[vertices[present]] @ matrix[:3, :3].T + matrix[:3, 3]
        distances = np.linalg.norm(locations.reshape(-1, 3)[present] - world, axis=1)
        distance_cells += [Cell(_length_text(context, float(value))) for value in distance_samples(distances)]
    return widest_row(count, int(vertices.max(initial=0)), twin_cells, distance_cells)


_widest_rows: dict[tuple[str, int], AnchorRow] = {}
"""The widest row of each layout's list (by name and length), found by ``filter_items`` once per redraw."""


def _length_text(context, value: float) -> str:
    """A distance in the scene's units, three significant digits ("0.0312 m", "3.12 cm", "1.2 ft")."""
    units = context.scene.unit_settings if context.scene is not None else None
    if units is None or units.system == "NONE":
        return f"{value:.3g}"
    return bpy.utils.units.to_string(
        units.system, "LENGTH", value * units.scale_length, precision=3, split_unit=units.use_separate
    )


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
        elif item.source_kind == "FEATURE_LINE":
            row.label(text=f"feature, confidence {item.confidence:.2f}", icon="SHARPCURVE")
        else:
            row.label(text=f"{len(item.points)} target vertices", icon="MESH_DATA")


classes = (SPRINGWRAP_UL_anchors, SPRINGWRAP_UL_curve_constraints)
