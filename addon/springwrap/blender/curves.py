"""The layout's curve constraints (``Object.springwrap.curve_constraints``), and the target polylines they
follow read again from their sources: an open spline of a curve object, or a chain of target vertices.
"""

import bpy

import numpy as np

from ..core import anchors, curves, edge_paths, transforms
from ..core.errors import LayoutError
from .evaluated_mesh import read_evaluated_mesh
from .layout import read_world_vertex_positions
from .target import read_target_edges


def read_curve_polyline(depsgraph: bpy.types.Depsgraph, curve_object: bpy.types.Object, near=None) -> np.ndarray:
    """(P, 3) float64 world points of an evaluated curve object, in order along its open spline.

    A curve object of several splines (``springwrap.detect_features`` puts all ridges in one) gives the
    spline nearest to ``near`` ((K, 3) world points: the chain being paired, or the polyline cached
    when it was): the mean distance of those points to each spline's points decides.
    Raises :class:`LayoutError` when it is not a curve object, or when the chosen spline is not open
    or has fewer than two points, or when it has several splines and ``near`` is None.
    """
    if curve_object is None or curve_object.type != "CURVE":
        raise LayoutError("The curve constraint's curve object is missing or not a curve")
    evaluated = read_evaluated_mesh(depsgraph, curve_object, edges=True, world=False)
    if evaluated is None:
        raise LayoutError(f"Curve '{curve_object.name}' has no points")
    positions, edges = evaluated.vertices, evaluated.edges
    if positions.shape[0] < 2:
        raise LayoutError(f"Curve '{curve_object.name}' has fewer than two points")
    world = transforms.transform_points(evaluated.matrix_world, positions)
    pieces = edge_paths.edge_graph(positions, edges).pieces
    starts = np.unique(pieces[np.asarray(edges, dtype=np.int64).reshape(-1)]) if len(edges) else pieces[:0]
    if starts.size > 1:
        if near is None:
            raise LayoutError(f"Curve '{curve_object.name}' has several splines: a constraint follows one open spline")
        near = np.asarray(near, dtype=np.float64).reshape(-1, 3)
        distances = np.linalg.norm(near[:, None, :] - world[None, :, :], axis=2)
        errors = [distances[:, pieces == start].min(axis=1).mean() for start in starts.tolist()]
        kept = np.flatnonzero(pieces == starts[int(np.argmin(errors))])
        renumber = np.full(positions.shape[0], -1, dtype=np.int64)
        renumber[kept] = np.arange(kept.size)
        edges = renumber[np.asarray(edges, dtype=np.int64).reshape(-1, 2)]
        edges = edges[(edges >= 0).all(axis=1)]
        world = world[kept]
    try:
        order = edge_paths.chain_from_edges(edges)
    except LayoutError as error:
        raise LayoutError(f"Curve '{curve_object.name}' is not one open spline: {error}") from error
    if order.size != world.shape[0]:
        raise LayoutError(f"Curve '{curve_object.name}' has several splines: a constraint follows one open spline")
    return world[order]


def read_curve_constraints(layout: bpy.types.Object) -> list:
    """The layout's curve constraints as stored (cached polylines), as ``curves.CurveConstraint``, in list order."""
    constraints = []
    for item in layout.springwrap.curve_constraints:
        points = np.empty(len(item.points) * 3, dtype=np.float64)
        if len(item.points):
            item.points.foreach_get("co", points)
        fractions = np.empty(len(item.fractions), dtype=np.float64)
        if len(item.fractions):
            item.fractions.foreach_get("value", fractions)
        chain = curves.parse_indices(item.layout_vertices)
        constraints.append(
            curves.make_constraint(
                chain,
                points,
                item.source_kind,
                curves.parse_indices(item.target_vertices),
                item.curve_object,
                item.confidence,
                fractions if fractions.size == chain.size else (),
            )
        )
    return constraints


def write_curve_constraints(layout: bpy.types.Object, constraints, active_index: int = -1) -> None:
    """Replace the layout's curve constraints; make ``active_index`` active (-1 keeps the current one, clamped)."""
    settings = layout.springwrap
    items = settings.curve_constraints
    items.clear()
    for constraint in constraints:
        item = items.add()
        item.layout_vertices = curves.format_indices(constraint.layout_vertices)
        item.source_kind = constraint.source_kind
        item.curve_object = constraint.curve_object if constraint.source_kind == curves.CURVE_OBJECT else None
        item.target_vertices = curves.format_indices(constraint.target_vertices)
        item.confidence = constraint.confidence
        for _ in range(constraint.points.shape[0]):
            item.points.add()
        if constraint.points.shape[0]:
            item.points.foreach_set("co", np.ascontiguousarray(constraint.points, dtype=np.float32).reshape(-1))
        for _ in range(constraint.fractions.size):
            item.fractions.add()
        if constraint.fractions.size:
            item.fractions.foreach_set("value", np.ascontiguousarray(constraint.fractions, dtype=np.float32))
    chosen = active_index if active_index >= 0 else settings.active_curve_constraint_index
    settings.active_curve_constraint_index = max(anchors.clamp_active_index(chosen, len(items)), 0)


def resolve_curve_constraints(depsgraph: bpy.types.Depsgraph, layout: bpy.types.Object, constraints) -> list:
    """The constraints with their target polylines read again from their sources (evaluated, world space).

    A curve object's polyline is oriented (and a closed one cut) to follow the cached polyline as a
    whole (or, with no cache, the chain: ``curves.orient_to_chain``); a target edge chain is read
    at its target vertices.
    Raises :class:`LayoutError` naming the constraint whose source is gone or unusable.
    """
    constraints = list(constraints)
    if not constraints:
        return []
    target_positions = None
    resolved = []
    for number, constraint in enumerate(constraints):
        if constraint.source_kind == curves.FEATURE_LINE:  # the stretch of feature found by pairing, kept
            if constraint.points.shape[0] < 2:
                raise LayoutError(f"Curve constraint {number} has lost its feature curve: pair the feature lines again")
            points = constraint.points
        elif constraint.source_kind == curves.CURVE_OBJECT:
            if constraint.points.shape[0] >= 2:
                reference = constraint.points
            else:
                reference = read_world_vertex_positions(layout, constraint.layout_vertices)
            try:
                points = read_curve_polyline(depsgraph, constraint.curve_object, near=reference)
            except LayoutError as error:
                raise LayoutError(f"Curve constraint {number}: {error}") from error
            points = curves.orient_to_chain(points, reference)
        else:
            if target_positions is None:
                target_positions, _edges = read_target_edges(depsgraph, layout)
            indices = constraint.target_vertices
            bad = indices[(indices < 0) | (indices >= target_positions.shape[0])]
            if bad.size or indices.size < 2:
                raise LayoutError(
                    f"Curve constraint {number} follows target vertices the target no longer has "
                    f"(it has {target_positions.shape[0]}): remove it and pair the chain again"
                )
            points = target_positions[indices]
        resolved.append(constraint._replace(points=points))
    return resolved
