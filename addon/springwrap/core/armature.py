"""Armature alignment on plain numpy arrays (no ``bpy``): which bones pair up, where each template bone goes.

``springwrap.align_armature`` (``operators.armature``, ``blender.armature``) poses a template armature so that each of its
bones lies on the target armature's bone of the same name. Per matched bone it asks Blender for the
pose whose *armature-space* matrix is :func:`desired_pose_matrix`: the target bone's head, its
direction and (optionally) its roll, and a scale along the bone so that the template bone's tail
lands on the target's tail (:data:`SCALE_ALONG`). Bones are posed a depth level at a time
(:func:`depth_levels`), parents first, because Blender derives a pose bone's local transform from
its parent's evaluated pose.

All matrices are 4x4 float64 with the translation in the last column (Blender's convention).
"""

from typing import NamedTuple

import numpy as np

SCALE_ALONG = "ALONG"
"""Scale each template bone along its length only: its tail meets the target's tail, its girth stays."""
SCALE_UNIFORM = "UNIFORM"
"""Scale each template bone uniformly by the length ratio (thicker when longer)."""
SCALE_NONE = "NONE"
"""Never scale: only the head and the direction match (a longer target bone leaves a gap at the joint)."""
SCALE_MODES = (SCALE_ALONG, SCALE_UNIFORM, SCALE_NONE)

MIN_BONE_LENGTH = 1e-9
"""Bones shorter than this (relative to the armature's size) have no direction: they are refused."""


class BoneFrame(NamedTuple):
    """A bone as the alignment sees it, in one armature space: head, tail, and the unit z axis (its roll)."""

    head: np.ndarray  # (3,)
    tail: np.ndarray  # (3,)
    z_axis: np.ndarray  # (3,) unit, orthogonal to tail - head


def matched_bones(template_names, target_names) -> list[str]:
    """Names present in both armatures, in the template's order."""
    target = set(target_names)
    return [name for name in template_names if name in target]


