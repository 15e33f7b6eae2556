"""The baselines inside the large-deformation loop (ibm.treatment's interface).

Wall terms live on wall ∩ current body (the outline's essential edges at the step start),
Gauss points per piece between grid lines; n is the outward normal, P the projector n n
(roller) or I (fixed), g the wall's displacement this step, dw = dU^h the plain field.
- `nodal`: strong constraints on the grid nodes lying on each wall (AMPLE's and most MPM codes'
  way); a wall that does not lie on a grid line, at every step, is refused.
- `penalty`: f = beta int P(dw - g) . v,  beta = beta0 M / h (linear: a constant tangent).
- `lagrange`: one constant multiplier per wall piece in a cut cell (pieces shorter than h/100
  merged), int psi P(dw - g) = 0, with the consistent augmentation (M/h) int P(dw - g) . v.
- `nitsche`: f = -int P(Pi n) . v - int P(dw - g) . (A_n : grad v) n + (gamma M / h) int P(dw - g) . v,
  Pi the first Piola stress of the step (relative to x_n) from the covering point's state,
  A_n the spatial tangent at the step start (frozen, so the symmetric term stays bilinear and
  consistent: it vanishes wherever dw = g); the exact linearisation of the first term makes the
  tangent unsymmetric.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from baselines.boundary import EdgePoints, edge_pieces
from baselines.nodal import wall_nodes
from baselines.lagrange import DEFAULT_AUGMENT, MERGE_FRACTION, components, merged_pieces
from baselines.nitsche import DEFAULT_GAMMA
from baselines.penalty import DEFAULT_BETA0
from ibm.assembly import shape_vector
from ibm.bands import edge_quadrature
from ibm.exceptions import InputError
from ibm.kinematics import gradient_operator, increment, is_small, planar
from ibm.treatment import SUPPORT_THRESHOLD, StepContext, StepTerms

ORDER = 4   # Gauss points per wall piece

# At large deformation the material moves through the grid and every step leaves nodes that a
# few point domains barely reach; a Newton update then moves such a node far, folding the points
# it touches (and, for the IBM, the band behind the wall). Nodes with less than 10 % of a cell's
# support are tied to their well-supported neighbours (ibm.support's extension, exact for
# bilinear fields, so the patch test still holds). Small kinematics keeps its own default.
LARGE_DEFAULTS = {"support_threshold": SUPPORT_THRESHOLD}



@dataclass(frozen=True)
class Nodal:
    """Nodes on a wall line get the wall's motion: its normal component (roller) or both (fixed);
    nodes with less than support_threshold of a cell's support are tied (none by default, as AMPLE)."""

    support_threshold: float = 0.0

    def step(self, context: StepContext) -> StepTerms:
        body, d = context.body, context.grid.dim
        dofs, values = [], []
        for wall, edge in enumerate(body.essential_edges):
            nodes, axis = wall_nodes(context.grid, context.lines.points[wall], context.lines.normals[wall], edge)
            g = context.wall_vector(wall)
            for c in ([axis] if body.kinds[edge] == "roller" else range(d)):
                dofs.append(d * nodes + c)
                values.append(np.full(len(nodes), g[c]))
        dofs, first = np.unique(np.concatenate(dofs), return_index=True)
        return StepTerms(fixed=(dofs, np.concatenate(values)[first]), support_threshold=self.support_threshold,
                         info={"n_fixed": len(dofs)})


