"""Body-fitted hexahedral finite-element reference for a 3D box (scikit-fem).

The box L x H x W is meshed in its local frame (xi, eta, zeta) by n = ceil(side / h) hexahedra
per side, trilinear (order 1) or triquadratic (order 2) Lagrange (ElementVector of ElementHex1 or
ElementHex2). Every face is axis-aligned there, so rollers are imposed strongly by dropping the
face-normal displacement component at the face's DOFs (all three on fixed faces). The essential
data come from the lift: u = u^h + u^a with u^h = 0 (its normal part on rollers) on the essential
faces, the lift's stress moved to the right-hand side as in baselines/fem/method.py. Gauss rules: order + 1
points per direction for the stiffness (exact on the axis-aligned box), order + 2 for the loads.
Results are rotated back: u = R u_loc, sigma = R sigma_loc R^T.

Faces in order, with their outward local normals: base (eta = 0, -e_eta), right (xi = L, e_xi),
top (eta = H, e_eta), left (xi = 0, -e_xi), front (zeta = 0, -e_zeta), back (zeta = W, e_zeta).
Placement: x = corner + R x_local, R (3, 3) with columns e_xi, e_eta, e_zeta (ibm.geometry.frames.frame_3d).

The mesh is a tensor grid, and so is the lattice of its Lagrange nodes (spacing h_i / order): the
solution is kept there, values[i, j, k] (local frame), and a point's element, its reference
coordinates and the tensor-product shape functions follow by arithmetic (no search).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from time import perf_counter
from typing import Callable

import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementHex1, ElementHex2, ElementVector, FacetBasis, LinearForm, MeshHex, asm
from skfem.helpers import ddot, dot, sym_grad
from skfem.models.elasticity import linear_elasticity

from ibm.geometry.outline import EDGE_KINDS, ESSENTIAL_KINDS

from ibm.exceptions import InputError
from ibm.models.elastic import Elastic
from ibm.solvers.linear import solve_system

FACES = ("base", "right", "top", "left", "front", "back")
OUTWARD = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0],
                    [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])                 # (6, 3) local outward normals
NORMAL_AXIS = tuple(int(a) for a in np.argmax(np.abs(OUTWARD), axis=1))  # 1, 0, 1, 0, 2, 2
AT_END = tuple(bool(e) for e in OUTWARD.sum(axis=1) > 0)               # on coordinate = side, else on 0

# local points xl (n, 3) -> (n, 3) body force; (face, xl) -> (n, 3) traction; xl -> u (n, 3), grad (n, 3, 3)
BodyForce = Callable[[np.ndarray], np.ndarray]
Traction = Callable[[int, np.ndarray], np.ndarray]
Lift = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def _shape_1d(t: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """1D Lagrange functions on nodes 0, 1 (order 1) or 0, 1/2, 1 (order 2) at t (n,):
    values and d/dt, each (n, order + 1)."""
    if order == 1:
        return np.stack([1 - t, t], axis=1), np.broadcast_to([-1.0, 1.0], (len(t), 2))
    return (np.stack([2 * (t - 0.5) * (t - 1), -4 * t * (t - 1), 2 * t * (t - 0.5)], axis=1),
            np.stack([4 * t - 3, 4 - 8 * t, 4 * t - 1], axis=1))


def isotropic_stress(grad: np.ndarray, material: Elastic) -> np.ndarray:
    """sigma = lam tr(eps) I + 2 mu eps (n, 3, 3) from displacement gradients (n, 3, 3)."""
    eps = 0.5 * (grad + np.swapaxes(grad, 1, 2))
    trace = np.einsum("pii->p", eps)
    return 2 * material.mu * eps + material.lam * trace[:, None, None] * np.eye(3)


@dataclass(frozen=True, eq=False)
class BoxSolution:
    """The finite-element solution on a box: u^h at its lattice of Lagrange nodes (local frame);
    the lift u^a is added wherever the solution is evaluated."""

    size: np.ndarray                 # (3,) L, H, W
    frame: np.ndarray                # (3, 3) R, columns e_xi, e_eta, e_zeta
    corner: np.ndarray               # (3,) the local origin in the global frame
    material: Elastic
    order: int
    counts: tuple[int, int, int]     # elements along xi, eta, zeta
    values: np.ndarray               # (order nx + 1, order ny + 1, order nz + 1, 3) u^h, local frame
    lift: Lift | None
    ndof: int                        # unknowns solved for (the constrained ones removed)
    info: dict = field(default_factory=dict)

    @property
    def spacing(self) -> np.ndarray:
        """(3,) element sizes along xi, eta, zeta."""
        return self.size / np.array(self.counts)

    @property
    def local_nodes(self) -> np.ndarray:
        """(m, 3) local positions of the lattice nodes, in the C order of values[..., c]."""
        axes = [np.linspace(0, s, self.order * n + 1) for s, n in zip(self.size, self.counts)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)

    @property
    def nodes(self) -> np.ndarray:
        """(m, 3) global positions of the lattice nodes."""
        return self.corner + self.local_nodes @ self.frame.T

    @property
    def nodal(self) -> np.ndarray:
        """(m, 3) u = u^h + u^a at the lattice nodes, global frame."""
        u = self.values.reshape(-1, 3)
        if self.lift is not None:
            u = u + self.lift(self.local_nodes)[0]
        return u @ self.frame.T

    def local_fields(self, xl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """u (n, 3) and grad (n, 3, 3), grad[p, i, j] = d u_i / d xl_j, at local points xl (n, 3),
        local frame, lift included; points are clipped into the box."""
        xl = np.clip(np.asarray(xl, float), 0.0, self.size)
        spacing, q = self.spacing, self.order + 1
        cell = np.clip(np.floor(xl / spacing).astype(int), 0, np.array(self.counts) - 1)    # (n, 3)
        t = xl / spacing - cell                                                             # (n, 3) in [0, 1]
        N, dN = zip(*(_shape_1d(t[:, a], self.order) for a in range(3)))                    # 3 x (n, q)
        dN = [d / s for d, s in zip(dN, spacing)]
        i, j, k = (self.order * cell[:, a, None] + np.arange(q) for a in range(3))         # 3 x (n, q)
        V = self.values[i[:, :, None, None], j[:, None, :, None], k[:, None, None, :]]     # (n, q, q, q, 3)
        u = np.einsum("pa,pb,pc,pabcd->pd", N[0], N[1], N[2], V, optimize=True)
        grad = np.stack([np.einsum("pa,pb,pc,pabcd->pd", dN[0], N[1], N[2], V, optimize=True),
                         np.einsum("pa,pb,pc,pabcd->pd", N[0], dN[1], N[2], V, optimize=True),
                         np.einsum("pa,pb,pc,pabcd->pd", N[0], N[1], dN[2], V, optimize=True)], axis=2)
        if self.lift is not None:
            u_a, grad_a = self.lift(xl)
            u, grad = u + u_a, grad + grad_a
        return u, grad

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """u (n, 3) and sigma (n, 3, 3) at global points x (n, 3), global frame."""
        R = self.frame
        u, grad = self.local_fields((np.asarray(x, float) - self.corner) @ R)
        sigma = isotropic_stress(grad, self.material)
        return u @ R.T, np.einsum("ai,pij,bj->pab", R, sigma, R)


def _checked(size, frame, corner, kinds, h, order) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
    """size (3,), frame (3, 3), corner (3,), kinds (6,), or InputError naming the bad value."""
    size = np.asarray(size, float)
    if size.shape != (3,) or not (np.all(np.isfinite(size)) and np.all(size > 0)):
        raise InputError(f"box sides must be three positive numbers, got {' x '.join(map(str, np.ravel(size)))}")
    R = np.asarray(frame, float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise InputError(f"the frame must be a finite (3, 3) matrix, got shape {R.shape}")
    deviation = np.abs(R.T @ R - np.eye(3)).max()
    if deviation > 1e-9:
        raise InputError(f"the frame is not orthonormal: max |R^T R - I| = {deviation:.3g} "
                         "(its columns must be the unit vectors e_xi, e_eta, e_zeta)")
    corner = np.asarray(corner, float)
    if corner.shape != (3,) or not np.all(np.isfinite(corner)):
        raise InputError(f"the corner must be a finite point (3,), got {np.ravel(corner).tolist()}")
    kinds = tuple(kinds)
    if len(kinds) != len(FACES):
        raise InputError(f"a box has {len(FACES)} faces ({', '.join(FACES)}) but {len(kinds)} kinds were given")
    for k, kind in enumerate(kinds):
        if kind not in EDGE_KINDS:
            raise InputError(f"face {k} ({FACES[k]}): kind {kind!r} is not one of {', '.join(EDGE_KINDS)}")
    if not (np.isfinite(h) and h > 0):
        raise InputError(f"cell size h={h} is not allowed; it must be > 0")
    if order not in (1, 2):
        raise InputError(f"order={order} is not allowed; it must be 1 (Hex1) or 2 (Hex2)")
    return size, R, corner, kinds


def _points(x: np.ndarray) -> np.ndarray:
    """scikit-fem's quadrature points (3, ...) as (n, 3)."""
    return x.reshape(3, -1).T


