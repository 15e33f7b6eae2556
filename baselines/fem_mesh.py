"""Body-fitted finite-element reference on any simple polygon: gmsh P2 triangles, scikit-fem.

The polygon is meshed by gmsh (one line per piece, so every mesh facet knows its piece) into
6-node triangles of about the grid's cell size. The sides are straight, so the midside nodes
sit at the edge midpoints (Mesh.SecondOrderLinear) and the mapping of every element is affine:
the mesh is a scikit-fem `MeshTri2` with `affine=True` and the vector P2 element. Stiffness by
a degree-4 rule, loads by degree 8. As in baselines.fem, u = u^h + u^a with the lift u^a; u^h
is imposed strongly on every node (corner and midside) of an essential piece through
U = T q: fixed pieces drop both components, a roller keeps the component along its tangent,
and a node on two rollers with different normals (or a roller and a fixed piece) drops both.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from time import perf_counter

import gmsh
import numpy as np
import scipy.linalg
import scipy.sparse as sp
import shapely
from scipy.spatial import cKDTree
from skfem import Basis, CellBasis, ElementTriP2, ElementVector, FacetBasis, LinearForm, MeshTri2, asm
from skfem.helpers import ddot, dot, sym_grad
from skfem.models.elasticity import linear_elasticity

from baselines.boundary import values_at
from ibm.geometry import Body, InputError
from ibm.model import Model, Solution
from ibm.solve import SolveError, solve_system

STIFFNESS_ORDER = 4     # P2: strain x strain is degree 2, so exact
LOAD_ORDER = 8          # body force, lift and tractions are arbitrary smooth functions
GMSH_ALGORITHM = 6      # Frontal-Delaunay, fixed so the mesh does not depend on gmsh's defaults
PARALLEL_TOLERANCE = 1e-9   # |n_1 x n_2| below this: two roller pieces are collinear
# gmsh keeps one global model per process: meshing is serialised across threads
_GMSH_LOCK = threading.Lock()
TRIANGLE6, LINE3 = 9, 8     # gmsh element types
BLOCK = 16384               # points located at a time


@dataclass(frozen=True, eq=False)
class PolygonMesh:
    """The P2 mesh of a body and where its pieces lie in it.

    mesh: MeshTri2 (affine), doflocs (2, n_nodes) are gmsh's nodes in scikit-fem's order
    (vertices, then one midside node per facet). piece_facets[k]: mesh facet ids on piece k;
    piece_nodes[k]: node ids (corner and midside, endpoints included) on piece k.
    """

    mesh: MeshTri2
    piece_facets: list[np.ndarray]
    piece_nodes: list[np.ndarray]


def check_polygon(body: Body) -> None:
    """InputError unless the outline is a simple polygon with pieces of positive length."""
    short = np.flatnonzero(body.lengths <= 1e-12 * body.lengths.max())
    if len(short):
        raise InputError(f"piece {short[0]} of the body has zero length; the fem mesh needs distinct vertices")
    if not shapely.LinearRing(body.vertices).is_simple:
        raise InputError("the body's outline intersects itself; the fem mesh needs a simple polygon")


def gmsh_triangles(vertices: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """gmsh's P2 mesh of the polygon `vertices` (n, 2) with element size h.

    Returns nodes (n_nodes, 2), triangles (n_elements, 6) and per piece k its 3-node line
    elements (m_k, 3), all as row indices of `nodes`; gmsh's local order: corners 0, 1, 2, then
    the midside nodes of edges 0-1, 1-2, 2-0 (lines: two ends, then the middle).
    """
    with _GMSH_LOCK:
        # interruptible=False: no SIGINT handler, which only the main thread could install
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        try:
            for name, value in (("General.Terminal", 0), ("General.NumThreads", 1),
                                ("Mesh.Algorithm", GMSH_ALGORITHM), ("Mesh.ElementOrder", 2),
                                ("Mesh.SecondOrderLinear", 1), ("Mesh.MeshSizeMax", h),
                                ("Mesh.MeshSizeExtendFromBoundary", 1)):
                gmsh.option.setNumber(name, value)
            gmsh.model.add("body")
            geo = gmsh.model.geo
            points = [geo.addPoint(x, y, 0.0, h) for x, y in vertices]
            n = len(points)
            lines = [geo.addLine(points[k], points[(k + 1) % n]) for k in range(n)]
            geo.addPlaneSurface([geo.addCurveLoop(lines)])
            geo.synchronize()
            gmsh.model.mesh.generate(2)
            tags, coords, _ = gmsh.model.mesh.getNodes()
            _, triangles = gmsh.model.mesh.getElementsByType(TRIANGLE6)
            pieces = [gmsh.model.mesh.getElementsByType(LINE3, tag=line)[1] for line in lines]
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
    nodes, triangles, pieces = gmsh_triangles(body.vertices, h)
    used = np.unique(triangles)
    if len(triangles) == 0 or any(len(p) == 0 for p in pieces):
        raise InputError("gmsh returned no triangles for the body (or left a piece without elements)")
    renumber = np.full(len(nodes), -1, np.int64)
    renumber[used] = np.arange(len(used))
    triangles, pieces = renumber[triangles], [renumber[p] for p in pieces]
    mesh = MeshTri2(nodes[used].T.copy(), triangles.T.copy(), affine=True)
    if mesh.doflocs.shape[1] != len(used):
        raise InputError("gmsh's mesh of the body is not a conforming P2 mesh")
    # MeshTri2 reorders its nodes (vertices first, then one per facet): gmsh row -> node id
    to_mesh = np.empty(len(used), np.int64)
    to_mesh[triangles[:, :3]] = mesh.t.T
    to_mesh[triangles[:, 3:]] = mesh.dofs.element_dofs[3:].T
    corners = mesh.p[:, mesh.t]                                                  # (2, 3, n_elements)
    area = 0.5 * np.sum((corners[0, 1] - corners[0, 0]) * (corners[1, 2] - corners[1, 0])
                        - (corners[1, 1] - corners[1, 0]) * (corners[0, 2] - corners[0, 0]))
    if not np.isclose(area, body.area, rtol=1e-9):
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
    return PolygonMesh(mesh, piece_facets, piece_nodes)


def facet_keys(mesh: MeshTri2, ends: np.ndarray) -> np.ndarray:
    """One integer per vertex pair (2, m), independent of the pair's order."""
    return np.min(ends, axis=0).astype(np.int64) * mesh.nvertices + np.max(ends, axis=0)


