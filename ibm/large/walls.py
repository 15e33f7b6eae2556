"""Walls and the tracked outline of a moving body (docs/large-deformation.md).

Every essential edge of the initial body lies on a wall: a straight line (a plane in 3D) fixed in space or
translated along its own normal by a prescribed motion (the top plate of a settlement test),
ramped over the load steps. The body's outline is a polygon whose vertices move with the
material; a vertex on a wall is put back on it after every step (rounding, or a method that
imposes the wall only approximately), so walls keep their lines exactly.

Within a step the walls sit where the outline's essential edges are at the step start; a
method imposes the step's wall increment g_k (a displacement vector per wall, g_k = m_k n_k
for a wall moving by m_k along its inward normal n_k).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.dirichlet import scalar
from ibm.exceptions import InputError
from ibm.geometry.outline import Body
from ibm.geometry.polyhedron import Polyhedron


@dataclass(frozen=True, eq=False)
class Outline:
    """Vertices (n, 2) counter-clockwise, edge kinds, and the wall of each edge (-1: none)."""

    vertices: np.ndarray
    kinds: tuple[str, ...]
    wall: np.ndarray            # (n_edges,) wall id of each edge
    frame: np.ndarray
    edge: np.ndarray            # (n_edges,) edge of the initial body each piece comes from

    @classmethod
    def of(cls, body: Body, pieces: int | np.ndarray = 1) -> "Outline":
        """The body's outline with every non-essential edge split into `pieces` equal pieces."""
        counts = np.broadcast_to(np.asarray(pieces, int), (body.n_edges,))
        vertices, kinds, wall, edge = [], [], [], []
        essential = body.essential_edges
        for k in range(body.n_edges):
            parts = 1 if k in essential else int(counts[k])
            t = np.arange(parts)[:, None] / parts
            vertices.append(body.starts[k] + t * body.tangents[k])
            kinds += [body.kinds[k]] * parts
            wall += [essential.index(k) if k in essential else -1] * parts
            edge += [k] * parts
        return cls(np.concatenate(vertices), tuple(kinds), np.array(wall), body.frame, np.array(edge))

    def body(self) -> Body:
        return Body(self.vertices, self.kinds, self.frame, tracked=True)

    def to_tree(self) -> dict:
        return {"vertices": self.vertices, "kinds": tuple(self.kinds), "wall": self.wall, "frame": self.frame,
                "edge": self.edge}

    def moved(self, displacement: np.ndarray, lines: "WallLines") -> "Outline":
        """Vertices moved by displacement (n, 2), then put back on their walls at `lines`: a vertex
        between two edges of one wall goes onto its line, a corner of two walls onto their crossing."""
        x = self.vertices + displacement
        before, after = np.roll(self.wall, 1), self.wall                     # walls of the edges each vertex joins
        wall = np.where(after >= 0, after, before)
        on_one = (wall >= 0) & ((before < 0) | (after < 0) | (before == after))
        normals = lines.normals[wall[on_one]]
        distance = np.sum((x[on_one] - lines.points[wall[on_one]]) * normals, axis=1)
        x[on_one] -= distance[:, None] * normals
        for i in np.flatnonzero((before >= 0) & (after >= 0) & (before != after)):   # corners: a few
            x[i] = lines.intersection(before[i], after[i], x[i])
        return Outline(x, self.kinds, self.wall, self.frame, self.edge)


@dataclass(frozen=True, eq=False)
class FacetedOutline:
    """A convex polyhedron's outline in 3D: vertices (n, 3), faces as vertex ids, inward unit normals
    (n_faces, 3), face kinds and the wall of each face (-1: none).

    Faces stay planes: after a step a wall face takes its wall's plane, a free face the plane
    fitted (least squares) to its moved vertices, and each vertex goes to the meeting point of its
    faces' planes. This is exact while the motion is affine on every free face (the uniaxial
    column, the confined block); a face that would bend is flattened to its mean plane.
    """

    vertices: np.ndarray
    faces: tuple[np.ndarray, ...]
    normals: np.ndarray
    kinds: tuple[str, ...]
    wall: np.ndarray
    frame: np.ndarray

    @property
    def edge(self) -> np.ndarray:
        """(n_faces,) the initial body's face each face is (faces are never split)."""
        return np.arange(len(self.faces))

    @classmethod
    def of(cls, body) -> "FacetedOutline":
        vertices = body.vertices
        scale = float(np.abs(vertices).max(initial=1.0))
        faces = tuple(np.array([int(np.argmin(np.linalg.norm(vertices - p, axis=1))) for p in face])
                      for face in body.faces)
        if max(float(np.abs(vertices[f] - face).max()) for f, face in zip(faces, body.faces)) > 1e-12 * scale:
            raise ValueError("a face's corner is not one of the body's vertices")
        essential = body.essential_edges
        wall = np.array([essential.index(k) if k in essential else -1 for k in range(body.n_edges)])
        return cls(vertices.copy(), faces, body.normals.copy(), tuple(body.kinds), wall, body.frame)

    def body(self):
        return Polyhedron(tuple(self.vertices[f] for f in self.faces), self.normals, self.kinds, self.frame)

    def moved(self, displacement: np.ndarray, lines: "WallLines") -> "FacetedOutline":
        """Vertices moved by displacement (n, 3), faces made planes again (see the class doc)."""
        x = self.vertices + displacement
        normals, offsets = np.empty_like(self.normals), np.empty(len(self.faces))
        for k, face in enumerate(self.faces):
            if self.wall[k] >= 0:
                n = lines.normals[self.wall[k]]
                normals[k], offsets[k] = n, lines.points[self.wall[k]] @ n
                continue
            centre = x[face].mean(axis=0)
            n = np.linalg.svd(x[face] - centre)[2][-1]                 # the fitted plane's normal
            n = n if n @ self.normals[k] > 0 else -n                     # still pointing inward
            normals[k], offsets[k] = n, centre @ n
        placed = np.empty_like(x)
        for v in range(len(x)):     # a few corners: each onto the meeting point of its faces' planes
            mine = [k for k, face in enumerate(self.faces) if v in face]
            placed[v] = np.linalg.lstsq(normals[mine], offsets[mine], rcond=None)[0]
        return FacetedOutline(placed, self.faces, normals, self.kinds, self.wall, self.frame)

    def to_tree(self) -> dict:
        return {"type": "faceted", "vertices": self.vertices, "face_vertices": np.concatenate(self.faces),
                "face_sizes": np.array([len(f) for f in self.faces]), "normals": self.normals,
                "kinds": tuple(self.kinds), "wall": self.wall, "frame": self.frame}

    @classmethod
    def from_tree(cls, tree: dict) -> "FacetedOutline":
        faces = tuple(np.split(np.asarray(tree["face_vertices"]), np.cumsum(tree["face_sizes"])[:-1]))
        return cls(tree["vertices"], faces, tree["normals"], tuple(tree["kinds"]), tree["wall"], tree["frame"])


