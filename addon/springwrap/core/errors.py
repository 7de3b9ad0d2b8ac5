"""The add-on's one error type, and every exception an operation turns into an error report."""

import springwrap_kernel


class LayoutError(ValueError):
    """Input the add-on cannot work with (no target, empty mesh, zero scale...); the message is for the user."""


ERRORS = (LayoutError, springwrap_kernel.SpringwrapError)
"""Every exception an operation turns into an error report (the layout is then left untouched)."""
