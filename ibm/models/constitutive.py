"""Constitutive models at finite strain, behind one interface, vectorised over points.

Every model maps a deformation-gradient increment dF (n, 3, 3) from the converged state of
the previous step to the Cauchy stress and the spatial tangent (docs/large-deformation.md).
Tensors are 3 x 3 in every dimension (plane strain: F_33 = 1), so the same
model serves 2D and 3D; the kinematics takes the in-plane part.

Hencky hyperelasticity (the elastic part of every model):
    b_e = dF b_e,n dF^T,   eps = 1/2 ln b_e,   tau = lam tr(eps) I + 2 mu eps,   sigma = tau / J
    a_ijkl = (1/J) (d tau / d b_e)_ijkq 2 b_e,ql - sigma_il delta_jk
with J = det F. The tangent is the one that multiplies the current spatial gradient of the trial
increment (i, j: d du_i / d x_j) and of the test function (k, l); K = sum_p v_p G^T a G.

Every model here is an isotropic tensor function tau(b) = sum_a tau_a(eps) n_a n_a of b's
eigenvalues lambda_a and vectors n_a (eps_a = 1/2 ln lambda_a), so its tangent is written in b's
eigenbasis (`spatial_tangent`), where (d tau / d b) 2 b has three kinds of entries only:
    (aa, cc): c_ac = d tau_a / d eps_c,
    (ab, ab): s_ab lambda_b and (ab, ba): s_ab lambda_a (a != b), s_ab = theta_ab g_ab / 2,
theta_ab = (tau_a - tau_b) / (eps_a - eps_b) and g_ab = (ln lambda_a - ln lambda_b) / (lambda_a -
lambda_b) (their limits at equal eigenvalues: c_aa - c_ab and 1 / lambda_a). For Hencky c = lam 1 1
+ 2 mu I and theta = 2 mu. Rotated back by P[(i, j), (a, b)] = Q_ia Q_jb (Q the eigenvectors) on the
first `dim` axes only: plane strain needs the in-plane components (16 of 81), and computing just
those is a fifth of the work.

A model is a small frozen dataclass with `initial(n)` (the undeformed state) and
`update(dF, state) -> Response`; plasticity adds internal variables to `State.internal`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ibm.exceptions import InputError
from ibm.models.elastic import Elastic


@dataclass(frozen=True, eq=False)
class State:
    """Converged state of every point at the start of a step.

    F (n, 3, 3) total deformation gradient, be (n, 3, 3) elastic left Cauchy-Green tensor,
    internal: model variables (name -> (n, ...)), empty for elastic models.
    """

    F: np.ndarray
    be: np.ndarray
    internal: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.F)

    def take(self, index: np.ndarray) -> "State":
        """The states of the points `index` (e.g. the points whose domains cover band points)."""
        return State(self.F[index], self.be[index], {k: v[index] for k, v in self.internal.items()})


@dataclass(frozen=True, eq=False)
class Response:
    """Cauchy stress (n, 3, 3), spatial tangent (n, dim, dim, dim, dim) on the first `dim` axes of
    `update` (3 unless asked: the in-plane part in plane strain) and the state it leads to."""

    sigma: np.ndarray
    tangent: np.ndarray
    state: State


def check_yield(yield_stress: float, hardening: float) -> None:
    """InputError unless the yield stress is > 0 and the linear hardening modulus finite and >= 0."""
    if not (yield_stress > 0):
        raise InputError(f"yield stress {yield_stress} is not allowed; it must be > 0")
    if not (np.isfinite(hardening) and hardening >= 0):
        raise InputError(f"hardening modulus {hardening} is not allowed; it must be >= 0")


def check_frictional(cohesion: float, friction_angle: float, dilation_angle: float) -> None:
    """InputError unless 0 <= phi < 90 degrees, 0 <= psi <= phi and c >= 0 (c > 0 where phi = 0), all finite."""
    if not (np.isfinite(friction_angle) and 0 <= friction_angle < 90):
        raise InputError(f"friction angle {friction_angle:g} is not allowed; it must be in [0, 90) degrees")
    if not (np.isfinite(dilation_angle) and 0 <= dilation_angle <= friction_angle):
        raise InputError(f"dilation angle {dilation_angle:g} is not allowed; it must be in [0, friction angle "
                         f"{friction_angle:g}] degrees")
    if not (np.isfinite(cohesion) and cohesion >= 0):
        raise InputError(f"cohesion {cohesion:g} is not allowed; it must be >= 0")
    if cohesion == 0 and friction_angle == 0:
        raise InputError("cohesion 0 is not allowed with friction angle 0 (no strength at all); give one of them > 0")


def undeformed(n: int) -> State:
    eye = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    return State(eye, eye.copy())


PAIRS = ([0, 0, 1], [1, 2, 2])       # the eigenvalue pairs (a, b), a < b: (0, 1), (0, 2), (1, 2)


def log_divided_differences(values: np.ndarray) -> np.ndarray:
    """g (3, n) of the PAIRS: (ln x_a - ln x_b) / (x_a - x_b), and 1 / x_a where x_a = x_b; x (n, 3) > 0."""
    xa, xb = values[:, PAIRS[0]].T, values[:, PAIRS[1]].T
    ratio = (xa - xb) / xb
    small = np.abs(ratio) < 1e-6
    # ln(1 + r) / r to round-off on both sides of the switch (series to r^3 below 1e-6)
    series = 1 - ratio / 2 + ratio ** 2 / 3
    with np.errstate(divide="ignore", invalid="ignore"):
        exact = np.log1p(np.where(small, 0.0, ratio)) / np.where(small, 1.0, ratio)
    lost = ~np.isfinite(exact)
    if lost.any():     # x_a / x_b so small that 1 + r rounds to 0: the logarithms themselves are finite
        exact[lost] = (np.log(xa[lost]) - np.log(xb[lost])) / ratio[lost]
    return np.where(small, series, exact) / xb


def spatial_tangent(vectors: np.ndarray, values: np.ndarray, c: np.ndarray, shear: np.ndarray,
                    sigma: np.ndarray, J: np.ndarray, dim: int = 3) -> np.ndarray:
    """a (n, dim, dim, dim, dim) = (1/J) P W P^T - sigma_il delta_jk on the first `dim` axes, W the
    tangent in b's eigenbasis (module docstring): eigenvectors (n, 3, 3), eigenvalues (n, 3),
    c (n, 3, 3) or (3, 3) = d tau_a / d eps_c, shear (3, n) = s_ab of the PAIRS.

    P W P^T is a sum of rank-one terms, 6 of them: sum_ac c_ac D_a D_c^T for the eigenprojections
    D_a = n_a n_a, and, the pairs (a, b) and (b, a) taken together, s_ab (O_ab + O_ba)(lambda_b O_ab
    + lambda_a O_ba)^T with O_ab = n_a n_b. Computed component-major (points last): numpy's loops
    then run over the points, not over 3 or 4 entries."""
    n = len(values)
    Q = np.ascontiguousarray(vectors[:, :dim, :].transpose(1, 2, 0))             # (d, 3, n) Q_ia
    lam = np.ascontiguousarray(values.T)                                         # (3, n)
    D = Q[:, None] * Q[None, :]                                                  # (d, d, 3, n) Q_ia Q_ja
    first, second = PAIRS
    O = Q[:, None, first] * Q[None, :, second]                                   # (d, d, 3, n) Q_ia Q_jb, a < b
    swapped = O.transpose(1, 0, 2, 3)                                            # Q_ib Q_ja
    cD = np.einsum("ac,ijcn->ijan", c, D) if c.ndim == 2 else np.einsum("nac,ijcn->ijan", c, D)
    left = np.concatenate([D, O + swapped], axis=2).reshape(dim * dim, 6, n)
    right = np.concatenate([cD, shear * (lam[second] * O + lam[first] * swapped)], axis=2).reshape(dim * dim, 6, n)
    tangent = np.einsum("irn,krn->nik", left, right)                             # (n, d d, d d)
    tangent /= J[:, None, None]
    tangent = tangent.reshape(n, dim, dim, dim, dim)
    for j in range(dim):
        tangent[:, :, j, j, :] -= sigma[:, :dim, :dim]                            # sigma_il delta_jk
    return tangent


def trial(dF: np.ndarray, state: State):
    """F = dF F_n, J = det F and the trial b_e = dF b_e,n dF^T of an increment dF (n, 3, 3);
    FloatingPointError where det F <= 0 (the driver then cuts the step)."""
    F = dF @ state.F
    J = np.linalg.det(F)
    if np.any(~(J > 0)):
        raise FloatingPointError("det F <= 0 at a point")
    return F, J, dF @ state.be @ dF.transpose(0, 2, 1)


def principal(be: np.ndarray):
    """Eigenvalues (n, 3) and eigenvectors (n, 3, 3) of b_e; FloatingPointError unless positive.
    In plane strain (b_e's third row and column are (0, 0, b_33): every 2D state) the in-plane block
    is solved in closed form, a tenth of LAPACK's batched 3 x 3 cost: m +- r with m, r the centre and
    radius of its Mohr circle, vectors at half the angle atan2(b_21, (b_11 - b_22) / 2)."""
    if np.any(be[:, 2, :2]) or np.any(be[:, :2, 2]):
        values, vectors = np.linalg.eigh(be)
    else:
        centre = 0.5 * (be[:, 0, 0] + be[:, 1, 1])
        half = 0.5 * (be[:, 0, 0] - be[:, 1, 1])
        radius = np.hypot(half, be[:, 1, 0])
        angle = 0.5 * np.arctan2(be[:, 1, 0], half)
        cos, sin = np.cos(angle), np.sin(angle)
        values = np.stack([centre - radius, centre + radius, be[:, 2, 2]], axis=1)
        vectors = np.zeros((len(be), 3, 3))
        vectors[:, 0, 0], vectors[:, 1, 0] = -sin, cos             # columns: the vectors of m - r, m + r, e_3
        vectors[:, 0, 1], vectors[:, 1, 1] = cos, sin
        vectors[:, 2, 2] = 1.0
    if np.any(values <= 0):
        raise FloatingPointError("elastic left Cauchy-Green tensor is not positive definite")
    return values, vectors


@dataclass(frozen=True)
class Hencky(Elastic):
    """Isotropic Hencky hyperelasticity (linear in logarithmic strain); E, nu, lam, mu, M as in Elastic."""

    def initial(self, n: int) -> State:
        return undeformed(n)

    def kirchhoff(self, be: np.ndarray):
        """tau (n, 3, 3), b_e's eigenvalues (n, 3) and vectors (n, 3, 3)."""
        values, vectors = principal(be)
        strain = 0.5 * np.log(values)                                      # principal log strains (n, 3)
        stresses = self.lam * strain.sum(axis=1, keepdims=True) + 2 * self.mu * strain   # principal tau
        tau = np.matmul(vectors * stresses[:, None, :], vectors.transpose(0, 2, 1))
        return tau, values, vectors

    def update(self, dF: np.ndarray, state: State, dim: int = 3) -> Response:
        F, J, be = trial(dF, state)
        tau, values, vectors = self.kirchhoff(be)
        sigma = tau / J[:, None, None]
        elastic = self.lam + 2 * self.mu * np.eye(3)                                # c = d tau_a / d eps_c
        tangent = spatial_tangent(vectors, values, elastic, self.mu * log_divided_differences(values), sigma, J, dim)
        return Response(sigma, tangent, State(F, be, {}))


MATERIALS = {"elastic": Hencky}
