"""Every method of the benchmark run on one case (``run_baselines``): the baselines of ``baselines.py`` and the
Springwrap, armature and mirror methods (``springwrap_methods``, ``armature_methods``, ``mirror_methods``), each
given the same case and anchors, and the proposals' truth (``proposal_truth``).

The method modules import ``baselines`` for its helpers; this module, above them all, is the one that knows
every method.
"""

from __future__ import annotations

import numpy as np

from benchmarks.retarget import armature_methods, mirror_methods, springwrap_methods
from benchmarks.retarget.baselines import (
    METHODS,
    BaselineUnavailable,
    MethodRefused,
    MethodResult,
    apply_matrix,
    clear_scene,
    mesh_object,
    nricp_amberg,
    shrinkwrap,
    springwrap_snap,
    umeyama,
)
from benchmarks.retarget.metrics import Measurement

PROPOSAL_TOLERANCE_PERCENT = 1.0
"""A proposed pair is right when its target point is within this % of the truth's bounding-box diagonal of the
true point of its vertex."""


def proposal_truth(true_positions: np.ndarray, vertices: np.ndarray, locations: np.ndarray) -> dict:
    """The proposals against the truth: how many, how many (and what share) within
    :data:`PROPOSAL_TOLERANCE_PERCENT` of the diagonal of their vertex's true point, the median error in %."""
    truth = np.asarray(true_positions, dtype=np.float64)
    diagonal = float(np.linalg.norm(truth.max(axis=0) - truth.min(axis=0)))
    errors = np.linalg.norm(np.asarray(locations, dtype=np.float64) - truth[np.asarray(vertices)], axis=1)
    percent = 100.0 * errors / diagonal
    right = int(np.count_nonzero(percent <= PROPOSAL_TOLERANCE_PERCENT))
    count = int(percent.shape[0])
    return {
        "count": count,
        "right": right,
        "share_right": right / count if count else float("nan"),
        "median_error_percent": float(np.median(percent)) if count else float("nan"),
    }


def run_baselines(
    case, anchor_count: int, methods: tuple[str, ...] = METHODS, wrap_max_iterations: int | None = None
) -> list[MethodResult]:
    """Run ``methods`` on a case (the Blender scene is cleared first), with its first ``anchor_count`` landmarks.

    ``wrap_max_iterations`` caps the wrap methods' iterations (None: the operator's default)."""
    marks = case.landmarks(anchor_count)
    anchors = case.true_positions[marks.vertices]
    with Measurement() as alignment_time:
        alignment = umeyama(case.layout_vertices[marks.vertices], anchors)
        aligned = apply_matrix(alignment, case.layout_vertices)
    clear_scene()
    target_object = mesh_object("Target", case.target_vertices, case.target_triangles)
    results = []
    for method in methods:
        result = MethodResult(method, "ok")
        try:
            with Measurement() as measured:
                if method == "aligned template":
                    result.positions = aligned
                elif method == "Shrinkwrap nearest":
                    result.positions = shrinkwrap(aligned, case.layout_quads, target_object, "NEAREST_SURFACEPOINT")
                elif method == "Shrinkwrap project":
                    result.positions = shrinkwrap(aligned, case.layout_quads, target_object, "PROJECT")
                elif method == "trimesh nricp_amberg":
                    result.positions, result.notes = nricp_amberg(
                        aligned, case.layout_quads, case.target_vertices, marks.vertices, anchors
                    )
                elif method == "Springwrap snap":
                    result.positions, result.notes = springwrap_snap(aligned, case.layout_quads, target_object)
                elif method in springwrap_methods.WRAP_METHODS:
                    proposals = [] if method in springwrap_methods.PROPOSE_METHODS else None
                    result.positions, result.notes, report = springwrap_methods.springwrap_wrap(
                        aligned,
                        case.layout_quads,
                        target_object,
                        marks.vertices,
                        anchors,
                        start=springwrap_methods.WRAP_METHODS[method],
                        max_iterations=wrap_max_iterations,
                        wrap_options=springwrap_methods.WRAP_OPTIONS.get(method),
                        proposals=proposals,
                    )
                    result.details = report.as_dict()
                    if proposals:
                        result.details["proposals"] = proposal_truth(case.true_positions, *proposals[0])
                elif method in springwrap_methods.ALIGN_METHODS:
                    result.positions, result.notes = springwrap_methods.springwrap_align(
                        case.layout_vertices, case.layout_quads, target_object, marks.vertices, anchors
                    )
                    if method == "Springwrap align+wrap":
                        result.positions, notes, report = springwrap_methods.springwrap_wrap(
                            result.positions,
                            case.layout_quads,
                            target_object,
                            marks.vertices,
                            anchors,
                            max_iterations=wrap_max_iterations,
                        )
                        result.notes += notes
                        result.details = report.as_dict()
                elif method in armature_methods.ARMATURE_METHODS:
                    result.positions, result.notes, result.details = armature_methods.springwrap_armature(
                        case,
                        target_object,
                        marks.vertices,
                        anchors,
                        wrap=method == "Springwrap armature+wrap",
                        max_iterations=wrap_max_iterations,
                    )
                elif method in mirror_methods.MIRROR_METHODS:
                    result.positions, result.notes, result.details = mirror_methods.springwrap_wrap_mirror(
                        case,
                        aligned,
                        target_object,
                        marks.vertices,
                        anchors,
                        max_iterations=wrap_max_iterations,
                    )
                else:
                    raise BaselineUnavailable(f"unknown method {method!r}")
        except BaselineUnavailable as error:
            result.status = f"skipped: {error}"
        except MethodRefused as error:
            result.status = f"refused: {error}"
        except Exception as error:  # noqa: BLE001 - one failing method must not stop the others
            result.status = f"failed: {type(error).__name__}: {error}"
        result.seconds = alignment_time.seconds if method == "aligned template" else measured.seconds
        result.peak_megabytes = measured.peak_megabytes
        results.append(result)
    return results
