"""Moment-fitted quadrature: few points that integrate every polynomial of a degree exactly
over a polytope piece.

A piece's simplices (ibm.geometry.polytope) with a Gauss rule of degree p integrate polynomials of
degree p exactly, but a grid cell cut by a thin band is dozens of simplices (each plane
through a simplex splits it in up to three), so thousands of points. Here the piece's
moments are taken once from those points, for an orthonormal basis: products of Legendre
polynomials phi_a(z) = prod_i sqrt(2 a_i + 1) P_(a_i)(2 z_i - 1) of total degree <= p in
coordinates z in [0, 1]^3 of the piece's bounding box in a frame G (rows: the bands'
normals, then tangents), m_a = int_piece phi_a(z(x)) dx. The rule then lives on M nodes
z_q of the box (M = dim P_p: 165 for p = 8), approximate Fekete points chosen once from a
fine Gauss grid by QR with column pivoting (well-conditioned V_qa = phi_a(z_q)), with the
weights solving V^T w = m. Any polynomial of degree <= p in x is one in z, so the rule is
exact for it on the piece. Nodes lie in the box, not necessarily in the piece: integrands
must be the polynomial on the whole box (see QuadraturePoints.region), and weights may be
negative.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import scipy.linalg
from numpy.polynomial import legendre
from threadpoolctl import threadpool_limits

from ibm.geometry import polytope
from ibm.discretise.grid import lattice

CHUNK = 1 << 12   # simplex-rule points per pass when taking moments (the (chunk, M) basis stays in cache)


@lru_cache(maxsize=None)
def exponents(degree: int, d: int = 3) -> np.ndarray:
    """(M, d) multi-indices of total degree <= degree."""
    every = lattice([np.arange(degree + 1)] * d)
    return every[every.sum(axis=1) <= degree]


def basis(z: np.ndarray, degree: int, transposed: bool = False) -> np.ndarray:
    """(n, M) orthonormal Legendre products at points z (n, d) of the unit box, in the order of
    exponents(); (M, n) if transposed (contiguous rows: the faster layout to build)."""
    n, d = z.shape
    scale = np.sqrt(2 * np.arange(degree + 1) + 1)[:, None]
    # values[i][k] = sqrt(2k + 1) P_k(2 z_i - 1), (degree + 1, n)
    values = [legendre.legvander(2 * z[:, i] - 1, degree).T * scale for i in range(d)]
    out = np.empty((len(exponents(degree, d)), n))
    row = 0
    # exponents() runs with the first index fastest: for each (a_1, ..., a_d-1) a contiguous run of a_0
    for rest in exponents(degree, d - 1):
        width = degree - int(rest.sum()) + 1
        factor = values[1][rest[0]] if d > 1 else np.ones(n)
        for i in range(2, d):
            factor = factor * values[i][rest[i - 1]]
        np.multiply(values[0][:width], factor[None, :], out=out[row:row + width])
        row += width
    return out if transposed else out.T


NODES_FILE = Path(__file__).with_name("moment_fitting_nodes.npz")   # the chosen nodes, per degree
STORED_DEGREES = range(1, 17)


def pivoted_choice(degree: int, d: int = 3) -> np.ndarray:
    """Indices (M,) of the Gauss grid's points (candidates()) that pivoted QR of V^T picks first.

    The grid is symmetric, so many candidates tie (the 8 corners for the first pivot, and so on)
    and which of them QR takes is decided by the LAPACK build's rounding: two builds give two
    equally good sets, and rules fitted on them integrate a non-polynomial integrand differently
    (2 % in an energy error norm at h = 25 in 3D). The choice is therefore made once and stored
    (NODES_FILE, written by write_nodes), so results do not depend on it."""
    V = basis(candidates(degree, d), degree)                       # (N, M)
    # one BLAS thread: a threaded pivoted QR of this size waits for its threads (docs/choices.md)
    with threadpool_limits(limits=1, user_api="blas"):
        _, _, pivots = scipy.linalg.qr(V.T, mode="economic", pivoting=True)
    return np.sort(pivots[:V.shape[1]])


def candidates(degree: int, d: int = 3) -> np.ndarray:
    """(N, d) the tensor Gauss grid of degree + 3 points per axis in the unit box."""
    g, _ = np.polynomial.legendre.leggauss(degree + 3)
    return lattice([(g + 1) / 2] * d)


@lru_cache(maxsize=None)
def _stored() -> dict[str, np.ndarray]:
    with np.load(NODES_FILE) as stored:
        return {key: stored[key] for key in stored.files}


@lru_cache(maxsize=None)
def nodes(degree: int, d: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Fekete-like nodes (M, d) in the unit box and the inverse (M, M) of V = basis(nodes):
    weights w = m @ inverse, i.e. V^T w = m.

    Chosen by pivoted QR from a Gauss grid, once (pivoted_choice: stored for the degrees in
    NODES_FILE, chosen here for others). (Leja points on the exponents' lower set, which need
    no QR and are as well conditioned, were tried: the IBM's large-deformation column then stops
    converging, since its band integrand is not a polynomial and these nodes sit elsewhere.)"""
    grid = candidates(degree, d)
    chosen = _stored().get(f"d{d}_degree{degree}")
    if chosen is None:
        chosen = pivoted_choice(degree, d)
    inverse = np.linalg.inv(basis(grid[chosen], degree))
    inverse.setflags(write=False)
    return grid[chosen], inverse