def outline_of(body, pieces: int | np.ndarray = 1):
    """The tracked outline of a body: a polygon (Outline) in 2D, a FacetedOutline in 3D."""
    return FacetedOutline.of(body) if body.dim == 3 else Outline.of(body, pieces)


def outline_from_tree(tree: dict):
    if tree.get("type") == "faceted":
        return FacetedOutline.from_tree(tree)
    return Outline(tree["vertices"], tuple(tree["kinds"]), tree["wall"], tree["frame"], tree["edge"])


@dataclass(frozen=True, eq=False)
class WallLines:
    """Lines (planes in 3D) of the walls: a point (n_walls, d) on each and its inward unit normal (n_walls, d)."""

    points: np.ndarray
    normals: np.ndarray

    @classmethod
    def of(cls, body: Body) -> "WallLines":
        k = body.essential_edges
        if body.dim == 3:
            return cls(np.array([body.faces[j][0] for j in k]).reshape(-1, 3), body.normals[k].copy())
        return cls(body.starts[k].copy(), body.normals[k].copy())

    def translated(self, motion: np.ndarray) -> "WallLines":
        """Each wall moved by its normal motion (n_walls,) along its inward normal."""
        return WallLines(self.points + motion[:, None] * self.normals, self.normals)

    def distance(self, wall: int, x: np.ndarray) -> np.ndarray:
        return (x - self.points[wall]) @ self.normals[wall]

    def project(self, wall: int, x: np.ndarray) -> np.ndarray:
        return x - self.distance(wall, x[None])[0] * self.normals[wall]

    def intersection(self, a: int, b: int, near: np.ndarray) -> np.ndarray:
        A = self.normals[[a, b]]
        if abs(np.linalg.det(A)) < 1e-12:
            return self.project(a, near)
        return np.linalg.solve(A, np.array([self.points[a] @ A[0], self.points[b] @ A[1]]))


def wall_lift(body: Body, increments: np.ndarray, delta: float):
    """A lift du^a(x) carrying the walls' motion, supported in their bands (the IBM's u^a).

    du^a = sum_k m_k n_k (1 - D(phi_k)), D the seed's Dirichlet function of band width delta:
    n_k . du^a = m_k on wall k, du^a = 0 beyond the band, so u^h carries the whole field
    (a homogeneous compression stays in the grid's space). A wall whose band meets a moving
    wall must be orthogonal to it. Returns lift(x) -> (du (n, d), grad du (n, d, d)), or None.
    """
    moving = np.flatnonzero(increments)
    if len(moving) == 0:
        return None
    essential = body.essential_edges
    d = body.dim
    for wall in moving:
        k = essential[wall]
        for j in essential:
            corners = body.faces[j] if d == 3 else body.vertices[[j, (j + 1) % body.n_edges]]
            near = body.signed_distance(corners)[:, k].min() < delta
            if j != k and near and abs(body.normals[j] @ body.normals[k]) > 1e-9:
                raise InputError(f"wall on edge {k} moves, but the wall on edge {j} meets its band and is not "
                                 "orthogonal to it (the IBM's lift is not defined for that)")

    def lift(x: np.ndarray):
        phi = body.signed_distance(x)
        du = np.zeros((len(x), d))
        grad = np.zeros((len(x), d, d))
        for wall in moving:
            k = essential[wall]
            n = body.normals[k]
            D, dD = scalar(phi[:, k], delta)
            du += increments[wall] * (1 - D)[:, None] * n
            grad -= (increments[wall] * dD)[:, None, None] * np.outer(n, n)[None]   # d phi / d x = n
        return du, grad

    return lift


def wall_predictor(body: Body, grid, increments: np.ndarray) -> np.ndarray | None:
    """Nodal values (d n_nodes,) of sum_k m_k n_k (1 - phi_k / W_k), W_k the width across wall k: a field with the
    walls' motion, Newton's first iterate for a method whose lift lives in a thin band (without
    it the band's first kinematics would fold over: grad du^a ~ m / delta)."""
    moving = np.flatnonzero(increments)
    if len(moving) == 0:
        return None
    nodes = grid.nodes()
    phi_nodes, phi_body = body.signed_distance(nodes), body.signed_distance(body.vertices)
    U = np.zeros((len(nodes), body.dim))
    for wall in moving:
        k = body.essential_edges[wall]
        s = 1 - phi_nodes[:, k] / phi_body[:, k].max()     # linear: exactly 0 on the opposite wall
        U += increments[wall] * s[:, None] * body.normals[k]
    return U.ravel()
