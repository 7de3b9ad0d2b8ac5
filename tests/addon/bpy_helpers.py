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


def number_faces_canonically(mesh) -> None:
    """Renumber ``mesh``'s faces the same way whatever order they were made in: each face's corners start at its
    lowest vertex (winding kept), the faces sorted by their corners. Blender's UV sphere numbers its faces (and
    where each starts) differently from one call to the next, on the same vertices: two scenes built alike would
    otherwise hand the wrap two differently triangulated targets."""
    corners = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", corners)  # every Blender (".corner_vert" is 4.0+)
    starts = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_start", starts)
    sizes = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", sizes)
    faces = []
    for start, size in zip(starts.tolist(), sizes.tolist()):
        face = corners[start : start + size].tolist()
        first = face.index(min(face))
        faces.append(tuple(face[first:] + face[:first]))
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    mesh.clear_geometry()
    mesh.from_pydata(positions.reshape(-1, 3).tolist(), [], sorted(faces))
    mesh.update()


def sphere_scene():
    """A UV-sphere target (radius 1.5) and a 10x10 grid bent onto a concentric cap of radius 1.8 (80 degrees wide)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=SPHERE_RADIUS, location=SPHERE_CENTER)
    target = bpy.context.active_object
    number_faces_canonically(target.data)
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


def wrapped_at_once():
    """In a fresh file, the plane scene with automatic anchors wrapped by the operator at once; the layout's
    ``snapshot`` (what a live wrap must end at)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    return snapshot(bpy.data.objects["Layout"])


def wrap_session(layout, paced=False, tolerance=None, **parameters):
    """A wrap session.

    Its frames (``advance``) run one iteration each, so that tests can count them; ``paced``: the real
    pacer, whose first frame of 1/30 s would finish these small wraps at once (a tiny ``tolerance`` keeps
    them going).
    """
    import springwrap_kernel
    from springwrap.blender.wrap_session import WrapSession
    from springwrap.core.wrap_inputs import WrapParameters
    from springwrap.core.wrap_run import FramePacer

    settings = springwrap_kernel.WrapSettings(**({} if tolerance is None else {"tolerance": tolerance}))
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


class FakeUI:
    """Stands in for the window manager, workspace, area and screen a modal operator talks to; records the calls."""

    def __init__(self):
        self.calls = []

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *args, **kwargs: self.calls.append((name, args))


class PanelRecorder:
    """Stands in for ``UILayout``: records operator buttons (and the keywords they were drawn with), labels and
    list templates."""

    def __init__(self):
        self.operators, self.labels, self.lists, self.props, self.texts = [], [], [], [], []
        self.prop_options = {}  # a property's name -> the keywords it was drawn with
        self.use_property_split = self.use_property_decorate = False
        self.active = self.alert = True

    def prop(self, data, name, **kwargs):
        self.props.append(name)
        self.prop_options[name] = kwargs

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

    def operator_menu_enum(self, idname, property, **kwargs):
        self.operators.append((idname, None))


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


# ---------------------------------------------------------------- everything else on a layout (what must survive)

_ATTRIBUTE_FIELDS = {
    # data type: (foreach property, numpy dtype, components)
    "FLOAT": ("value", np.float32, 1),
    "INT": ("value", np.int32, 1),
    "INT8": ("value", np.int32, 1),
    "BOOLEAN": ("value", bool, 1),
    "FLOAT_VECTOR": ("vector", np.float32, 3),
    "FLOAT2": ("vector", np.float32, 2),
    "FLOAT_COLOR": ("color", np.float32, 4),
    "BYTE_COLOR": ("color", np.float32, 4),
    "INT32_2D": ("value", np.int32, 2),
    "INT16_2D": ("value", np.int32, 2),
    "QUATERNION": ("value", np.float32, 4),
    "FLOAT4X4": ("value", np.float32, 16),
}
"""How each attribute type is read and written with foreach_get / foreach_set (STRING goes item by item)."""

CUSTOM_ATTRIBUTE_TYPES = tuple(
    data_type
    for data_type in ("FLOAT", "INT", "INT8", "BOOLEAN", "FLOAT_VECTOR", "FLOAT2", "FLOAT_COLOR", "BYTE_COLOR")
    + ("INT32_2D", "INT16_2D", "QUATERNION", "FLOAT4X4", "STRING")
    if data_type in bpy.types.Attribute.bl_rna.properties["data_type"].enum_items.keys()
)
"""The attribute types of this Blender that a user can add (3.4 has the first eight and STRING)."""