def depth_levels(names, parents) -> list[list[str]]:
    """``names`` grouped by depth in the hierarchy (roots first); ``parents[i]`` is the parent of
    ``names[i]`` or "" for a root. A parent that is not among ``names`` counts as none."""
    parent_of = dict(zip(names, parents))
    depth: dict[str, int] = {}

    def depth_of(name: str) -> int:
        chain: list[str] = []
        current = name
        while current not in depth:
            parent = parent_of.get(current, "")
            if not parent or parent not in parent_of:
                depth[current] = 0
                break
            if current in chain:
                raise ValueError(f"bone parents form a cycle through {current!r}")
            chain.append(current)
            current = parent
        for child in reversed(chain):
            depth[child] = depth[parent_of[child]] + 1
        return depth[name]

    levels: dict[int, list[str]] = {}
    for name in names:
        levels.setdefault(depth_of(name), []).append(name)
    return [levels[key] for key in sorted(levels)]


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``matrix`` (4x4) applied to points (..., 3)."""
    matrix = np.asarray(matrix, dtype=np.float64)
    return np.asarray(points, dtype=np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def frame_from_matrix(pose_matrix: np.ndarray, length: float) -> BoneFrame:
    """The :class:`BoneFrame` of a bone whose pose (or rest) matrix is ``pose_matrix`` (its y axis runs
    from head to tail; its columns may be scaled) and whose tail lies ``length`` along that axis."""
    matrix = np.asarray(pose_matrix, dtype=np.float64)
    head = matrix[:3, 3].copy()
    tail = head + matrix[:3, 1] * length
    return BoneFrame(head, tail, _unit_z(tail - head, matrix[:3, 2]))


def frame_in_space(frame: BoneFrame, matrix: np.ndarray) -> BoneFrame:
    """``frame`` moved by ``matrix`` (e.g. from world into an armature's space), its z axis kept a unit
    vector orthogonal to the bone (a non-uniform ``matrix`` would skew it)."""
    head, tail, z_end = transform_points(matrix, np.stack([frame.head, frame.tail, frame.head + frame.z_axis]))
    return BoneFrame(head, tail, _unit_z(tail - head, z_end - head))


def _unit_z(direction: np.ndarray, z_guess: np.ndarray) -> np.ndarray:
    """``z_guess`` made orthogonal to ``direction`` and of unit length (any orthogonal unit vector if parallel)."""
    y_axis = direction / np.linalg.norm(direction)
    z_axis = z_guess - np.dot(z_guess, y_axis) * y_axis
    norm = np.linalg.norm(z_axis)
    if norm < 1e-12:
        helper = np.eye(3)[int(np.argmin(np.abs(y_axis)))]
        z_axis = helper - np.dot(helper, y_axis) * y_axis
        norm = np.linalg.norm(z_axis)
    return z_axis / norm


def rotation_between(source: np.ndarray, destination: np.ndarray) -> np.ndarray:
    """The smallest 3x3 rotation turning direction ``source`` onto direction ``destination``."""
    source = np.asarray(source, dtype=np.float64) / np.linalg.norm(source)
    destination = np.asarray(destination, dtype=np.float64) / np.linalg.norm(destination)
    cross = np.cross(source, destination)
    cosine = float(np.dot(source, destination))
    sine = float(np.linalg.norm(cross))
    if sine < 1e-12:
        if cosine > 0.0:
            return np.eye(3)
        # Half a turn about any axis orthogonal to source.
        helper = np.eye(3)[int(np.argmin(np.abs(source)))]
        axis = np.cross(source, helper)
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    axis = cross / sine
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + sine * skew + (1.0 - cosine) * skew @ skew


def desired_pose_matrix(
    target: BoneFrame,
    rest_matrix: np.ndarray,
    rest_length: float,
    match_roll: bool = True,
    scale_mode: str = SCALE_ALONG,
) -> np.ndarray:
    """The armature-space pose matrix that puts a template bone onto ``target`` (in the template armature's space).

    ``rest_matrix``: the template bone's rest matrix (``Bone.matrix_local``, orthonormal), ``rest_length``
    its length. The head goes to the target's head and the y axis along the target bone; with
    ``match_roll`` the z axis is the target's (the bone turns about itself as the target's does),
    otherwise the rest frame is turned by the smallest rotation from its y axis to the target's (the
    template's own roll is kept). The length ratio ``s`` = target length / ``rest_length`` scales the
    y column (:data:`SCALE_ALONG`), every column (:data:`SCALE_UNIFORM`) or nothing (:data:`SCALE_NONE`).
    """
    if scale_mode not in SCALE_MODES:
        raise ValueError(f"unknown scale mode {scale_mode!r}; known: {', '.join(SCALE_MODES)}")
    rest = np.asarray(rest_matrix, dtype=np.float64)
    direction = target.tail - target.head
    length = float(np.linalg.norm(direction))
    if length < MIN_BONE_LENGTH or rest_length < MIN_BONE_LENGTH:
        raise ValueError("a bone of zero length has no direction")
    y_axis = direction / length
    if match_roll:
        z_axis = _unit_z(direction, target.z_axis)
        rotation = np.column_stack([np.cross(y_axis, z_axis), y_axis, z_axis])
    else:
        rotation = rotation_between(rest[:3, 1], y_axis) @ rest[:3, :3]
    ratio = length / rest_length
    if scale_mode == SCALE_ALONG:
        rotation = rotation * np.array([1.0, ratio, 1.0])
    elif scale_mode == SCALE_UNIFORM:
        rotation = rotation * ratio
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = target.head
    return matrix


def bone_mismatch(posed: BoneFrame, target: BoneFrame) -> float:
    """The larger of the head and tail distances between a posed template bone and its target bone."""
    return float(max(np.linalg.norm(posed.head - target.head), np.linalg.norm(posed.tail - target.tail)))
