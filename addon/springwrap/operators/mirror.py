"""``springwrap.mirror``: mirror the surfaced half of a layout and wrap the copy onto the target's other half.

Paper, section 3 ("Mirroring example", Figure 8). The plane is the layout's local X, Y or Z plane,
or that plane of a mirror object (an empty), as in Blender's Mirror modifier. The operator

1. reads the layout and decides the seam (vertices on the plane), the faces that cross the plane
   and whether the plane meets the layout at all (``mirroring.plan``): a plane that misses it is
   an error and nothing is changed;
2. adds the reflected copy of the layout's faces and loose edges, winding reversed, on the seam's own
   vertices, each copy with its original's data (``mirror_data.mirror_mesh_topology``; custom normals
   reflected by ``mirror_data.mirror_custom_normals``); writes the reflected
   positions, the rest shape reflected the same way, and the state: the surfaced half keeps its
   face-points, the copy is made of space-points (``mirroring.mirrored_layout``);
3. unless ``wrap`` is off, wraps the copy onto the target with the surfaced half pinned (anchors at
   themselves) and the seam held on the plane (the kernel's plane constraint: seam points slide along
   the target's cross-section with the plane), through the same ``WrapSession`` as ``springwrap.wrap``.

Faces that cross the plane are reported with a warning and selected. Any error after step 2 puts
the mesh back as it was. Anchors and curve constraints of the surfaced half are not mirrored: they
mark features of that half of the target, and on a near-symmetric target their mirror images are
only guesses (a wrong anchor is a hard constraint); the pinned half and the seam guide the wrap.
"""

import time

import bpy

import numpy as np

from .. import property_kinds as props
from ..blender import anchors as anchor_data
from ..blender import attributes, last_run, live_wraps, wrap_session
from ..blender import layout as layout_data
from ..blender import mirror as mirror_data
from ..blender import quality as quality_data
from ..blender import shape_keys as shape_key_data
from ..blender import target as target_data
from ..blender.edit_mode import object_mode
from ..blender.wrap_session import WrapSession
from ..core import anchors, input_policy, layout_state, mirror_seam, mirroring, quality, transforms, wrap_inputs
from ..core.errors import ERRORS, LayoutError
from ..core.mirroring import AXES, DEFAULT_WELD_FRACTION, MirrorOutcome
from ..core.transforms import matrix_array
from ..core.wrap_inputs import WrapParameters
from ..properties import (
    WRAP_DEFAULTS,
    max_iterations_property,
    retired_solver_property,
    shape_keys_property,
    tolerance_property,
)
from .base import SpringwrapOperator, check_inputs, open_layout, poll_layout, report_retired_solver

LANDING_REACH = 0.25
"""Before the wrap, a copy within this fraction of its mean edge length of the target lands there at once."""
ON_PLANE_TOLERANCE = 1e-6
"""Without a wrap, a seam face-point moved onto the plane by more than this fraction of the layout's
size becomes a space-point (its face no longer lies under it)."""