ATTRIBUTE_DOMAINS = ("POINT", "EDGE", "FACE", "CORNER")

VERTEX_GROUPS = ("Arm.L", "Arm.R", "Spine", "hand_L", "hand_R", "Eye.L")
"""The dressed layout's vertex groups: two mirror pairs in Blender's two naming conventions, one central group
and one whose mirror partner does not exist (Blender's Mirror modifier then keeps the weights in it)."""

SPRINGWRAP_STATE = ("springwrap_state", "springwrap_face", "springwrap_bary")
"""What the operators write by design (besides positions): the face-point state."""
UV_SELECTION = (".uv_select_vert", ".uv_select_edge", ".uv_select_face")
"""The UV editor's selection, which Blender adds (all False) whenever a mesh goes through bmesh or edit mode."""


def attribute_values(attribute) -> np.ndarray:
    """The raw values of an attribute (any domain and type) as a numpy array (STRING: an object array)."""
    if attribute.data_type == "STRING":
        return np.array([item.value for item in attribute.data], dtype=object)
    field, dtype, width = _ATTRIBUTE_FIELDS[attribute.data_type]
    values = np.empty(len(attribute.data) * width, dtype=dtype)
    attribute.data.foreach_get(field, values)
    return values.reshape(len(attribute.data), width)


def _random_attribute_values(data_type, count, random):
    if data_type == "STRING":
        return [f"s{value}" for value in random.integers(0, 1000, count)]
    _field, _dtype, width = _ATTRIBUTE_FIELDS[data_type]
    if data_type == "BOOLEAN":
        return random.random(count) < 0.5
    if data_type == "INT8":
        return random.integers(-128, 128, count)
    if data_type == "INT16_2D":
        return random.integers(-32768, 32768, count * width)
    if data_type in ("INT", "INT32_2D"):
        return random.integers(-(2**31), 2**31, count * width)
    if data_type == "BYTE_COLOR":
        return random.integers(0, 256, count * width) / 255.0  # exactly representable in a byte
    return random.normal(size=count * width) * 10.0 ** random.integers(-3, 4, count * width)


def set_attribute(mesh, name, data_type, domain, values) -> None:
    """Create (or fill) an attribute with ``values`` (flat, or a list of strings)."""
    attribute = mesh.attributes.get(name) or mesh.attributes.new(name, data_type, domain)
    if data_type == "STRING":
        for item, value in zip(attribute.data, values):
            try:
                item.value = value
            except TypeError:  # Blender 5.0 takes bytes, 3.4 a str
                item.value = value.encode()
        return
    field, dtype, _width = _ATTRIBUTE_FIELDS[data_type]
    attribute.data.foreach_set(field, np.ascontiguousarray(values, dtype=dtype).ravel())


def read_creases(mesh, domain: str) -> np.ndarray | None:
    """Vertex (``POINT``) or edge (``EDGE``) creases, None when the mesh has no such layer (any supported Blender)."""
    from springwrap.blender import compat

    return compat.read_creases(mesh, domain)


def set_creases(mesh, domain: str, values) -> None:
    """Write vertex (``POINT``) or edge (``EDGE``) creases: attributes ``crease_vert`` / ``crease_edge`` since
    Blender 4.0; before, the edges' ``crease`` and a bmesh vertex crease layer (3.4 offers no other way)."""
    values = np.ascontiguousarray(values, dtype=np.float32)
    if bpy.app.version >= (4, 0, 0):
        set_attribute(mesh, "crease_vert" if domain == "POINT" else "crease_edge", "FLOAT", domain, values)
    elif domain == "EDGE":
        mesh.edges.foreach_set("crease", values)
    else:
        editable = bmesh.new()
        editable.from_mesh(mesh)
        layer = editable.verts.layers.crease.verify()
        for vertex, value in zip(editable.verts, values.tolist()):
            vertex[layer] = value
        editable.to_mesh(mesh)
        editable.free()
    mesh.update()


def _flags(collection, name, dtype=bool):
    values = np.empty(len(collection), dtype=dtype)
    collection.foreach_get(name, values)
    return values


