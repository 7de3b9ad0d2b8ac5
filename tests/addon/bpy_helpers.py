"""Helpers the add-on tests share (Blender: ``bpy``, ``bmesh``, ``mathutils``): scene builders, readers of the
layout's state, kernel-independent references built with ``mathutils``, and stand-ins for Blender's UI.

Only tests under ``tests/addon`` import this (their conftest has reset the scene and enabled the add-on);
helpers that need no Blender are in ``tests/helpers.py``.
"""

import importlib
import math

import bpy

import bmesh
import numpy as np
from mathutils import Matrix, Vector
from mathutils.bvhtree import BVHTree
from mathutils.kdtree import KDTree

# ---------------------------------------------------------------- scenes, readers, references


TOLERANCE = 1e-5
SPACE_POINT, FACE_POINT = 0, 1


STATE_ATTRIBUTE = "springwrap_state"


FACE_ATTRIBUTE = "springwrap_face"


BARYCENTRIC_ATTRIBUTE = "springwrap_bary"


STATE_NAMES = (STATE_ATTRIBUTE, FACE_ATTRIBUTE, BARYCENTRIC_ATTRIBUTE)


def addon_module(name):
    """A submodule of the enabled add-on (importable once the conftest fixture enabled it)."""
    return importlib.import_module(f"springwrap.{name}")


def make_target(name="Target", **transform):
    """A UV sphere (radius 1.5) with an offset, a rotation and a non-uniform scale."""
    transform = {"location": (0.3, -0.2, 0.1), "rotation": (0.4, 0.1, -0.3), "scale": (1.3, 0.9, 1.1)} | transform
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.5, **transform)
    target = bpy.context.active_object
    target.name = name
    return target


def make_grid_layout(target, name="Layout", size=2.4, subdivisions=10):
    """A grid above the target, rotated and scaled; large enough that its corners miss the target."""
    bpy.ops.mesh.primitive_grid_add(
        x_subdivisions=subdivisions,
        y_subdivisions=subdivisions,
        size=size,
        location=(0.2, 0.1, 2.4),
        rotation=(0.15, -0.1, 0.5),
        scale=(1.1, 0.8, 1.0),
    )
    return as_layout(bpy.context.active_object, name, target)


def make_inner_layout(target, name="Layout"):
    """An ico sphere inside the target, non-uniformly scaled: its normals point at the target."""
    bpy.ops.mesh.primitive_ico_sphere_add(
        subdivisions=2, radius=0.7, location=(0.35, -0.15, 0.15), rotation=(0.3, 0.2, 0.1), scale=(1.2, 0.8, 1.0)
    )
    return as_layout(bpy.context.active_object, name, target)


def as_layout(obj, name, target):
    obj.name = name
    obj.springwrap.target = target
    bpy.context.view_layer.objects.active = obj
    return obj


def scene(layout_kind="grid"):
    target = make_target()
    layout = make_grid_layout(target) if layout_kind == "grid" else make_inner_layout(target)
    return target, layout


def set_selection(obj, mask):
    obj.data.vertices.foreach_set("select", np.asarray(mask, dtype=bool))
    obj.data.update()


def local_positions(obj):
    positions = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", positions)
    return positions.reshape(-1, 3)


def world_positions(obj):
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    return local_positions(obj).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def read_state(obj):
    """(states, faces, barycentrics) from the attributes, or None when they do not exist."""
    mesh = obj.data
    if any(mesh.attributes.get(name) is None for name in STATE_NAMES):
        return None
    count = len(mesh.vertices)
    states = np.empty(count, dtype=np.int32)
    faces = np.empty(count, dtype=np.int32)
    barycentrics = np.empty(count * 3, dtype=np.float32)
    mesh.attributes[STATE_ATTRIBUTE].data.foreach_get("value", states)
    mesh.attributes[FACE_ATTRIBUTE].data.foreach_get("value", faces)
    mesh.attributes[BARYCENTRIC_ATTRIBUTE].data.foreach_get("vector", barycentrics)
    return states, faces, barycentrics.reshape(-1, 3)


