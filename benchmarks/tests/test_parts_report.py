"""The parts benchmark's Markdown (``benchmarks/parts.py``) and its place in ``docs/benchmarks.md``
(``benchmarks/report.py --only-parts``), on made-up results: fast, no Blender."""

import numpy as np

from benchmarks import parts, report


def entry(body, near, mean, largest, eye=0.0):
    pieces = {group: {"mean": mean, "max": largest, "skin": near} for group in parts.PART_GROUPS}
    return {
        "body_mean": body,
        "near_parts_mean": near,
        "parts_mean": mean,
        "parts_max": largest,
        "eye_shape_change": eye,
        "pieces": pieces,
        "notes": "Parts: 9 pieces",
    }


RESULT = {
    "part_vertices": 756,
    "template_move": parts.TEMPLATE_MOVE,
    "anchors": 24,
    "near_parts": 0.05,
    "cases": [
        {
            "case": "heavy",
            "methods": {
                "wrap, body alone": {"body_mean": 0.2, "near_parts_mean": 0.05},
                "wrap, parts pulled": entry(0.2, 0.05, 0.7, 2.3, 30.0),
                "wrap (defaults)": entry(0.2, 0.05, 0.06, 0.9),
            },
            "true_surface": {
                "parts_mean": 0.03,
                "parts_max": 0.1,
                "pieces": {group: {"mean": 0.03, "max": 0.1} for group in parts.PART_GROUPS},
            },
        }
    ],
}


def test_the_section_has_every_method_and_says_which_aims_are_missed():
    text = "\n".join(parts.markdown(RESULT))
    assert "| heavy | wrap, body alone | 0.200 | 0.050 | - | - | - |" in text
    assert "| heavy | wrap, parts pulled | 0.200 | 0.050 | 0.700 | 2.300 | 30.00 |" in text
    assert "parts mean ≤ near mean: 0.060 against 0.050 (missed by 0.010)" in text
    assert "parts max ≤ 0.6 %: 0.900 against 0.600 (missed by 0.300)" in text
    assert "body ≤ body alone: 0.200 against 0.200 (met)" in text
    assert "- heavy: Parts: 9 pieces" in text
    # Per piece: the skin it follows most closely and the piece on the true surface.
    assert "| heavy: skin within 5 mm, mean | 0.05 |" in text
    assert "| heavy: on the true surface | 0.03 / 0.10 |" in text


def test_the_section_is_put_in_place_or_replaced():
    document = "# Benchmarks\n\n## Few anchors\n\nx\n\n## Performance\n\ny\n"
    section = parts.markdown(RESULT)
    once = report.splice_section(document, section)
    assert once.index("## Parts that follow the surface") < once.index("## Performance")
    assert "## Few anchors\n\nx" in once and once.endswith("y\n")
    assert report.splice_section(once, section) == once


def face(head_p95, lips, eyelids):
    return {
        "head_mean": 0.2,
        "head_p95": head_p95,
        "head_max": 1.0,
        "lips_mean": lips,
        "lips_max": 0.9,
        "eyelids_mean": eyelids,
        "eyelids_max": 0.3,
    }


def test_the_face_table_gives_the_pairing_ratios_against_wrapping_twice():
    result = {
        **RESULT,
        "cases": [
            {
                "case": "face-expression",
                "methods": {
                    "wrap, body alone": {"body_mean": 0.1, "near_parts_mean": 0.2, "face": face(0.7, 0.3, 0.2)},
                    "wrap twice": entry(0.1, 0.2, 0.2, 0.9) | {"face": face(0.8, 0.3, 0.18)},
                    "wrap + feature pairing": entry(0.1, 0.2, 0.2, 0.9) | {"face": face(0.4, 0.2, 0.2)},
                },
            }
        ],
    }
    text = "\n".join(parts.markdown(result))
    assert "| face-expression | wrap twice | 0.200 | 0.800 | 1.000 | 0.300 | 0.900 | 0.180 |" in text
    assert "| face-expression | wrap, body alone | 0.200 | 0.700 |" in text
    assert "without / with the feature pairing: lips 1.50×, eyelids 0.90×, head p95 2.00×" in text
    assert "head mean %" not in "\n".join(parts.markdown(RESULT))  # no face measured: no face table


def tube(around=6, along=4):
    """Quads of a tube: ``around`` vertices a ring, ``along`` rings (vertex a + around * r)."""
    index = np.arange(around * along).reshape(along, around)
    following = np.roll(index, -1, axis=1)
    return np.stack([index[:-1], following[:-1], following[1:], index[1:]], axis=-1).reshape(-1, 4)


def test_an_edge_loop_goes_round_a_ring_and_stops_at_a_border():
    quads = tube()
    np.testing.assert_array_equal(parts.edge_loop(quads, 6, 7), [6, 7, 8, 9, 10, 11])  # an inner ring closes
    np.testing.assert_array_equal(parts.edge_loop(quads, 7, 13), [7, 13, 19])  # across: ends on the border


def test_the_carried_share_is_the_median_share_of_the_true_motion_made_along_it():
    aligned = np.zeros((5, 3))
    truth = np.array([[0.0, -2.0, 0.0], [0.0, -2.0, 0.0], [0.0, -2.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    # Half way down, all the way, and half way with a step sideways (not counted); the fourth has no motion to
    # make, the fifth is not a member.
    positions = np.array([[0.0, -1.0, 0.0], [0.0, -2.0, 0.0], [0.5, -1.0, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    members = np.array([True, True, True, True, False])
    assert parts.carried_share(aligned, truth, positions, members) == 0.5
    assert parts.carried_share(aligned, truth, truth, members) == 1.0
    assert parts.carried_share(aligned, truth, aligned, members) == 0.0
    assert np.isnan(parts.carried_share(aligned, aligned, positions, members))
