"""Which anchor the pair tool's mouse is over, shared by the pair tool, the viewport overlay and the anchor list.

Kept in memory only (never saved, no undo step, no depsgraph update): hovering must not write Blender data. The
pair number an artist reads is the anchor's position in ``Object.springwrap.anchors`` plus one.
"""

NO_ANCHOR = -1
"""No anchor is hovered."""

_hovered: dict[str, int] = {}


def hovered_anchor(layout) -> int:
    """Index of the anchor of ``layout`` under the pair tool's mouse, or :data:`NO_ANCHOR`."""
    return _hovered.get(layout.name, NO_ANCHOR) if layout is not None else NO_ANCHOR


def set_hovered_anchor(layout, index: int) -> bool:
    """Remember the hovered anchor of ``layout`` (:data:`NO_ANCHOR`: none); True when it changed (redraw then)."""
    before = hovered_anchor(layout)
    if index == NO_ANCHOR:
        _hovered.pop(layout.name, None)
    else:
        _hovered[layout.name] = index
    return before != index


def pair_number(index: int) -> int:
    """The number an artist reads for the anchor at ``index`` of the list (in the list and in the viewport)."""
    return index + 1


def forget() -> None:
    """Forget every hovered anchor (a file was loaded, the tool ended)."""
    _hovered.clear()
