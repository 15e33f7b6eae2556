"""3D box problems with exact solutions, as data: name -> (Field, kinds, summary).

A box is L x H x W (prm.width, prm.height, prm.depth) along (xi, eta, zeta) in its local
frame, the base corner at the local origin and eta the loaded direction. kinds has one
boundary kind per face in the order of studies.problems.manufactured.FACES: base (eta = 0), right
(xi = L), top (eta = H), left (xi = 0), front (zeta = 0), back (zeta = W). Each Field is
sympy source text (studies/problems/manufactured.py derives the stress, b = -div sigma and the
tractions sigma n on the faces); the boundary data hold exactly (tests/studies/problems/test_boxes.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baselines.fem.hexahedra import isotropic_stress
from ibm.geometry.frames import frame_3d
from ibm.exceptions import InputError
from ibm.small.model import Loads
from ibm.geometry.polyhedron import Polyhedron, box
from ibm.large.loadsteps import Loading
from studies.problems.finite_strain import column_exact
from studies.problems.manufactured import FACES, Field
from studies.problems.library import Parameters, Placed


def _kinds(top: str) -> tuple[str, ...]:
    """Rollers on every face but the top, which is `top`."""
    return tuple(top if face == "top" else "roller" for face in FACES)


BOXES: dict[str, tuple[Field, tuple[str, ...], str]] = {
    # uniform strain -p / M along eta: sigma_eta_eta = -p, sigma_xi_xi = sigma_zeta_zeta = -lam p / M
    "confined-block": (
        Field("0", "-(p / M) * eta", "0"), _kinds("traction"),
        "box, rollers on base and the four sides, uniform pressure p on top (linear u)"),
    # self-weight rho g = p / H along -eta (p is the base stress): quadratic u, linear sigma
    "column": (
        Field("0", "-(p / (H * M)) * (H * eta - eta**2 / 2)", "0"), _kinds("free"),
        "self-weight column (rho g = load / height along -eta), rollers on base and the four sides, free top"),
    # u_i = A_i sin(k_i x_i) prod_{j != i} cos(k_j x_j), k = (pi / L, pi / (2 H), pi / W): on every
    # roller face the normal component carries sin(0) or sin(pi) and both shears carry the same
    # factor, so they vanish; amplitudes p H / M times 1, 1/2, 1/3 give stresses of order p
    "manufactured": (
        Field("p * H / M * sin(pi * xi / L) * cos(pi * eta / (2 * H)) * cos(pi * zeta / W)",
              "p * H / (2 * M) * cos(pi * xi / L) * sin(pi * eta / (2 * H)) * cos(pi * zeta / W)",
              "p * H / (3 * M) * cos(pi * xi / L) * cos(pi * eta / (2 * H)) * sin(pi * zeta / W)"),
        _kinds("traction"),
        "smooth trigonometric field, rollers on base and the four sides, its traction on top, b = -div sigma"),
}


def _column_large(size, load: float, R: np.ndarray):
    """The column's self-weight rho_0 g = load / H along -eta and its exact finite-strain field
    exact(material, t) (studies.problems.finite_strain): the material slides down the four walls."""
    H = float(size[1])
    return Loading(body_force=-(load / H) * R[:, 1]), lambda material, t: column_exact(H, load, material, t)


# the boxes with an exact finite-strain solution: name -> (size (3,), load, frame (3, 3)) -> loading, exact
FINITE_STRAIN = {"column": _column_large}


# --- placed in the grid -----------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class PlacedBox(Placed):
    """A box problem placed at (theta, tilt) with its base corner at `corner`: the body, the loads
    (global frame, for the grid methods) and the exact fields (global frame)."""

    name: str
    parameters: Parameters
    body: Polyhedron
    loads: Loads
    corner: np.ndarray

    @property
    def field(self) -> Field:
        return BOXES[self.name][0]

    def to_local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xl = (x - self.corner) @ self.frame
        return xl[:, 0], xl[:, 1], xl[:, 2]

    def exact(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u (n, 3), sigma (n, 3, 3), sigma_zz (n,) at global points x (n, 3)."""
        R = self.frame
        u, grad = self.field(*self.to_local(x), self.parameters)
        sigma = R @ isotropic_stress(grad, self.parameters.material) @ R.T
        return u @ R.T, sigma, sigma[:, 2, 2]


def place_box(name: str, parameters: Parameters, theta: float, tilt: float, offset, cell: float) -> PlacedBox:
    """Put box problem `name` at (theta, tilt) with its base corner at offset * cell (offset (3,))."""
    if name not in BOXES:
        raise InputError(f"3D problem {name!r} is not allowed; allowed: {', '.join(BOXES)}")
    field, kinds, _ = BOXES[name]
    R = frame_3d(theta, tilt)
    corner = np.asarray(offset, float) * cell
    size = (parameters.width, parameters.height, parameters.depth)
    body = box(size, kinds, R, corner)
    placed = PlacedBox(name, parameters, body, Loads(), corner)

    def traction_on(face):
        def traction(x):
            _, sigma, _ = placed.exact(x)
            return np.einsum("pij,pj->pi", sigma, body.outward(face, x))
        return traction

    def body_force(x):
        return field.body_force(*placed.to_local(x), parameters) @ R.T

    tractions = {k: traction_on(k) for k in body.edges_of_kind("traction")}
    loads = Loads(body_force=body_force, tractions=tractions)
    return PlacedBox(name, parameters, body, loads, corner)
