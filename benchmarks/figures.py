"""The benchmark's PNG figures under ``docs/img/``, from the benchmark's own output (never typed-in numbers).

    .venv/bin/python benchmarks/figures.py [--retarget out/bench/retarget.json] [--performance out/bench/performance.json]
                                          [--positions out/bench/retarget-positions] [--output docs/img]

- **error heat-maps** (``heatmap-<case>.png``): each method's retargeted layout on a body case,
  coloured by its per-vertex error to the true position (same scale for every method of a case,
  in % of the truth's bounding-box diagonal, clipped at :data:`HEATMAP_CLIP_PERCENT`), rendered
  headless by Blender (the ``bpy`` module, Workbench engine, the error as a colour attribute,
  studio light, an orthographic camera in front of the body). The positions come from
  ``out/bench/retarget-positions/<case>.npz`` (written by ``benchmarks.retarget.run``); the body
  is turned back by the case's placement so that the camera looks at its front;
- **error bars** (``errors-per-method.png``): mean and p95 error per method, one panel per case
  (matplotlib);
- **scaling** (``scaling.png``): log-log time against target triangles (BVH build, Shrinkwrap's
  first evaluation, snap of 100k points) and against layout size (snap, wrap per iteration),
  from ``out/bench/performance.json``.

PNGs are written as 256-colour palettes (Pillow) to keep them small.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
if str(REPOSITORY_ROOT) not in sys.path:
    sys.path.insert(0, str(REPOSITORY_ROOT))

from benchmarks.retarget import baselines  # noqa: E402

HEATMAP_CLIP_PERCENT = 2.0
"""Errors at or above this (% of the diagonal) get the colour ramp's last colour."""
HEATMAP_METHODS = baselines.METHODS
"""Every method of the run, in the tables' order."""
HEATMAP_CASES = ("heavy", "heavy-holes", "heavy-posed")
RENDER_SIZE = (360, 720)
# Colour ramp of the heat-maps (and of their colour bar): dark blue, teal, yellow, red.
RAMP = np.array([[0.05, 0.10, 0.45], [0.00, 0.55, 0.60], [0.95, 0.85, 0.10], [0.85, 0.10, 0.05]])


# ---------------------------------------------------------------- plain helpers (tested without Blender)


def error_colors(
    errors_percent: np.ndarray, clip_percent: float = HEATMAP_CLIP_PERCENT, ramp: np.ndarray = RAMP
) -> np.ndarray:
    """(N, 4) RGBA in [0, 1] of errors on the piecewise-linear ``ramp`` from 0 to ``clip_percent`` (clipped).

    Non-finite errors are magenta, so they stand out."""
    errors = np.asarray(errors_percent, dtype=np.float64)
    finite = np.isfinite(errors)
    position = np.clip(np.where(finite, errors, 0.0) / clip_percent, 0.0, 1.0) * (len(ramp) - 1)
    lower = np.minimum(np.floor(position).astype(int), len(ramp) - 2)
    fraction = (position - lower)[:, None]
    colors = ramp[lower] * (1.0 - fraction) + ramp[lower + 1] * fraction
    colors[~finite] = (1.0, 0.0, 1.0)
    return np.concatenate([colors, np.ones((len(errors), 1))], axis=1)


def placement_inverse(placement: dict) -> np.ndarray:
    """4x4 inverse of a case placement (scale, turn about +Y, shift): puts a placed body back in front of +Z."""
    from benchmarks.retarget.cases import similarity_matrix

    return np.linalg.inv(similarity_matrix(**placement))


def load_json(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.exists() else None


def save_palette_png(figure_or_image, path: Path) -> None:
    """Save a matplotlib figure or a PIL image as a 256-colour PNG."""
    from PIL import Image

    if isinstance(figure_or_image, Image.Image):
        image = figure_or_image
    else:
        import io

        buffer = io.BytesIO()
        figure_or_image.savefig(buffer, format="png", dpi=110)
        buffer.seek(0)
        image = Image.open(buffer)
        image.load()
    image.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)


# ---------------------------------------------------------------- heat-maps (Blender)


