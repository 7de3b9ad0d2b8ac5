"""The methods the benchmark compares, each given the same case and the same anchors.

Every method starts from the template and the anchors (landmark layout vertices and their true
positions on the target) and returns the layout's new vertex positions:

- ``aligned template``: the similarity (rotation, uniform scale, translation) that best maps the
  landmarks onto their anchors (Umeyama 1991, least squares), applied to the whole template. Not
  a retargeting method: the starting point of the next three, and a reference row;
- ``Shrinkwrap nearest``: Blender's Shrinkwrap modifier, ``NEAREST_SURFACEPOINT``, on the
  aligned template;
- ``Shrinkwrap project``: Blender's Shrinkwrap modifier, ``PROJECT`` along the layout's vertex
  normals, both directions, no distance limit (vertices whose rays miss stay where they are);
- ``Springwrap snap``: the add-on's operators on the aligned template, as a user runs them:
  ``springwrap.detach`` then ``springwrap.snap(mode='SURFACE')``;
- ``Springwrap align`` and ``align+wrap``: the template as given, aligned by the add-on's own
  ``springwrap.align`` (anchors, then ICP), then wrapped (see ``springwrap_methods``);
- ``Springwrap armature`` and ``armature+wrap``: posed cases only: the template skinned to
  MakeHuman's rig, posed onto the target's rig by ``springwrap.align_armature``, then wrapped (see
  ``armature_methods``);
- ``trimesh nricp_amberg``: non-rigid ICP (Amberg et al. 2007) from trimesh, on the aligned
  template triangulated, with the landmarks and their anchors, trimesh's default schedule. The
  target is handed over as the point cloud of its vertices (trimesh then matches with a KD-tree);
  with the triangles, its closest-point query (pure Python + an R-tree) made a run on the
  280k-triangle body targets several minutes long.

The Shrinkwrap and snap baselines use the anchors only through the alignment; nricp uses them as
landmark terms. Blender work goes through ``bpy`` (imported inside functions); the helpers that
need no Blender (:func:`umeyama`) are unit-tested without it.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from dataclasses import dataclass, field

import numpy as np


class BaselineUnavailable(RuntimeError):
    """A method cannot run this case (missing package, unsupported input); the message says why."""


class MethodRefused(RuntimeError):
    """The product refused the case: an operator reported an error and returned ``{'CANCELLED'}``.

    A measured outcome (what a user would see), not a failure of the harness; the message is the
    operator's report."""


# ---------------------------------------------------------------- alignment


def umeyama(source: np.ndarray, destination: np.ndarray, with_scale: bool = True) -> np.ndarray:
    """The 4x4 similarity ``M`` minimising ``sum |M(source_i) - destination_i|²`` (Umeyama 1991).

    ``source`` and ``destination`` are (K, 3) with K >= 3 points not all on a line. A proper
    rotation (no reflection) is returned; ``with_scale=False`` gives the rigid fit."""
    source = np.asarray(source, dtype=np.float64)
    destination = np.asarray(destination, dtype=np.float64)
    if source.shape != destination.shape or source.ndim != 2 or source.shape[1] != 3 or len(source) < 3:
        raise ValueError(f"umeyama needs two (K, 3) arrays with K >= 3, got {source.shape} and {destination.shape}")
    source_mean, destination_mean = source.mean(axis=0), destination.mean(axis=0)
    source_centred, destination_centred = source - source_mean, destination - destination_mean
    covariance = destination_centred.T @ source_centred / len(source)
    left, singular, right_transposed = np.linalg.svd(covariance)
    reflection = np.eye(3)
    if np.linalg.det(left) * np.linalg.det(right_transposed) < 0:
        reflection[2, 2] = -1.0
    rotation = left @ reflection @ right_transposed
    variance = (source_centred**2).sum() / len(source)
    if variance <= 0.0:
        raise ValueError("umeyama: the source points all coincide")
    scale = float(np.trace(np.diag(singular) @ reflection) / variance) if with_scale else 1.0
    matrix = np.eye(4)
    matrix[:3, :3] = scale * rotation
    matrix[:3, 3] = destination_mean - scale * rotation @ source_mean
    return matrix