def fitted(vertices: np.ndarray, owner: np.ndarray, frame: np.ndarray, degree: int):
    """A fitted rule per owner of simplices (m, 4, 3) sorted by owner (m,): nodes (n_owner M, 3),
    weights (n_owner M,), the owner of each node, and the boxes' lower and upper corners in
    frame coordinates (n_owner, 3) (frame (3, 3) invertible: y = frame @ x)."""
    first = np.flatnonzero(np.concatenate([[True], owner[1:] != owner[:-1]]))
    owners = owner[first]
    y = vertices @ frame.T                                          # (m, 4, 3)
    low = np.minimum.reduceat(y.min(axis=1), first, axis=0)         # (k, 3)
    high = np.maximum.reduceat(y.max(axis=1), first, axis=0)
    group = np.repeat(np.arange(len(first)), np.diff(np.append(first, len(owner))))   # (m,) piece of each simplex
    moments = np.zeros((len(first), len(exponents(degree))))
    per_simplex = len(polytope.simplex_rule(3, degree)[1])
    simplices = max(1, CHUNK // per_simplex)
    # the simplices' rule points a chunk at a time: all at once they would be 2.5 GB at a million unknowns
    for start in range(0, len(group), simplices):
        chunk = slice(start, start + simplices)
        x, w, piece = polytope.quadrature(vertices[chunk], group[chunk], degree)
        z = (x @ frame.T - low[piece]) / (high - low)[piece]
        # sum_q w_q phi_a(z_q) per piece: pieces are runs of points, summed along contiguous rows
        starts = np.flatnonzero(np.concatenate([[True], piece[1:] != piece[:-1]]))
        values = basis(z, degree, transposed=True) * w[None, :]      # (M, chunk)
        moments[piece[starts]] += np.add.reduceat(values, starts, axis=1).T
    reference, inverse = nodes(degree)
    weights = moments @ inverse                                     # (k, M)
    y_nodes = low[:, None, :] + (high - low)[:, None, :] * reference[None]      # (k, M, 3)
    x_nodes = np.linalg.solve(frame, y_nodes.reshape(-1, 3).T).T
    return x_nodes, weights.ravel(), np.repeat(owners, len(reference)), low, high


def write_nodes() -> None:
    """Write NODES_FILE: this machine's pivoted choice for STORED_DEGREES (run once; it fixes the nodes)."""
    np.savez_compressed(NODES_FILE, **{f"d3_degree{k}": pivoted_choice(k).astype(np.int32) for k in STORED_DEGREES})


if __name__ == "__main__":
    write_nodes()
