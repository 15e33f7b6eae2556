"""Problems with exact solutions, as data.

A problem is a body in its local frame (xi along the base, eta inward normal to the base):
a rectangle (width L, height H) with one boundary kind per side (base, right, top, left),
or any outline of pieces (`outline`, scaled by L and H, e.g. the L-shape), and an
exact displacement field in that frame (a function, or sympy source text: see
studies/problems/manufactured.py, which also derives the body force b = -div sigma). Stresses, tractions on traction sides and the
rotation into the grid at angle theta are derived here once for every problem:
u = R u_loc, grad u = R grad_loc R^T, sigma = R sigma_loc R^T.

A problem may have several loadings (LOAD_TYPES): `pressure` (load is a stress: the top
pressure, the column's base stress, the manufactured field's stress scale) and
`settlement` (load is a prescribed displacement, carried by the lift u^a: the top's settlement,
`lame-dirichlet`'s inner u_r).
"""
from __future__ import annotations

from dataclasses import dataclass
from difflib import get_close_matches
from typing import Callable

import numpy as np

from ibm.exceptions import InputError
from ibm.geometry.arcs import Arc
from ibm.geometry.frames import frame_of_angle
from ibm.geometry.outline import Body, rectangle
from ibm.models.elastic import Elastic
from ibm.small.model import Loads
from studies.problems.manufactured import Field
from studies.problems.materials import FRICTIONAL, VON_MISES