def render_layout(
    positions: np.ndarray,
    quads: np.ndarray,
    colors: np.ndarray,
    path: Path,
    size: tuple[int, int] = RENDER_SIZE,
    frame: tuple[np.ndarray, np.ndarray] | None = None,
) -> None:
    """Render a quad mesh with per-vertex colours, front view (camera on +Z, looking at -Z, +Y up), Workbench.

    ``frame`` (minimum, maximum corners) fixes the camera so several renders line up; by default
    the mesh's own bounding box."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Layout")
    mesh.vertices.add(len(positions))
    mesh.vertices.foreach_set("co", np.ascontiguousarray(positions, dtype=np.float32).ravel())
    quads = np.ascontiguousarray(quads, dtype=np.int32)
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    mesh.update(calc_edges=True)
    attribute = mesh.color_attributes.new("error", "FLOAT_COLOR", "POINT")
    attribute.data.foreach_set("color", np.ascontiguousarray(colors, dtype=np.float32).ravel())
    mesh.color_attributes.active_color = attribute
    obj = bpy.data.objects.new("Layout", mesh)
    scene.collection.objects.link(obj)

    minimum, maximum = frame if frame is not None else (positions.min(axis=0), positions.max(axis=0))
    centre = (minimum + maximum) / 2.0
    camera_data = bpy.data.cameras.new("Camera")
    camera_data.type = "ORTHO"
    width, height = size
    extent_x, extent_y = maximum[0] - minimum[0], maximum[1] - minimum[1]
    camera_data.ortho_scale = 1.04 * max(extent_y, extent_x * height / width)
    camera_data.clip_end = 100.0
    camera = bpy.data.objects.new("Camera", camera_data)
    camera.location = (centre[0], centre[1], maximum[2] + 5.0)
    camera.rotation_euler = (0.0, 0.0, 0.0)  # looks along -Z with +Y up
    scene.collection.objects.link(camera)
    scene.camera = camera

    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "VERTEX"
    shading.show_specular_highlight = False
    world = bpy.data.worlds.new("White")  # a Workbench render's background is the world colour
    world.color = (1.0, 1.0, 1.0)
    scene.world = world
    scene.view_settings.view_transform = "Standard"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)


def heatmap_figure(case_record: dict, positions_file: Path, output: Path, work_folder: Path) -> Path | None:
    """Render every method of one case and put the renders side by side with a colour bar; the PNG's path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LinearSegmentedColormap
    from PIL import Image

    stored = np.load(positions_file)
    methods = [str(name) for name in stored["methods"]]
    truth = stored["true_positions"].astype(np.float64)
    quads = stored["layout_quads"]
    diagonal = float(np.linalg.norm(truth.max(axis=0) - truth.min(axis=0)))
    placement = case_record["info"].get("placement") or case_record["spec"].get("placement")
    inverse = placement_inverse(placement) if placement else np.eye(4)

    def unplace(points):
        return points @ inverse[:3, :3].T + inverse[:3, 3]

    truth_front = unplace(truth)
    frame = (truth_front.min(axis=0) - 0.02 * diagonal, truth_front.max(axis=0) + 0.02 * diagonal)
    chosen = [method for method in HEATMAP_METHODS if method in methods]
    if not chosen:
        return None
    renders = []
    for method in chosen:
        positions = stored[f"positions_{methods.index(method)}"].astype(np.float64)
        errors = np.linalg.norm(positions - truth, axis=1) * 100.0 / diagonal
        errors[~np.isfinite(errors)] = np.inf
        render_path = work_folder / f"{case_record['case']}-{methods.index(method)}.png"
        # Quads with a non-finite corner are left out (the title counts those vertices).
        finite_quads = quads[np.isfinite(positions).all(axis=1)[quads].all(axis=1)]
        render_layout(unplace(np.nan_to_num(positions)), finite_quads, error_colors(errors), render_path, frame=frame)
        renders.append((method, errors, Image.open(render_path).convert("RGB")))

    figure, axes = plt.subplots(1, len(renders), figsize=(1.95 * len(renders) + 1.3, 4.3))
    axes = np.atleast_1d(axes)
    for axis, (method, errors, image) in zip(axes, renders):
        axis.imshow(image)
        axis.set_axis_off()
        finite = errors[np.isfinite(errors)]
        title = f"{method}\nmean {finite.mean():.2f} %, p95 {np.percentile(finite, 95):.2f} %"
        if len(finite) < len(errors):
            title += f"\n(of the finite; {len(errors) - len(finite)} NaN, not drawn)"
        axis.set_title(title, fontsize=7)
    colormap = LinearSegmentedColormap.from_list("error", RAMP)
    mappable = plt.cm.ScalarMappable(cmap=colormap, norm=plt.Normalize(0.0, HEATMAP_CLIP_PERCENT))
    bar = figure.colorbar(mappable, ax=list(axes), fraction=0.025, pad=0.01)
    millimetres = HEATMAP_CLIP_PERCENT / 100.0 * diagonal * 1000.0
    bar.set_label(f"error, % of the diagonal (≥ {HEATMAP_CLIP_PERCENT:g} % = {millimetres:.0f} mm)", fontsize=7)
    bar.ax.tick_params(labelsize=7)
    figure.suptitle(
        f"Error to the true position, case {case_record['case']} "
        f"({case_record['layout_vertices']:,} layout vertices, {len(case_record['anchors'])} anchors)",
        fontsize=9,
    )
    path = output / f"heatmap-{case_record['case']}.png"
    save_palette_png(figure, path)
    plt.close(figure)
    return path