@dataclass(frozen=True, eq=False)
class WallPoints:
    """Gauss points of every wall piece in one step: x (m, d), weight (m,), cells (m,), outward
    normal (m, d), projector P (m, d, d), wall displacement g (m, d), DOFs (m, k d), Nv (m, d, k d)
    (k = 2^d nodes a cell), and the edge points of each wall (for grouping)."""

    x: np.ndarray
    weight: np.ndarray
    cells: np.ndarray
    normal: np.ndarray
    projector: np.ndarray
    g: np.ndarray
    dofs: np.ndarray
    Nv: np.ndarray
    edges: list

    n_dofs: int = 0

    def blocks(self, left: np.ndarray, right: np.ndarray) -> sp.csr_matrix:
        """sum_q left_q^T right_q for (m, r, k d) operators, assembled on the points' DOFs."""
        block = np.matmul(left.transpose(0, 2, 1), right)
        order, starts, dofs = self.by_cell
        # a 2D wall has ~4 points a cell: kept point by point, which keeps 2D's recorded results to the
        # bit (the penalty footing at 90 degrees, B/h = 16, meets a singular tangent at step 4 when the
        # wall matrix is only summed in another order: 1.7e-16 of its entries)
        if len(starts) > len(order) / 8:
            return _assemble(self.dofs, block, self.n_dofs)
        # the points of one cell share its DOFs: summed there first (a 3D wall has ~100 points a cell)
        return _assemble(dofs, np.add.reduceat(block[order], starts, axis=0), self.n_dofs)

    @cached_property
    def by_cell(self) -> tuple:
        """(order sorting the points by cell, start of each cell's run, DOFs (c, k d) of each cell)."""
        order = np.argsort(self.cells, kind="stable")
        starts = np.flatnonzero(np.concatenate([[True], np.diff(self.cells[order]) != 0]))
        return order, starts, self.dofs[order[starts]]


def _assemble(dofs: np.ndarray, block: np.ndarray, n: int) -> sp.csr_matrix:
    m = dofs.shape[1]
    return sp.csr_matrix((block.ravel(), (np.repeat(dofs, m, axis=1).ravel(), np.tile(dofs, (1, m)).ravel())),
                         shape=(n, n))


def wall_points(context: StepContext) -> WallPoints:
    grid, body = context.grid, context.body
    parts, edges = [], []
    for wall, edge in enumerate(body.essential_edges):
        qp = edge_quadrature(body, grid, edge, None, order=ORDER)
        n = -body.normals[edge]
        P = np.outer(n, n) if body.kinds[edge] == "roller" else np.eye(grid.dim)
        m = len(qp)
        edges.append(EdgePoints(edge, body.kinds[edge], np.tile(n, (m, 1)), qp, edge_pieces(body, edge, qp, ORDER)))
        parts.append((qp.x, qp.weight, qp.cells, np.tile(n, (m, 1)), np.tile(P, (m, 1, 1)),
                      np.tile(context.wall_vector(wall), (m, 1))))
    x, weight, cells, normal, projector, g = (np.concatenate([p[i] for p in parts]) for i in range(6))
    N, _ = grid.shape_functions(x, cells)
    return WallPoints(x, weight, cells, normal, projector, g, grid.cell_dofs(cells), shape_vector(N), edges,
                      grid.dim * grid.n_nodes)


def _penalty(points: WallPoints, beta: float):
    """dU -> (beta int P(dw - g) . v, its constant tangent)."""
    PNv = np.matmul(points.projector, points.Nv) * (beta * points.weight)[:, None, None]
    K = points.blocks(points.Nv, PNv)
    g_load = np.bincount(points.dofs.ravel(), np.einsum("qia,qi->qa", PNv, points.g).ravel(),
                         minlength=points.n_dofs)

    def wall(dU):
        return K @ dU - g_load, K

    return wall, K, g_load


@dataclass(frozen=True)
class Penalty:
    beta0: float = DEFAULT_BETA0
    support_threshold: float = SUPPORT_THRESHOLD

    def step(self, context: StepContext) -> StepTerms:
        points = wall_points(context)
        beta = self.beta0 * context.material.M / context.grid.h
        wall, _, _ = _penalty(points, beta)
        return StepTerms(wall=wall, cells=points.cells, support_threshold=self.support_threshold,
                         info={"beta": beta})


