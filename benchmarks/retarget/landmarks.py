"""Landmarks: named layout vertices that stand for an artist's anchors, chosen by geometry.

An artist retargeting a body pins a few unmistakable points (fingertips, nose tip, chin,
navel, knees...) and lets the tool do the rest. The benchmark places anchors at those layout
vertices' *true* positions on the target. Which vertices they are is decided here, once, on the
template alone, by rules on its geometry (never by hand-picked indices), so the choice is
deterministic, documented and independent of any target.

The body rules (:data:`BODY_LANDMARKS`) assume the MakeHuman base mesh's frame: metres, +Y up,
+Z the front, +X the body's left, standing in its A-pose. Heights are fractions ``h`` of the
template's height (0 at the soles, 1 at the crown), sideways extents fractions of its half span
``w`` (|x| at the outermost fingertip); ``d`` is the geodesic distance (along mesh edges) from
the navel. Their order is a priority: the first ``count`` are used, spread over the body first
(head, hands, feet, knees), then filling in.

For other shapes (the synthetic cases) :func:`farthest_point_landmarks` picks ``count`` vertices
by farthest-point sampling from the vertex of largest x, which also only depends on geometry.
Everything here is numpy (and ``heapq`` for geodesic distances); no ``bpy``.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

# (name, rule) in priority order; the rule is what `body_landmarks` implements, said in words.
BODY_LANDMARKS: tuple[tuple[str, str], ...] = (
    ("crown", "highest vertex"),
    ("nose_tip", "most forward vertex above h = 0.85"),
    ("chin", "midline vertex maximising z - y between 0.03 m and 0.12 m below the nose tip"),
    ("navel", "front-midline vertex between h = 0.48 and 0.65 deepest below the front profile 2.5 cm above and below"),
    ("left_middle_fingertip", "left hand: 2nd-most forward of the 4 fingertips other than the thumb"),
    ("right_middle_fingertip", "right hand: likewise"),
    ("left_big_toe", "most forward vertex of the left foot (h < 0.05)"),
    ("right_big_toe", "most forward vertex of the right foot"),
    ("left_knee", "most forward vertex of the left leg between h = 0.27 and 0.29 (knee height)"),
    ("right_knee", "most forward vertex of the right leg between h = 0.27 and 0.29"),
    ("left_thumb_tip", "left hand: the fingertip nearest the navel (geodesically)"),
    ("right_thumb_tip", "right hand: likewise"),
    ("left_elbow", "rearmost vertex of the left arm (|x| > 0.6 w) between h = 0.62 and 0.76"),
    ("right_elbow", "rearmost vertex of the right arm between h = 0.62 and 0.76"),
    ("left_heel", "rearmost vertex of the left foot (h < 0.05)"),
    ("right_heel", "rearmost vertex of the right foot"),
    ("left_ear", "outermost vertex on the left above h = 0.88"),
    ("right_ear", "outermost vertex on the right above h = 0.88"),
    ("left_shoulder", "outermost vertex on the left between h = 0.78 and 0.80"),
    ("right_shoulder", "outermost vertex on the right between h = 0.78 and 0.80"),
    ("crotch", "lowest midline vertex above h = 0.3"),
    ("left_nipple", "most forward vertex of the left chest (0.1 w < |x| < 0.3 w) between h = 0.68 and 0.76"),
    ("right_nipple", "most forward vertex of the right chest between h = 0.68 and 0.76"),
    ("left_little_fingertip", "left hand: rearmost of the 4 fingertips other than the thumb"),
    ("right_little_fingertip", "right hand: likewise"),
    ("left_hip", "outermost vertex on the left between h = 0.45 and 0.50"),
    ("right_hip", "outermost vertex on the right between h = 0.45 and 0.50"),
    ("left_index_fingertip", "left hand: most forward of the 4 fingertips other than the thumb"),
    ("right_index_fingertip", "right hand: likewise"),
    ("left_ankle", "outermost vertex on the left between h = 0.04 and 0.06"),
    ("right_ankle", "outermost vertex on the right between h = 0.04 and 0.06"),
    ("left_ring_fingertip", "left hand: 3rd-most forward of the 4 fingertips other than the thumb"),
    ("right_ring_fingertip", "right hand: likewise"),
    ("left_buttock", "rearmost vertex on the left between h = 0.45 and 0.55"),
    ("right_buttock", "rearmost vertex on the right between h = 0.45 and 0.55"),
    ("nape", "rearmost midline vertex between h = 0.84 and 0.88"),
)
DEFAULT_COUNT = 24
# A vertex is "on the midline" when |x| is below this (metres); MakeHuman's midline is exact.
MIDLINE_TOLERANCE = 1e-3
# Fingertips: local maxima of the geodesic distance from the navel, no two within this geodesic
# distance of each other (metres; a fingertip is ~1.5 cm across, neighbouring tips ~10 cm apart
# along the surface, through the palm).
FINGERTIP_SEPARATION = 0.02


class LandmarkError(ValueError):
    """Landmarks cannot be chosen: a rule found no vertex, or more landmarks were asked than exist."""


@dataclass(frozen=True)
class Landmarks:
    """Named layout vertices, in priority order."""

    names: tuple[str, ...]
    vertices: np.ndarray  # (K,) int64 layout vertex indices

    def __len__(self) -> int:
        return len(self.names)

    def first(self, count: int) -> Landmarks:
        """The first ``count`` landmarks (:class:`LandmarkError` when fewer exist)."""
        if not 1 <= count <= len(self.names):
            raise LandmarkError(f"{count} landmarks asked, {len(self.names)} defined (1..{len(self.names)})")
        return Landmarks(self.names[:count], self.vertices[:count].copy())


# ---------------------------------------------------------------- mesh graph


def edges_of_faces(faces: np.ndarray) -> np.ndarray:
    """(E, 2) int64 sorted unique undirected edges of (F, k) polygon corners."""
    faces = np.asarray(faces, dtype=np.int64)
    pairs = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    return np.unique(np.sort(pairs, axis=1), axis=0)


@dataclass(frozen=True)
class EdgeGraph:
    """Vertex adjacency in compressed rows, with edge lengths (for Dijkstra)."""

    starts: np.ndarray  # (N + 1,) row starts
    neighbours: np.ndarray  # (2E,)
    lengths: np.ndarray  # (2E,)

    @classmethod
    def of_mesh(cls, vertices: np.ndarray, faces: np.ndarray) -> EdgeGraph:
        """The edge graph of a polygon mesh."""
        edges = edges_of_faces(faces)
        lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
        sources = np.concatenate([edges[:, 0], edges[:, 1]])
        order = np.argsort(sources, kind="stable")
        return cls(
            np.searchsorted(sources[order], np.arange(len(vertices) + 1)),
            np.concatenate([edges[:, 1], edges[:, 0]])[order],
            np.concatenate([lengths, lengths])[order],
        )

    def geodesic(self, source: int, limit: float = np.inf) -> np.ndarray:
        """(N,) shortest-path distances along edges from ``source`` (``inf`` beyond ``limit``)."""
        distances = np.full(len(self.starts) - 1, np.inf)
        distances[source] = 0.0
        starts, neighbours, lengths = self.starts.tolist(), self.neighbours.tolist(), self.lengths.tolist()
        heap = [(0.0, source)]
        while heap:
            distance, vertex = heapq.heappop(heap)
            if distance > distances[vertex]:
                continue
            for slot in range(starts[vertex], starts[vertex + 1]):
                candidate = distance + lengths[slot]
                other = neighbours[slot]
                if candidate < distances[other] and candidate <= limit:
                    distances[other] = candidate
                    heapq.heappush(heap, (candidate, other))
        return distances

    def local_maxima(self, values: np.ndarray, candidates: np.ndarray) -> np.ndarray:
        """Those of ``candidates`` (bool (N,)) whose value is >= every edge neighbour's."""
        owner = np.repeat(np.arange(len(self.starts) - 1), np.diff(self.starts))
        beaten = values[self.neighbours] > values[owner]
        has_higher = np.zeros(len(values), dtype=bool)
        np.logical_or.at(has_higher, owner[beaten], True)
        return candidates & ~has_higher


