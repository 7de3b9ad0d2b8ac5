"""Pieces of ``blender_scripts/scene_io.py`` that need no scene (it imports ``bpy``: the bpy module, or the
blender binary of the 3.4 lane)."""

from scene_io import importer_message

PYTHON_IMPORTER_FAILURE = """Error: Python: Traceback (most recent call last):
  File "/usr/share/blender/scripts/addons/io_scene_gltf2/blender/imp/gltf2_blender_mesh.py", line 612, in do
    poly_smooths = np.empty(num_polys, dtype=np.bool)
AttributeError: module 'numpy' has no attribute 'bool'.
`np.bool` was a deprecated alias for the builtin `bool`.
    https://numpy.org/devdocs/release/1.20.0-notes.html#deprecations. Did you mean: 'bool_'?

Location: /usr/share/blender/scripts/modules/bpy/ops.py:113
"""


def test_an_importers_failure_is_its_exception_line():
    """A Python importer's traceback: the exception, not the last line of numpy's advice."""
    assert importer_message(PYTHON_IMPORTER_FAILURE) == "AttributeError: module 'numpy' has no attribute 'bool'."
    assert (
        importer_message("Error: PLY Importer: junk: Invalid PLY header.\n")
        == "PLY Importer: junk: Invalid PLY header."
    )
    assert importer_message("") == "unknown error"
