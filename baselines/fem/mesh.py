"""Body-fitted finite-element reference on any simple outline: gmsh P2 triangles, scikit-fem.

The outline is meshed by gmsh (one curve per piece, so every mesh facet knows its piece) into
6-node triangles of about the grid's cell size. A body of straight pieces only has straight
elements: the midside nodes sit at the edge midpoints (Mesh.SecondOrderLinear) and the mesh is
a scikit-fem `MeshTri2` with `affine=True`. Arc pieces are gmsh circle arcs (geo kernel, split
in two halves when they turn by more than ARC_SPLIT, as gmsh's arcs must turn by less than 180
degrees); their corner and midside nodes lie on the circle (Mesh.SecondOrderLinear=0; interior
midside nodes stay at edge midpoints) and the mesh is the isoparametric (curved) `MeshTri2`.
Vector P2 element; stiffness by a degree-4 rule, loads by degree 8 (tractions on arcs by
CURVED_LOAD_ORDER along the curved facets). As in baselines.fem.method, u = u^h + u^a with the lift
u^a, so the essential data u = u^a (its normal part on rollers) hold at the nodes when u^h
vanishes there: u^h is imposed strongly on every node (corner and midside) of an essential
piece, straight or arc, through U = T q: fixed pieces drop both components, a roller keeps the
component along its tangent at the node (on an arc the exact circle's, the node being on the
circle), and a node on two rollers with different normals (or a roller and a fixed piece)
drops both. Each piece's reaction is the residual K U - f at its nodes
(baselines.boundary.piece_reactions, with the normals the constraints use).
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field
from time import perf_counter

import gmsh
import numpy as np
import scipy.linalg
import scipy.sparse as sp
import shapely
from scipy.spatial import cKDTree
from skfem import Basis, CellBasis, ElementTriP1, ElementTriP2, ElementVector, FacetBasis, LinearForm, MeshTri2, asm
from skfem.helpers import ddot, dot, sym_grad
from skfem.models.elasticity import linear_elasticity

from baselines.boundary import piece_reactions, values_at
from ibm.geometry.outline import Body
from ibm.exceptions import InputError, SolveError
from ibm.small.model import Model, Solution
from ibm.solvers.linear import solve_system

STIFFNESS_ORDER = 4     # P2: strain x strain is degree 2, exact on straight elements (rational on curved)
LOAD_ORDER = 8          # body force, lift and tractions are arbitrary smooth functions
CURVED_LOAD_ORDER = 12  # tractions on arcs: the facet's length element is not a polynomial
ARC_SPLIT = np.radians(120.0)   # arcs turning further are built from two halves
NEWTON_STEPS = 30       # inverse isoparametric map: at most this many Newton steps
NEWTON_TOLERANCE = 1e-14    # ... until the step in reference coordinates is below this
GMSH_ALGORITHM = 6      # Frontal-Delaunay, fixed so the mesh does not depend on gmsh's defaults
PARALLEL_TOLERANCE = 1e-9   # |n_1 x n_2| below this: two roller pieces are collinear
# gmsh keeps one global model per process: meshing is serialised across threads
_GMSH_LOCK = threading.Lock()
TRIANGLE6, LINE3 = 9, 8     # gmsh element types
BLOCK = 16384               # points located at a time


@dataclass(frozen=True, eq=False)
class PolygonMesh:
    """The P2 mesh of a body and where its pieces lie in it.

    mesh: MeshTri2 (affine for straight pieces only, else isoparametric), doflocs (2, n_nodes)
    are gmsh's nodes in scikit-fem's order (vertices, then one midside node per facet).
    piece_facets[k]: mesh facet ids on piece k; piece_nodes[k]: node ids (corner and midside,
    endpoints included) on piece k; curved (n_elements,): the element has a facet on an arc.
    """

    mesh: MeshTri2
    piece_facets: list[np.ndarray]
    piece_nodes: list[np.ndarray]
    curved: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


def check_polygon(body: Body) -> None:
    """InputError unless the outline (arcs as chords of at most 2 degrees) is simple, with
    pieces of positive length."""
    short = np.flatnonzero(body.lengths <= 1e-12 * body.lengths.max())
    if len(short):
        raise InputError(f"piece {short[0]} of the body has zero length; the fem mesh needs distinct vertices")
    if not shapely.LinearRing(body.ring(np.radians(2.0)) if body.arcs else body.vertices).is_simple:
        raise InputError("the body's outline intersects itself; the fem mesh needs a simple polygon")


def arc_curves(body: Body) -> list:
    """Per piece None (a line) or (center (2,), inner points (m, 2)): the arc is built from m + 1
    gmsh arcs through the inner points, m = 1 (its midpoint) when it turns by more than ARC_SPLIT."""
    curves = []
    for k, arc in enumerate(body.arcs or (None,) * body.n_edges):
        if arc is None:
            curves.append(None)
            continue
        radius, start, sweep = body.arc_angles(k)
        center = np.asarray(arc.center, float)
        middle = start + 0.5 * sweep
        inner = center + radius * np.array([[np.cos(middle), np.sin(middle)]]) if abs(sweep) > ARC_SPLIT \
            else np.zeros((0, 2))
        curves.append((center, inner))
    return curves


def gmsh_triangles(vertices: np.ndarray, h: float, arcs: list | None = None
                   ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """gmsh's P2 mesh of the outline `vertices` (n, 2) with element size h; piece k is a line,
    or the circle arc arcs[k] = (center, inner points) of arc_curves when given and not None.

    Returns nodes (n_nodes, 2), triangles (n_elements, 6) and per piece k its 3-node line
    elements (m_k, 3), all as row indices of `nodes`; gmsh's local order: corners 0, 1, 2, then
    the midside nodes of edges 0-1, 1-2, 2-0 (lines: two ends, then the middle). With arcs the
    midside nodes on them lie on the circle (Mesh.SecondOrderLinear=0), otherwise at midpoints.
    """
    arcs = arcs if arcs is not None and any(a is not None for a in arcs) else None
    with _GMSH_LOCK:
        # interruptible=False: no SIGINT handler, which only the main thread could install
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        try:
            for name, value in (("General.Terminal", 0), ("General.NumThreads", 1),
                                ("Mesh.Algorithm", GMSH_ALGORITHM), ("Mesh.ElementOrder", 2),
                                ("Mesh.SecondOrderLinear", 0 if arcs else 1), ("Mesh.MeshSizeMax", h),
                                ("Mesh.MeshSizeExtendFromBoundary", 1)):
                gmsh.option.setNumber(name, value)
            gmsh.model.add("body")
            geo = gmsh.model.geo
            points = [geo.addPoint(x, y, 0.0, h) for x, y in vertices]
            n = len(points)
            curves = []                     # per piece its gmsh curves, in order along it
            for k in range(n):
                a, b = points[k], points[(k + 1) % n]
                if arcs is None or arcs[k] is None:
                    curves.append([geo.addLine(a, b)])
                    continue
                center = geo.addPoint(*arcs[k][0], 0.0, h)
                stops = [a] + [geo.addPoint(x, y, 0.0, h) for x, y in arcs[k][1]] + [b]
                curves.append([geo.addCircleArc(p, center, q) for p, q in zip(stops[:-1], stops[1:])])
            geo.addPlaneSurface([geo.addCurveLoop([c for piece in curves for c in piece])])
            geo.synchronize()
            gmsh.model.mesh.generate(2)
            tags, coords, _ = gmsh.model.mesh.getNodes()
            _, triangles = gmsh.model.mesh.getElementsByType(TRIANGLE6)
            pieces = [np.concatenate([gmsh.model.mesh.getElementsByType(LINE3, tag=c)[1] for c in piece])
                      for piece in curves]
        except Exception as error:      # gmsh raises bare Exceptions with its last error message
            raise InputError(f"gmsh could not mesh the body: {error}") from None
        finally:
            gmsh.finalize()
    index = np.zeros(int(tags.max(initial=0)) + 1, np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    nodes = coords.reshape(-1, 3)[:, :2]
    return nodes, index[triangles.astype(np.int64)].reshape(-1, 6), [index[p.astype(np.int64)].reshape(-1, 3) for p in pieces]


def mesh_polygon(body: Body, h: float) -> PolygonMesh:
    """The P2 mesh of `body` with element size about h, pieces located; InputError if it fails."""
    check_polygon(body)
    arcs = arc_curves(body) if body.arcs else None
    nodes, triangles, pieces = gmsh_triangles(body.vertices, h, arcs)
    used = np.unique(triangles)
    if len(triangles) == 0 or any(len(p) == 0 for p in pieces):
        raise InputError("gmsh returned no triangles for the body (or left a piece without elements)")
    renumber = np.full(len(nodes), -1, np.int64)
    renumber[used] = np.arange(len(used))
    triangles, pieces = renumber[triangles], [renumber[p] for p in pieces]
    mesh = MeshTri2(nodes[used].T.copy(), triangles.T.copy(), affine=arcs is None)
    if mesh.doflocs.shape[1] != len(used):
        raise InputError("gmsh's mesh of the body is not a conforming P2 mesh")
    # MeshTri2 reorders its nodes (vertices first, then one per facet): gmsh row -> node id
    to_mesh = np.empty(len(used), np.int64)
    to_mesh[triangles[:, :3]] = mesh.t.T
    to_mesh[triangles[:, 3:]] = mesh.dofs.element_dofs[3:].T
    if arcs is None:
        corners = mesh.p[:, mesh.t]                                              # (2, 3, n_elements)
        area = 0.5 * np.sum((corners[0, 1] - corners[0, 0]) * (corners[1, 2] - corners[1, 0])
                            - (corners[1, 1] - corners[1, 0]) * (corners[0, 2] - corners[0, 0]))
        if not np.isclose(area, body.area, rtol=1e-9):
            raise InputError(f"gmsh's mesh covers area {area:.6g}, the body {body.area:.6g}")
    else:   # det DF is quadratic, so degree 2 is exact; a P2 arc facet misses the circle's area by
        # chord^5 / (960 R^3) to leading order: four times that is allowed
        area = float(CellBasis(mesh, ElementTriP1(), intorder=2).dx.sum())
        tolerance = 1e-9 * abs(body.area)
        for k, arc in enumerate(body.arcs):
            if arc is not None:
                chords = np.linalg.norm(np.diff(mesh.doflocs[:, to_mesh[pieces[k][:, :2]]], axis=2), axis=0)
                tolerance += float(np.sum(chords ** 5)) / (240 * body.arc_angles(k)[0] ** 3)
        if not abs(area - body.area) <= tolerance:
            raise InputError(f"gmsh's mesh covers area {area:.6g}, the body {body.area:.6g}")
    keys = facet_keys(mesh, mesh.facets)
    order = np.argsort(keys)
    piece_facets, piece_nodes = [], []
    for lines in pieces:
        ends = to_mesh[lines[:, :2]].T                                         # (2, m) vertex ids
        wanted = facet_keys(mesh, ends)
        at = np.minimum(np.searchsorted(keys, wanted, sorter=order), len(keys) - 1)
        if not np.array_equal(keys[order[at]], wanted):
            raise InputError("gmsh's boundary lines do not match the triangles' facets")
        piece_facets.append(order[at])
        piece_nodes.append(np.unique(to_mesh[lines]))
    curved = np.zeros(mesh.nelements, bool)
    for k, arc in enumerate(body.arcs):
        if arc is not None:
            curved[mesh.f2t[0, piece_facets[k]]] = True
    return PolygonMesh(mesh, piece_facets, piece_nodes, curved)


def facet_keys(mesh: MeshTri2, ends: np.ndarray) -> np.ndarray:
    """One integer per vertex pair (2, m), independent of the pair's order."""
    return np.min(ends, axis=0).astype(np.int64) * mesh.nvertices + np.max(ends, axis=0)