def repair_edge_selection(mesh) -> None:
    """Remove a ``.select_edge`` attribute that is not BOOLEAN: bpy 5.0.1's ``from_pydata`` makes it INT32_2D, and
    setting edge selection then crashes (Blender recreates it right on the next selection change)."""
    broken = mesh.attributes.get(".select_edge")
    if broken is not None and broken.data_type != "BOOLEAN":
        mesh.attributes.remove(broken)


def dress_layout(layout, creases=True, seed=7):
    """Give the layout everything an artist's layout carries besides its shape (no shape keys): two UV maps,
    weighted vertex groups, an attribute of every type on every domain, vertex and edge creases (zero when
    ``creases`` is off: the subdivision fit refuses creased layouts), seams, sharp edges, flat and smooth faces,
    three materials, a vertex colour layer, custom split normals, a Subdivision Surface and a Mirror modifier, a
    parent, custom properties, a selection and hidden faces. Returns the parent empty."""
    random = np.random.default_rng(seed)
    mesh = layout.data
    counts = {
        "POINT": len(mesh.vertices),
        "EDGE": len(mesh.edges),
        "FACE": len(mesh.polygons),
        "CORNER": len(mesh.loops),
    }
    for name in ("UVMap", "Detail"):
        mesh.uv_layers.new(name=name)
        mesh.uv_layers[name].data.foreach_set("uv", random.random(counts["CORNER"] * 2).astype(np.float32))
    mesh.uv_layers.active_index = 1
    for name in VERTEX_GROUPS:
        group = layout.vertex_groups.new(name=name)
        for vertex in np.flatnonzero(random.random(counts["POINT"]) < 0.4).tolist():
            group.add([vertex], float(random.random()), "REPLACE")
    layout.vertex_groups["Spine"].lock_weight = True
    layout.vertex_groups.active_index = 2
    for domain in ATTRIBUTE_DOMAINS:
        for data_type in CUSTOM_ATTRIBUTE_TYPES:
            name = f"user_{domain.lower()}_{data_type.lower()}"
            set_attribute(mesh, name, data_type, domain, _random_attribute_values(data_type, counts[domain], random))
    mesh.attributes.active = mesh.attributes["user_edge_float"]
    color = mesh.color_attributes.new("Paint", "BYTE_COLOR", "CORNER")
    color.data.foreach_set("color", random.integers(0, 256, counts["CORNER"] * 4) / 255.0)
    set_creases(mesh, "POINT", random.random(counts["POINT"]) * creases)
    set_creases(mesh, "EDGE", random.random(counts["EDGE"]) * creases)
    mesh.edges.foreach_set("use_seam", random.random(counts["EDGE"]) < 0.3)
    mesh.edges.foreach_set("use_edge_sharp", random.random(counts["EDGE"]) < 0.3)
    mesh.polygons.foreach_set("use_smooth", random.random(counts["FACE"]) < 0.7)
    for name in ("Skin", "Cloth", "Metal"):
        mesh.materials.append(bpy.data.materials.new(name))
    mesh.polygons.foreach_set("material_index", random.integers(0, 3, counts["FACE"]).astype(np.int32))
    if hasattr(mesh, "use_auto_smooth"):
        mesh.use_auto_smooth = True  # custom normals need it before Blender 4.1
    normals = random.normal(size=(counts["CORNER"], 3))
    mesh.normals_split_custom_set((normals / np.linalg.norm(normals, axis=1)[:, None]).tolist())
    # Selection and hiding as Blender keeps them (flushed): an edge or face is selected when all its vertices
    # are, hidden when one of them is; nothing hidden is selected.
    hidden = random.random(counts["POINT"]) < 0.1
    selected = (random.random(counts["POINT"]) < 0.6) & ~hidden
    edge_vertices = np.empty(counts["EDGE"] * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edge_vertices)
    corner_vertices = np.empty(counts["CORNER"], dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", corner_vertices)
    corner_faces = np.repeat(np.arange(counts["FACE"]), _flags(mesh.polygons, "loop_total", np.int64))
    repair_edge_selection(mesh)
    for collection, flags in (("select", selected), ("hide", hidden)):
        reduce = np.logical_and if collection == "select" else np.logical_or
        face_flags = np.full(counts["FACE"], collection == "select")
        reduce.at(face_flags, corner_faces, flags[corner_vertices])
        mesh.vertices.foreach_set(collection, flags)
        mesh.edges.foreach_set(collection, reduce.reduce(flags[edge_vertices.reshape(-1, 2)], axis=1))
        mesh.polygons.foreach_set(collection, face_flags)
    mesh.update()
    subdivision = layout.modifiers.new("Subdivision", "SUBSURF")
    subdivision.levels = 1
    mirror = layout.modifiers.new("Mirror", "MIRROR")
    mirror.use_axis = (False, True, False)
    mirror.use_clip = True
    parent = bpy.data.objects.new("Layout Parent", None)
    bpy.context.scene.collection.objects.link(parent)
    parent.location = (0.05, -0.1, 0.02)
    parent.rotation_euler = (0.02, 0.0, 0.1)
    bpy.context.view_layer.update()
    world = layout.matrix_world.copy()
    layout.parent = parent
    layout.matrix_world = world
    layout["artist_note"] = "retopo v3"
    layout["lod"] = 2
    mesh["scan_id"] = 1234
    mesh["tags"] = [1.5, 2.5]
    bpy.context.view_layer.update()
    return parent


def layout_data(layout) -> dict:
    """Everything on the layout besides its vertex positions and Springwrap's face-point state, datum by datum,
    as values that compare equal exactly when the data are bit-identical (``repr`` or raw bytes)."""
    mesh = layout.data
    data = {}
    loop_starts = _flags(mesh.polygons, "loop_start", np.int64)
    loop_totals = _flags(mesh.polygons, "loop_total", np.int64)
    edge_vertices = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edge_vertices)
    data["topology"] = (
        len(mesh.vertices),
        edge_vertices.tobytes(),
        _flags(mesh.loops, "vertex_index", np.int64).tobytes(),
        _flags(mesh.loops, "edge_index", np.int64).tobytes(),
        loop_starts.tobytes(),
        loop_totals.tobytes(),
    )
    for uv_layer in mesh.uv_layers:
        uvs = np.empty(len(uv_layer.data) * 2, dtype=np.float32)
        uv_layer.data.foreach_get("uv", uvs)
        data[f"UV map {uv_layer.name}"] = uvs.tobytes()
    data["UV maps"] = (mesh.uv_layers.keys(), mesh.uv_layers.active_index, [uv.active_render for uv in mesh.uv_layers])
    data["vertex groups"] = repr(
        (
            [(group.name, group.index, group.lock_weight) for group in layout.vertex_groups],
            layout.vertex_groups.active_index,
        )
    )
    data["vertex group weights"] = repr(
        [[(item.group, item.weight) for item in vertex.groups] for vertex in mesh.vertices]
    )
    for attribute in mesh.attributes:
        if attribute.name in ("position",) + SPRINGWRAP_STATE + UV_SELECTION:
            continue
        values = attribute_values(attribute)
        data[f"attribute {attribute.name}"] = (
            attribute.domain,
            attribute.data_type,
            repr(values.tolist()) if values.dtype == object else values.tobytes(),
        )
    data["attribute names"] = sorted(
        (attribute.name, attribute.domain, attribute.data_type)
        for attribute in mesh.attributes
        if attribute.name not in SPRINGWRAP_STATE + UV_SELECTION
    )
    data["vertex creases"] = None if read_creases(mesh, "POINT") is None else read_creases(mesh, "POINT").tobytes()
    data["edge creases"] = None if read_creases(mesh, "EDGE") is None else read_creases(mesh, "EDGE").tobytes()
    data["seams"] = _flags(mesh.edges, "use_seam").tobytes()
    data["sharp edges"] = _flags(mesh.edges, "use_edge_sharp").tobytes()
    data["smooth faces"] = _flags(mesh.polygons, "use_smooth").tobytes()
    data["material indices"] = _flags(mesh.polygons, "material_index", np.int32).tobytes()
    data["materials"] = [material.name for material in mesh.materials]
    data["material slots"] = [(slot.link, slot.name) for slot in layout.material_slots]
    colors = mesh.color_attributes
    data["colour attributes"] = (
        colors.keys(),
        getattr(colors, "active_color_name", colors.active_color.name if colors.active_color else None),
    )
    data["active attribute"] = None if mesh.attributes.active is None else mesh.attributes.active.name
    data["custom normals"] = mesh.has_custom_normals
    for domain, collection in (("vertices", mesh.vertices), ("edges", mesh.edges), ("faces", mesh.polygons)):
        data[f"selected {domain}"] = _flags(collection, "select").tobytes()
        data[f"hidden {domain}"] = _flags(collection, "hide").tobytes()
    data["modifiers"] = repr(
        [
            (modifier.name, modifier.type, modifier.show_viewport, modifier.show_render)
            + ((modifier.levels, modifier.render_levels) if modifier.type == "SUBSURF" else ())
            + ((tuple(modifier.use_axis), modifier.use_clip) if modifier.type == "MIRROR" else ())
            for modifier in layout.modifiers
        ]
    )
    data["parent"] = (
        None if layout.parent is None else layout.parent.name,
        layout.parent_type,
        repr([tuple(row) for row in layout.matrix_parent_inverse]),
    )
    data["object custom properties"] = repr({key: layout[key] for key in layout.keys() if key != "springwrap"})
    data["mesh custom properties"] = repr(
        {key: mesh[key] if not hasattr(mesh[key], "to_list") else mesh[key].to_list() for key in mesh.keys()}
    )
    data["object selected, hidden, active"] = (
        layout.select_get(),
        layout.hide_get(),
        bpy.context.view_layer.objects.active == layout,
    )
    settings = layout.springwrap
    data["Springwrap target"] = None if settings.target is None else settings.target.name
    # A face anchor's location is a cache of its triangle and barycentric on the target, which the wrap and
    # Update Anchors refresh: on an unchanged target it may differ from the stored one in the last float bit.
    data["Springwrap anchors"] = repr(
        [
            (item.vertex_index, item.target_kind, item.triangle, tuple(item.barycentric))
            + (
                (tuple(item.location),)
                if item.target_kind != "FACE"
                else tuple(round(value, 5) for value in item.location)
            )
            for item in settings.anchors
        ]
    )
    data["Springwrap curve constraints"] = repr(
        [
            (
                item.layout_vertices,
                item.source_kind,
                item.target_vertices,
                tuple(tuple(point.co) for point in item.points),
                tuple(entry.value for entry in item.fractions),
            )
            for item in settings.curve_constraints
        ]
    )
    return data