# ---------------------------------------------------------------- charts (matplotlib)


def error_bars(retarget: dict, path: Path) -> Path:
    """Mean (bar) and p95 (whisker mark) error per method, one panel per case."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    records = retarget["cases"]
    columns = min(3, len(records))
    rows = math.ceil(len(records) / columns)
    figure, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 2.9 * rows), squeeze=False)
    for axis, record in zip(axes.ravel(), records):
        names, means, p95s, colours = [], [], [], []
        for method, entry in record["methods"].items():
            row = entry.get("metrics")
            names.append(method.replace("Shrinkwrap ", "SW ").replace("Springwrap ", "").replace("trimesh ", ""))
            means.append(row["error_percent_mean"] if row else np.nan)
            p95s.append(row["error_percent_p95"] if row else np.nan)
            colours.append("#d95f02" if method.startswith("Springwrap") else "#7570b3")
        positions = np.arange(len(names))
        means_array, p95_array = np.array(means, dtype=float), np.array(p95s, dtype=float)
        # A method far off the others (10 x their median) would flatten every other bar: the axis stops
        # above the rest, and the off-scale bars carry their value.
        finite_means = means_array[np.isfinite(means_array)]
        typical = np.median(finite_means) if len(finite_means) else 1.0
        in_scale = np.isfinite(means_array) & (means_array <= 10.0 * typical)
        top = 1.15 * max(np.nanmax(np.where(in_scale, np.maximum(means_array, np.nan_to_num(p95_array)), np.nan)), 1e-9)
        axis.bar(positions, np.minimum(np.nan_to_num(means_array, nan=0.0, posinf=top), top), color=colours)
        axis.scatter(
            positions[p95_array <= top],
            p95_array[p95_array <= top],
            marker="_",
            s=120,
            color="black",
            zorder=3,
            label="p95",
        )
        axis.set_ylim(0.0, top)
        for position, (mean, entry) in enumerate(zip(means, record["methods"].values())):
            if entry.get("metrics") is None:
                label = entry["status"].split(":")[0]
            elif not np.isfinite(mean):
                label = f"NaN ({entry['metrics'].get('nonfinite_vertices', '?')} vertices)"
            elif mean > top:
                label = f"{mean:.1f} (off scale)"
            else:
                continue
            axis.text(
                position,
                0.03 * top if entry.get("metrics") is None else 0.5 * top,
                label,
                rotation=90,
                ha="center",
                va="bottom" if entry.get("metrics") is None else "center",
                fontsize=7,
            )
        axis.set_xticks(positions, names, rotation=40, ha="right", fontsize=7)
        axis.set_title(record["case"], fontsize=9)
        axis.set_ylabel("error, % of diagonal", fontsize=7)
        axis.tick_params(axis="y", labelsize=7)
        axis.grid(axis="y", alpha=0.3)
    for axis in axes.ravel()[len(records) :]:
        axis.set_axis_off()
    axes.ravel()[0].legend(fontsize=7)
    figure.suptitle("Mean error per method (bars) and 95th percentile (marks)", fontsize=10)
    figure.tight_layout()
    save_palette_png(figure, path)
    plt.close(figure)
    return path


def scaling_plot(performance: dict, path: Path) -> Path:
    """Log-log time against target size and against layout size."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results = performance["results"]
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    target = results["target"]
    if target:
        triangles = [row["triangles"] for row in target]
        left.loglog(triangles, [row["build_seconds"] for row in target], "o-", label="kernel BVH build (face tree)")
        left.loglog(
            triangles,
            [row["prepare_all_seconds"] for row in target],
            "o--",
            label="kernel prepare_all (vertex tree, adjacency, normals)",
        )
        left.loglog(
            triangles,
            [row["query_seconds"] for row in target],
            "s-",
            label=f"kernel snap of {target[0]['queries']:,} points",
        )
        left.loglog(
            triangles,
            [row["shrinkwrap_first_evaluation_seconds"] for row in target],
            "^-",
            label=f"Shrinkwrap: BVH + {target[0]['queries']:,} points",
        )
    left.set_xlabel("target triangles")
    left.set_ylabel("seconds")
    left.set_title("time vs target size", fontsize=10)
    layout, wrap = results["layout"], results["wrap"]
    if layout:
        right.loglog(
            [row["points"] for row in layout],
            [row["query_seconds"] for row in layout],
            "s-",
            label=f"kernel snap on {layout[0]['target_triangles']:,} triangles",
        )
    if wrap:
        right.loglog(
            [row["layout_vertices"] for row in wrap],
            [row["wrap_seconds"] / row["wrap_iterations"] for row in wrap],
            "o-",
            label=f"wrap operator, per iteration (its {wrap[0]['wrap_iterations']} with setup / "
            f"{wrap[0]['wrap_iterations']}; {wrap[0]['target_triangles']:,} triangles)",
        )
        right.loglog(
            [row["layout_vertices"] for row in wrap],
            [row["snap_seconds"] for row in wrap],
            "^--",
            label="snap operator (incl. reading/writing the mesh)",
        )
    right.set_xlabel("layout vertices (query points)")
    right.set_title("time vs layout size", fontsize=10)
    right.set_ylim(top=right.get_ylim()[1] * 30.0)  # room for the legend above the lines
    left.legend(fontsize=7, loc="lower right")
    right.legend(fontsize=7, loc="upper left")
    for axis in (left, right):
        axis.grid(which="both", alpha=0.3)
    machine = performance["machine"]
    figure.suptitle(
        f"{machine['cpu']}, {machine['cpu_count']} CPUs (shared), kernel {machine['springwrap_kernel']}", fontsize=9
    )
    figure.tight_layout()
    save_palette_png(figure, path)
    plt.close(figure)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="figures.py", description=__doc__.splitlines()[0])
    parser.add_argument("--retarget", type=Path, default=REPOSITORY_ROOT / "out" / "bench" / "retarget.json")
    parser.add_argument("--performance", type=Path, default=REPOSITORY_ROOT / "out" / "bench" / "performance.json")
    parser.add_argument("--positions", type=Path, default=REPOSITORY_ROOT / "out" / "bench" / "retarget-positions")
    parser.add_argument("--output", type=Path, default=REPOSITORY_ROOT / "docs" / "img")
    parser.add_argument("--cases", nargs="+", default=list(HEATMAP_CASES), help="cases to render heat-maps of")
    arguments = parser.parse_args(sys.argv[1:] if argv is None else argv)
    arguments.output.mkdir(parents=True, exist_ok=True)
    retarget, performance = load_json(arguments.retarget), load_json(arguments.performance)
    written = []
    if retarget is not None:
        written.append(error_bars(retarget, arguments.output / "errors-per-method.png"))
        import tempfile

        with tempfile.TemporaryDirectory() as work:
            for record in retarget["cases"]:
                positions_file = arguments.positions / f"{record['case']}.npz"
                if record["case"] in arguments.cases and positions_file.exists():
                    path = heatmap_figure(record, positions_file, arguments.output, Path(work))
                    if path is not None:
                        written.append(path)
    else:
        print(f"figures.py: no {arguments.retarget}; run `python -m benchmarks.retarget.run` first", file=sys.stderr)
    if performance is not None:
        written.append(scaling_plot(performance, arguments.output / "scaling.png"))
    else:
        print(f"figures.py: no {arguments.performance}; run `benchmarks/performance.py` first", file=sys.stderr)
    for path in written:
        print(
            f"wrote {path.relative_to(REPOSITORY_ROOT) if path.is_relative_to(REPOSITORY_ROOT) else path} "
            f"({path.stat().st_size / 1024:.0f} KB)"
        )
    return 0 if retarget is not None and performance is not None else 1


if __name__ == "__main__":
    sys.exit(main())