def node_dofs(basis: Basis) -> np.ndarray:
    """(2, n_nodes) DOF ids of the components of every mesh node (vertices, then facets)."""
    return np.hstack([basis.nodal_dofs, basis.facet_dofs])


def normals_at(body: Body, k: int, x: np.ndarray) -> np.ndarray:
    """(m, 2) inward unit normals of piece k at its nodes x (m, 2): body.normals[k] on a line, on an
    arc the circle's own normal at each node (-body.outward), not its chord's."""
    if body.arcs and body.arcs[k] is not None:
        return -body.outward(k, x)
    return np.broadcast_to(body.normals[k], x.shape)


def constraint_transform(body: Body, polygon: PolygonMesh, dofs: np.ndarray) -> sp.csr_matrix:
    """T (n_dofs, n_q) with U = T q for all U vanishing on fixed pieces and normal-vanishing
    on rollers (at every node, with the node's own normal on an arc: normals_at); dofs (2, n_nodes)
    from node_dofs. Its columns are orthonormal."""
    n_nodes = dofs.shape[1]
    x = polygon.mesh.doflocs.T                                                 # (n_nodes, 2)
    clamped = np.zeros(n_nodes, bool)
    held = np.zeros(n_nodes, bool)               # node already on a roller, with normal[node]
    normal = np.zeros((n_nodes, 2))
    for k in body.essential_edges:
        nodes = polygon.piece_nodes[k]
        if body.kinds[k] == "fixed":
            clamped[nodes] = True
            continue
        n = normals_at(body, k, x[nodes])                                      # (m, 2)
        cross = normal[nodes, 0] * n[:, 1] - normal[nodes, 1] * n[:, 0]
        clamped[nodes[held[nodes] & (np.abs(cross) > PARALLEL_TOLERANCE)]] = True
        fresh = ~held[nodes]
        normal[nodes[fresh]], held[nodes[fresh]] = n[fresh], True
    roller = held & ~clamped
    columns = np.where(clamped, 0, np.where(roller, 1, 2))                     # (n_nodes,)
    first = np.cumsum(columns) - columns
    free = np.flatnonzero(columns == 2)
    slide = np.flatnonzero(roller)
    tangent = np.stack([-normal[slide, 1], normal[slide, 0]], axis=1)          # (n_slide, 2)
    rows = np.concatenate([dofs[0, free], dofs[1, free], dofs[0, slide], dofs[1, slide]])
    cols = np.concatenate([first[free], first[free] + 1, first[slide], first[slide]])
    vals = np.concatenate([np.ones(2 * len(free)), tangent[:, 0], tangent[:, 1]])
    return sp.csr_matrix((vals, (rows, cols)), shape=(2 * n_nodes, int(columns.sum())))