def snapshot(obj):
    """Everything the operators may write, as bytes: compare two snapshots for bit-identity."""
    state = read_state(obj)
    return {
        "positions": local_positions(obj).tobytes(),
        "attribute_names": sorted(obj.data.attributes.keys()),
        "state": None if state is None else tuple(array.tobytes() for array in state),
        "signature": obj.springwrap.target_signature,
    }


class Reference:
    """The evaluated target in world space, with mathutils trees over its loop triangles."""

    def __init__(self, target):
        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = target.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        mesh.calc_loop_triangles()
        matrix = evaluated.matrix_world.copy()
        self.vertices = np.array([tuple(matrix @ vertex.co) for vertex in mesh.vertices], dtype=np.float64)
        self.triangles = np.array([tuple(triangle.vertices) for triangle in mesh.loop_triangles], dtype=np.int64)
        self.polygons = np.array([triangle.polygon_index for triangle in mesh.loop_triangles], dtype=np.int64)
        evaluated.to_mesh_clear()
        self.bvh = BVHTree.FromPolygons([tuple(v) for v in self.vertices], self.triangles.tolist())
        self.kd = KDTree(len(self.vertices))
        for index, vertex in enumerate(self.vertices):
            self.kd.insert(vertex, index)
        self.kd.balance()
        self.diagonal = float(np.linalg.norm(self.vertices.max(axis=0) - self.vertices.min(axis=0)))

    def nearest(self, point):
        location, _normal, index, distance = self.bvh.find_nearest(Vector(point))
        return np.array(location), index, distance

    def ray(self, origin, direction, both_directions):
        """Nearest hit (location, signed distance) along the ray (and backwards), or (None, None)."""
        best = (None, None)
        signs = (1.0, -1.0) if both_directions else (1.0,)
        for sign in signs:
            location, _normal, _index, distance = self.bvh.ray_cast(Vector(origin), Vector(direction) * sign)
            if location is not None and (best[1] is None or distance < abs(best[1])):
                best = (np.array(location), sign * distance)
        return best

    def face_point_positions(self, faces, barycentrics):
        corners = self.vertices[self.triangles[faces]]  # (K, 3 corners, 3)
        return np.einsum("kc,kcx->kx", barycentrics.astype(np.float64), corners)

    def signature(self):
        return addon_module("core.layout_state").target_signature(self.triangles.astype(np.uint32), len(self.vertices))


def assert_face_points_consistent(layout, reference, mask=None):
    """Face-points of ``layout`` (in ``mask``) sit where their triangle + barycentrics say."""
    states, faces, barycentrics = read_state(layout)
    mask = np.ones(len(states), dtype=bool) if mask is None else mask
    chosen = mask & (states == FACE_POINT)
    assert chosen.any()
    assert np.all((faces[chosen] >= 0) & (faces[chosen] < len(reference.triangles)))
    np.testing.assert_allclose(barycentrics[chosen].sum(axis=1), 1.0, atol=1e-5)
    assert np.all(barycentrics[chosen] >= -1e-5)
    rebuilt = reference.face_point_positions(faces[chosen], barycentrics[chosen])
    np.testing.assert_allclose(rebuilt, world_positions(layout)[chosen], rtol=0, atol=TOLERANCE)


# ---------------------------------------------------------------- wrap scenes and checks


HOLE_CENTER = Vector((0.1, 0.05, 0.0))  # in the plane target's object space


HOLE_RADIUS = 0.5


PLANE_LOCATION = Vector((0.2, -0.1, 0.05))


PLANE_ROTATION = (0.2, 0.1, 0.3)


SPHERE_CENTER = Vector((0.3, -0.2, 0.1))


SPHERE_RADIUS = 1.5


def activate_layout(layout, target):
    layout.name = "Layout"
    layout.springwrap.target = target
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    return layout


