"""What old ``.blend`` files still carry of retired features, found and removed with a message.

A layout saved before the spring solver was retired keeps its panel's solver choice as a bare ID property
(``layout.springwrap["wrap_solver"]``: Blender keeps a value stored for a property it no longer declares).
The wrap ignores it; :func:`take_retired_solver` says so once and removes it.
"""

import bpy

from ..core import defaults

STORED_SOLVER = "wrap_solver"
"""The retired panel setting's name in the layout's settings (``layout.springwrap``)."""


def take_retired_solver(layout: bpy.types.Object | None) -> bool:
    """Remove the solver choice an old ``.blend`` stored on ``layout``'s settings; whether it named the retired
    spring solver (``core.defaults.is_retired_solver``: the caller then says it wrapped with the energy solver).
    False, and nothing changed, for a layout without one."""
    if layout is None or getattr(layout, "springwrap", None) is None:
        return False
    settings = layout.springwrap
    if STORED_SOLVER not in settings.keys():
        return False
    value = settings[STORED_SOLVER]
    del settings[STORED_SOLVER]
    return defaults.is_retired_solver(value)
