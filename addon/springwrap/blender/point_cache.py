"""The layout's sequence as a point cache other programs read: the frames of its sequence keys (``Wrap 0001``, …)
written by Blender's own Alembic or USD exporter, the layout alone, one sample of its vertex positions per frame.

Both exporters evaluate the layout at each frame (its keyed shape keys mixed) and write the positions as time
samples; imported back (File > Import, or a Mesh Sequence Cache modifier) they give the same positions frame for
frame. The selection, the active object and the scene's frame and frame range are put back as they were.
"""

from pathlib import Path

import bpy

from ..core import sequence
from ..core.errors import LayoutError

FORMATS = {"ALEMBIC": (".abc",), "USD": (".usdc", ".usd", ".usda")}
"""The point-cache formats and their file extensions (the first is added to a path without one of them)."""


def sequence_frames(layout) -> list[int]:
    """The frames of the layout's sequence keys, in order (empty when it has none)."""
    keys = layout.data.shape_keys
    if keys is None:
        return []
    names = [block.name for block in keys.key_blocks if sequence.is_sequence_key(block.name)]
    return sorted(int(name[len(sequence.KEY_PREFIX) :]) for name in names)


def cache_path(filepath: str, file_format: str) -> str:
    """``filepath`` with the format's extension (kept when it already has one of the format's)."""
    if file_format not in FORMATS:
        raise LayoutError(f"Point cache format must be one of {', '.join(FORMATS)}, not {file_format!r}")
    if not filepath:
        raise LayoutError("No file path for the point cache")
    path = Path(bpy.path.abspath(filepath))
    if path.suffix.lower() not in FORMATS[file_format]:
        path = path.with_name(path.name + FORMATS[file_format][0])
    return str(path)


def export_point_cache(context, layout, filepath: str, file_format: str) -> tuple[str, list[int]]:
    """Write the layout's sequence (every frame of its sequence keys) to ``filepath`` as ``file_format``
    (``'ALEMBIC'`` or ``'USD'``); (the path written, the frames). Raises :class:`LayoutError` when the layout has no
    sequence keys, this Blender has no such exporter, or the exporter fails; the scene is left as it was."""
    path = cache_path(filepath, file_format)
    frames = sequence_frames(layout)
    if not frames:
        raise LayoutError(f"Layout '{layout.name}' has no sequence keys to export: run Wrap Sequence first")
    if not getattr(bpy.app.build_options, "alembic" if file_format == "ALEMBIC" else "usd", False):
        raise LayoutError(f"This Blender has no {file_format.title()} exporter")
    if not layout.visible_get():
        raise LayoutError(f"Layout '{layout.name}' is hidden: the exporters write visible objects only")
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    scene, view_layer = context.scene, context.view_layer
    selected = [obj for obj in view_layer.objects if obj.select_get()]
    active = view_layer.objects.active
    frame_range = (scene.frame_start, scene.frame_end, scene.frame_current, scene.frame_subframe)
    try:
        for obj in selected:
            obj.select_set(False)
        layout.select_set(True)
        view_layer.objects.active = layout
        _set_range(scene, frames[0], frames[-1])
        if file_format == "ALEMBIC":
            outcome = bpy.ops.wm.alembic_export(
                filepath=path, start=frames[0], end=frames[-1], selected=True, as_background_job=False
            )
        else:
            outcome = bpy.ops.wm.usd_export(
                filepath=path,
                selected_objects_only=True,
                export_animation=True,
                export_shapekeys=False,  # the mixed positions, sampled per frame (not blend shapes)
                export_materials=False,
            )
    except RuntimeError as error:
        raise LayoutError(f"The {file_format.title()} export of '{layout.name}' failed: {error}") from error
    finally:
        layout.select_set(False)
        for obj in selected:
            obj.select_set(True)
        view_layer.objects.active = active
        start, end, current, subframe = frame_range
        _set_range(scene, start, end)
        scene.frame_set(current, subframe=subframe)
    if "FINISHED" not in outcome or not Path(path).is_file():
        raise LayoutError(f"The {file_format.title()} export of '{layout.name}' wrote nothing to {path}")
    return path, frames


def _set_range(scene, start: int, end: int) -> None:
    """The scene's frame range (Blender moves one end when the other passes it: set twice)."""
    for _round in range(2):
        scene.frame_start, scene.frame_end = start, end