class SPRINGWRAP_OT_mirror(SpringwrapOperator, bpy.types.Operator):
    """Mirror the layout across its local X, Y or Z plane (or a mirror object's), weld the seam, and wrap the new half onto the target's other half"""

    bl_label = "Mirror"

    last_outcome = None  # the last run's MirrorOutcome (class attribute: scripts and tests read it)

    axis: props.choice(
        "Axis",
        "The mirror plane is perpendicular to this axis of the layout object (or of the mirror object)",
        tuple((axis, axis, f"Mirror across the plane {axis.lower()} = 0") for axis in AXES),
        "X",
    )
    mirror_object: props.text(
        "Mirror Object", "Name of an object (an empty) whose local plane is the mirror plane; empty: the layout's own"
    )
    weld_distance: props.number(
        "Weld Distance",
        "Vertices this close to the plane, as a fraction of the mean length of their edges, are "
        "snapped onto it and shared by both halves (the seam)",
        DEFAULT_WELD_FRACTION,
        min=1e-6,
        soft_max=0.5,
        precision=3,
    )
    wrap: props.flag(
        "Wrap",
        "Wrap the new half onto the target's other half (surfaced half pinned, seam held on the plane); "
        "off: only mirror",
        True,
    )
    surfaced_half: props.choice(
        "Surfaced Half",
        "What the half that was there before does during the wrap",
        (
            ("PIN", "Pin", "It is done: it does not move, only the new half is wrapped"),
            ("FREE", "Free", "Both halves are wrapped together, the seam held on the plane"),
        ),
        "PIN",
    )
    seam: props.choice(
        "Seam",
        "What the seam (the vertices on the plane) does during the wrap",
        (
            (
                "SLIDE",
                "Slide",
                "Seam points slide along the target's cross-section with the plane, drawn by both halves",
            ),
            (
                "HOLD",
                "Hold",
                "Seam points only move onto the target's cross-section, the shortest way, and stay: the "
                "seam stays as the surfaced half has it",
            ),
        ),
        "SLIDE",
    )
    mirror_anchors: props.flag(
        "Mirror Anchors",
        "Give the new half the mirror images of the surfaced half's anchors, put on the closest target "
        "point (a guess as good as the target's symmetry); anchors on the seam are dropped either way",
        True,
    )
    solver: retired_solver_property()
    max_iterations: max_iterations_property()
    tolerance: tolerance_property()
    shape_keys: shape_keys_property(
        "A layout with shape keys: mirror every key onto the new half and carry the keys over the wrap, or refuse it"
    )

    @classmethod
    def poll(cls, context):
        return poll_layout(cls, context, require_target=False)

    def execute(self, context):
        layout = open_layout(self, context, require_target=self.wrap, moves_vertices=True)
        if layout is None:
            return {"CANCELLED"}
        type(self).last_outcome = None
        with object_mode(layout):
            try:
                live_wraps.take_over(context, layout)  # one wrap per layout: the pair tool's re-settle kept
                check_inputs(context, layout, with_target=self.wrap)
                prepared = self._prepare(context, layout)
            except ERRORS as error:
                self.report({"ERROR"}, str(error))
                return {"CANCELLED"}
            backup = mirror_data.backup_mesh(layout)
            anchors_before = (
                anchor_data.read_anchors(layout),
                layout.springwrap.anchors_signature,
                layout.springwrap.active_anchor_index,
                layout.springwrap.target_signature,
            )
            window_manager = context.window_manager
            progress = not bpy.app.background
            try:
                if progress:
                    window_manager.progress_begin(0, self.max_iterations)
                outcome = self._run(context, layout, prepared, window_manager if progress else None)
            except Exception as error:  # noqa: BLE001 - any failure puts the mesh back, then reports
                mirror_data.restore_mesh(layout, backup)
                shape_key_data.restore(layout, prepared["shape_keys"])
                anchor_data.write_anchors(layout, anchors_before[0], anchors_before[2], anchors_before[1])
                layout.springwrap.target_signature = anchors_before[3]
                self.report({"ERROR"}, f"Mirroring failed and was undone: {error}")
                return {"CANCELLED"}
            finally:
                bpy.data.meshes.remove(backup)
                if progress:
                    window_manager.progress_end()
        type(self).last_outcome = outcome
        if outcome.wrap is not None:
            wrap_session.remember_result(outcome.wrap, "Mirror")
        else:
            last_run.remember_mirror(layout.name, outcome.copies, outcome.seam_vertices)
        self._report(outcome)
        return {"FINISHED"}

    def _plane(self, context, layout):
        """(the mirror plane in world space, the name of the object it belongs to), checked by the input policy."""
        plane, owner = self._find_plane(context, layout)
        extent = None
        if self.wrap:
            extent = target_data.read_target(context.evaluated_depsgraph_get(), layout).extent
        input_policy.check_plane(plane.point, plane.normal, owner, extent)
        return plane, owner

    def _find_plane(self, context, layout):
        if not self.mirror_object:
            return mirroring.plane_from_matrix(matrix_array(layout.matrix_world), self.axis), layout.name
        mirror = context.scene.objects.get(self.mirror_object) or bpy.data.objects.get(self.mirror_object)
        if mirror is None:
            raise LayoutError(f"There is no object named '{self.mirror_object}' to mirror across")
        if mirror == layout:
            return mirroring.plane_from_matrix(matrix_array(layout.matrix_world), self.axis), layout.name
        return mirroring.plane_from_matrix(matrix_array(mirror.matrix_world), self.axis), mirror.name

    def _prepare(self, context, layout):
        """Read and check everything; decide the mirror. Writes nothing."""
        if self.wrap:
            target_data.check_target(layout)
            wrap_inputs.check_wrap_parameters(self.parameters())
        arrays = layout_data.read_layout(layout)
        if not transforms.is_invertible(arrays.matrix_world):
            raise LayoutError(f"Layout '{layout.name}' has zero scale: it cannot be mirrored")
        anchors.check_anchor_vertices(anchor_data.read_anchors(layout), arrays.positions.shape[0])
        plane, plane_owner = self._plane(context, layout)
        topology = layout_data.read_layout_topology(layout)
        world = transforms.world_positions(arrays)
        decided = mirroring.plan(
            world,
            topology.face_corners,
            topology.face_sizes,
            topology.edges,
            plane,
            self.weld_distance,
            layout_name=f"layout '{layout.name}'",
            axis=self.axis,
        )
        rest = attributes.read_rest(layout)
        world_rest = world if rest is None else wrap_inputs.rest_world_positions(arrays, rest)
        return {
            "arrays": arrays,
            "shape_keys": shape_key_data.read(layout),
            "plane": plane,
            "plane_owner": plane_owner,
            "plan": decided,
            "world": world,
            "world_rest": world_rest,
        }

    def parameters(self):
        """The wrap's ``wrap_inputs.WrapParameters`` (the wrap operator's defaults, this operator's limits)."""
        return WrapParameters(
            max_iterations=self.max_iterations,
            settings=WRAP_DEFAULTS.replace(tolerance=self.tolerance),
        )

    def _run(self, context, layout, prepared, window_manager):
        """Mirror the mesh, then wrap; raises on failure (the caller restores the mesh)."""
        start = time.perf_counter()
        self._readout = None
        arrays, plane, decided = prepared["arrays"], prepared["plane"], prepared["plan"]
        original_count = arrays.positions.shape[0]
        custom_normals = mirror_data.read_custom_normals(layout)
        mirrored_mesh = mirror_data.mirror_mesh_topology(
            layout, decided.duplicate_faces, decided.duplicate_edges, decided.seam
        )
        source = mirrored_mesh.vertex_source
        if prepared["shape_keys"] is not None:  # each copy's keys: its source's, reflected
            matrix = arrays.matrix_world
            shape_key_data.write_mirrored(
                layout,
                prepared["shape_keys"],
                source,
                original_count,
                lambda local: transforms.to_local(
                    matrix, mirroring.reflect(transforms.transform_points(matrix, local), plane)
                ),
            )
        size = float(np.linalg.norm(np.ptp(prepared["world"], axis=0))) or 1.0
        mirrored = mirroring.mirrored_layout(
            prepared["world"],
            arrays.state,
            prepared["world_rest"],
            source,
            decided.seam,
            plane,
            keep_seam_face_points=self.wrap,
            on_plane_tolerance=ON_PLANE_TOLERANCE * size,
        )
        target = None
        if layout.springwrap.target is not None:
            target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
        landed_copies = 0
        wrap_rest = None
        if self.wrap:
            mirrored_edges = layout_data.read_layout_topology(layout).edges
            if self.surfaced_half == "PIN":
                wrap_rest = mirroring.surfaced_rest(mirrored, mirrored_edges)
            edge_lengths = mirroring.vertex_edge_lengths(mirrored.positions, mirrored_edges)
            before = int((mirrored.state.states == layout_state.FACE_POINT).sum())
            mirrored = mirroring.land_copies(mirrored, edge_lengths, target, LANDING_REACH)
            landed_copies = int((mirrored.state.states == layout_state.FACE_POINT).sum()) - before
        to_local = lambda points: transforms.to_local(arrays.matrix_world, points)  # noqa: E731
        attributes.write_rest(layout, to_local(mirrored.rest))
        layout_data.write_layout(layout, to_local(mirrored.positions), mirrored.state)
        if custom_normals is not None:
            mirror_data.mirror_custom_normals(layout, custom_normals, mirrored_mesh.corner_source, plane)
        anchor_list = anchor_data.read_anchors(layout)
        if target is not None:
            anchor_list, _ = anchors.resolve(anchor_list, target, layout.springwrap.anchors_signature)
        mirrored_anchors = mirroring.mirrored_anchors(
            anchor_list, source, mirrored.is_copy, decided.seam, plane, target, mirror=self.mirror_anchors
        )
        anchor_data.write_anchors(layout, mirrored_anchors.anchors, -1, None if target is None else target.signature)
        mirror_seconds = time.perf_counter() - start
        result = None
        if self.wrap:
            # Seam vertices brought back onto the plane pull their neighbours along: those re-settle too.
            drifted = np.zeros(source.shape[0], dtype=bool)
            drifted[:original_count] = decided.drifted
            pinned = ~mirrored.is_copy & ~mirrored.seam & ~mirror_seam.resettled(mirrored_edges, drifted)
            if self.surfaced_half == "FREE":
                pinned = np.zeros_like(pinned)
            seam_vertices = np.flatnonzero(mirrored.seam)
            session = WrapSession(
                context,
                layout,
                self.parameters(),
                shape_keys=self.shape_keys,
                adjust_inputs=lambda inputs: mirroring.hold_inputs(
                    inputs, pinned, seam_vertices, plane, slide=self.seam == "SLIDE", rest=wrap_rest
                ),
            )
            if window_manager is not None:
                session.run(progress=lambda report: window_manager.progress_update(report.total_iterations))
            else:
                session.run()
            result = session.finish()
            self._readout = result.readout
        elif target is not None:  # the quality read-out, as the wrap's finish writes it
            self._readout = quality_data.update_layout(layout, target)
        if decided.crossing_faces.size:
            mirror_data.select_faces(layout, decided.crossing_faces)
        world_now = transforms.world_positions(layout_data.read_layout(layout))
        seam_distances = np.abs(mirroring.signed_distances(world_now[mirrored.seam], plane))
        return MirrorOutcome(
            layout_name=layout.name,
            plane_owner=prepared["plane_owner"],
            axis=self.axis,
            original_vertices=original_count,
            vertices=int(source.shape[0]),
            copies=int(mirrored.is_copy.sum()),
            seam_vertices=int(mirrored.seam.sum()),
            drifted_seam=int(decided.drifted.sum()),
            seam_drift=float(np.abs(decided.distances[decided.seam]).max()),
            crossing_faces=decided.crossing_faces.copy(),
            in_plane_faces=decided.in_plane_faces,
            source=source,
            is_copy=mirrored.is_copy,
            seam=mirrored.seam,
            plane=plane,
            seam_max_distance=float(seam_distances.max()) if seam_distances.size else 0.0,
            mirror_seconds=mirror_seconds,
            mirrored_anchors=mirrored_anchors.mirrored_count,
            landed_copies=landed_copies,
            dropped_anchors=mirrored_anchors.dropped_count,
            wrap=result,
            seconds=time.perf_counter() - start,
            face_points=layout_state.point_counts(attributes.read_state(layout.data).states)[0],
        )

    def _report(self, outcome) -> None:
        text = (
            f"Mirrored '{outcome.layout_name}' across the {outcome.axis} plane of '{outcome.plane_owner}': "
            f"{outcome.copies} new vertices, {outcome.seam_vertices} on the seam"
        )
        if outcome.wrap is not None:
            ending = "converged" if outcome.wrap.converged else "stopped at the iteration limit"
            text += (
                f"; the new half wrapped in {outcome.wrap.iterations} iterations ({ending}), "
                f"{outcome.wrap.face_points} face-points, {outcome.wrap.space_points} space-points"
            )
        if outcome.drifted_seam:
            text += (
                f"; {outcome.drifted_seam} of them (the half's open border, up to {outcome.seam_drift:.3g} off the "
                "plane) brought back onto it" + (" and the border re-settled" if outcome.wrap is not None else "")
            )
        if outcome.mirrored_anchors or outcome.dropped_anchors:
            text += f"; {outcome.mirrored_anchors} anchors mirrored, {outcome.dropped_anchors} on the seam dropped"
        text += f" ({outcome.seconds:.2f} s)"
        self.report({"INFO"} if outcome.wrap is None or outcome.wrap.converged else {"WARNING"}, text)
        if getattr(self, "_readout", None) is not None:
            self.report({"INFO"}, quality.report_line(self._readout))
        if outcome.wrap is not None and outcome.wrap.parts:
            self.report({"INFO"}, outcome.wrap.parts)
        if outcome.crossing_faces.size:
            self.report(
                {"WARNING"},
                f"{outcome.crossing_faces.size} faces of the layout cross the mirror plane (corners clearly on both "
                "sides): their mirror overlaps them. They are selected; cut them at the plane or move them to one side",
            )
        if outcome.wrap is not None:
            report_retired_solver(self, bpy.data.objects.get(outcome.layout_name))


classes = (SPRINGWRAP_OT_mirror,)
