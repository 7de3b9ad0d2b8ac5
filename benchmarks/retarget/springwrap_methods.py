"""Springwrap's wrap as benchmark methods, run through the add-on's operators exactly as a user runs them.

- ``Springwrap wrap``: on the aligned template, ``springwrap.detach`` (every vertex a
  space-point), one ``springwrap.anchor_add(vertex_index=i, location=p, use_location=True)`` per
  landmark (``p`` its true position on the target; the operator's default ``on_surface=True``
  anchors it to the closest target point, as a click on the target does), then
  ``springwrap.wrap()`` with the operator's default parameters (synchronous in background mode);
- ``Springwrap wrap local``: the same with ``springwrap.wrap(schedule='LOCAL')`` (the default ``'AUTO'``
  chooses a schedule from the anchors);
- ``Springwrap wrap global``: the same with ``springwrap.wrap(schedule='GLOBAL_TO_LOCAL')``: stiff,
  nearly affine levels before the local fit;
- ``Springwrap wrap proposals``: ``Springwrap wrap`` with ``springwrap.anchors_propose(accept=True)`` after
  the anchors: further pairs proposed from them (tips and pits of both shapes) and all accepted, as the
  command line's ``--propose-anchors`` does; the proposals are returned for the truth check;
- ``Springwrap snap+wrap``: the same, with ``springwrap.snap(mode='SURFACE')`` after the detach,
  so the wrap starts from face-points on the surface instead of a floating template;
- ``Springwrap project+wrap``: the same, with ``springwrap.project(direction='NORMAL',
  both_directions=True, max_distance=d)`` after the detach, ``d`` = :data:`PROJECT_DISTANCE` of
  the layout's bounding-box diagonal (~5 cm on the body; unlimited rays reach the other leg or
  arm): the README's workflow without its snap (vertices whose rays miss stay space-points);
- ``Springwrap align``: the template *as given* (not aligned by the harness), one
  ``springwrap.anchor_add`` per landmark as above, then ``springwrap.align(method='SIMILARITY',
  use_icp=True, apply='BAKE')``: the add-on's own alignment (anchor fit, then trimmed ICP), to set
  against the harness's ``aligned template`` (the anchor fit alone);
- ``Springwrap align+wrap``: that aligned template through ``Springwrap wrap``.

The wrap's own report (``Wrapped 'X' in N iterations (converged), T s: F face-points, S
space-points ...``, printed to stdout in background mode) is captured and parsed
(:func:`parse_wrap_report`) for the iteration count, convergence and the wrap's own time; the
benchmark's time is the wall time of every operator call together.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
from dataclasses import dataclass

import numpy as np

from benchmarks.retarget.baselines import MethodRefused, mesh_object, read_positions

WRAP_METHODS = {
    "Springwrap wrap": "detach",
    "Springwrap wrap local": "detach",
    "Springwrap wrap global": "detach",
    "Springwrap wrap proposals": "detach",
    "Springwrap snap+wrap": "snap",
    "Springwrap project+wrap": "project",
}
"""The wrap methods and how each starts (:func:`springwrap_wrap`'s ``start``)."""
PROPOSE_METHODS = ("Springwrap wrap proposals",)
"""The wrap methods that propose (and accept) further pairs before the wrap."""
WRAP_OPTIONS = {
    "Springwrap wrap local": {"schedule": "LOCAL"},
    "Springwrap wrap global": {"schedule": "GLOBAL_TO_LOCAL"},
}
"""The wrap methods' ``springwrap.wrap`` properties besides the defaults."""
ALIGN_METHODS = ("Springwrap align", "Springwrap align+wrap")
"""The methods that start from the template as given and align it with ``springwrap.align``."""
_ALIGN_REPORT = re.compile(r"ICP on \d+ points, (?P<iterations>\d+) iterations, (?P<ending>converged|not converged)")
PROJECT_DISTANCE = 0.025
"""``project+wrap``'s ray length limit, a fraction of the layout's bounding-box diagonal."""

_WRAP_REPORT = re.compile(
    r"Wrapped '(?P<name>[^']*)' in (?P<iterations>\d+) iterations \((?P<ending>[^)]*)\), "
    r"(?P<seconds>[0-9.]+) s: (?P<face_points>\d+) face-points, (?P<space_points>\d+) space-points"
)


@dataclass(frozen=True)
class WrapReport:
    """What the wrap operator reported about its run."""

    iterations: int
    converged: bool
    seconds: float
    face_points: int
    space_points: int

    @property
    def iterations_per_second(self) -> float:
        return self.iterations / self.seconds if self.seconds > 0 else float("nan")

    def as_dict(self) -> dict:
        """The fields and the rate, for the JSON."""
        return {
            "iterations": self.iterations,
            "converged": self.converged,
            "wrap_seconds": self.seconds,
            "iterations_per_second": self.iterations_per_second,
            "face_points": self.face_points,
            "space_points": self.space_points,
        }


def parse_wrap_report(text: str) -> WrapReport:
    """The last wrap summary in ``text`` (the operator's captured output); ``ValueError`` if there is none."""
    matches = list(_WRAP_REPORT.finditer(text))
    if not matches:
        raise ValueError(f"no wrap report in the operator's output: {text.strip()[-300:]!r}")
    match = matches[-1]
    return WrapReport(
        iterations=int(match["iterations"]),
        converged=match["ending"] == "converged",
        seconds=float(match["seconds"]),
        face_points=int(match["face_points"]),
        space_points=int(match["space_points"]),
    )


@contextlib.contextmanager
def captured_stdout():
    """Capture what is written to file descriptor 1 (Blender prints operator reports there in background).

    Yields a list that holds the captured text once the block has ended."""
    sys.stdout.flush()
    saved = os.dup(1)
    captured: list[str] = []
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 1)
        try:
            yield captured
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)
            sink.seek(0)
            captured.append(sink.read().decode("utf-8", "replace"))