def plane_target(hole=False):
    """A 4x4 plane target (40x40 quads, tilted and moved), optionally with a round hole; (target, world normal)."""
    bpy.ops.mesh.primitive_grid_add(
        x_subdivisions=40, y_subdivisions=40, size=4, location=PLANE_LOCATION, rotation=PLANE_ROTATION
    )
    target = bpy.context.active_object
    target.name = "Target"
    if hole:
        editable = bmesh.new()
        editable.from_mesh(target.data)
        doomed = [face for face in editable.faces if (face.calc_center_median() - HOLE_CENTER).length < HOLE_RADIUS]
        bmesh.ops.delete(editable, geom=doomed, context="FACES")
        editable.to_mesh(target.data)
        editable.free()
        target.data.update()
    return target, np.array(target.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0)))


def plane_scene(hole=False, subdivisions=12):
    """The plane target and a grid layout 0.3 above it; (target, layout, world normal of the plane).

    The layout is turned 0.4 rad about the plane's normal and scaled 1.1 x 0.9 (a template that is
    not the target's own grid).
    """
    target, normal = plane_target(hole)
    rotation = target.matrix_world.to_3x3()
    bpy.ops.mesh.primitive_grid_add(
        x_subdivisions=subdivisions,
        y_subdivisions=subdivisions,
        size=2,
        location=PLANE_LOCATION + Vector(normal) * 0.3,
        rotation=(rotation @ Matrix.Rotation(0.4, 3, "Z")).to_euler(),
        scale=(1.1, 0.9, 1.0),
    )
    layout = activate_layout(bpy.context.active_object, target)
    return target, layout, normal


def sphere_scene():
    """A UV-sphere target (radius 1.5) and a 10x10 grid bent onto a concentric cap of radius 1.8 (80 degrees wide)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=SPHERE_RADIUS, location=SPHERE_CENTER)
    target = bpy.context.active_object
    target.name = "Target"
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=10, y_subdivisions=10, size=2)
    layout = activate_layout(bpy.context.active_object, target)
    flat = local_positions(layout).astype(np.float64)
    spread = math.tan(math.radians(40.0))
    directions = np.stack([flat[:, 0] * spread, flat[:, 1] * spread, np.ones(len(flat))], axis=1)
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    turn = np.array(Matrix.Rotation(0.5, 3, "X") @ Matrix.Rotation(0.3, 3, "Y"))
    cap = directions @ turn.T * 1.8 + np.array(SPHERE_CENTER)
    layout.data.vertices.foreach_set("co", cap.astype(np.float32).reshape(-1))
    layout.data.update()
    return target, layout


def radial(points):
    """Unit directions from the sphere target's centre: its outward normals."""
    directions = np.asarray(points) - np.array(SPHERE_CENTER)
    return directions / np.linalg.norm(directions, axis=1)[:, None]


def edges_of(obj):
    edges = np.empty(len(obj.data.edges) * 2, dtype=np.int64)
    obj.data.edges.foreach_get("vertices", edges)
    return edges.reshape(-1, 2)


def quads_of(obj):
    corners = np.empty(len(obj.data.loops), dtype=np.int64)
    obj.data.loops.foreach_get("vertex_index", corners)
    return corners.reshape(-1, 4)  # the generated layouts are all quads


def edge_lengths(points, edges):
    return np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)


def quad_normals(points, quads):
    corners = points[quads]
    normals = np.cross(corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 1])
    return normals / np.linalg.norm(normals, axis=1)[:, None]


def anchor_targets(layout):
    """(vertex indices, world target locations) of the layout's anchors."""
    anchors = layout.springwrap.anchors
    vertices = np.array([anchor.vertex_index for anchor in anchors], dtype=np.int64)
    locations = np.array([tuple(anchor.location) for anchor in anchors], dtype=np.float64).reshape(-1, 3)
    return vertices, locations


def surface_distances(reference, points):
    return np.array([reference.nearest(point)[2] for point in points])


