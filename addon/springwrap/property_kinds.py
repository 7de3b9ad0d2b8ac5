"""The kinds of Blender property the add-on declares: each a function of the label, the tooltip and the default
(in that order, as a reader looks for them), its other settings by keyword.

Blender fixes a property's default and range when its class is defined; these functions only make the
declarations short enough to read as a list (``operators.*``, ``properties``). The wrap's settings take their
defaults and ranges from the kernel (``properties.WRAP_DEFAULTS`` / ``WRAP_RANGES``).
"""

import bpy

from .blender import compat


def flag(name: str, description: str, default: bool, **options):
    """An on / off setting (a checkbox)."""
    return bpy.props.BoolProperty(name=name, description=description, default=default, **options)


def choice(name: str, description: str, items, default: str, **options):
    """One of ``items`` (``(identifier, label, tooltip[, icon, number])`` tuples)."""
    return bpy.props.EnumProperty(name=name, description=description, items=items, default=default, **options)


def integer(name: str, description: str, default: int, **limits):
    """A whole number; ``limits``: ``min``, ``max``, ``soft_min``, ``soft_max``."""
    return bpy.props.IntProperty(name=name, description=description, default=default, **limits)


def number(name: str, description: str, default: float, **options):
    """A number without a unit (a weight, a fraction, a ratio); ``options``: limits, ``subtype``, ``precision``."""
    return bpy.props.FloatProperty(name=name, description=description, default=default, **options)


def distance(name: str, description: str, default: float = 0.0, **limits):
    """A length in the scene's unit, never negative."""
    return bpy.props.FloatProperty(
        name=name, description=description, default=default, min=0.0, subtype="DISTANCE", unit="LENGTH", **limits
    )


def point(name: str, description: str, default=(0.0, 0.0, 0.0), **options):
    """A position, three numbers in the scene's unit."""
    return bpy.props.FloatVectorProperty(
        name=name, description=description, size=3, default=default, subtype="XYZ", unit="LENGTH", **options
    )


def text(name: str, description: str, default: str = "", **options):
    """A text: a name (of an object, a vertex group) or a list written out."""
    return bpy.props.StringProperty(name=name, description=description, default=default, **options)


def hidden_text(name: str, description: str):
    """A text the add-on keeps for itself (a signature, saved settings), not shown to the user."""
    return bpy.props.StringProperty(name=name, description=description, default="", options={"HIDDEN"})


def list_position(name: str, description: str, **options):
    """The position of the active item of a list (``template_list``'s active index); ``options``: ``update``."""
    return bpy.props.IntProperty(name=name, description=description, default=0, min=0, **options)


def object_pointer(name: str, description: str, poll=None):
    """An object of the scene; ``poll(owner, candidate)`` says which objects can be picked."""
    options = {} if poll is None else {"poll": compat.pointer_poll(poll)}
    return bpy.props.PointerProperty(name=name, description=description, type=bpy.types.Object, **options)


def items(name: str, description: str, item_type):
    """A list of ``item_type`` property groups."""
    return bpy.props.CollectionProperty(name=name, description=description, type=item_type)