# ---------------------------------------------------------------- the body


def _pick(score: np.ndarray, mask: np.ndarray, name: str) -> int:
    """The vertex of largest ``score`` among ``mask`` (lowest index on ties)."""
    if not mask.any():
        raise LandmarkError(f"landmark {name!r}: its rule selects no vertex on this template")
    masked = np.where(mask, score, -np.inf)
    return int(np.argmax(masked))


def _fingertips(
    graph: EdgeGraph, from_navel: np.ndarray, forward: np.ndarray, hand: np.ndarray, side: str
) -> dict[str, int]:
    """The five fingertips of one hand: geodesic extremities seen from the navel, named by position.

    The thumb is the tip nearest the navel; the other four, most forward (``forward``, z) first,
    are the index, middle, ring and little fingers (the hands hang palm inwards, thumb forward)."""
    peaks = np.flatnonzero(graph.local_maxima(from_navel, hand))
    peaks = peaks[np.argsort(-from_navel[peaks], kind="stable")]
    tips: list[int] = []
    suppressed = np.zeros(len(from_navel), dtype=bool)
    for peak in peaks:
        if suppressed[peak]:
            continue
        tips.append(int(peak))
        if len(tips) == 5:
            break
        suppressed |= graph.geodesic(int(peak), FINGERTIP_SEPARATION) <= FINGERTIP_SEPARATION
    if len(tips) < 5:
        raise LandmarkError(f"found {len(tips)} fingertips on the {side} hand, expected 5")
    thumb = min(tips, key=lambda vertex: (from_navel[vertex], vertex))
    others = sorted(set(tips) - {thumb}, key=lambda vertex: (-forward[vertex], vertex))
    names = ("index_fingertip", "middle_fingertip", "ring_fingertip", "little_fingertip")
    return {"thumb_tip": thumb, **dict(zip(names, others))}