def require_held(T: sp.csr_matrix, x: np.ndarray, dofs: np.ndarray) -> None:
    """SolveError if a rigid motion of the nodes x (n_nodes, 2) lies in the range of T."""
    c = (x - x.mean(axis=0)) / max(np.ptp(x, axis=0).max(), np.finfo(float).tiny)
    R = np.zeros((T.shape[0], 3))                                              # (n_dofs, 3) rigid modes
    R[dofs[0], 0], R[dofs[1], 1] = 1.0, 1.0
    R[dofs[0], 2], R[dofs[1], 2] = -c[:, 1], c[:, 0]
    P = R - T @ (T.T @ R)                                                      # part the constraints remove
    values, vectors = scipy.linalg.eigh(P.T @ P, R.T @ R)
    if values[0] < 1e-10:
        v = vectors[:, 0] / np.abs(vectors[:, 0]).max()
        mode = " ".join(f"{a:+.3g} {name}" for a, name in zip(v, ("translation x", "translation y", "rotation"))
                        if abs(a) > 1e-6)
        raise SolveError(f"rigid-body motion is not constrained ({mode}); the body needs more essential boundaries")


class TriangleLocator:
    """Element and reference coordinates of points in an affine triangle mesh.

    Candidates are the elements with the nearest centroids; each point takes the candidate
    closest to it (distance 0 inside, so points on the outline or a shared facet are found).
    Points outside the mesh (rounding, or centroids of clipped non-convex point domains) are
    moved to the nearest point of that element, as baselines.fem.method clips to the rectangle.
    """

    def __init__(self, p: np.ndarray, t: np.ndarray):
        self.corners = np.transpose(p[:, t], (2, 1, 0))                        # (n_elements, 3, 2)
        J = np.stack([self.corners[:, 1] - self.corners[:, 0], self.corners[:, 2] - self.corners[:, 0]], axis=2)
        self.inverse = np.linalg.inv(J)                                         # (n_elements, 2, 2)
        self.tree = cKDTree(self.corners.mean(axis=1))
        edges = self.corners - np.roll(self.corners, -1, axis=1)
        self.size = float(np.linalg.norm(edges, axis=2).max())

    def reference(self, x: np.ndarray, elements: np.ndarray) -> np.ndarray:
        """(..., 2) reference coordinates of points x (..., 2) in `elements` (...)."""
        return np.einsum("...ij,...j->...i", self.inverse[elements], x - self.corners[elements, 0])

    def nearest(self, x: np.ndarray, elements: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (n, k) of points x (n, 2) to candidate elements (n, k) and the nearest points (n, k, 2)."""
        X = self.reference(x[:, None], elements)                               # (n, k, 2)
        inside = (X.min(axis=2) >= 0) & (X.sum(axis=2) <= 1)
        a = self.corners[elements]                                             # (n, k, 3, 2)
        e = np.roll(a, -1, axis=2) - a
        d = x[:, None, None] - a
        s = np.clip(np.sum(d * e, axis=3) / np.sum(e * e, axis=3), 0.0, 1.0)
        foot = a + s[..., None] * e                                            # (n, k, 3, 2)
        gap = np.linalg.norm(x[:, None, None] - foot, axis=3)                  # (n, k, 3)
        side = np.argmin(gap, axis=2)
        y = np.where(inside[..., None], x[:, None], np.take_along_axis(foot, side[..., None, None], 2)[:, :, 0])
        return np.where(inside, 0.0, gap.min(axis=2)), y

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Elements (n,) and reference coordinates (2, n) of points x (n, 2); InputError for
        points further than two element sizes from the mesh."""
        elements, y = np.zeros(len(x), np.int64), x.copy()
        for block in range(0, len(x), BLOCK):         # bounded memory: (BLOCK, k, 3, 2) candidates
            part = slice(block, block + BLOCK)
            elements[part], y[part] = self.closest(x[part])
        return elements, self.reference(y, elements).T

    def closest(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Element (n,) nearest to each point x (n, 2) and the nearest point (n, 2) in it."""
        n_elements = len(self.inverse)
        elements, y = np.zeros(len(x), np.int64), x.copy()
        distance = np.full(len(x), np.inf)
        todo = np.arange(len(x))
        for k in (8, 64):                             # a miss among 8 candidates retries with 64
            k = min(k, n_elements)
            candidates = self.tree.query(x[todo], k)[1].reshape(len(todo), k)  # (m, k)
            gap, foot = self.nearest(x[todo], candidates)
            best = np.argmin(gap, axis=1)
            pick = np.arange(len(todo))
            better = gap[pick, best] < distance[todo]
            mine = todo[better]
            elements[mine] = candidates[pick, best][better]
            y[mine] = foot[pick, best][better]
            distance[mine] = gap[pick, best][better]
            todo = todo[distance[todo] > 0]
            if len(todo) == 0 or k == n_elements:
                break
        far = distance > 2 * self.size
        if np.any(far):
            bad = x[np.argmax(far)]
            raise InputError(f"point ({bad[0]:.6g}, {bad[1]:.6g}) lies outside the body's mesh")
        return elements, y


def p2_shapes(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P2 shape functions (m, 6) and their gradients (m, 6, 2) at reference points X (m, 2), in
    scikit-fem's local order: corners (0, 0), (1, 0), (0, 1), then midsides of 0-1, 1-2, 0-2."""
    x, y = X[:, 0], X[:, 1]
    l0 = 1 - x - y
    phi = np.stack([l0 * (2 * l0 - 1), x * (2 * x - 1), y * (2 * y - 1), 4 * l0 * x, 4 * x * y, 4 * l0 * y], 1)
    zero = np.zeros_like(x)
    dx = np.stack([1 - 4 * l0, 4 * x - 1, zero, 4 * (l0 - x), 4 * y, -4 * y], 1)
    dy = np.stack([1 - 4 * l0, zero, 4 * y - 1, -4 * x, 4 * x, 4 * (l0 - y)], 1)
    return phi, np.stack([dx, dy], 2)


def onto_reference(X: np.ndarray) -> np.ndarray:
    """The nearest points (m, 2) of the reference triangle to reference points X (m, 2)."""
    inside = (X.min(axis=1) >= 0) & (X.sum(axis=1) <= 1)
    a = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    e = np.roll(a, -1, axis=0) - a
    s = np.clip(np.einsum("mkd,kd->mk", X[:, None] - a, e) / np.sum(e * e, axis=1), 0.0, 1.0)
    foot = a + s[..., None] * e                                                # (m, 3, 2)
    side = np.argmin(np.linalg.norm(X[:, None] - foot, axis=2), axis=1)
    return np.where(inside[:, None], X, foot[np.arange(len(X)), side])


class CurvedLocator(TriangleLocator):
    """Element and reference coordinates of points in an isoparametric P2 triangle mesh.

    TriangleLocator on the corner (chord) triangles first: a point in a straight element's
    triangle keeps its affine coordinates. The others (in a curved element's chord triangle, or
    outside every chord triangle: in a bulge beyond a convex arc, or outside the body) are
    mapped back by Newton's method on the P2 map of each curved candidate (the affine pick and
    the 8 elements with the nearest centroids), from the affine guess; a point takes the
    candidate whose reference coordinates lie least outside the reference triangle, and those
    are moved to the nearest point of the reference triangle (points outside the body by
    rounding, or beyond a concave arc's P2 facets). If a straight candidate fits best, the
    affine pick stays.
    """

    def __init__(self, mesh: MeshTri2, curved: np.ndarray):
        super().__init__(mesh.p, mesh.t)
        self.nodes = np.transpose(mesh.doflocs[:, mesh.dofs.element_dofs], (2, 1, 0))   # (n_elements, 6, 2)
        self.curved = curved

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Elements (n,) and reference coordinates (2, n) of points x (n, 2); InputError for
        points further than two element sizes from the mesh."""
        elements, y = np.zeros(len(x), np.int64), x.copy()
        for block in range(0, len(x), BLOCK):
            part = slice(block, block + BLOCK)
            elements[part], y[part] = self.closest(x[part])
        X = self.reference(y, elements)
        suspect = np.flatnonzero(self.curved[elements] | np.any(y != x, axis=1))
        for block in range(0, len(suspect), BLOCK):
            part = suspect[block:block + BLOCK]
            elements[part], X[part] = self.curved_pick(x[part], elements[part], X[part])
        return elements, X.T

    def curved_pick(self, x: np.ndarray, elements: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Elements (m,) and reference coordinates (m, 2) of points x (m, 2), given the affine
        picks `elements` and their (clipped) coordinates X (see the class doc)."""
        k = min(8, len(self.inverse))
        candidates = np.column_stack([elements, self.tree.query(x, k)[1].reshape(len(x), k)])   # (m, k + 1)
        guess = self.reference(x[:, None], candidates)                             # (m, k + 1, 2)
        curved = self.curved[candidates]
        mapped, converged = self.invert(x[np.nonzero(curved)[0]], candidates[curved], guess[curved])
        guess[curved] = mapped
        outside = np.maximum(np.maximum(-guess[..., 0], -guess[..., 1]), guess.sum(axis=2) - 1).clip(0.0)
        outside[curved] = np.where(converged, outside[curved], np.inf)
        best = np.argmin(outside, axis=1)
        pick = np.arange(len(x))
        take = curved[pick, best] & np.isfinite(outside[pick, best])
        elements, X = elements.copy(), X.copy()
        elements[take] = candidates[pick, best][take]
        X[take] = onto_reference(guess[pick, best][take])
        return elements, X

    def invert(self, x: np.ndarray, elements: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Newton's method for F_e(X) = x (P2 maps of `elements` (m,)) from X (m, 2): the
        reference points (m, 2) and whether they converged (m,) to the point within 1e-9 sizes."""
        nodes = self.nodes[elements]                                               # (m, 6, 2)
        X = X.copy()
        active = np.arange(len(x))                    # points still moving
        for _ in range(NEWTON_STEPS):
            phi, dphi = p2_shapes(X[active])
            r = x[active] - np.einsum("mi,mid->md", phi, nodes[active])
            J = np.einsum("mia,mid->mda", dphi, nodes[active])                     # dF_d / dX_a
            det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.stack([J[:, 1, 1] * r[:, 0] - J[:, 0, 1] * r[:, 1],
                                 J[:, 0, 0] * r[:, 1] - J[:, 1, 0] * r[:, 0]], 1) / det[:, None]
            step = np.where(np.isfinite(step), step, 0.0)
            # clipped: the P2 map means nothing far from the triangle (the point is not in this element)
            X[active] = np.clip(X[active] + step, -1.0, 2.0)
            active = active[np.any(np.abs(step) >= NEWTON_TOLERANCE, axis=1)]
            if len(active) == 0:
                break
        phi, _ = p2_shapes(X)
        gap = np.linalg.norm(x - np.einsum("mi,mid->md", phi, nodes), axis=1)
        return X, gap <= 1e-9 * self.size


def solve_fem_mesh(model: Model, estimate_condition: bool = True) -> Solution:
    """Body-fitted P2 solution of the model on a gmsh mesh of its body (any simple outline)."""
    start = perf_counter()
    body, material, loads = model.body, model.material, model.loads
    lam, mu = material.lam, material.mu
    polygon = mesh_polygon(body, model.grid.h)
    meshed = perf_counter()
    mesh = polygon.mesh
    element = ElementVector(ElementTriP2())
    basis = Basis(mesh, element, intorder=STIFFNESS_ORDER)
    load_basis = Basis(mesh, element, intorder=LOAD_ORDER)

    def at(field, x):                       # (n, 2)-point field at skfem points x (2, ...) -> (2, ...)
        return field(x.reshape(2, -1).T).T.reshape(x.shape)

    K = asm(linear_elasticity(lam, mu), basis)
    # the load fields once at the quadrature points (a LinearForm runs once per test function)
    x_q = np.asarray(load_basis.global_coordinates())                          # (2, n_elements, n_qp)
    _, grad_a = model.lift(x_q.reshape(2, -1).T)                               # (n, 2, 2)
    grad_a = np.moveaxis(grad_a, 0, 2).reshape(2, 2, *x_q.shape[1:])
    eps_a = 0.5 * (grad_a + np.swapaxes(grad_a, 0, 1))
    sigma_a = 2 * mu * eps_a + lam * np.einsum("ii...->...", eps_a) * np.eye(2)[:, :, None, None]
    force = np.zeros_like(x_q) if loads.body_force is None else at(loads.body_force, x_q)
    f = asm(LinearForm(lambda v, w: dot(w.b, v) - ddot(w.sigma_a, sym_grad(v))), load_basis, b=force, sigma_a=sigma_a)
    for k, traction in loads.tractions.items():
        order = CURVED_LOAD_ORDER if body.arcs and body.arcs[k] is not None else LOAD_ORDER
        facets = FacetBasis(mesh, element, facets=polygon.piece_facets[k], intorder=order)
        t = at(traction, np.asarray(facets.global_coordinates()))                  # (2, n_facets, n_qp)
        f = f + asm(LinearForm(lambda v, w: dot(w.t, v)), facets, t=t)

    dofs = node_dofs(basis)
    T = constraint_transform(body, polygon, dofs)
    require_held(T, mesh.doflocs.T, dofs)
    A, b = sp.csr_matrix(T.T @ K @ T), T.T @ f
    assembled = perf_counter()
    q, info = solve_system(A, b, estimate_condition)
    U = T @ q
    solved = perf_counter()
    nodes = {k: polygon.piece_nodes[k] for k in body.essential_edges}
    normals = {k: -normals_at(body, k, mesh.doflocs.T[at]) for k, at in nodes.items()}      # outward
    reactions = piece_reactions(dict(enumerate(body.kinds)), nodes, normals, (K @ U - f)[dofs].T)
    locate = CurvedLocator(mesh, polygon.curved) if body.arcs else TriangleLocator(mesh.p, mesh.t)

    def evaluate(x: np.ndarray, cells: np.ndarray | None = None):
        """u, sigma, sigma_zz at global points x (n, 2) inside the body (`cells` is ignored)."""
        if len(x) == 0:
            return np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros(0)
        elements, X = locate(x)
        points = CellBasis(mesh, element, quadrature=(X[:, :, None], np.ones((len(x), 1))), elements=elements)
        u_h, grad_h = values_at(points, U)
        u_a, grad_a = model.lift(x)
        grad = grad_h + grad_a
        eps = 0.5 * (grad + np.swapaxes(grad, 1, 2))
        trace = eps[:, 0, 0] + eps[:, 1, 1]
        sigma = 2 * mu * eps + lam * trace[:, None, None] * np.eye(2)
        return u_h + u_a, sigma, lam * trace

    u, sigma, sigma_zz = evaluate(model.points.x)
    info.update(ndof=A.shape[0], n_elements=mesh.nelements, time_mesh=meshed - start,
                time_assemble=assembled - start, time_solve=solved - assembled, time_s=perf_counter() - start)
    return Solution(u, sigma, sigma_zz, evaluate, info, reactions=reactions)
