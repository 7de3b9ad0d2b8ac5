"""A re-tessellation that keeps a part's surface and its sharp creases: what a CAD model re-exported with other
tessellation settings gives.

Every edge is split at a random point between 35 and 65 % of its length (each triangle into four: the new
vertices lie on the old surface), then the edges whose two triangles are coplanar are flipped, in random order,
where the flip makes the pair's smallest angle larger (Delaunay flips inside flat patches). A flip across a bend
would cut through the solid, and one across a crease would round it: neither is made, so the surface and its
creases stay exactly where they were while almost no triangle is the one it was.
"""

from __future__ import annotations

import numpy as np

FLAT_DEGREES = 0.05
"""Two triangles whose normals differ by less than this are coplanar (their shared edge may be flipped)."""


def split_edges(vertices: np.ndarray, triangles: np.ndarray, rng: np.random.Generator):
    """(vertices, triangles): each edge split at a random point between 35 and 65 % of its length, each
    triangle into four (three at its corners, one in the middle)."""
    corners = np.asarray(triangles, dtype=np.int64)
    edges = np.concatenate([corners[:, [0, 1]], corners[:, [1, 2]], corners[:, [2, 0]]])
    keys, inverse = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True)
    t = rng.uniform(0.35, 0.65, size=keys.shape[0])[:, None]
    split = vertices[keys[:, 0]] * (1.0 - t) + vertices[keys[:, 1]] * t
    middle = vertices.shape[0] + inverse.reshape(3, -1)  # the split vertex of edges 01, 12, 20 per triangle
    a, b, c = corners.T
    ab, bc, ca = middle
    new = np.concatenate([np.stack(rows, axis=1) for rows in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return np.concatenate([vertices, split]), new


def _unit_normals(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    normal = np.cross(b - a, c - a)
    return normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)


def _smallest_angles(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(T,) the smallest corner angle (radians) of each triangle."""
    found = np.full(a.shape[0], np.pi)
    for here, after, before in ((a, b, c), (b, c, a), (c, a, b)):
        u, v = after - here, before - here
        lengths = np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1), 1e-300)
        found = np.minimum(found, np.arccos(np.clip(np.sum(u * v, axis=1) / lengths, -1.0, 1.0)))
    return found


def _flip_round(vertices: np.ndarray, faces: np.ndarray, rng: np.random.Generator) -> int:
    """One round of flips (``faces`` changed in place) on a random set of edges no two of which share a
    triangle; how many were flipped."""
    count = faces.shape[0]
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    opposite = np.concatenate([faces[:, 2], faces[:, 0], faces[:, 1]])
    owner = np.tile(np.arange(count), 3)
    keys = np.sort(edges, axis=1)
    order = np.lexsort((keys[:, 1], keys[:, 0]))
    same = np.all(keys[order[1:]] == keys[order[:-1]], axis=1)
    first, second = order[:-1][same], order[1:][same]  # the two half-edges of each interior edge
    u, v = edges[first, 0], edges[first, 1]  # f runs u -> v, g runs v -> u
    p, q = opposite[first], opposite[second]
    f, g = owner[first], owner[second]
    x = vertices
    normal = _unit_normals(x[u], x[v], x[p])
    flat = np.sum(normal * _unit_normals(x[v], x[u], x[q]), axis=1) >= np.cos(np.radians(FLAT_DEGREES))
    convex = np.minimum(
        np.sum(normal * _unit_normals(x[p], x[u], x[q]), axis=1),
        np.sum(normal * _unit_normals(x[q], x[v], x[p]), axis=1),
    ) >= np.cos(np.radians(FLAT_DEGREES))
    better = np.minimum(_smallest_angles(x[p], x[u], x[q]), _smallest_angles(x[q], x[v], x[p])) > np.minimum(
        _smallest_angles(x[u], x[v], x[p]), _smallest_angles(x[v], x[u], x[q])
    )
    size = np.int64(vertices.shape[0])
    existing = keys[:, 0].astype(np.int64) * size + keys[:, 1]
    new_keys = np.minimum(p, q).astype(np.int64) * size + np.maximum(p, q)
    candidate = np.flatnonzero(flat & convex & better & (p != q) & ~np.isin(new_keys, existing))
    candidate = candidate[rng.permutation(candidate.size)]
    _, unique_new = np.unique(new_keys[candidate], return_index=True)
    candidate = candidate[np.sort(unique_new)]
    # Keep an edge when it is the first (in the random order) to claim each of its two triangles.
    claims = np.concatenate([f[candidate], g[candidate]])
    rank = np.concatenate([np.arange(candidate.size)] * 2)
    first_claim = np.full(count, candidate.size)
    np.minimum.at(first_claim, claims, rank)
    index = np.arange(candidate.size)
    chosen = candidate[(first_claim[f[candidate]] == index) & (first_claim[g[candidate]] == index)]
    faces[f[chosen]] = np.stack([p[chosen], u[chosen], q[chosen]], axis=1)
    faces[g[chosen]] = np.stack([q[chosen], v[chosen], p[chosen]], axis=1)
    return int(chosen.size)


def flip_flat_edges(vertices: np.ndarray, triangles: np.ndarray, rng: np.random.Generator, rounds: int = 12):
    """``triangles`` after Delaunay flips of the edges between coplanar triangles (see the module docs)."""
    faces = np.array(triangles, dtype=np.int64)
    for _ in range(rounds):
        if _flip_round(vertices, faces, rng) == 0:
            break
    return faces


def retessellate(vertices, triangles, seed: int = 1):
    """(vertices float64, triangles int64): the part re-tessellated without moving its surface."""
    rng = np.random.default_rng(seed)
    split, corners = split_edges(np.asarray(vertices, dtype=np.float64), triangles, rng)
    return split, flip_flat_edges(split, corners, rng)
