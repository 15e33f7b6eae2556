"""The closed-form problems (studies.problems.library) as problems of a study, at small and large strain.

Each library problem is one ClosedFormProblem: at small kinematics a linear solve against its exact
field (studies.run.small); the confined block and the column also have exact finite-strain
solutions (studies.problems.finite_strain) and run the load steps (studies.run.large):

- confined-block, pressure: rollers on base and sides, pressure p = load on the top (on its
  current length), homogeneous stretch s = exp(-W(p/M));
- confined-block, settlement: the top is a roller wall moved down by load, s = 1 - load/H; with
  material von Mises, the radial return of uniaxial strain (exact at every load fraction);
- column: self-weight rho_0 g = load / H along -eta (load is the base stress), free top, the
  Lambert-W solution.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ibm.exceptions import InputError
from ibm.geometry.outline import rectangle
from ibm.large.loadsteps import Loading, Setup
from ibm.models.constitutive import Hencky
from ibm.models.elastic import Elastic
from ibm.solvers import backends as solvers
from studies.problems import finite_strain
from studies.problems.library import LOADINGS, PROBLEMS as LIBRARY, ClosedForm, Parameters, place, plastic
from studies.problems.materials import model_of
from studies.problems.problem import Problem
from studies.run.large import run_large_case
from studies.run.small import run_small_case


class ClosedFormProblem(Problem):
    """A library problem: its loadings (load type -> ClosedForm) and, where it has one, its exact
    finite-strain solution: large(spec, material, t) -> (field, top height, stress scale) with
    field(X local (n, 2)) -> (u_eta (n,), sigma_eta_eta (n,)) at load fraction t, and
    loading(spec, body) -> the load steps' Loading; plastic_loadings: the load types with an exact
    elasto-plastic solution."""

    def __init__(self, name: str, loadings: dict[str, ClosedForm], large: Callable | None = None,
                 loading: Callable | None = None, plastic_loadings: tuple[str, ...] = ()):
        self.name, self.loadings = name, loadings
        self.large, self.loading, self.plastic_loadings = large, loading, plastic_loadings
        self.summary = next(iter(loadings.values())).summary

    def load_types(self) -> tuple[str, ...]:
        return tuple(self.loadings)

    def instance(self, spec):
        parameters = Parameters(Elastic(spec.E, spec.nu), spec.load, spec.width, spec.height)
        return place(self.loadings[spec.load_type], parameters, spec.angle, spec.offset, spec.cell)

    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        if spec.kinematics == "large" or plastic(spec):
            with solvers.choice(solver):
                setup, corner, R = self.setup(spec)
                return run_large_case(spec, setup, corner, R, lambda material, t: self.exact(spec, material, t),
                                      keep_fields, progress, checkpoint)
        return run_small_case(spec, self.instance(spec), keep_fields, solver)

    # --- the load steps ------------------------------------------------------------------------
    def exact(self, spec, material, t: float):
        """The exact field at load fraction t (see ClosedFormProblem)."""
        if plastic(spec):
            return _uniaxial_plastic(spec, material, t)
        return self.large(spec, material, t)

    def setup(self, spec) -> tuple[Setup, np.ndarray, np.ndarray]:
        """The load steps' setup, the body's corner (2,) and frame (2, 2); InputError (one line) for a
        loading without an exact finite-strain (or elasto-plastic) solution."""
        if self.large is None or spec.load_type not in self.loadings:
            allowed = ", ".join(f"{p.name} ({t})" for p in PROBLEMS if p.large is not None for t in p.loadings)
            raise InputError(f"problem {spec.problem!r} with load type {spec.load_type!r} has no exact finite-strain "
                             f"solution for load steps (large kinematics, or material von-mises); allowed: {allowed}")
        material = Hencky(spec.E, spec.nu)
        if plastic(spec):
            if spec.load_type not in self.plastic_loadings:
                raise InputError(f"material {spec.material} has an exact solution only for the confined block's "
                                 f"settlement; problem {spec.problem!r} ({spec.load_type}) is not allowed with it")
            material = model_of(spec)        # small: the return on the initial configuration
        corner = np.asarray(spec.offset, float) * spec.cell
        body = rectangle(spec.width, spec.height, self.loadings[spec.load_type].kinds, spec.angle, corner)
        setup = Setup(body, material, self.loading(spec, body), spec.cell, spec.ppc, spec.basis, spec.steps)
        return setup, corner, body.frame


def _uniaxial_plastic(spec, material, t: float):
    """Homogeneous uniaxial strain: coaxial and proportional, so the radial return from the undeformed
    state is the exact response at every t, whatever the steps taken."""
    s = 1 - t * spec.load / spec.height
    response = material.update(np.diag([1.0, s, 1.0])[None], material.initial(1))
    stress = float(response.sigma[0, 1, 1])

    def plastic_field(X):
        return (s - 1) * X[:, 1], np.full(len(X), stress)
    return plastic_field, s * spec.height, max(abs(stress), 1e-300)


def _block(spec, material, t: float):
    """The confined block under the top pressure or settlement at load fraction t."""
    lam, M = material.lam, material.M
    if spec.load_type == "pressure":
        s = float(finite_strain.compression_stretch_of_pressure(t * spec.load, M))
    else:
        s = 1 - t * spec.load / spec.height

    def block_field(X):
        state = finite_strain.compression(X[:, 1], s, lam, M)
        return state.u_eta, state.sigma_eta_eta
    return block_field, s * spec.height, abs(M * np.log(s) / s)


def _block_loading(spec, body) -> Loading:
    if spec.load_type == "pressure":
        if spec.load <= 0:
            raise InputError(f"load {spec.load} is not allowed for large kinematics; it must be > 0 (compressive)")
        return Loading(pressures={2: spec.load})
    if not 0 < spec.load < spec.height:
        raise InputError(f"settlement {spec.load} is not allowed; it must be in (0, height = {spec.height:g})")
    motion = np.zeros(len(body.essential_edges))
    motion[body.essential_edges.index(2)] = spec.load          # the top wall, along its inward normal
    return Loading(wall_motion=motion)


def _column(spec, material, t: float):
    return finite_strain.column_exact(spec.height, spec.load, material, t)


def _column_loading(spec, body) -> Loading:
    if spec.load <= 0:
        raise InputError(f"load {spec.load} is not allowed for large kinematics; it must be > 0 (compressive)")
    return Loading(body_force=-(spec.load / spec.height) * body.frame[:, 1])


FINITE_STRAIN = {"confined-block": (_block, _block_loading, ("settlement",)), "column": (_column, _column_loading, ())}
PROBLEMS = tuple(ClosedFormProblem(name, {t: p for (n, t), p in LOADINGS.items() if n == name},
                                   *FINITE_STRAIN.get(name, (None, None, ())))
                 for name in LIBRARY)

