"""``retarget.py --feature-lines``, end to end in its own process: a quad cube template onto a larger box of other
triangles, its twelve creases paired with the box's sharp edges and listed in the report with their confidences;
without the flag the report has no pairs."""

import json

import numpy as np

from helpers import REPOSITORY, obj_text, options, outputs, run_script

RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"


def quad_cube(cells: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """A closed cube of half-size 1, each face ``cells`` x ``cells`` quads wound outwards, welded."""
    a = -1.0 + 2.0 * np.arange(cells + 1) / cells
    u, v = np.meshgrid(a, a, indexing="ij")
    index = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    quad = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], -1).reshape(-1, 4)
    points, quads = [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            face = np.zeros((u.size, 3))
            face[:, axis] = sign
            face[:, (axis + 1) % 3] = u.ravel()
            face[:, (axis + 2) % 3] = v.ravel()
            quads.append(quad[:, ::-1] + len(points) * u.size if sign < 0 else quad + len(points) * u.size)
            points.append(face)
    points, quads = np.concatenate(points), np.concatenate(quads)
    welded, inverse = np.unique(np.round(points, 6), axis=0, return_inverse=True)
    return welded, inverse.reshape(-1)[quads]


def test_the_creases_are_paired_wrapped_and_reported(tmp_path):
    template, target = tmp_path / "cube.obj", tmp_path / "box.obj"
    template.write_text(obj_text(*quad_cube(), digits=6))
    vertices, quads = quad_cube(7)
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    target.write_text(obj_text(1.1 * vertices, triangles, digits=6))
    reports = {}
    for flag in (False, True):
        out = tmp_path / f"out{int(flag)}"
        process = run_script(
            RETARGET,
            *options(template=template, target=target, anchors_spacing=0, feature_lines=flag),
            *outputs(out, "r", ("report",)),
        )
        assert process.returncode == 0, process.stderr[-3000:]
        reports[flag] = json.loads((out / "r.json").read_text())
    assert reports[False]["feature_lines"] is None
    lines = reports[True]["feature_lines"]
    assert len(lines["paired"]) == 12 and lines["free"] == []
    assert all(0.3 <= pair["confidence"] <= 1.0 and pair["vertices"] == 5 for pair in lines["paired"])
    assert "feature lines" in reports[True]["timings"]
