"""The only modules that read or write Blender data: they turn objects, meshes and properties into the arrays
``core`` works on, and write results back (``foreach_get`` / ``foreach_set``).

``evaluated_mesh`` (the one reader of an evaluated mesh), ``attributes`` (the one reader / writer of mesh
attributes), ``edit_mode`` (the one way out of edit mode and back), ``layout``, ``target``, ``anchors``,
``curves``, ``features``, ``mirror``, ``armature``, ``wrap_session``; ``compat`` for Blender versions.
"""
