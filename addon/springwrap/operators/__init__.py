"""The add-on's operators: ``poll`` says why one cannot run, ``execute`` / ``invoke`` check, call ``core`` and
``blender``, and report. One module per operator family; ``base`` holds their shared opening."""

from . import (
    align,
    anchors,
    armature,
    cage_fit,
    curves,
    feature_lines,
    features,
    mirror,
    pair_tool,
    proposals,
    quality,
    sequence,
    snapping,
    wrap,
)

classes = (
    snapping.classes
    + align.classes
    + anchors.classes
    + proposals.classes
    + pair_tool.classes
    + curves.classes
    + wrap.classes
    + sequence.classes
    + armature.classes
    + features.classes
    + feature_lines.classes
    + mirror.classes
    + cage_fit.classes
    + quality.classes
)
"""Every operator class, in the order they are registered."""