def _call(name: str, operator, **properties) -> str:
    """Run one operator with its reports captured; its output.

    Raises :class:`MethodRefused` with the operator's message when it reported an error (``bpy``
    raises ``RuntimeError`` then) or did not finish."""
    try:
        with captured_stdout() as output:
            result = operator(**properties)
    except RuntimeError as error:
        raise MethodRefused(f"springwrap.{name}: {str(error).strip()}") from None
    if result != {"FINISHED"}:
        raise MethodRefused(f"springwrap.{name} returned {sorted(result)}: {output[0].strip()[-300:]}")
    return output[0]


def _select_only(layout) -> None:
    import bpy

    bpy.context.view_layer.update()  # objects removed since the last update would be listed as None
    for obj in bpy.context.view_layer.objects:
        if obj is not None:
            obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout


def _add_anchors(layout, landmark_vertices: np.ndarray, anchor_positions: np.ndarray) -> int:
    """One ``anchor_add`` per landmark at its true position (closest target point, as a click); the count."""
    import bpy

    for vertex, position in zip(np.asarray(landmark_vertices).tolist(), np.asarray(anchor_positions).tolist()):
        _call(
            "anchor_add", bpy.ops.springwrap.anchor_add, vertex_index=int(vertex), location=position, use_location=True
        )
    anchor_count = len(layout.springwrap.anchors)
    if anchor_count != len(landmark_vertices):
        raise RuntimeError(f"{anchor_count} anchors on the layout after adding {len(landmark_vertices)}")
    return anchor_count


def springwrap_align(
    layout_positions: np.ndarray,
    quads: np.ndarray,
    target_object,
    landmark_vertices: np.ndarray,
    anchor_positions: np.ndarray,
    anchor_weight: float | None = None,
) -> tuple[np.ndarray, list[str]]:
    """anchor_add per landmark → align (similarity + ICP, baked) on a new layout object; (positions, notes).

    ``anchor_weight=None`` keeps the operator's default."""
    import bpy

    layout = mesh_object("Springwrap align", layout_positions, quads)
    layout.springwrap.target = target_object
    _select_only(layout)
    anchor_count = _add_anchors(layout, landmark_vertices, anchor_positions)
    weight = {} if anchor_weight is None else {"anchor_weight": float(anchor_weight)}
    output = _call("align", bpy.ops.springwrap.align, method="SIMILARITY", use_icp=True, apply="BAKE", **weight)
    match = _ALIGN_REPORT.search(output)
    notes = [f"{anchor_count} anchors, similarity fit then ICP"]
    if match:
        notes.append(f"ICP {match['iterations']} iterations ({match['ending']})")
    return read_positions(layout.data), notes


