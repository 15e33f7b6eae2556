"""Material point domains in 3D as sets of tetrahedra: made with the points, mapped by F, clipped.

A point's domain starts as its clipped cube (ibm.geometry.polyhedron.material_points): the Kuhn
tetrahedra of a whole cube, or the pieces of a cut cube left inside the body. In a load step
it follows the point's deformation gradient, vertex X_c -> x_p + F_p (X_c - X_p) (an affine map
keeps tetrahedra tetrahedra), and is clipped by the half-spaces of the current walls (so it never
reaches through one; the parts are again tetrahedra, ibm.geometry.polytope.clip_all). Free faces do not
clip: a faceted outline's free face is the plane fitted to its moved corners
(ibm.large.walls.FacetedOutline), cruder than the domains' own mapped faces, and a thin cut domain
under it would fall outside it within a few steps. As in 2D (ibm.discretise.basis), a homogeneous F maps
the domains onto a tiling of the mapped body.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.geometry import polytope


@dataclass(frozen=True, eq=False)
class SimplexDomains:
    vertices: np.ndarray   # (m, 4, 3) tetrahedra
    owner: np.ndarray      # (m,) the point of each, ascending
    n: int                 # number of points (a point may own no tetrahedron: its domain is lost)

    def __len__(self) -> int:
        return self.n

    def volumes(self) -> np.ndarray:
        """(n,) the volume of each point's domain."""
        return polytope.sums(self.owner, polytope.measure(self.vertices), self.n)

    def mapped(self, X: np.ndarray, x: np.ndarray, F: np.ndarray) -> "SimplexDomains":
        """Each point's tetrahedra moved affinely: X_c -> x_p + F_p (X_c - X_p); X, x (n, 3), F (n, 3, 3)."""
        o = self.owner
        moved = x[o, None, :] + np.einsum("mij,mvj->mvi", F[o], self.vertices - X[o, None, :])
        return SimplexDomains(moved, o, self.n)

    def clipped(self, normals: np.ndarray, offsets: np.ndarray) -> "SimplexDomains":
        """The parts in the half-spaces n_j . x >= c_j: normals (k, 3), offsets (k,)."""
        vertices, owner = polytope.clip_all(self.vertices, self.owner, -np.asarray(normals), -np.asarray(offsets))
        return SimplexDomains(vertices, owner, self.n)