def apply_matrix(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 affine matrix to (N, 3) points."""
    return np.asarray(points, dtype=np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def triangulate_quads(quads: np.ndarray) -> np.ndarray:
    """(2F, 3) triangles of (F, 4) quads, split along the 0-2 diagonal."""
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


# ---------------------------------------------------------------- results


@dataclass
class MethodResult:
    """What one method produced on one case."""

    method: str
    status: str  # "ok", or why it did not run ("skipped: ...", "failed: ...")
    positions: np.ndarray | None = None  # (N, 3) float64 world positions of the layout
    seconds: float = float("nan")
    peak_megabytes: float = float("nan")
    notes: list[str] = field(default_factory=list)
    details: dict = field(default_factory=dict)  # method-specific numbers (the wrap's iterations...)


# ---------------------------------------------------------------- Blender


def clear_scene() -> None:
    """Remove every object and mesh of the current Blender file (cheaper than reading a new one)."""
    import bpy

    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for mesh in list(bpy.data.meshes):
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)


def mesh_object(name: str, vertices: np.ndarray, faces: np.ndarray):
    """A new object in the scene holding a mesh of equal-size polygons ((F, k) corner indices)."""
    import bpy

    faces = np.ascontiguousarray(faces, dtype=np.int32)
    corner_count = faces.shape[1]
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    mesh.loops.add(faces.size)
    mesh.loops.foreach_set("vertex_index", faces.ravel())
    mesh.polygons.add(len(faces))
    mesh.polygons.foreach_set("loop_start", np.arange(0, faces.size, corner_count, dtype=np.int32))
    if bpy.app.version < (4, 0, 0):  # before 4.0 the corner counts are stored, not derived from loop_start
        mesh.polygons.foreach_set("loop_total", np.full(len(faces), corner_count, dtype=np.int32))
    mesh.update(calc_edges=True)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def read_positions(mesh) -> np.ndarray:
    """(N, 3) float64 vertex positions of a Blender mesh."""
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    return positions.reshape(-1, 3).astype(np.float64)


def shrinkwrap(layout_positions: np.ndarray, quads: np.ndarray, target_object, mode: str) -> np.ndarray:
    """Blender's Shrinkwrap modifier on a layout mesh: ``NEAREST_SURFACEPOINT`` or ``PROJECT`` (normals).

    The timed work, for the caller, is the modifier's evaluation (it builds Blender's BVH of the
    target) and reading the positions back."""
    import bpy

    layout = mesh_object(f"Shrinkwrap {mode}", layout_positions, quads)
    modifier = layout.modifiers.new("Shrinkwrap", "SHRINKWRAP")
    modifier.target = target_object
    modifier.wrap_method = mode
    if mode == "PROJECT":
        modifier.use_project_x = modifier.use_project_y = modifier.use_project_z = False  # along normals
        modifier.use_negative_direction = True
        modifier.use_positive_direction = True
        modifier.cull_face = "OFF"
        modifier.project_limit = 0.0
    evaluated = layout.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    try:
        return read_positions(mesh)
    finally:
        evaluated.to_mesh_clear()


@contextlib.contextmanager
def operator_reports_silenced():
    """Keep the operators' INFO reports (printed to stdout in background mode) out of the progress lines."""
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 1)
        try:
            yield
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)


def springwrap_snap(layout_positions: np.ndarray, quads: np.ndarray, target_object) -> tuple[np.ndarray, list[str]]:
    """The add-on's detach then snap (SURFACE) on a layout mesh, through its operators."""
    import bpy

    layout = mesh_object("Springwrap snap", layout_positions, quads)
    layout.springwrap.target = target_object
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    notes = []
    for step, operator, properties in (
        ("detach", bpy.ops.springwrap.detach, {"only_selected": False}),
        ("snap", bpy.ops.springwrap.snap, {"mode": "SURFACE", "only_selected": False, "max_distance": 0.0}),
    ):
        with operator_reports_silenced():
            result = operator(**properties)
        if result != {"FINISHED"}:
            raise RuntimeError(f"springwrap.{step} returned {result}")
    state = layout.data.attributes.get("springwrap_state")
    if state is not None:
        values = np.empty(len(layout.data.vertices), dtype=np.int32)
        state.data.foreach_get("value", values)
        notes.append(f"{int((values == 1).sum())} of {len(values)} vertices face-points")
    return read_positions(layout.data), notes


# ---------------------------------------------------------------- trimesh


def nricp_amberg(
    layout_positions: np.ndarray,
    quads: np.ndarray,
    target_vertices: np.ndarray,
    landmark_vertices: np.ndarray,
    anchor_positions: np.ndarray,
) -> tuple[np.ndarray, list[str]]:
    """trimesh's ``registration.nricp_amberg`` (default schedule) onto the target's vertex cloud, with landmarks."""
    try:
        import trimesh
        from trimesh import registration
    except ImportError as error:
        raise BaselineUnavailable(
            f"trimesh is not installed ({error}); `pip install -r benchmarks/requirements.txt`"
        ) from None
    source = trimesh.Trimesh(vertices=layout_positions, faces=triangulate_quads(quads), process=False)
    result = registration.nricp_amberg(
        source,
        np.asarray(target_vertices, dtype=np.float64),
        source_landmarks=np.asarray(landmark_vertices, dtype=np.int64),
        target_positions=np.asarray(anchor_positions, dtype=np.float64),
        use_faces=False,
    )
    return np.asarray(result, dtype=np.float64), [f"target as {len(target_vertices)} points (KD-tree)"]


# ---------------------------------------------------------------- all of them


METHODS = (
    "aligned template",
    "Shrinkwrap nearest",
    "Shrinkwrap project",
    "trimesh nricp_amberg",
    "Springwrap snap",
    "Springwrap wrap",
    "Springwrap wrap local",
    "Springwrap wrap global",
    "Springwrap wrap proposals",
    "Springwrap snap+wrap",
    "Springwrap project+wrap",
    "Springwrap align",
    "Springwrap align+wrap",
    "Springwrap armature",
    "Springwrap armature+wrap",
    "Springwrap wrap+mirror",
)