# ---------------------------------------------------------------- a target that changes over time

SEQUENCE_FRAMES = (1, 2, 3)


def animated_target(name="Target"):
    """A UV sphere whose shape key stretches it along x over frames 1 .. 3 (value 0, 0.5, 1)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.5)
    target = bpy.context.active_object
    target.name = name
    target.shape_key_add(name="Basis", from_mix=False)
    stretch = target.shape_key_add(name="Stretch", from_mix=False)
    points = np.empty(len(stretch.data) * 3, dtype=np.float32)
    stretch.data.foreach_get("co", points)
    points = points.reshape(-1, 3)
    points[:, 0] *= 1.4
    points[:, 2] *= 0.85
    stretch.data.foreach_set("co", points.reshape(-1))
    for frame, value in zip(SEQUENCE_FRAMES, (0.0, 0.5, 1.0)):
        stretch.value = value
        stretch.keyframe_insert("value", frame=frame)
    return target


def make_sphere_layout(target, name="Layout"):
    """An ico sphere just inside the target sphere: one wrap lands every vertex."""
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=1.3, location=(0.05, -0.02, 0.03))
    return as_layout(bpy.context.active_object, name, target)


def stretched_ball_scene(landmarks: int = 3):
    """The target: a finer bumpy ball, stretched; the layout: a coarser one where Align would put it, anchored at
    its first ``landmarks`` tips' true points (hand pairs). (layout, truth: each layout vertex's true point)."""
    from helpers import ball_landmarks, ball_stretch, bumpy_ball, triangulated

    rest, faces = bumpy_ball(60, 90)
    fine, fine_faces = bumpy_ball(110, 170)
    target = make_object("Target", ball_stretch(fine), [tuple(t) for t in triangulated(fine_faces)], Matrix.Identity(4))
    layout = make_object("Layout", rest * 1.05 + np.array([0.1, -0.2, 0.05]), faces, Matrix.Identity(4))
    layout.springwrap.target = target
    activate(layout)
    truth = ball_stretch(rest)
    for vertex in ball_landmarks(rest, landmarks).tolist():
        assert bpy.ops.springwrap.anchor_add(vertex_index=vertex, location=tuple(truth[vertex]), use_location=True) == {
            "FINISHED"
        }
    return layout, truth
