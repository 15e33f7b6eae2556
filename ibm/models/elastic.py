"""Linear elastic material: plane strain in 2D, its full 3D form in 3D."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.exceptions import InputError


@dataclass(frozen=True)
class Elastic:
    """Isotropic linear elasticity, plane strain. Voigt order (xx, yy, xy), engineering shear."""

    E: float
    nu: float

    def __post_init__(self):
        if not (np.isfinite(self.E) and self.E > 0):
            raise InputError(f"Young's modulus E={self.E} is not allowed; it must be > 0")
        if not (np.isfinite(self.nu) and -1.0 < self.nu < 0.5):
            raise InputError(f"Poisson's ratio nu={self.nu} is not allowed; it must be in (-1, 0.5)")

    @property
    def lam(self) -> float:
        return self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))

    @property
    def mu(self) -> float:
        return self.E / (2 * (1 + self.nu))

    @property
    def M(self) -> float:
        """P-wave modulus lambda + 2 mu."""
        return self.lam + 2 * self.mu

    @property
    def C(self) -> np.ndarray:
        """(3, 3) plane-strain stiffness in Voigt form."""
        lam, mu = self.lam, self.mu
        return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])

    def stiffness(self, dim: int) -> np.ndarray:
        """Voigt stiffness: (3, 3) in plane strain (dim 2, = C), (6, 6) in 3D (xx, yy, zz, xy, yz, zx)."""
        if dim == 2:
            return self.C
        lam, mu = self.lam, self.mu
        C = np.zeros((6, 6))
        C[:3, :3] = lam
        C[[0, 1, 2], [0, 1, 2]] = lam + 2 * mu
        C[[3, 4, 5], [3, 4, 5]] = mu
        return C

    def sigma_zz(self, sigma: np.ndarray) -> np.ndarray:
        """sigma_zz from Voigt stresses: in plane strain (..., 3) nu (sigma_xx + sigma_yy), in 3D (..., 6) its own entry."""
        if sigma.shape[-1] == 6:
            return sigma[..., 2]
        return self.nu * (sigma[..., 0] + sigma[..., 1])
