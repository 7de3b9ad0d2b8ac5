"""The body of ``wrap_speed.py`` (the ``heavy`` case remeshed to ~200k triangles, the aligned template and
its first N landmarks as face-point anchors) written as raw little-endian arrays, for the kernel's
``examples/wrap_profile.rs`` (the wrap's time phase by phase, in processor seconds, without Python):

    .venv/bin/python benchmarks/wrap_case_files.py out/wrap-case 24 6
    cargo run --release -p springwrap-kernel --example wrap_profile -- out/wrap-case 24 3

Writes ``target_vertices.f32``, ``target_triangles.u32`` and ``quads.u32`` in the folder and, per anchor
count N, ``aN/aligned.f32``, ``anchor_vertices.u32``, ``anchor_triangles.u32``, ``anchor_barycentrics.f32``
and ``anchor_positions.f32`` (the anchors as ``wrap_solvers.py`` places them: the target's closest points
to the true positions).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks import wrap_speed
from benchmarks.wrap_solvers import prepared


def write(path: Path, values, dtype: str) -> None:
    """``values`` as raw little-endian ``dtype`` (``<f4`` or ``<u4``)."""
    np.ascontiguousarray(values, dtype=dtype).tofile(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("anchors", nargs="+", type=int, help="anchor counts (the first N landmarks)")
    arguments = parser.parse_args(argv)
    import springwrap_kernel as kernel

    folder = arguments.folder
    folder.mkdir(parents=True, exist_ok=True)
    case, vertices, triangles, _voxel = wrap_speed.body_case()
    vertices = np.ascontiguousarray(vertices, dtype=np.float32)
    triangles = np.ascontiguousarray(triangles, dtype=np.uint32)
    write(folder / "target_vertices.f32", vertices, "<f4")
    write(folder / "target_triangles.u32", triangles, "<u4")
    write(folder / "quads.u32", case.layout_quads, "<u4")
    target = kernel.TargetMesh(vertices, triangles)
    for count in arguments.anchors:
        landmark_vertices, anchors, aligned = prepared(case, count)
        hits = target.closest_points(np.ascontiguousarray(anchors, dtype=np.float32))
        anchored = folder / f"a{count}"
        anchored.mkdir(exist_ok=True)
        write(anchored / "aligned.f32", aligned, "<f4")
        write(anchored / "anchor_vertices.u32", landmark_vertices, "<u4")
        write(anchored / "anchor_triangles.u32", hits.triangles, "<u4")
        write(anchored / "anchor_barycentrics.f32", hits.barycentrics, "<f4")
        write(anchored / "anchor_positions.f32", hits.positions, "<f4")
        print(f"{count} anchors: {len(aligned)} layout vertices, {len(triangles)} target triangles in {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