# (xi, eta) arrays, parameters -> u_loc (n, 2), grad_loc (n, 2, 2) with grad[p, i, j] = d u_i / d x_j
LocalField = Callable[[np.ndarray, np.ndarray, "Parameters"], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Parameters:
    """Physical parameters of a problem instance (units are consistent but arbitrary)."""

    material: Elastic
    load: float          # pressure p (or the problem's load scale)
    width: float = 100.0
    height: float = 100.0
    depth: float = 100.0     # W, the third side of a 3D box (studies/problems/boxes.py); 2D problems ignore it


@dataclass(frozen=True)
class ClosedForm:
    """A closed-form problem under one loading: its body, boundary kinds and exact field (local frame)."""

    name: str
    summary: str
    kinds: tuple[str, str, str, str]          # base, right, top, left
    exact: LocalField
    body_force: Callable[[np.ndarray, np.ndarray, Parameters], np.ndarray] | None = None  # local (n, 2)
    lift: LocalField | None = None
    reported: str = "sigma_eta_eta"           # the stress component err_sigma reports
    load_type: str = "pressure"               # what `load` means: a stress, or the top settlement
    # parameters -> local vertices (n, 2) counter-clockwise from the base corner, a kind per piece
    # and optionally an Arc (local centre) or None per piece; None: the rectangle of `kinds`
    outline: Callable[["Parameters"], tuple[np.ndarray, tuple[str, ...]]] | None = None

    def body(self, parameters: "Parameters", angle: float, corner: np.ndarray) -> Body:
        """The body placed at `angle` with its base corner (local origin) at `corner`."""
        if self.outline is None:
            return rectangle(parameters.width, parameters.height, self.kinds, angle, corner)
        local, kinds, *arcs = self.outline(parameters)
        R = frame_of_angle(angle)
        corner = np.asarray(corner, float)
        placed = tuple(None if arc is None else Arc(corner + np.asarray(arc.center, float) @ R.T, arc.clockwise)
                       for arc in (arcs[0] if arcs else ()))
        return Body(corner + local @ R.T, kinds, frame=R, arcs=placed)


def local_stress(grad: np.ndarray, material: Elastic) -> tuple[np.ndarray, np.ndarray]:
    """Plane-strain stress (n, 2, 2) and sigma_zz (n,) from a displacement gradient (n, 2, 2)."""
    # component by component: millions of error-quadrature points go through here
    exx, eyy = grad[:, 0, 0], grad[:, 1, 1]
    exy = 0.5 * (grad[:, 0, 1] + grad[:, 1, 0])
    trace = exx + eyy
    two_mu, lam = 2 * material.mu, material.lam
    sigma = np.empty_like(grad)
    sigma[:, 0, 0] = two_mu * exx + lam * trace
    sigma[:, 1, 1] = two_mu * eyy + lam * trace
    sigma[:, 0, 1] = sigma[:, 1, 0] = two_mu * exy
    return sigma, lam * trace


class Placed:
    """What every placed problem (built-in or from a file) shares: its frame and loaded direction."""

    body: Body

    @property
    def frame(self) -> np.ndarray:
        return self.body.frame

    @property
    def direction(self) -> np.ndarray:
        """Unit e_eta: the loaded direction whose normal stress err_sigma reports."""
        return self.frame[:, 1]


@dataclass(frozen=True, eq=False)
class Instance(Placed):
    """A problem placed in the grid: the body, its loads and the exact fields (global frame)."""

    problem: ClosedForm
    parameters: Parameters
    body: Body
    loads: Loads
    corner: np.ndarray

    def to_local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xl = (x - self.corner) @ self.frame
        return xl[:, 0], xl[:, 1]

    def exact(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u (n, 2), sigma (n, 2, 2), sigma_zz (n,) at global points x (n, 2)."""
        R = self.frame
        u, grad = self.problem.exact(*self.to_local(x), self.parameters)
        sigma, zz = local_stress(grad, self.parameters.material)
        return u @ R.T, rotated(sigma, R), zz

    def exact_gradient(self, x: np.ndarray) -> np.ndarray:
        _, grad = self.problem.exact(*self.to_local(x), self.parameters)
        return self.frame @ grad @ self.frame.T


def rotated(tensor: np.ndarray, R: np.ndarray) -> np.ndarray:
    """R T R^T for tensors T (n, 2, 2): vec(R T R^T) = (R kron R) vec(T), one (n, 4) x (4, 4) product
    (a batched matmul of 2 x 2 blocks is several times slower)."""
    return (tensor.reshape(-1, 4) @ np.kron(R, R).T).reshape(-1, 2, 2)


def place(problem: ClosedForm, parameters: Parameters, angle: float, offset, cell: float) -> Instance:
    """Put the problem's body at `angle` with its base corner at offset * cell from a grid node."""
    corner = np.asarray(offset, float) * cell
    body = problem.body(parameters, angle, corner)
    R = body.frame

    def to_local(x):
        xl = (x - corner) @ R
        return xl[:, 0], xl[:, 1]

    def traction_on(edge):
        def traction(x):
            _, grad = problem.exact(*to_local(x), parameters)
            sigma, _ = local_stress(grad, parameters.material)
            return np.einsum("ij,pjk,lk,pl->pi", R, sigma, R, body.outward(edge, x))
        return traction

    body_force = None
    if problem.body_force is not None:
        def body_force(x):
            return problem.body_force(*to_local(x), parameters) @ R.T

    lift = None
    if problem.lift is not None:
        def lift(x):
            u, grad = problem.lift(*to_local(x), parameters)
            return u @ R.T, R @ grad @ R.T

    tractions = {k: traction_on(k) for k in body.edges_of_kind("traction")}
    loads = Loads(body_force=body_force, tractions=tractions, lift=lift)
    return Instance(problem, parameters, body, loads, corner)


# --- the problem library -------------------------------------------------------------

def _confined_block(xi, eta, prm: Parameters):
    """Rollers on base and sides, pressure p on top: u_eta = -(p/M) eta, u_xi = 0."""
    strain = -prm.load / prm.material.M
    u = np.stack([np.zeros_like(eta), strain * eta], axis=1)
    grad = np.zeros((len(eta), 2, 2))
    grad[:, 1, 1] = strain
    return u, grad


LOAD_TYPES = ("pressure", "settlement")
PROBLEMS: dict[str, ClosedForm] = {}                       # name -> problem under its first loading
LOADINGS: dict[tuple[str, str], ClosedForm] = {}           # (name, load type) -> problem


def register(problem: ClosedForm) -> ClosedForm:
    if problem.load_type not in LOAD_TYPES:
        raise InputError(f"load type {problem.load_type!r} is not one of {', '.join(LOAD_TYPES)}")
    PROBLEMS.setdefault(problem.name, problem)
    LOADINGS[problem.name, problem.load_type] = problem
    return problem


def symbolic(name: str, summary: str, kinds: tuple[str, ...], u: tuple[str, str],
             lift: tuple[str, str] | None = None, load_type: str = "pressure", outline=None) -> ClosedForm:
    """A problem whose exact field (and lift) is sympy source text; b = -div sigma is derived.

    Derivation is lazy (first use), so importing the library does not run sympy.
    """
    field = Field(*u)
    return ClosedForm(name, summary, kinds, field, body_force=field.body_force,
                   lift=Field(*lift) if lift is not None else None, load_type=load_type, outline=outline)


register(ClosedForm(
    "confined-block",
    "square, rollers on base and sides, uniform pressure on top (the seed's validation problem)",
    ("roller", "roller", "traction", "roller"), _confined_block))

# Settlement: the top is a roller moved down by Delta = load, u_eta = -Delta eta / H (the
# pressure solution with p = M Delta / H). The only LINEAR lift meeting the roller data is
# the exact field itself, which would leave u^h = 0 and test nothing; the lift
# u^a_eta = -Delta (eta / H)^2 meets them too (0 on the base, -Delta on the top, no u_xi on
# the sides), so u^h must carry the quadratic difference -Delta eta (H - eta) / H^2 and the
# case converges at the discretisation's rate instead of being exact to round-off.
register(symbolic(
    "confined-block",
    "square, rollers on all four sides, the top one settled by Delta = load (quadratic lift)",
    ("roller", "roller", "roller", "roller"),
    u=("0", "-p * eta / H"), lift=("0", "-p * (eta / H)**2"), load_type="settlement"))

# Self-weight rho g = p / H along -eta (p is the base stress): quadratic u, linear sigma.
register(symbolic(
    "column",
    "self-weight column (rho g = load / height along -eta), rollers on base and sides, free top",
    ("roller", "roller", "free", "roller"),
    u=("0", "-(p / (H * M)) * (H * eta - eta**2 / 2)")))

# Roller-compatible on eta = 0, xi = 0, xi = L (normal displacement
# and shear stress vanish there); amplitudes A = p H / M, B = A / 2 give stresses of order p.
register(symbolic(
    "manufactured",
    "smooth trigonometric field, rollers on base and sides, its traction on top, b = -div sigma",
    ("roller", "roller", "traction", "roller"),
    u=("p * H / M * sin(pi * xi / L) * cos(pi * eta / (2 * H))",
       "p * H / (2 * M) * cos(pi * xi / L) * sin(pi * eta / (2 * H))")))

# The same on a fixed base: both components vanish on eta = 0, rollers on the sides.
register(symbolic(
    "manufactured-fixed",
    "smooth trigonometric field, fixed base, rollers on the sides, its traction on top",
    ("fixed", "roller", "traction", "roller"),
    u=("p * H / M * sin(pi * xi / L) * sin(pi * eta / (2 * H))",
       "p * H / (2 * M) * cos(pi * xi / L) * sin(pi * eta / (2 * H))")))


def _l_shape(prm: Parameters) -> tuple[np.ndarray, tuple[str, ...]]:
    """The L of the square L x H without its upper right quarter; the re-entrant corner at (L/2, H/2)."""
    L, H = prm.width, prm.height
    vertices = np.array([[0, 0], [L, 0], [L, H / 2], [L / 2, H / 2], [L / 2, H], [0, H]], float)
    return vertices, L_SHAPE_KINDS


# pieces: base, right side, top of the right arm (roller), inner side of the upper arm (fixed),
# top, left side; the roller and the fixed piece meet at the re-entrant corner
L_SHAPE_KINDS = ("traction", "traction", "roller", "fixed", "traction", "traction")

# Non-convex: with a = (xi - L/2) / (L/2), b = (eta - H/2) / (H/2), u vanishes on the fixed piece
# a = 0 (b > 0); on the roller b = 0 (a > 0) u_eta = 0 and the shear stress vanishes (both terms
# of d u_xi / d eta + d u_eta / d xi carry sin(pi b / 2)), so the roller's data are exact; the
# other pieces carry the field's own tractions (checked in tests/ibm/geometry/test_outlines.py).
register(symbolic(
    "l-shape",
    "L-shaped (non-convex), fixed and roller pieces meeting at the re-entrant corner, smooth field",
    L_SHAPE_KINDS,
    u=("p * H / M * sin(pi * (xi - L / 2) / L) * cos(pi * (eta - H / 2) / H)",
       "p * H / (2 * M) * sin(pi * (xi - L / 2) / L) * sin(pi * (eta - H / 2) / H)"),
    outline=_l_shape))


def _quarter_annulus(prm: Parameters):
    """Quarter of the ring a = L/2 <= r <= b = L about the local origin: rollers on the symmetry
    lines, the outer arc free, the inner arc loaded (traction)."""
    a, b = prm.width / 2, prm.width
    vertices = np.array([[a, 0], [b, 0], [0, b], [0, a]], float)
    centre = np.zeros(2)
    return vertices, ("roller", "free", "roller", "traction"), (None, Arc(centre), None, Arc(centre, clockwise=True))


# Lame's thick cylinder (plane strain), inner pressure p, a = L/2, b = L: A = p a^2 / (b^2 - a^2) = p / 3,
# u_r = (A / (2 mu)) (mu / (lam + mu) r + b^2 / r), so u = u_r x / r (checked in tests/studies/problems/test_library.py).
register(symbolic(
    "lame",
    "quarter thick cylinder (Lame), inner pressure p, outer arc free, rollers on both symmetry lines",
    ("roller", "free", "roller", "traction"),
    u=("p / (6 * mu) * (mu / (lam + mu) + L**2 / (xi**2 + eta**2)) * xi",
       "p / (6 * mu) * (mu / (lam + mu) + L**2 / (xi**2 + eta**2)) * eta"),
    outline=_quarter_annulus))


def _quarter_annulus_dirichlet(prm: Parameters):
    """The quarter ring of `lame` with essential arcs: the inner one a roller, the outer one fixed."""
    vertices, _, arcs = _quarter_annulus(prm)
    return vertices, ("roller", "fixed", "roller", "roller"), arcs


# Lame with displacement data: u_r(a) = u0 = load on the inner (roller) arc, u = 0 on the outer
# (fixed) arc, a = L/2, b = L. u_r = A r + B / r with A a + B / a = u0, A b + B / b = 0 gives
# u_r = (2 u0 / 3) (L / r - r / L), sigma_r_theta = 0 (the roller's zero shear) and b = 0 (checked in
# tests/studies/problems/test_library.py). The lift u^a = u0 ((L - r) / (L / 2))^2 e_r meets the data (radial, so
# also the symmetry rollers) but is not the exact field: u^h carries the difference.
register(symbolic(
    "lame-dirichlet",
    "quarter thick cylinder, inner arc a roller with u_r = load, outer arc fixed, rollers on the symmetry lines",
    ("roller", "fixed", "roller", "roller"),
    u=("2 * p / 3 * (L / (xi**2 + eta**2) - 1 / L) * xi",
       "2 * p / 3 * (L / (xi**2 + eta**2) - 1 / L) * eta"),
    lift=("p * (2 * (L - sqrt(xi**2 + eta**2)) / L)**2 * xi / sqrt(xi**2 + eta**2)",
          "p * (2 * (L - sqrt(xi**2 + eta**2)) / L)**2 * eta / sqrt(xi**2 + eta**2)"),
    load_type="settlement", outline=_quarter_annulus_dirichlet))


def _holed_plate(prm: Parameters):
    """Quarter of a square plate of side 2L with a hole of radius a = L/5 at the local origin: rollers
    on the symmetry lines, the exact tractions on the outer sides, the hole free."""
    a, L = prm.width / 5, prm.width
    vertices = np.array([[a, 0], [L, 0], [L, L], [0, L], [0, a]], float)
    return (vertices, ("roller", "traction", "traction", "roller", "free"),
            (None, None, None, None, Arc(np.zeros(2), clockwise=True)))


# Kirsch: remote tension p along xi, hole radius a = L/5; Kirsch's u (polar, kappa = 3 - 4 nu)
# written with cos(k theta), sin(k theta) as polynomials in xi, eta over powers of r (checked against
# the notes' stresses, the free hole and the symmetry lines in tests/studies/problems/test_library.py).
_KAPPA = "((lam + 3 * mu) / (lam + mu))"
_R2 = "(xi**2 + eta**2)"
register(symbolic(
    "kirsch",
    "quarter plate with a hole (Kirsch), remote tension p, exact tractions on the outer sides, hole free",
    ("roller", "traction", "traction", "roller", "free"),
    u=(f"p / (8 * mu) * (({_KAPPA} + 1) * xi + 2 * (L / 5)**2 * ((1 + {_KAPPA}) * xi / {_R2}"
       f" + (xi**3 - 3 * xi * eta**2) / {_R2}**2) - 2 * (L / 5)**4 * (xi**3 - 3 * xi * eta**2) / {_R2}**3)",
       f"p / (8 * mu) * (({_KAPPA} - 3) * eta + 2 * (L / 5)**2 * ((1 - {_KAPPA}) * eta / {_R2}"
       f" + (3 * xi**2 * eta - eta**3) / {_R2}**2) - 2 * (L / 5)**4 * (3 * xi**2 * eta - eta**3) / {_R2}**3)"),
    outline=_holed_plate))


def load_types(name: str) -> list[str]:
    return [load for (other, load) in LOADINGS if other == name]


def plastic(spec) -> bool:
    """A case of a material that yields (von Mises, Mohr-Coulomb or Drucker-Prager): load steps at small strain."""
    return spec.material in (*VON_MISES, *FRICTIONAL)


def default_load_type(name: str) -> str:
    """`pressure` where the problem has it, else its first loading (a problem given only by
    displacement data, such as lame-dirichlet, has only `settlement`)."""
    types = load_types(name)
    return "pressure" if "pressure" in types or not types else types[0]


def closest(name: str, choices) -> str:
    """' (did you mean X?)' for the nearest of `choices`, or ''."""
    match = get_close_matches(name, list(choices), n=1)
    return f" (did you mean {match[0]!r}?)" if match else ""


def get_problem(name: str, load_type: str | None = None) -> ClosedForm:
    """The problem `name` under `load_type` (None: its first registered loading)."""
    if name not in PROBLEMS:
        raise InputError(f"unknown problem {name!r}{closest(name, PROBLEMS)}; allowed: {', '.join(PROBLEMS)}")
    if load_type is None:
        return PROBLEMS[name]
    if (name, load_type) not in LOADINGS:
        raise InputError(f"load type {load_type!r} is not allowed for problem {name!r}; "
                         f"allowed: {', '.join(load_types(name))}")
    return LOADINGS[name, load_type]