def springwrap_wrap(
    layout_positions: np.ndarray,
    quads: np.ndarray,
    target_object,
    landmark_vertices: np.ndarray,
    anchor_positions: np.ndarray,
    start: str = "detach",
    max_iterations: int | None = None,
    wrap_options: dict | None = None,
    proposals: list | None = None,
) -> tuple[np.ndarray, list[str], WrapReport]:
    """detach [→ snap or project] → anchor_add per landmark [→ anchors_propose] → wrap, on a new layout object;
    (positions, notes, report). With a list as ``proposals``, further pairs are proposed and accepted, and
    ``(vertices, locations)`` of those pairs appended to it.

    ``start`` is ``"detach"``, ``"snap"`` or ``"project"``; ``max_iterations=None`` keeps the operator's default;
    ``wrap_options``: more ``springwrap.wrap`` properties."""
    if start not in ("detach", "snap", "project"):
        raise ValueError(f"unknown start {start!r}")
    layout = mesh_object(f"Springwrap {start}", layout_positions, quads)
    layout.springwrap.target = target_object
    return wrap_layout(
        layout, layout_positions, landmark_vertices, anchor_positions, start, max_iterations, wrap_options, proposals
    )


def wrap_layout(
    layout,
    layout_positions: np.ndarray,
    landmark_vertices: np.ndarray,
    anchor_positions: np.ndarray,
    start: str = "detach",
    max_iterations: int | None = None,
    wrap_options: dict | None = None,
    proposals: list | None = None,
) -> tuple[np.ndarray, list[str], WrapReport]:
    """:func:`springwrap_wrap` on an existing layout object whose target is set (``layout_positions``: its
    vertices, for ``project``'s ray length; ``wrap_options``: more ``springwrap.wrap`` properties);
    (positions, notes, report)."""
    import bpy

    _select_only(layout)
    _call("detach", bpy.ops.springwrap.detach, only_selected=False)
    if start == "snap":
        _call("snap", bpy.ops.springwrap.snap, mode="SURFACE", only_selected=False, max_distance=0.0)
    elif start == "project":
        diagonal = float(np.linalg.norm(np.ptp(np.asarray(layout_positions, dtype=np.float64), axis=0)))
        _call(
            "project",
            bpy.ops.springwrap.project,
            direction="NORMAL",
            both_directions=True,
            max_distance=PROJECT_DISTANCE * diagonal,
            only_selected=False,
        )
    anchor_count = _add_anchors(layout, landmark_vertices, anchor_positions)
    if proposals is not None:
        _call("anchors_propose", bpy.ops.springwrap.anchors_propose, accept=True)
        items = list(layout.springwrap.anchors)[anchor_count:]
        proposals.append(
            (
                np.array([item.vertex_index for item in items], dtype=np.int64),
                np.array([tuple(item.location) for item in items], dtype=np.float64).reshape(-1, 3),
            )
        )
    wrap_properties = {} if max_iterations is None else {"max_iterations": int(max_iterations)}
    report = parse_wrap_report(_call("wrap", bpy.ops.springwrap.wrap, **wrap_properties, **(wrap_options or {})))
    ending = "converged" if report.converged else "stopped at the iteration limit"
    notes = [
        f"{report.iterations} iterations ({ending}), wrap {report.seconds:.2f} s, "
        f"{report.iterations_per_second:.0f} iterations/s",
        f"{report.face_points} face-points, {report.space_points} space-points, {anchor_count} anchors",
    ]
    if max_iterations is not None:
        notes.append(f"max_iterations capped at {max_iterations}")
    return read_positions(layout.data), notes, report