def body_landmarks(vertices: np.ndarray, faces: np.ndarray) -> Landmarks:
    """Every landmark of :data:`BODY_LANDMARKS` on a MakeHuman-like body (metres, +Y up, +Z front)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    x, y, z = vertices.T
    height_fraction = (y - y.min()) / (y.max() - y.min())
    half_span = np.abs(x).max()
    side_fraction = np.abs(x) / half_span
    midline = np.abs(x) < MIDLINE_TOLERANCE
    left, right = x > MIDLINE_TOLERANCE, x < -MIDLINE_TOLERANCE

    def band(low: float, high: float) -> np.ndarray:
        return (height_fraction >= low) & (height_fraction <= high)

    found: dict[str, int] = {}
    found["crown"] = _pick(y, np.ones(len(y), dtype=bool), "crown")
    found["nose_tip"] = _pick(z, height_fraction > 0.85, "nose_tip")
    nose_y = y[found["nose_tip"]]
    found["chin"] = _pick(z - y, midline & (y < nose_y - 0.03) & (y > nose_y - 0.12), "chin")
    # The navel is a dent in the front midline profile: lower than the profile both above and below.
    rows = np.flatnonzero(midline & (z > 0.0) & band(0.48, 0.65))
    if len(rows) == 0:
        raise LandmarkError("landmark 'navel': no front-midline vertex between h = 0.48 and 0.65")
    rise = y[rows][None, :] - y[rows][:, None]
    above = np.where((rise > 0) & (rise < 0.025), z[rows][None, :], -np.inf).max(axis=1)
    below = np.where((rise < 0) & (rise > -0.025), z[rows][None, :], -np.inf).max(axis=1)
    found["navel"] = int(rows[np.argmax(np.minimum(above, below) - z[rows])])
    found["crotch"] = _pick(-y, midline & (height_fraction > 0.3), "crotch")
    found["nape"] = _pick(-z, midline & band(0.84, 0.88), "nape")

    graph = EdgeGraph.of_mesh(vertices, faces)
    from_navel = graph.geodesic(found["navel"])
    for side, mask in (("left", left), ("right", right)):
        foot = mask & (height_fraction < 0.05)
        found[f"{side}_big_toe"] = _pick(z, foot, f"{side}_big_toe")
        found[f"{side}_heel"] = _pick(-z, foot, f"{side}_heel")
        found[f"{side}_knee"] = _pick(z, mask & band(0.27, 0.29), f"{side}_knee")
        found[f"{side}_elbow"] = _pick(-z, mask & band(0.62, 0.76) & (side_fraction > 0.6), f"{side}_elbow")
        found[f"{side}_ear"] = _pick(np.abs(x), mask & (height_fraction > 0.88), f"{side}_ear")
        found[f"{side}_shoulder"] = _pick(np.abs(x), mask & band(0.78, 0.80), f"{side}_shoulder")
        chest = mask & band(0.68, 0.76) & (side_fraction > 0.1) & (side_fraction < 0.3)
        found[f"{side}_nipple"] = _pick(z, chest, f"{side}_nipple")
        found[f"{side}_hip"] = _pick(np.abs(x), mask & band(0.45, 0.50), f"{side}_hip")
        found[f"{side}_ankle"] = _pick(np.abs(x), mask & band(0.04, 0.06), f"{side}_ankle")
        found[f"{side}_buttock"] = _pick(-z, mask & band(0.45, 0.55), f"{side}_buttock")
        hand = mask & band(0.5, 0.66) & (side_fraction > 0.6)
        for finger, vertex in _fingertips(graph, from_navel, z, hand, side).items():
            found[f"{side}_{finger}"] = vertex
    names = tuple(name for name, _rule in BODY_LANDMARKS)
    indices = np.array([found[name] for name in names], dtype=np.int64)
    if len(np.unique(indices)) != len(indices):
        raise LandmarkError("two body landmarks fell on the same vertex")
    return Landmarks(names, indices)


# ---------------------------------------------------------------- any shape


def farthest_point_landmarks(vertices: np.ndarray, count: int) -> Landmarks:
    """``count`` vertices by farthest-point sampling (Euclidean), starting at the vertex of largest x.

    Ties go to the lowest index, so the result depends only on the vertex positions."""
    vertices = np.asarray(vertices, dtype=np.float64)
    if not 1 <= count <= len(vertices):
        raise LandmarkError(f"{count} landmarks asked of a mesh of {len(vertices)} vertices")
    chosen = [int(np.argmax(vertices[:, 0]))]
    nearest = np.linalg.norm(vertices - vertices[chosen[0]], axis=1)
    while len(chosen) < count:
        chosen.append(int(np.argmax(nearest)))
        nearest = np.minimum(nearest, np.linalg.norm(vertices - vertices[chosen[-1]], axis=1))
    return Landmarks(tuple(f"extreme_{rank:02d}" for rank in range(count)), np.array(chosen, dtype=np.int64))
