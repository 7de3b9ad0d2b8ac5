"""benchmarks/sequence.py's own arithmetic on made-up inputs (no Blender, no data): the expression weights, the
errors and jitter, the summary and its Markdown."""

import numpy as np

from benchmarks import sequence


def test_the_expressions_start_neutral_and_stay_within_their_peaks():
    weights = sequence.weights(20)
    assert weights.shape == (20, len(sequence.EXPRESSIONS))
    assert np.all(weights[0] == 0.0)
    peaks = np.array([peak for _unit, peak, *_rest in sequence.EXPRESSIONS])
    assert np.all(weights <= peaks + 1e-12) and np.all(weights.max(axis=0) > 0.5 * peaks)


def test_errors_and_jitter():
    truths = np.zeros((3, 4, 3))
    truths[:, :, 0] = np.arange(3)[:, None]  # every vertex moves 1 along x per frame
    results = truths.copy()
    results[1, 0, 1] = 0.002  # vertex 0 is 2 mm off on frame 1 only
    valid = np.ones((3, 4), dtype=bool)
    rows = sequence.errors(results, truths, valid)
    assert rows[0] == {"mean_mm": 0.0, "p95_mm": 0.0}
    assert np.isclose(rows[1]["mean_mm"], 0.5) and np.isclose(rows[1]["jitter_mean_mm"], 0.5)
    assert np.isclose(rows[2]["mean_mm"], 0.0) and np.isclose(rows[2]["jitter_mean_mm"], 0.5)


def made_up_result():
    rows = [{"mean_mm": 1.0, "p95_mm": 2.0}] + [
        {"mean_mm": 1.0, "p95_mm": 2.0, "jitter_mean_mm": 0.5, "jitter_p95_mm": 1.0}
    ] * 2
    return {
        "frames": 3,
        "voxel_size": 0.004,
        "layout_vertices": 13380,
        "target_triangles": [280000, 281000, 282000],
        "expressions": [list(entry) for entry in sequence.EXPRESSIONS],
        "failed_frames": [],
        "sequence": {
            "seconds": [4.0, 1.0, 1.0],
            "iterations": [19, 19, 0],
            "steps": [{"target": 1.0}, {"target": 0.25, "solve": 0.5}, {"target": 0.75}],
            "errors": rows,
        },
        "cold": {"seconds": [4.0, 4.0, 4.0], "iterations": [19, 19, 19], "errors": rows},
    }


def test_summary_and_markdown():
    numbers = sequence.summary(made_up_result())
    assert numbers["speedup"] == 4.0 and numbers["sequence"]["later_seconds"] == 1.0
    text = "\n".join(sequence.markdown(made_up_result()))
    assert "## Over time" in text and "4.00× less time" in text and "| Wrap Sequence | 4.00 | 1.00 |" in text
    assert numbers["later_steps"]["target"] == 0.5 and numbers["later_steps"]["solve"] == 0.25
    assert "target read and built 0.500" in text and "iterations 0.250" in text
    assert "the cold wraps' mean error spans 1.00–1.00 mm" in text


def test_processor_time_beside_the_wall_time():
    """With each frame's processor time measured, the table has its column and the ratio is said; a result
    measured before it was (no processor times) still reads, the column then NaN."""
    result = made_up_result()
    result["sequence"]["processor_seconds"] = [2.0, 0.25, 0.25]
    result["cold"]["processor_seconds"] = [2.0, 1.5, 1.5]
    numbers = sequence.summary(result)
    assert numbers["processor_speedup"] == 6.0 and numbers["sequence"]["later_processor_seconds"] == 0.25
    text = "\n".join(sequence.markdown(result))
    assert "| Wrap Sequence | 4.00 | 1.00 | 0.25 |" in text and "(6.00× less processor time)" in text
    older = "\n".join(sequence.markdown(made_up_result()))
    assert "| Wrap Sequence | 4.00 | 1.00 | nan |" in older and "processor time)" not in older


def test_frames_above_the_cold_wrap_are_counted_from_the_run_s_first_frame():
    result = made_up_result()
    result["range"] = [40, 43]
    result["sequence"]["errors"] = [dict(row) for row in result["sequence"]["errors"]]
    result["sequence"]["errors"][2]["p95_mm"] = 2.5  # the third frame, 0.5 mm above the cold wrap's
    worse = sequence.worse_than_cold(result)
    assert worse["p95_mm"] == {"count": 1, "most_mm": 0.5, "frames": [42]}
    assert worse["mean_mm"] == {"count": 0, "most_mm": 0.0, "frames": []}