def wrap_with_anchors(layout, spacing, **properties):
    assert bpy.ops.springwrap.anchors_auto(spacing=spacing) == {"FINISHED"}
    return bpy.ops.springwrap.wrap(**properties)


def assert_no_flipped_quads(layout, surface_normals):
    """Every quad of the layout faces the way the surface under it does (the templates all start so)."""
    world = world_positions(layout)
    quads = quads_of(layout)
    alignment = np.einsum("kx,kx->k", quad_normals(world, quads), surface_normals(world[quads].mean(axis=1)))
    flipped = np.flatnonzero(alignment <= 0.9)
    assert not flipped.size, f"quads {flipped.tolist()} are flipped or turned on edge (alignment {alignment.min():.3f})"


def assert_wrapped_onto(layout, reference, template, surface_normals, edge_ratio_bounds, check_flips=True):
    """The checks every wrap must pass.

    Face-points lie on the target (BVHTree) and where their triangle + barycentric say; anchors
    are met; no quad is flipped against the surface normal (unless ``check_flips`` is off: a
    separate test checks it where the kernel is known to flip); every edge keeps its template length
    within ``edge_ratio_bounds`` relative to the median edge ratio (the whole sheet may shrink
    or grow, as a sphere cap does going from radius 1.8 to 1.5, but must not tear or collapse).
    """
    states, _faces, _barycentrics = read_state(layout)
    world = world_positions(layout)
    on_face = states == 1
    assert on_face.sum() > 0.5 * len(states)
    assert surface_distances(reference, world[on_face]).max() <= TOLERANCE
    assert_face_points_consistent(layout, reference)
    anchored, locations = anchor_targets(layout)
    assert len(anchored) >= 4
    np.testing.assert_allclose(world[anchored], locations, rtol=0, atol=TOLERANCE)
    if check_flips:
        assert_no_flipped_quads(layout, surface_normals)
    edges = edges_of(layout)
    ratios = edge_lengths(world, edges) / edge_lengths(template, edges)
    relative = ratios / np.median(ratios)
    low, high = edge_ratio_bounds
    assert low <= relative.min() and relative.max() <= high, (relative.min(), relative.max())


class RecordingLayout:
    """Stands in for ``UILayout``: records buttons, searched properties and disabled rows."""

    def __init__(self):
        self.operators, self.searches, self.props, self.labels = [], [], [], []
        self.use_property_split = self.use_property_decorate = False
        self.enabled = True

    def row(self, *args, **kwargs):
        return self

    def box(self, *args, **kwargs):
        return self

    def column(self, *args, **kwargs):
        return self

    split = column

    def label(self, text="", **kwargs):
        self.labels.append(text)

    def prop(self, data, name, **kwargs):
        self.props.append((name, self.enabled))

    def prop_search(self, data, name, search_data, search_name, **kwargs):
        self.searches.append((name, search_data.name, search_name))

    def operator(self, idname, **kwargs):
        self.operators.append(idname)
        return type("Button", (), {})()


