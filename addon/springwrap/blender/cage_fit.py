"""The subdivision cage fit in Blender: the layout read as a cage, Blender's own Subdivision Surface points of
any cage position (a temporary object with the modifier, removed again), and the fitted cage written back.

``core.cage_fit`` does the fitting on arrays; this module is its only contact with Blender data.
"""

from typing import NamedTuple

import bpy

import numpy as np

from ..core import anchors as anchor_logic
from ..core import cage_fit, layout_state, parts, proposals, transforms
from ..core.errors import LayoutError
from . import anchors as anchor_data
from . import compat
from . import layout as layout_data
from . import parts as part_data
from .evaluated_mesh import read_evaluated_mesh

TEMPORARY_NAME = "springwrap_cage_fit"
"""Name of the temporary object (and mesh) that evaluates Blender's Subdivision Surface during a fit."""


class CageFitParameters(NamedTuple):
    """What the operator, the command line and the benchmark ask of a fit."""

    levels: int = cage_fit.DEFAULT_LEVELS
    rounds: int = cage_fit.DEFAULT_ROUNDS
    boundary: str = "ALL"  # the modifier's Boundary Smooth
    smoothness: float | None = None  # None: the kernel's default
    max_distance: float = 0.0  # 0: no limit
    only_selected: bool = False


def check_no_creases(layout: bpy.types.Object) -> None:
    """Raise :class:`LayoutError` when the layout has creased edges or vertices: the fit models Blender's
    subdivision without creases (the modifier's *Use Creases* would give another surface)."""
    for domain, name in (("EDGE", "edges"), ("POINT", "vertices")):
        values = compat.read_creases(layout.data, domain)
        if values is not None and np.any(values > 0.0):
            raise LayoutError(
                f"Layout '{layout.name}' has creased {name} ({int(np.count_nonzero(values > 0.0))}): the fit "
                "models the Subdivision Surface without creases; clear them (Edge / Vertex Crease 0) first"
            )


