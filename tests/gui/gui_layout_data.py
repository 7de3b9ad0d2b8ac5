"""What the GUI lane's pair-tool steps read of a layout to compare it (``gui_pair_tool.py``, ``gui_wrap_drag.py``):
its world positions, and its positions, attributes and pairs as bytes."""

import numpy as np


def world_of(obj) -> np.ndarray:
    positions = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", positions)
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    return positions.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def snapshot(obj) -> tuple:
    """The layout's positions and every attribute, and its anchor list, as bytes (bit-for-bit comparisons)."""
    positions = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", positions)
    attributes = []
    for attribute in sorted(obj.data.attributes, key=lambda a: a.name):
        if attribute.domain == "POINT" and attribute.data_type in {"INT", "FLOAT", "FLOAT_VECTOR"}:
            width = 3 if attribute.data_type == "FLOAT_VECTOR" else 1
            values = np.empty(len(attribute.data) * width, dtype=np.float64)
            attribute.data.foreach_get("vector" if width == 3 else "value", values)
            attributes.append((attribute.name, values.tobytes()))
    return positions.tobytes(), tuple(attributes), anchors_of(obj)


def anchors_of(obj) -> tuple:
    return tuple(
        (item.vertex_index, item.target_kind, item.triangle, tuple(item.barycentric), tuple(item.location))
        for item in obj.springwrap.anchors
    )
