"""3D box problems with exact solutions, as data: name -> (Field, kinds, summary).

A box is L x H x W (prm.width, prm.height, prm.depth) along (xi, eta, zeta) in its local
frame, the base corner at the local origin and eta the loaded direction. kinds has one
boundary kind per face in the order of studies.manufactured.FACES: base (eta = 0), right
(xi = L), top (eta = H), left (xi = 0), front (zeta = 0), back (zeta = W). Each Field is
sympy source text (studies/manufactured.py derives the stress, b = -div sigma and the
tractions sigma n on the faces); the boundary data hold exactly (tests/test_boxes.py).
"""
from __future__ import annotations

from studies.manufactured import FACES, Field


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