def _stiffness(basis: Basis, intorder: int, lam: float, mu: float) -> sp.csr_matrix:
    """K (N, N) of linear elasticity on the basis' mesh. On a uniform tensor mesh every element is the
    same box with the same local node pattern (checked), so one element's matrix (scikit-fem on
    element 0) is scattered to all, several times faster than asm over every element; any other
    mesh goes to asm."""
    mesh, form = basis.mesh, linear_elasticity(lam, mu)
    offsets = mesh.p[:, mesh.t] - mesh.p[:, mesh.t[:1]]                              # (3, 8, n_elements)
    if np.abs(offsets - offsets[:, :, :1]).max() > 1e-12 * np.abs(mesh.p).max():
        return asm(form, basis)
    one = Basis(mesh, basis.elem, intorder=intorder, elements=np.array([0]))
    local = basis.element_dofs[:, 0]
    Ke = asm(form, one)[local][:, local].toarray()                                     # (m, m)
    dofs = basis.element_dofs                                                          # (m, n_elements)
    m, n = dofs.shape
    rows = np.broadcast_to(dofs[:, None, :], (m, m, n)).ravel()
    cols = np.broadcast_to(dofs[None, :, :], (m, m, n)).ravel()
    data = np.broadcast_to(Ke[:, :, None], (m, m, n)).ravel()
    return sp.csr_matrix((data, (rows, cols)), shape=(basis.N, basis.N))


