"""A few thousand random calls to every function and class of the binding, in a subprocess so that an abort
is seen (no bpy). The calls and their checks are in ``fuzz_calls.py``; the seed is fixed."""

import subprocess
from pathlib import Path

from helpers import kernel_python

SCRIPT = Path(__file__).with_name("fuzz_calls.py")
SEED = 20261202
CALLS = 10000


def test_random_calls_return_or_raise_the_modules_errors_and_never_abort():
    executable, environment = kernel_python()
    result = subprocess.run(
        [executable, str(SCRIPT), str(SEED), str(CALLS)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
        env=environment,
    )
    assert result.returncode == 0, f"exit status {result.returncode}\n{result.stderr[-4000:]}"
    outcomes = {}
    for line in result.stdout.splitlines():
        name, outcome, count = line.split()
        outcomes.setdefault(name, {})[outcome] = int(count)
    assert sum(sum(counts.values()) for counts in outcomes.values()) == CALLS
    # Every entry point was called, and each both returned and refused (the catalogue is neither all
    # hostile nor all plausible).
    assert len(outcomes) == 8, outcomes
    for name, counts in outcomes.items():
        assert counts.get("ok", 0) > 0, (name, counts)
        assert sum(counts.values()) > counts.get("ok", 0), (name, counts)
