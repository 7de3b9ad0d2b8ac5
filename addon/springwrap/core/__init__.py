"""Springwrap's logic on plain arrays: no ``bpy`` here, so all of it is importable and tested without Blender
(numpy and the ``springwrap_kernel`` wheel only).

``errors`` (the one error type), ``layout_state`` (the face-point state), ``transforms``, ``target``
(the target mesh and the deleted-face rule), ``snapping`` (detach, snap, project), ``wrap_inputs``,
``wrap_run`` (result, pacing, the modal's state machine), ``anchors``, ``curves``, ``alignment``,
``armature`` (bone maths), ``mirroring``, ``subdivision``, ``features`` (region colours, the default scale).
"""