@dataclass(frozen=True)
class Lagrange:
    augment: float = DEFAULT_AUGMENT
    support_threshold: float = SUPPORT_THRESHOLD

    def step(self, context: StepContext) -> StepTerms:
        points = wall_points(context)
        rows, g, start = [], [], 0
        for edge in points.edges:
            m = len(edge.points)
            part = slice(start, start + m)
            start += m
            group = merged_pieces(edge, context.grid.h, MERGE_FRACTION)
            directions = components(edge.kind, edge.normal)                             # (m, c, d)
            c = directions.shape[1]
            values = np.einsum("mci,mia,m->mca", directions, points.Nv[part], points.weight[part])
            row = group[:, None, None] * c + np.arange(c)[None, :, None]
            n_rows = (group.max() + 1) * c
            rows.append(sp.coo_matrix((values.ravel(), (np.broadcast_to(row, values.shape).ravel(),
                                       np.broadcast_to(points.dofs[part][:, None, :], values.shape).ravel())),
                                      shape=(n_rows, points.n_dofs)))
            # C dU = g: the same rows applied to the wall's uniform displacement
            target = np.einsum("mci,mi,m->mc", directions, points.g[part], points.weight[part])
            g.append(np.bincount((group[:, None] * c + np.arange(c)).ravel(),
                                 target.ravel(), minlength=n_rows))
        C = sp.vstack(rows, format="csr")
        wall = _penalty(points, self.augment * context.material.M / context.grid.h)[0] if self.augment > 0 else None
        return StepTerms(constraints=(C, np.concatenate(g)), wall=wall, cells=points.cells,
                         support_threshold=self.support_threshold, info={"n_multipliers": C.shape[0]})


@dataclass(frozen=True)
class Nitsche:
    gamma: float = DEFAULT_GAMMA
    support_threshold: float = SUPPORT_THRESHOLD

    def step(self, context: StepContext) -> StepTerms:
        points = wall_points(context)
        grid, model = context.grid, context.material
        N, dN = grid.shape_functions(points.x, points.cells)
        G = gradient_operator(N, dN)                                             # (m, d d, k d)
        state = context.state.take(context.state_of(points.x))
        m, d = len(points.weight), grid.dim
        A_n = planar(model.update(np.broadcast_to(np.eye(3), (m, 3, 3)).copy(), state, dim=d).tangent, d)   # (m, d d, d d)
        n = points.normal

        def traction_operator(A):    # (m, d, d d): (A : grad) n, component i = sum_J A[(i, J), .] n_J
            return np.einsum("qiJc,qJ->qic", A.reshape(m, d, d, d * d), n)

        stabilised, K3, g_load = _penalty(points, self.gamma * model.M / grid.h)
        PNv = np.matmul(points.projector, points.Nv) * points.weight[:, None, None]     # (m, d, k d)
        traction_n = np.matmul(traction_operator(A_n), G)                             # (m, d, k d)
        symmetric_part = -points.blocks(traction_n, PNv)                               # -int P(dw) . (A_n:grad v) n
        symmetric_load = -np.bincount(points.dofs.ravel(), np.einsum(
            "qic,qi->qc", traction_n, np.einsum("qij,qj->qi", points.projector, points.g)
            * points.weight[:, None]).ravel(), minlength=points.n_dofs)

        def wall(dU):
            dF = increment(G, dU[points.dofs])
            response = model.update(dF, state, dim=d)
            if is_small(model):          # on the initial configuration: P = sigma, dP = a
                J, inverse = np.ones(m), np.broadcast_to(np.eye(d), (m, d, d))
            else:
                J, inverse = np.linalg.det(dF[:, :d, :d]), np.linalg.inv(dF[:, :d, :d])
            first_piola = J[:, None, None] * response.sigma[:, :d, :d] @ inverse.transpose(0, 2, 1)
            traction = np.einsum("qij,qj->qi", first_piola, n)                        # nominal traction (m, d)
            # dP_imkn = J inverse_mj a_ijkl inverse_nl; its traction n_m dP_imkn, contracted in two steps
            a = response.tangent[:, :d, :d, :d, :d]
            v = J[:, None] * np.einsum("qm,qmj->qj", n, inverse)
            dT = np.matmul(np.einsum("qj,qijkl->qikl", v, a), inverse.transpose(0, 2, 1)[:, None])   # (m, d, d, d)
            force = -np.bincount(points.dofs.ravel(), np.einsum("qia,qi->qa", PNv, traction).ravel(),
                                 minlength=points.n_dofs)
            K1 = -points.blocks(PNv, np.matmul(dT.reshape(m, d, d * d), G))
            force += symmetric_part @ dU - symmetric_load
            stab_force, _ = stabilised(dU)
            return force + stab_force, K1 + symmetric_part + K3

        return StepTerms(wall=wall, cells=points.cells, symmetric=False, support_threshold=self.support_threshold,
                         info={"gamma": self.gamma})