def node_dofs(basis: Basis) -> np.ndarray:
    """(2, n_nodes) DOF ids of the components of every mesh node (vertices, then facets)."""
    return np.hstack([basis.nodal_dofs, basis.facet_dofs])


def constraint_transform(body: Body, polygon: PolygonMesh, dofs: np.ndarray) -> sp.csr_matrix:
    """T (n_dofs, n_q) with U = T q for all U vanishing on fixed pieces and normal-vanishing
    on rollers; dofs (2, n_nodes) from node_dofs. Its columns are orthonormal."""
    n_nodes = dofs.shape[1]
    clamped = np.zeros(n_nodes, bool)
    held = np.zeros(n_nodes, bool)               # node already on a roller, with normal[node]
    normal = np.zeros((n_nodes, 2))
    for k in body.essential_edges:
        nodes = polygon.piece_nodes[k]
        if body.kinds[k] == "fixed":
            clamped[nodes] = True
            continue
        n = body.normals[k]
        cross = normal[nodes, 0] * n[1] - normal[nodes, 1] * n[0]
        clamped[nodes[held[nodes] & (np.abs(cross) > PARALLEL_TOLERANCE)]] = True
        fresh = nodes[~held[nodes]]
        normal[fresh], held[fresh] = n, True
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
    moved to the nearest point of that element, as baselines.fem clips to the rectangle.
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


def solve_fem_mesh(model: Model, estimate_condition: bool = True) -> Solution:
    """Body-fitted P2 solution of the model on a gmsh mesh of its body (any simple polygon)."""
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
        facets = FacetBasis(mesh, element, facets=polygon.piece_facets[k], intorder=LOAD_ORDER)
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
    locate = TriangleLocator(mesh.p, mesh.t)

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
    return Solution(u, sigma, sigma_zz, evaluate, info)
