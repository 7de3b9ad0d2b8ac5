"""What last changed each layout, for the Check panel (this Blender session only, by layout name).

A wrap, a mirror or a subdivision fit is remembered with the rows the panel shows for it; any other write of
a layout's positions (``layout.write_layout``: Snap, Project, Align, a pose) forgets it, so the panel never
shows a result the layout no longer has.
"""

from typing import NamedTuple


class LastRun(NamedTuple):
    """The last wrap, mirror or fit of a layout."""

    operation: str  # "Wrap", "Mirror", "Fit Subdivision"
    result: object  # the wrap's ``core.wrap_run.WrapResult`` (the wrap's or the mirror's); None for a fit
    rows: tuple  # (label, value) pairs the panel shows after the operation's name


_last_runs: dict[str, LastRun] = {}


def remember(layout_name: str, run: LastRun) -> None:
    """Keep ``run`` as the last one on the layout of this name."""
    _last_runs[layout_name] = run


def forget(layout_name: str) -> None:
    """The layout of this name was changed otherwise: its last run no longer describes it."""
    _last_runs.pop(layout_name, None)


def last(layout_name: str) -> LastRun | None:
    """The last run remembered on the layout of this name, if any."""
    return _last_runs.get(layout_name)


def forget_all() -> None:
    """Drop every remembered run (the add-on is unregistered, another file is loaded)."""
    _last_runs.clear()


def remember_fit(layout_name: str, levels: int, outcome) -> None:
    """Keep a subdivision fit (``core.cage_fit.CageFitOutcome``) as the layout's last run: its cage vertices lie
    off the target by design (the level-``levels`` surface lies on it)."""
    rows = (
        ("Last Fit", f"Level {levels}"),
        ("Rounds", str(outcome.rounds)),
        ("Surface Mean", f"{outcome.after.mean:.3g}"),
        ("Surface Max", f"{outcome.after.max:.3g}"),
    )
    remember(layout_name, LastRun("Fit Subdivision", None, rows))


def remember_mirror(layout_name: str, copies: int, seam: int) -> None:
    """Keep a mirror without a wrap as the layout's last run."""
    rows = (("Last Mirror", "Not wrapped"), ("New Vertices", str(copies)), ("Seam", str(seam)))
    remember(layout_name, LastRun("Mirror", None, rows))
