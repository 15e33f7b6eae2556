"""Isotropic plasticity written in principal stresses, at small and at finite strain (docs/plasticity.md).

A model whose return map acts on principal values only (Mohr-Coulomb, Drucker-Prager) gives, for the
trial elastic strains eps_tr (n, 3) in one eigenbasis, the returned stresses sigma (n, 3), their
derivative c_ab = d sigma_a / d eps_tr,b (n, 3, 3) and the elastic strains left. The tensors follow:

    sigma = sum_a sigma_a n_a n_a,
    C = sum_ac c_ac D_a x D_c + sum_(a<b) theta_ab / 2 (O_ab + O_ba) x (O_ab + O_ba),

D_a = n_a n_a, O_ab = n_a n_b, theta_ab = (sigma_a - sigma_b) / (eps_a - eps_b) (its limit c_aa - c_ab at
equal trial strains): the derivative of an isotropic tensor function (de Souza Neto, Peric and Owen,
Computational Methods for Plasticity, 2008, appendix A). At small strain eps_tr = sym(F - I) - eps_p,n
and C is the algorithmic modulus; at finite strain eps_tr = 1/2 ln b_e,tr, the stresses are Kirchhoff's
and the spatial tangent is Hencky's (ibm.models.constitutive.spatial_tangent) from the same c and theta.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.models.constitutive import (PAIRS, Hencky, Response, State, check_frictional, log_divided_differences,
                                     principal, spatial_tangent, trial, undeformed)
from ibm.models.small_strain import LinearElastic, strain

# trial strains closer than this (relative to their size and 1e-300) count as equal in theta
EQUAL = 1e-8


def divided_differences(stress: np.ndarray, strain_: np.ndarray, c: np.ndarray) -> np.ndarray:
    """theta (3, n) of the PAIRS: (sigma_a - sigma_b) / (eps_a - eps_b), c_aa - c_ab where eps_a ~ eps_b."""
    first, second = PAIRS
    gap = (strain_[:, first] - strain_[:, second]).T
    close = np.abs(gap) < EQUAL
    limit = (c[:, first, first] - c[:, first, second]).T
    return np.where(close, limit, (stress[:, first] - stress[:, second]).T / np.where(close, 1.0, gap))


def small_strain_tangent(vectors: np.ndarray, c: np.ndarray, theta: np.ndarray, dim: int) -> np.ndarray:
    """C (n, dim, dim, dim, dim) from the eigenvectors (n, 3, 3), c (n, 3, 3) and theta (3, n) (module doc)."""
    Q = vectors[:, :dim, :]                                                    # (n, d, 3) Q_ia
    D = np.einsum("nia,nja->naij", Q, Q)                                       # (n, 3, d, d)
    tangent = np.einsum("nac,naij,nckl->nijkl", c, D, D)
    for pair, (a, b) in enumerate(zip(*PAIRS)):
        O = np.einsum("ni,nj->nij", Q[:, :, a], Q[:, :, b])
        S = O + O.transpose(0, 2, 1)                                           # (n, d, d)
        tangent += 0.5 * theta[pair][:, None, None, None, None] * np.einsum("nij,nkl->nijkl", S, S)
    return tangent


def elastic_strains(stress: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """The principal strains (n, 3) of principal stresses (n, 3):
    eps = (sigma - lam tr sigma / (3 lam + 2 mu)) / (2 mu)."""
    return (stress - lam / (3 * lam + 2 * mu) * stress.sum(axis=1, keepdims=True)) / (2 * mu)


@dataclass(frozen=True)
class PrincipalSmallStrain(LinearElastic):
    """A small-strain model from a principal return map `returned(eps_tr (n, 3)) -> (sigma (n, 3),
    c (n, 3, 3), region (n,))` (0 elastic, > 0 the model's return regions); State.internal carries the
    plastic strain tensor "plastic", the equivalent plastic strain "alpha" (the sum of sqrt(2/3) |d eps_p|
    over the steps) and "region", the last step's region per point."""

    def initial(self, n: int) -> State:
        state = undeformed(n)
        return State(state.F, state.be, {"plastic": np.zeros((n, 3, 3)), "alpha": np.zeros(n),
                                         "region": np.zeros(n, int)})

    def returned(self, strain_: np.ndarray):
        raise NotImplementedError

    def update(self, dF: np.ndarray, state: State, dim: int = 3) -> Response:
        n = len(dF)
        F = state.F + (dF - np.eye(3))
        plastic_n = state.internal.get("plastic", np.zeros((n, 3, 3)))
        total = strain(F)
        values, vectors = np.linalg.eigh(total - plastic_n)
        stress, c, region = self.returned(values)
        transposed = vectors.transpose(0, 2, 1)
        sigma = np.matmul(vectors * stress[:, None, :], transposed)
        elastic = np.matmul(vectors * elastic_strains(stress, self.lam, self.mu)[:, None, :], transposed)
        tangent = small_strain_tangent(vectors, c, divided_differences(stress, values, c), dim)
        yielding = region > 0                   # elsewhere the plastic strain stays as it was, to the bit
        plastic = np.where(yielding[:, None, None], total - elastic, plastic_n)
        flow = np.where(yielding, np.sqrt(2 / 3 * np.sum((plastic - plastic_n) ** 2, axis=(1, 2))), 0.0)
        internal = {"plastic": plastic, "alpha": state.internal.get("alpha", np.zeros(n)) + flow, "region": region}
        return Response(sigma, tangent, State(F, state.be, internal))


@dataclass(frozen=True)
class PrincipalFiniteStrain(Hencky):
    """The same return map on Hencky's logarithmic strains and Kirchhoff stresses (multiplicative
    plasticity, the exponential map: b_e = sum_a exp(2 eps_e,a) n_a n_a after the return); "alpha" sums
    sqrt(2/3) |eps_tr - eps_e| of the principal logarithmic strains over the steps."""

    def initial(self, n: int) -> State:
        state = undeformed(n)
        return State(state.F, state.be, {"alpha": np.zeros(n), "region": np.zeros(n, int)})

    def returned(self, strain_: np.ndarray):
        raise NotImplementedError

    def update(self, dF: np.ndarray, state: State, dim: int = 3) -> Response:
        F, J, b_trial = trial(dF, state)
        values, vectors = principal(b_trial)
        strains = 0.5 * np.log(values)                                          # (n, 3) trial log strains
        tau, c, region = self.returned(strains)
        transposed = vectors.transpose(0, 2, 1)
        elastic = elastic_strains(tau, self.lam, self.mu)
        be = np.matmul(vectors * np.exp(2 * elastic)[:, None, :], transposed)
        sigma = np.matmul(vectors * (tau / J[:, None])[:, None, :], transposed)
        shear = 0.5 * divided_differences(tau, strains, c) * log_divided_differences(values)
        tangent = spatial_tangent(vectors, values, c, shear, sigma, J, dim)
        flow = np.where(region > 0, np.sqrt(2 / 3 * np.sum((strains - elastic) ** 2, axis=1)), 0.0)
        alpha = state.internal.get("alpha", np.zeros(len(F))) + flow
        return Response(sigma, tangent, State(F, be, {"alpha": alpha, "region": region}))


@dataclass(frozen=True)
class FrictionalSoil:
    """A frictional soil's data, cohesion c >= 0, friction angle phi and dilation angle psi (degrees,
    0 <= psi <= phi < 90), beside PrincipalSmallStrain or PrincipalFiniteStrain; a model names its principal
    return map `return_map(strain, lam, mu, c, phi, psi) -> (sigma, c, region)` (a staticmethod)."""

    cohesion: float = 0.0
    friction_angle: float = 0.0
    dilation_angle: float = 0.0
    return_map = None

    def __post_init__(self):
        super().__post_init__()
        check_frictional(self.cohesion, self.friction_angle, self.dilation_angle)

    def returned(self, strain_: np.ndarray):
        return self.return_map(strain_, self.lam, self.mu, self.cohesion, self.friction_angle, self.dilation_angle)