# --- every method's treatment, by name ---------------------------------------------------------



def _ibm(delta_rel: float = 1e-5, support_threshold: float = LARGE_DEFAULTS["support_threshold"], band: str = "auto"):
    from ibm.treatment import ImplicitBoundary
    return ImplicitBoundary(delta_rel, support_threshold, band)


TREATMENTS = {
    "ibm": _ibm,
    "nodal": lambda support_threshold=0.0: Nodal(support_threshold),
    "penalty": lambda beta0=DEFAULT_BETA0, support_threshold=LARGE_DEFAULTS["support_threshold"]:
        Penalty(beta0, support_threshold),
    "lagrange": lambda augment=DEFAULT_AUGMENT, support_threshold=LARGE_DEFAULTS["support_threshold"]:
        Lagrange(augment, support_threshold),
    "nitsche": lambda gamma=DEFAULT_GAMMA, support_threshold=LARGE_DEFAULTS["support_threshold"]:
        Nitsche(gamma, support_threshold),
}


def parameters_used(method: str, declared: dict, given: dict) -> dict:
    """The values a large-kinematics run of `method` uses: given, else the large default, else declared."""
    return {k: given.get(k) if given.get(k) is not None else LARGE_DEFAULTS.get(k, v) for k, v in declared.items()}


# Methods that refuse large kinematics, and why (the README repeats these lines).
REFUSED = {
    "ibm-limit": "its boundary terms and corner point terms are the delta -> 0 limit of the linear-elastic "
                 "band energy; at finite strain the band stress is not linear in the band coordinate, so "
                 "the limit form would not be the IBM's limit (use ibm)",
    "lagrange-nodal": "its collocated multipliers are inf-sup unstable already at small strain; it is kept "
                      "only to show that failure (use lagrange)",
}


def check_band(band: str, method: str, in_load_steps: bool) -> None:
    """InputError unless `band` is one of ibm.treatment.BAND_KINEMATICS and, when not "auto", the
    IBM's in the load steps (large kinematics or material von-mises, not the collapse problems)."""
    from ibm.treatment import BAND_KINEMATICS
    if band not in BAND_KINEMATICS:
        raise InputError(f"band {band!r} is not allowed; allowed: {', '.join(BAND_KINEMATICS)}")
    if band != "auto" and method != "ibm":
        raise InputError(f"band {band!r} is for method 'ibm'; leave it 'auto' for {method!r}")
    if band != "auto" and not in_load_steps:
        raise InputError(f"band {band!r} is for method 'ibm' in the load steps of large kinematics or "
                         "material von-mises (not the collapse problems); leave it 'auto' here")


def treatment(method: str, parameters: dict):
    """The named method's treatment with its parameters; InputError for a method that refuses."""
    if method in REFUSED:
        raise InputError(f"method {method!r} refuses large kinematics: {REFUSED[method]}")
    chosen = {k: v for k, v in parameters.items() if v is not None}
    return TREATMENTS[method](**chosen)