class BlenderSubdivision:
    """Blender's Subdivision Surface of the layout's cage at any positions: a temporary object (a copy of the
    layout's mesh, identity transform, one modifier) in the scene, evaluated on demand and removed on exit.

    ``evaluate(world_positions)`` gives the subdivided points (world) and their triangles.
    """

    def __init__(self, context: bpy.types.Context, layout: bpy.types.Object, levels: int, boundary: str) -> None:
        self.context = context
        self.layout = layout
        self.levels = levels
        self.boundary = boundary
        self.mesh = None
        self.object = None

    def __enter__(self) -> "BlenderSubdivision":
        self.mesh = self.layout.data.copy()
        self.mesh.name = TEMPORARY_NAME
        self.object = bpy.data.objects.new(TEMPORARY_NAME, self.mesh)
        self.context.scene.collection.objects.link(self.object)
        modifier = self.object.modifiers.new("Subdivision", "SUBSURF")
        modifier.levels = self.levels
        modifier.render_levels = self.levels
        modifier.boundary_smooth = self.boundary
        modifier.use_limit_surface = True
        return self

    def __exit__(self, *exception) -> None:
        if self.object is not None:
            bpy.data.objects.remove(self.object)
        if self.mesh is not None:
            bpy.data.meshes.remove(self.mesh)
        self.object = self.mesh = None

    def evaluate(self, world_positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P, 3) float64 subdivided points and (T, 3) uint32 triangles of the cage at ``world_positions``."""
        self.mesh.vertices.foreach_set("co", transforms.as_float32_points(world_positions).reshape(-1))
        self.mesh.update()
        evaluated = read_evaluated_mesh(self.context.evaluated_depsgraph_get(), self.object, triangles=True)
        if evaluated is None:
            raise LayoutError(f"Blender's Subdivision Surface of '{self.layout.name}' gave no mesh")
        return evaluated.vertices, evaluated.triangles


class CageFitSession:
    """A fit of the layout (object mode data) as a subdivision cage to ``target`` (a ``core.target.Target``),
    round by round: :meth:`start` checks and reads everything, refuses a fit that will not fit in memory
    (``core.cage_fit.check_fit_size``) and builds the run (Blender's subdivision on a temporary object);
    :meth:`step` runs a round; :meth:`finish` writes the best cage (moved vertices become space-points) and
    :meth:`cancel` writes nothing. Either removes the temporary object. The modal operator drives it by
    :meth:`tick` instead of :meth:`step`: the kernel's part of each round runs in a worker thread
    (``core.cage_fit.RoundWorker``) and :meth:`cancel` stops it inside the round. Anchors hold their vertex's point of the
    subdivided surface on their target point (face anchors found again on the current target; the list itself
    is not rewritten). Every problem raises one of ``core.errors.ERRORS`` before anything is written.
    """

    def __init__(self, context: bpy.types.Context, layout: bpy.types.Object, target, parameters: CageFitParameters):
        self.context = context
        self.layout = layout
        self.target = target
        self.parameters = parameters
        self.run = None
        self.size = None
        self.parts = None  # the parts the last wrap moved (core.parts.PartPlan), which follow the fit
        self._subdivision = None
        self._worker = None

    def start(self) -> "CageFitSession":
        layout, parameters = self.layout, self.parameters
        cage_fit.check_levels(parameters.levels, cage_fit.fit_defaults()["max_levels"])
        check_no_creases(layout)
        self.arrays = arrays = layout_data.read_layout(layout)
        topology = layout_data.read_layout_topology(layout)
        if topology.face_sizes.size == 0:
            raise LayoutError(f"Layout '{layout.name}' has no faces: there is no subdivision surface to fit")
        self.size = cage_fit.check_fit_size(topology.face_sizes, parameters.levels, cage_fit.available_memory())
        vertex_count = arrays.positions.shape[0]
        on_face = np.zeros(vertex_count, dtype=bool)
        on_face[np.asarray(topology.face_corners, dtype=np.int64)] = True
        movable = cage_fit.movable_mask(vertex_count, on_face, arrays.selection, parameters.only_selected)
        # The parts the last wrap moved are not fitted (the target lacks them): their faces are left out of the
        # subdivision fitted, and they follow the fitted surface's motion at the end.
        self.parts = part_data.read_followed_plan(layout, topology)
        face_corners, face_sizes = topology.face_corners, topology.face_sizes
        if self.parts is not None:
            movable &= ~self.parts.parts
            face_corners, face_sizes = parts.faces_without(topology, self.parts.parts)
        if not movable.any():
            raise LayoutError(f"Layout '{layout.name}': no vertex to move (no selected vertex on a face)")
        anchors = proposals.used_by_wrap(anchor_data.read_anchors(layout))
        anchor_logic.check_anchor_vertices(anchors, vertex_count)
        anchors, _ = anchor_logic.resolve(anchors, self.target, layout.springwrap.anchors_signature)
        valid = anchor_logic.valid_vertex_mask(anchors, vertex_count)
        anchor_logic.check_anchor_locations(anchors, valid)
        world = transforms.world_positions(arrays)
        # The kernel's mesh lives in a frame centred on the target (``core.target.CentredMesh``): the fit runs in
        # it, Blender's subdivision (affine-invariant) is evaluated in world space and brought into it.
        frame = self.target.mesh
        self._subdivision = BlenderSubdivision(self.context, layout, parameters.levels, parameters.boundary)
        subdivision = self._subdivision.__enter__()

        def evaluate(cage_in_frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            points, triangles = subdivision.evaluate(frame.from_kernel(cage_in_frame))
            return points - frame.origin, triangles

        try:
            self.run = cage_fit.CageFitRun(
                frame.kernel,
                world - frame.origin,
                face_corners,
                face_sizes,
                movable,
                levels=parameters.levels,
                rounds=parameters.rounds,
                boundary=parameters.boundary,
                smoothness=parameters.smoothness,
                max_distance=parameters.max_distance,
                anchor_vertices=anchors.vertex_indices[valid],
                anchor_points=anchors.locations[valid] - frame.origin,
                evaluate=evaluate,
            )
        except BaseException:
            self.cancel()
            raise
        return self

    @property
    def done(self) -> bool:
        return self.run.done

    def step(self) -> None:
        """One round (the temporary object removed if it fails)."""
        try:
            self.run.step()
        except BaseException:
            self.cancel()
            raise

    def tick(self) -> None:
        """Drive the fit from a timer: start the next round's kernel part in a worker thread when none runs, take
        a finished one (Blender's subdivision and the distances, here in the main thread). Raises what the
        round raised (the temporary object removed)."""
        if self._worker is None:
            self._worker = cage_fit.RoundWorker(self.run)
            return
        if self._worker.running:
            return
        worker, self._worker = self._worker, None
        try:
            self.run.advance(worker.outcome())
        except BaseException:
            self.cancel()
            raise

    def status_text(self) -> str:
        """The interface's progress line."""
        return (
            f"Fit Subdivision: round {self.run.round + 1} of {self.run.rounds}, level {self.parameters.levels} "
            f"({self.size.points:,} points, about {self.size.seconds:.0f} s a round); Esc stops (nothing written)"
        )

    def finish(self) -> cage_fit.CageFitOutcome:
        """Write the best cage and remove the temporary object."""
        self.cancel()
        outcome = self.run.outcome()
        outcome = outcome._replace(positions=self.target.mesh.from_kernel(outcome.positions))
        local = transforms.to_local(self.arrays.matrix_world, outcome.positions)
        positions = np.where(outcome.moved[:, None], local, self.arrays.positions)
        moved = outcome.moved
        if self.parts is not None:  # the parts: moved by the surface's motion, off the target
            world = transforms.world_positions(self.arrays)
            follower = parts.make_follower(self.parts, world)
            followed = parts.follow(
                follower, self.parts, transforms.transform_points(self.arrays.matrix_world, positions)
            )
            positions = transforms.to_local(self.arrays.matrix_world, followed)
            moved = moved | self.parts.parts
        state = layout_state.detach_points(self.arrays.state, moved)
        layout_data.write_layout(self.layout, positions, state)
        return outcome

    def cancel(self) -> None:
        """Stop a round running in the worker (inside the round) and remove the temporary object; the layout is
        left as it was before the fit."""
        if self._worker is not None:
            self._worker.stop()
            self._worker = None
        if self._subdivision is not None:
            self._subdivision.__exit__(None, None, None)
            self._subdivision = None


def fit_subdivision(
    context: bpy.types.Context, layout: bpy.types.Object, target, parameters: CageFitParameters
) -> cage_fit.CageFitOutcome:
    """The whole fit at once (:class:`CageFitSession`: the command line, scripts, the operator without a window)."""
    session = CageFitSession(context, layout, target, parameters).start()
    while not session.done:
        session.step()
    return session.finish()
