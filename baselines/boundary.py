"""Shared machinery of the grid baselines: the grid as a scikit-fem mesh, basis evaluation
at arbitrary points, boundary Gauss points and the bulk system every method starts from.

The background grid becomes a scikit-fem `MeshQuad` whose node and element numbering is
ibm.discretise.grid's (node j (nx + 1) + i, cell j nx + i, local nodes counter-clockwise from the
lower-left), so `ElementVector(ElementQuad1())` numbers DOFs [2 I, 2 I + 1] exactly like
`Grid.cell_dofs`. Boundary terms are integrated by a `CellBasis` whose "elements" are the
cells holding the Gauss points, one point per entry (per-element quadrature; on
scikit-fem 12.0.2 it needs `elements=`), with weights rescaled so that `w.dx` is the
point's own weight (a length for boundary points).

Normals `n` in the boundary forms are OUTWARD unit normals, one per boundary point (body.outward:
-body.normals[k] on a straight edge, radial on an arc); the forms read them as the field w.n
(and the tangent w.t), passed by `edge_asm`.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from time import perf_counter

import numpy as np
import scipy.sparse as sp
from skfem import BilinearForm, CellBasis, ElementHex1, ElementQuad1, ElementVector, LinearForm, MeshHex, MeshQuad, asm
from skfem.helpers import div, dot, eye, mul, sym_grad

from ibm.small import forms
from ibm.discretise.assembly import tensor, voigt
from ibm.quadrature.bands import edge_quadrature
from ibm.discretise.grid import Grid
from ibm.small.model import BoundaryTraction, Model, Solution
from ibm.quadrature.rules import ARC_ORDER, QuadraturePoints
from ibm.solvers.rigid_modes import require_constrained
from ibm.solvers.linear import active_dofs, solve_system
from ibm.exceptions import SolveError
from ibm.discretise.support import Extension, extension


# --- the grid as a scikit-fem space -------------------------------------------------------

@dataclass(frozen=True, eq=False)
class GridSpace:
    """The background grid as a scikit-fem mesh with the vector Q1 element."""

    grid: Grid
    mesh: MeshQuad
    element: ElementVector


# scikit-fem's local node order of a hexahedron, as offsets from its lowest corner (its reference
# coordinates are then X = 1 - (x - corner) / h, ElementHex1's nodes sitting at 1 - offset)
HEX_OFFSETS = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 0], [1, 0, 0], [0, 1, 1], [1, 0, 1], [1, 1, 0], [1, 1, 1]])


@lru_cache(maxsize=8)
def grid_space(grid: Grid) -> GridSpace:
    """scikit-fem mesh of every grid cell, numbered like ibm.discretise.grid (checked): Q4 in 2D, Hex1 in 3D."""
    cells = np.arange(grid.n_cells)
    if grid.dim == 3:
        order = [int(np.flatnonzero(np.all(grid.local_nodes == o, axis=1))[0]) for o in HEX_OFFSETS]
        mesh = MeshHex(grid.nodes().T.copy(), grid.cell_nodes(cells)[:, order].T.astype(np.int64).copy())
        space = GridSpace(grid, mesh, ElementVector(ElementHex1()))
        probe = point_basis(mesh, space.element, grid.cell_corners(cells[:1]) + 0.3 * grid.h, cells[:1])
        if not np.array_equal(np.sort(probe.element_dofs[:, 0]), np.sort(grid.cell_dofs(cells[:1])[0])):
            raise RuntimeError("scikit-fem DOF numbering differs from ibm.discretise.grid's; the grid bridge needs updating")
        return space
    mesh = MeshQuad(grid.nodes().T.copy(), grid.cell_nodes(cells).T.astype(np.int64).copy())
    space = GridSpace(grid, mesh, ElementVector(ElementQuad1()))
    probe = point_basis(mesh, space.element, grid.cell_corners(cells[:1]) + 0.5 * grid.h, cells[:1])
    if not np.array_equal(probe.element_dofs[:, 0], grid.cell_dofs(cells[:1])[0]):
        raise RuntimeError("scikit-fem DOF numbering differs from ibm.discretise.grid's; the grid bridge needs updating")
    return space


def reference_coordinates(mesh, x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(2, n) coordinates in the reference square [0, 1]^2 of points x (n, 2) in their cells.

    Grid and body-fitted cells are parallelograms, so F(X) = p0 + X0 (p1 - p0) + X1 (p3 - p0)
    inverts in closed form (scikit-fem's Newton inverse clips to the square and fails to
    converge for points a rounding error outside it). Points further than 1e-9 of a cell
    outside it are refused; other quadrilaterals go through scikit-fem's Newton.
    """
    if mesh.p.shape[0] == 3:   # the grid's hexahedra (grid_space), axis-aligned boxes
        corner, far = mesh.p[:, mesh.t[0, cells]], mesh.p[:, mesh.t[7, cells]]
        X = 1 - (x.T - corner) / (far - corner)
        outside = np.max(np.maximum(-X, X - 1), axis=0)
        if np.any(outside > 1e-9):
            worst = int(np.argmax(outside))
            raise ValueError(f"point {x[worst]} lies {outside[worst]:.3g} cell widths outside its cell {cells[worst]}")
        return X
    p = mesh.p[:, mesh.t[:, cells]]                                        # (2, 4, n)
    e1, e3 = p[:, 1] - p[:, 0], p[:, 3] - p[:, 0]                          # (2, n)
    if np.abs(p[:, 2] - p[:, 1] - e3).max() > 1e-12 * np.abs(e1).max():
        return mesh.mapping().invF(x.T[:, :, None], tind=cells)[:, :, 0]
    det = e1[0] * e3[1] - e1[1] * e3[0]
    d = x.T - p[:, 0]
    X = np.stack([(d[0] * e3[1] - d[1] * e3[0]) / det, (e1[0] * d[1] - e1[1] * d[0]) / det])
    outside = np.max(np.maximum(-X, X - 1), axis=0)
    if np.any(outside > 1e-9):
        worst = int(np.argmax(outside))
        raise ValueError(f"point {x[worst]} lies {outside[worst]:.3g} cell widths outside its cell {cells[worst]}")
    return X