def curves_layout(target, shift):
    """A quad strip (2 x 8 quads) with a seam along its middle row and a loose 9-vertex chain (a curve).

    Placed in the plane target's frame, 0.25-0.3 above it, moved by ``shift`` (in the plane).
    """
    mesh = bpy.data.meshes.new("Curves")
    strip = [(x + shift, y + shift, 0.3) for y in (-0.2, 0.0, 0.2) for x in np.linspace(-0.8, 0.8, 9)]
    chain = [(x + shift, 0.6 + shift, 0.25) for x in np.linspace(-0.8, 0.8, 9)]
    faces = [(row * 9 + i, row * 9 + i + 1, row * 9 + i + 10, row * 9 + i + 9) for row in range(2) for i in range(8)]
    chain_edges = [(27 + i, 28 + i) for i in range(8)]
    mesh.from_pydata(strip + chain, chain_edges, faces)
    mesh.update()
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edges)
    mesh.edges.foreach_set("use_seam", (edges.reshape(-1, 2) // 9 == 1).all(axis=1))  # the strip's middle row
    layout = bpy.data.objects.new("Curves", mesh)
    bpy.context.scene.collection.objects.link(layout)
    layout.matrix_world = target.matrix_world.copy()
    return activate_layout(layout, target)


def wrap_session(layout, solver="SPRINGS", paced=False, tolerance=None, **parameters):
    """A wrap session; the spring solver unless said (its hundreds of iterations make many frames).

    Its frames (``advance``) run one iteration each, so that tests can count them; ``paced``: the real
    pacer, whose first frame of 1/30 s would finish these small wraps at once (a tiny ``tolerance`` keeps
    them going).
    """
    import springwrap_kernel
    from springwrap.blender.wrap_session import WrapSession
    from springwrap.core.wrap_inputs import WrapParameters
    from springwrap.core.wrap_run import FramePacer

    settings = springwrap_kernel.WrapSettings(solver=solver, **({} if tolerance is None else {"tolerance": tolerance}))
    session = WrapSession(bpy.context, layout, WrapParameters(settings=settings, **parameters))
    if not paced:
        session.pacer = FramePacer(frame_rate=1e6)  # a microsecond of solving: one iteration a frame
    return session


# ---------------------------------------------------------------- anchors


def anchor_rows(layout):
    """The anchor list as plain tuples (vertex, kind, triangle, barycentric, location)."""
    return [
        (anchor.vertex_index, anchor.target_kind, anchor.triangle, tuple(anchor.barycentric), tuple(anchor.location))
        for anchor in layout.springwrap.anchors
    ]


def anchor_snapshot(layout):
    """Everything the anchor operators may write: compare two snapshots for identity."""
    settings = layout.springwrap
    return {
        "anchors": repr(anchor_rows(layout)),  # repr: a NaN equals itself
        "active": settings.active_anchor_index,
        "signature": settings.anchors_signature,
        "positions": world_positions(layout).tobytes(),
        "attributes": sorted(layout.data.attributes.keys()),
    }


class PanelRecorder:
    """Stands in for ``UILayout``: records operator buttons (and the keywords they were drawn with), labels and
    list templates."""

    def __init__(self):
        self.operators, self.labels, self.lists, self.props, self.texts = [], [], [], [], []
        self.use_property_split = self.use_property_decorate = False
        self.active = self.alert = True

    def prop(self, data, name, **kwargs):
        self.props.append(name)

    def label(self, text="", **kwargs):
        self.labels.append(text)

    def template_list(self, *args, **kwargs):
        self.lists.append(args)

    def separator(self, *args, **kwargs):
        pass

    def column(self, *args, **kwargs):
        return self

    row = box = split = column

    def operator(self, idname, **kwargs):
        button = type("Button", (), {})()
        self.operators.append((idname, button))
        self.texts.append((idname, kwargs))
        return button


# ---------------------------------------------------------------- curves


def select_edges(layout, vertex_pairs):
    """Select exactly the edges joining the given vertex pairs (object mode data), then enter edit mode."""
    wanted = {tuple(sorted(pair)) for pair in vertex_pairs}
    mesh = layout.data
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edges)
    keys = [tuple(sorted(pair)) for pair in edges.reshape(-1, 2).tolist()]
    selected = np.array([key in wanted for key in keys])
    assert selected.sum() == len(wanted)
    vertices = np.zeros(len(mesh.vertices), dtype=bool)
    vertices[np.array(sorted(wanted)).reshape(-1)] = True
    mesh.vertices.foreach_set("select", vertices)
    mesh.edges.foreach_set("select", selected)
    mesh.polygons.foreach_set("select", np.zeros(len(mesh.polygons), dtype=bool))
    mesh.update()
    bpy.context.tool_settings.mesh_select_mode = (False, True, False)
    bpy.ops.object.mode_set(mode="EDIT")


def chain_pairs(chain):
    return list(zip(chain[:-1], chain[1:]))


def distance_to_polyline(points, polyline):
    """(K,) distance of each point to the polyline (its segments)."""
    starts, ends = polyline[:-1], polyline[1:]
    direction = ends - starts
    lengths = np.maximum((direction**2).sum(axis=1), 1e-30)
    offsets = points[:, None, :] - starts[None, :, :]
    t = np.clip(np.einsum("ksx,sx->ks", offsets, direction) / lengths, 0.0, 1.0)
    closest = starts[None, :, :] + t[:, :, None] * direction[None, :, :]
    return np.sqrt(((points[:, None, :] - closest) ** 2).sum(axis=2)).min(axis=1)


# ---------------------------------------------------------------- mirror scenes


PLACEMENT = Matrix.Translation((0.3, -0.2, 0.15)) @ Matrix.Rotation(0.4, 4, Vector((0.3, 1.0, 0.2)).normalized())


def half_sphere_grid(rings: int, segments: int):
    """Unit directions of the x >= 0 half of a sphere grid (midline exactly at x = 0) and its faces (poles: triangles)."""
    polar = np.linspace(0.0, np.pi, rings + 1)[1:-1]
    azimuth = np.linspace(-np.pi / 2, np.pi / 2, segments + 1)
    grid_polar, grid_azimuth = np.meshgrid(polar, azimuth, indexing="ij")
    directions = np.stack(
        [np.sin(grid_polar) * np.cos(grid_azimuth), np.sin(grid_polar) * np.sin(grid_azimuth), np.cos(grid_polar)],
        axis=-1,
    ).reshape(-1, 3)
    directions[np.isclose(np.abs(grid_azimuth.ravel()), np.pi / 2), 0] = 0.0
    directions = np.vstack([[0.0, 0.0, 1.0], directions, [0.0, 0.0, -1.0]])
    columns = segments + 1
    south = len(directions) - 1

    def index(ring, column):
        return 1 + ring * columns + column

    faces = []  # wound one way (outward), the pole triangles as the quads
    for column in range(segments):
        faces.append([index(0, column), index(0, column + 1), 0])
        faces.append([index(rings - 2, column + 1), index(rings - 2, column), south])
    for ring in range(rings - 2):
        for column in range(segments):
            faces.append(
                [index(ring + 1, column), index(ring + 1, column + 1), index(ring, column + 1), index(ring, column)]
            )
    return directions, faces


def head_shape(directions: np.ndarray) -> np.ndarray:
    """A head-like deformation, symmetric in x: a nose on the midline, two ears, a flattened top."""
    x, y, z = np.abs(directions[:, 0]), directions[:, 1], directions[:, 2]
    nose = 0.25 * np.exp(-(x**2 + (y - 0.9) ** 2 + (z - 0.1) ** 2) / 0.05)
    ears = 0.15 * np.exp(-((x - 0.95) ** 2 + y**2 + (z - 0.2) ** 2) / 0.04)
    radius = 1.0 + 0.15 * z**2 + 0.1 * y * x**2 + nose + ears
    return directions * radius[:, None]


def symmetric_target_arrays(rings: int = 48, segments: int = 48):
    """(V, 3) vertices and (T, 3) triangles of an exactly symmetric (x -> -x) closed head, in its own space."""
    directions, faces = half_sphere_grid(rings, segments)
    vertices = head_shape(directions)
    triangles = []
    for face in faces:
        triangles += [face] if len(face) == 3 else [[face[0], face[1], face[2]], [face[0], face[2], face[3]]]
    triangles = np.array(triangles, dtype=np.int64)
    off_plane = np.flatnonzero(vertices[:, 0] != 0.0)
    partner = np.arange(len(vertices))
    partner[off_plane] = len(vertices) + np.arange(off_plane.size)
    mirrored = vertices[off_plane] * np.array([-1.0, 1.0, 1.0])
    return np.vstack([vertices, mirrored]), np.vstack([triangles, partner[triangles][:, ::-1]])


def make_object(name, vertices, faces, matrix=PLACEMENT):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, point)) for point in vertices], [], [list(map(int, face)) for face in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    obj.matrix_world = matrix
    bpy.context.scene.collection.objects.link(obj)
    return obj


def activate(layout):
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout


def head_scene(scale=1.05, on_target=False):
    """The symmetric head target and a half-head layout (12 rings, 8 columns) around it, both placed by PLACEMENT.

    ``on_target``: the layout's vertices are target vertices (its grid is every 4th ring and 6th column of the
    target's), else a sphere of radius ``scale``.
    """
    target = make_object("Target", *symmetric_target_arrays())
    directions, faces = half_sphere_grid(12, 8)
    layout = make_object("Layout", head_shape(directions) if on_target else directions * scale, faces)
    layout.springwrap.target = target
    activate(layout)
    return target, layout


def symmetric_head_scene(scale=1.05, shuffle_seed=0):
    """The symmetric head target and a whole sphere layout around it (both halves of a 12 x 8 half grid, the
    second reflected, faces reversed), its vertices numbered in a shuffled order; both placed by PLACEMENT.

    Returns (target, layout, twins): ``twins`` (N,) each layout vertex's mirror image (itself on x = 0).
    """
    target = make_object("Target", *symmetric_target_arrays())
    directions, faces = half_sphere_grid(12, 8)
    off_plane = np.flatnonzero(directions[:, 0] != 0.0)
    partner = np.arange(len(directions))
    partner[off_plane] = len(directions) + np.arange(off_plane.size)
    vertices = np.vstack([directions, directions[off_plane] * [-1.0, 1.0, 1.0]]) * scale
    faces = [list(face) for face in faces] + [list(partner[face][::-1]) for face in faces]
    twins = np.arange(len(vertices))
    twins[partner] = np.arange(len(directions))
    twins[np.arange(len(directions))] = partner
    old_of_new = np.random.default_rng(shuffle_seed).permutation(len(vertices))
    new_of_old = np.argsort(old_of_new)
    layout = make_object("Layout", vertices[old_of_new], [list(new_of_old[face]) for face in faces])
    layout.springwrap.target = target
    activate(layout)
    return target, layout, new_of_old[twins[old_of_new]]


def world_plane():
    """The layout's local x = 0 plane in world space: (point, unit normal)."""
    normal = np.array(PLACEMENT.to_3x3() @ Vector((1.0, 0.0, 0.0)))
    return np.array(PLACEMENT.translation), normal / np.linalg.norm(normal)


def mirror_outcome():
    from springwrap.operators.mirror import SPRINGWRAP_OT_mirror

    return SPRINGWRAP_OT_mirror.last_outcome


def midline_drift(layout, midline):
    point, normal = world_plane()
    return float(np.abs((world_positions(layout)[midline] - point) @ normal).max())


# ---------------------------------------------------------------- bad inputs (each breaks the scene one way)


def no_target(target, layout):
    layout.springwrap.target = None


def empty_target(target, layout):
    target.data.clear_geometry()


def delete_faces(obj, polygons=None):
    """Delete the mesh's polygons of these indices (all of them by default), keeping their vertices and edges."""
    mesh = obj.data
    editable = bmesh.new()
    editable.from_mesh(mesh)
    editable.faces.ensure_lookup_table()
    faces = list(editable.faces) if polygons is None else [editable.faces[int(i)] for i in polygons]
    bmesh.ops.delete(editable, geom=faces, context="FACES_ONLY")
    editable.to_mesh(mesh)
    editable.free()
    mesh.update()


def target_without_faces(target, layout):
    delete_faces(target)


def nan_target_vertex(target, layout):
    target.data.vertices[5].co.y = math.nan
    target.data.update()


def nan_layout_vertex(target, layout):
    layout.data.vertices[7].co.z = math.nan
    layout.data.update()