def solve_box(size, frame, corner, kinds, material: Elastic, h: float, body_force: BodyForce | None = None,
              traction: Traction | None = None, lift: Lift | None = None, order: int = 1) -> BoxSolution:
    """Solve linear elasticity on the box `size` = (L, H, W) placed at `corner` with frame R (3, 3).

    kinds: one of roller, fixed, traction, free per face (FACES order). body_force, traction and lift
    take and return local-frame quantities (see BodyForce, Traction, Lift); traction is asked only
    for the faces of kind traction. Raises InputError on bad input, ibm.solvers.linear.SolveError when the
    box is not held (no essential faces enough to stop rigid motions).
    """
    start = perf_counter()
    size, R, corner, kinds = _checked(size, frame, corner, kinds, h, order)
    if traction is None and "traction" in kinds:
        k = kinds.index("traction")
        raise InputError(f"face {k} ({FACES[k]}) is of kind traction but no traction was given")
    lam, mu = material.lam, material.mu
    counts = tuple(max(1, int(np.ceil(side / h - 1e-9))) for side in size)
    mesh = MeshHex.init_tensor(*(np.linspace(0, side, n + 1) for side, n in zip(size, counts)))
    element = ElementVector(ElementHex1() if order == 1 else ElementHex2())
    basis = Basis(mesh, element, intorder=2 * order + 1)          # order + 1 Gauss points per direction
    load_order = 2 * order + 2                                     # order + 2 points per direction

    K = _stiffness(basis, 2 * order + 1, lam, mu)
    f = np.zeros(basis.N)
    if lift is not None or body_force is not None:
        @LinearForm
        def loads_form(v, w):
            shape = w.x.shape[1:]
            result = 0.0
            if lift is not None:
                _, grad_a = lift(_points(w.x))                                        # (n, 3, 3)
                sigma_a = np.moveaxis(isotropic_stress(grad_a, material), 0, -1).reshape(3, 3, *shape)
                result = result - ddot(sigma_a, sym_grad(v))
            if body_force is not None:
                result = result + dot(body_force(_points(w.x)).T.reshape(3, *shape), v)
            return result

        f += asm(loads_form, Basis(mesh, element, intorder=load_order))

    tol = 1e-9 * size.max()
    for k, kind in enumerate(kinds):
        if kind != "traction":
            continue
        axis, at = NORMAL_AXIS[k], size[NORMAL_AXIS[k]] if AT_END[k] else 0.0
        facets = mesh.facets_satisfying(lambda x, axis=axis, at=at: np.abs(x[axis] - at) < tol)

        @LinearForm
        def traction_form(v, w, k=k):
            return dot(traction(k, _points(w.x)).T.reshape(w.x.shape), v)

        f += asm(traction_form, FacetBasis(mesh, element, facets=facets, intorder=load_order))

    # strong essential faces: the DOFs located on the face, its normal component (all on fixed)
    component = np.empty(basis.N, dtype=int)
    for c, dofs in enumerate(basis.split_indices()):
        component[dofs] = c
    locations = basis.doflocs                                                         # (3, N) local
    constrained = np.zeros(basis.N, dtype=bool)
    for k, kind in enumerate(kinds):
        if kind in ESSENTIAL_KINDS:
            axis, at = NORMAL_AXIS[k], size[NORMAL_AXIS[k]] if AT_END[k] else 0.0
            on = np.abs(locations[axis] - at) < tol
            constrained |= on & ((component == axis) | (kind == "fixed"))
    free = np.flatnonzero(~constrained)
    assembled = perf_counter()
    U = np.zeros(basis.N)
    U[free], info = solve_system(K[free][:, free], f[free], estimate_condition=False, symmetric=True)
    solved = perf_counter()

    # the DOFs on the lattice of Lagrange nodes, spacing h_i / order
    lattice = np.rint(locations.T * (order * np.array(counts) / size)).astype(int)    # (N, 3)
    values = np.full((*(order * n + 1 for n in counts), 3), np.nan)
    values[lattice[:, 0], lattice[:, 1], lattice[:, 2], component] = U
    if np.isnan(values).any():
        raise RuntimeError("scikit-fem's DOFs do not fill the Lagrange lattice; fem_hex needs updating")
    info.update(ndof=len(free), n_elements=mesh.nelements, time_assemble=assembled - start,
                time_solve=solved - assembled, time_s=perf_counter() - start)
    return BoxSolution(size, R, corner, material, order, counts, values, lift, len(free), info)