def point_basis(mesh, element, x: np.ndarray, cells: np.ndarray, weight: np.ndarray | None = None) -> CellBasis:
    """CellBasis evaluating at points x (n, 2) of `cells` (n,), one point per entry.

    With `weight` (n,) the basis integrates sum_q weight_q f(x_q): w.dx == weight.
    """
    X = reference_coordinates(mesh, x, cells)[:, :, None]                  # (2, n, 1) reference coords
    if weight is None:
        weight = np.ones(len(x))
    detDF = np.abs(mesh.mapping().detDF(X, tind=cells))                   # (n, 1)
    return CellBasis(mesh, element, quadrature=(X, weight[:, None] / detDF), elements=cells)


def values_at(basis: CellBasis, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Field u (n, 2) and gradient (n, 2, 2) [p, i, j] = d u_i / d x_j of DOF vector U at the basis points."""
    field = basis.interpolate(U)
    return np.asarray(field)[:, :, 0].T, np.moveaxis(np.asarray(field.grad)[:, :, :, 0], 2, 0)


# --- boundary points ------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class EdgePoints:
    """Gauss points of one essential edge split at grid lines, and the outward unit normal at each."""

    edge: int
    kind: str
    normal: np.ndarray       # (m, 2) outward unit normal at each point (one row repeated on a straight edge)
    points: QuadraturePoints
    piece: np.ndarray        # (m,) index of the piece (edge part inside one cell) of each point

    @property
    def fields(self) -> dict[str, np.ndarray]:
        """The normal n and tangent t = (-n_y, n_x) as scikit-fem fields (2, m, 1), for asm(**fields)."""
        n = self.normal.T[:, :, None]
        return {"n": n, "t": np.stack([-n[1], n[0]])} if len(n) == 2 else {"n": n}


def cell_pieces(cells: np.ndarray, count: int) -> np.ndarray:
    """Piece (m,) of each point from the cells (m,) of runs of `count` points (one straight part or
    one sub-arc, each in one cell): consecutive runs in the same cell make one piece."""
    first = cells[::count]
    new = np.concatenate([[True], first[1:] != first[:-1]])
    return np.repeat(np.cumsum(new) - 1, count)


def essential_edge_points(model: Model, order: int = 4) -> list[EdgePoints]:
    """Gauss points on every essential edge: order per straight piece (exact to degree 2 order - 1),
    ibm.quadrature.rules.ARC_ORDER per sub-arc (edge_quadrature)."""
    body, grid = model.body, model.grid
    result = []
    for k in body.essential_edges:
        qp = edge_quadrature(body, grid, k, None, order=order)
        result.append(EdgePoints(k, body.kinds[k], body.outward(k, qp.x), qp, edge_pieces(body, k, qp, order)))
    return result


def edge_pieces(body, edge: int, qp, order: int) -> np.ndarray:
    """Piece (m,) of each of edge_quadrature's points on `edge` (straight parts of `order` points)."""
    if body.dim == 3:      # face pieces: runs of points in one cell
        return np.cumsum(np.concatenate([[True], qp.cells[1:] != qp.cells[:-1]])) - 1
    count = ARC_ORDER if body.arcs and body.arcs[edge] is not None else order
    return cell_pieces(qp.cells, count)


def edge_basis(model: Model, edge: EdgePoints) -> CellBasis:
    space = grid_space(model.grid)
    return point_basis(space.mesh, space.element, edge.points.x, edge.points.cells, edge.points.weight)


def edge_asm(form, model: Model, edge: EdgePoints, basis: CellBasis | None = None):
    """asm(form) over the edge's points, with the outward normal w.n and tangent w.t at each."""
    return asm(form, edge_basis(model, edge) if basis is None else basis, **edge.fields)


# --- boundary forms (w.n the outward normal at each point) -------------------------------------

def stress(w, lam: float, mu: float):
    """Plane-strain (or, for a 3D field, isotropic) stress of a skfem field w."""
    return 2 * mu * sym_grad(w) + lam * eye(div(w), w.shape[0])


def mass_form(kind: str) -> BilinearForm:
    """(n.u)(n.v) on rollers, u.v on fixed edges."""
    if kind == "roller":
        return BilinearForm(lambda u, v, w: dot(u, w.n) * dot(v, w.n))
    return BilinearForm(lambda u, v, w: dot(u, v))


def consistency_form(kind: str, lam: float, mu: float) -> BilinearForm:
    """Nitsche's consistency term (n.v)(n.sigma(u) n) on rollers, v.sigma(u) n on fixed edges."""
    if kind == "roller":
        return BilinearForm(lambda u, v, w: dot(v, w.n) * dot(w.n, mul(stress(u, lam, mu), w.n)))
    return BilinearForm(lambda u, v, w: dot(v, mul(stress(u, lam, mu), w.n)))


def symmetric(K: sp.spmatrix) -> sp.csr_matrix:
    """K + K^T."""
    return sp.csr_matrix(K + K.T)


def lift_traction(model: Model, edge: EdgePoints) -> np.ndarray:
    """sigma(u^a) n (m, 2) at the edge's Gauss points (n outward)."""
    _, grad_a = model.lift(edge.points.x)
    sigma_a = tensor(voigt(grad_a) @ model.C.T)
    return np.einsum("mij,mj->mi", sigma_a, edge.normal)


def consistency_load(model: Model, edge: EdgePoints) -> np.ndarray:
    """The consistency term with u = u^a moved to the right-hand side: int (n.v)(n.sigma(u^a) n)
    on rollers, int v.sigma(u^a) n on fixed edges; (2 n_nodes,). Zero without a lift."""
    if model.loads.lift is None:
        return np.zeros(model.dim * model.grid.n_nodes)
    t = lift_traction(model, edge)                                           # (m, 2)
    if edge.kind == "roller":
        t = np.sum(t * edge.normal, axis=1)[:, None] * edge.normal           # normal part only
    field = t.T[:, :, None]                                                  # (d, m, 1)
    return asm(LinearForm(lambda v, w: dot(v, w.traction)), edge_basis(model, edge), traction=field)


# --- bulk system shared with the core ---------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Bulk:
    """Material-point stiffness and loads (body force, lift, tractions), no boundary treatment."""

    K: sp.csr_matrix
    f: np.ndarray
    points: QuadraturePoints
    edges: list[EdgePoints]


def bulk_system(model: Model) -> Bulk:
    points = model.points.quadrature()
    tractions = {k: edge_quadrature(model.body, model.grid, k, None) for k in model.loads.tractions}
    K = forms.stiffness(model, points)
    f = (forms.body_force(model, points) + forms.lift_force(model, points)
         + forms.traction_force(model, tractions))
    return Bulk(K, f, points, essential_edge_points(model))


@dataclass(frozen=True, eq=False)
class Reduction:
    """The unknowns actually solved for: active DOFs (nodes of cells holding material or
    boundary points) with tiny-support nodes tied to well-supported cells (ibm.discretise.support, the
    core's remedy), so U[dofs] = T @ x."""

    dofs: np.ndarray
    tie: Extension
    n_extended: int

    @property
    def T(self) -> sp.csr_matrix:
        return self.tie.T

    def reduce(self, K: sp.spmatrix, f: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
        """T^T K T and T^T f on the active DOFs, from K (2 n_nodes)^2 and f (2 n_nodes,)."""
        return self.tie.reduce(K, f, self.dofs)


def reduction(model: Model, bulk: Bulk, support_threshold: float) -> Reduction:
    dofs = active_dofs(model.grid, bulk.points.cells, *[e.points.cells for e in bulk.edges])
    tie = extension(model.grid, model.points, dofs, support_threshold)
    return Reduction(dofs, tie, len(tie.extended))


def solve_weak(model: Model, bulk: Bulk, K: sp.spmatrix, f: np.ndarray, start: float,
               support_threshold: float, estimate_condition: bool = True, check=None) -> tuple[np.ndarray, dict]:
    """Solve K U = f for U (2 n_nodes,) on the reduced unknowns.

    check(A, info), if given, inspects the reduced matrix and the solve's info (the structure that
    stood) and raises SolveError to refuse the solution.
    """
    assembled = perf_counter()
    r = reduction(model, bulk, support_threshold)
    A, b = r.reduce(K, f)
    # the extension reproduces linear fields, so rigid modes of the reduced system are exact
    require_constrained(A, model.grid, r.dofs[r.tie.kept])
    d = model.dim
    kept = r.dofs[r.tie.kept]                                  # (x, y[, z]) of the kept nodes
    x, info = solve_system(A, b, estimate_condition, positions=model.grid.nodes()[kept[0::d] // d])
    if check is not None:
        check(A, info)
    U = np.zeros(d * model.grid.n_nodes)
    U[r.dofs] = r.T @ x
    info.update(ndof=A.shape[0], n_extended=r.n_extended, time_assemble=assembled - start,
                time_solve=perf_counter() - assembled)
    return U, info


def check_condition(info: dict, limit: float, what: str) -> None:
    """Refuse a solution whose system was numerically singular."""
    if info.get("cond_est", 0.0) > limit:
        raise SolveError(f"the {what} system is numerically singular (condition estimate "
                         f"{info['cond_est']:.3g} > {limit:.0e}); {'its solution is not unique'}")


def grid_solution(model: Model, U: np.ndarray, info: dict, start: float,
                  tractions: BoundaryTraction | None = None, reactions: dict | None = None) -> Solution:
    """Recover u = u^h + u^a and sigma at the material points from nodal values U."""
    evaluate = forms.field_evaluator(model, U)
    u, sigma, sigma_zz = evaluate(model.points.x, model.points.cells)
    info["time_s"] = perf_counter() - start
    return Solution(u, sigma, sigma_zz, evaluate, info, tractions, nodal=U, reactions=reactions)


def traction_variation(tractions: BoundaryTraction, body) -> float:
    """Total variation of the recovered normal traction along each edge, relative to its mean
    magnitude, summed over edges: 0 for a constant traction, O(1) and up when it oscillates."""
    total = 0.0
    for k in np.unique(tractions.edge):
        mine = tractions.edge == k
        s = (tractions.x[mine] - body.starts[k]) @ (body.tangents[k] / body.lengths[k])
        tn = np.sum(tractions.value[mine] * body.outward(k, tractions.x[mine]), axis=1)
        tn = tn[np.argsort(s, kind="stable")]
        scale = np.abs(np.average(tn, weights=tractions.weight[mine][np.argsort(s, kind="stable")]))
        total += float(np.sum(np.abs(np.diff(tn))) / max(scale, np.finfo(float).tiny))
    return total


def trace_operator(model: Model, x: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Displacement operator Nv (m, d, k d) and DOF ids (m, k d) at points x (m, d), from scikit-fem."""
    space = grid_space(model.grid)
    basis = point_basis(space.mesh, space.element, x, cells)
    Nv = np.stack([np.asarray(basis.basis[j][0])[:, :, 0].T for j in range(basis.Nbfun)], axis=2)
    return Nv, basis.element_dofs.T


def multiplier_system(K: sp.spmatrix, G: sp.spmatrix, f: np.ndarray, r: Reduction) -> tuple[sp.csr_matrix, np.ndarray]:
    """[[T^T K T, (G T)^T], [G T, 0]] on the reduced unknowns and its right-hand side [T^T f; 0]
    (homogeneous constraints: the lift carries the essential data)."""
    Kd, fd = r.reduce(K, f)
    Gd = sp.csr_matrix(sp.csr_matrix(G)[:, r.dofs] @ r.T)
    A = sp.bmat([[Kd, Gd.T], [Gd, None]], format="csr")
    return A, np.concatenate([fd, np.zeros(G.shape[0])])


def piece_reactions(kinds: dict[int, str], nodes: dict[int, np.ndarray], normals: dict[int, np.ndarray],
                    force: np.ndarray) -> dict[int, np.ndarray]:
    """Resultant (2,) on each essential piece k of the nodal residual `force` (n_nodes, 2) = K U - f
    at its constrained nodes nodes[k] (m_k,), normals[k] (m_k, 2) its unit normal at them.

    A node on one piece gives a roller (n.r) n, a fixed piece r. A node on two pieces (a corner) is
    split: two rollers with different normals take r = a n_1 + b n_2 apart; a roller beside a fixed
    piece takes (n.r) n and the fixed piece the rest (at a right angle the fixed piece's traction
    has no component along the roller's normal, that being the roller's shear); two fixed pieces
    or collinear rollers take half each. A node on more pieces gives each of them (n.r) n or r over
    their number.
    """
    count = np.zeros(len(force), int)
    first, first_normal = np.full(len(force), -1), np.zeros((len(force), 2))    # the first piece at each node
    for k, at in nodes.items():
        new = count[at] == 0
        first[at[new]], first_normal[at[new]] = k, normals[k][new]
        count[at] += 1
    second, second_normal = np.full(len(force), -1), np.zeros((len(force), 2))  # the second one
    for k, at in nodes.items():
        later = (count[at] == 2) & (first[at] != k)
        second[at[later]], second_normal[at[later]] = k, normals[k][later]
    result = {}
    for k, at in nodes.items():
        r, n, c = force[at], normals[k], count[at][:, None]                          # (m, 2), (m, 2), (m, 1)
        mine_first = first[at] == k
        j = np.where(mine_first, second[at], first[at])                              # the other piece (m,)
        m = np.where(mine_first[:, None], second_normal[at], first_normal[at])       # its normal (m, 2)
        beside_fixed = np.array([kinds.get(int(i)) == "fixed" for i in j])[:, None]
        along = np.sum(r * n, axis=1)[:, None] * n                                  # (n.r) n
        cross = n[:, 0] * m[:, 1] - n[:, 1] * m[:, 0]                               # n x m
        if kinds[k] == "fixed":
            rest = r - np.sum(r * m, axis=1)[:, None] * m
            pair = np.where(beside_fixed, r / 2, rest)
            share = np.where(c == 1, r, np.where(c == 2, pair, r / c))
        else:
            apart = (r[:, 0] * m[:, 1] - r[:, 1] * m[:, 0]) / np.where(cross == 0, 1.0, cross)
            pair = np.where(beside_fixed, along, np.where((np.abs(cross) <= 1e-9)[:, None], along / 2,
                                                          apart[:, None] * n))
            share = np.where(c == 1, along, np.where(c == 2, pair, along / c))
        result[k] = share.sum(axis=0)
    return result


# Multiplier pieces shorter than this fraction of h (h^2 in 3D) join a neighbour (baselines.lagrange).
MERGE_FRACTION = 1e-2


def merge_short(piece: np.ndarray, weight: np.ndarray, size: float, fraction: float = MERGE_FRACTION) -> np.ndarray:
    """Group (m,) of points whose pieces (m,), numbered along the edge, have the lengths (areas) of their
    weights: pieces below fraction * size join the previous piece (the next one at the start)."""
    length = np.bincount(piece, weights=weight)
    short = length < fraction * size
    if short.all():
        return np.zeros_like(piece)
    index = np.where(short, -1, np.arange(len(length)))
    forward = np.maximum.accumulate(index)                       # last long piece before
    backward = np.minimum.accumulate(np.where(index < 0, len(length), index)[::-1])[::-1]
    group = np.where(forward >= 0, forward, backward)
    return np.unique(group, return_inverse=True)[1][piece]
