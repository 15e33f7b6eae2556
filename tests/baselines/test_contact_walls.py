"""The contact walls' tangents are the derivatives of their forces (central finite differences on a
step of the frictional block, in stick and in slip), for the penalty and for Nitsche's three variants."""
import numpy as np
import pytest

import ibm.large.loadsteps as loadsteps
from baselines.nitsche import Nitsche
from baselines.penalty import Penalty
from ibm.contact.laws import SLIP, STICK
from studies.problems.frictional_block import FRICTIONAL_BLOCK
from studies.run.case import CaseSpec

BLOCK = CaseSpec(problem="frictional-block", method="penalty", angle=30.0, ppc=2, steps=8, friction=0.3)


def _captured_steps(treatment, monkeypatch):
    """(terms, converged dU) of every load step of the block run with `treatment`."""
    captured = []
    newton = loadsteps.newton

    def keep(context, terms, *args, **kwargs):
        solution = newton(context, terms, *args, **kwargs)
        captured.append((terms, solution.dU))
        return solution

    monkeypatch.setattr(loadsteps, "newton", keep)
    setup = FRICTIONAL_BLOCK.setup(BLOCK)[0]
    loadsteps.run(setup, treatment)
    return captured


@pytest.mark.parametrize("treatment", [Penalty(beta0=1e3), Nitsche(), Nitsche(theta=0.0), Nitsche(theta=-1.0)],
                         ids=["penalty", "nitsche", "nitsche-incomplete", "nitsche-skew"])
def test_contact_tangent_is_the_derivative_of_the_force(treatment, monkeypatch):
    captured = _captured_steps(treatment, monkeypatch)
    rng = np.random.default_rng(7)
    statuses = set()
    for step in (4, 7):                         # t = 0.625: sticking; t = 1: slipping
        terms, dU = captured[step]
        force, stiffness = terms.wall(dU)
        used = np.flatnonzero(np.abs(stiffness).sum(axis=0).A1 > 0)
        direction = np.zeros_like(dU)
        direction[used] = rng.normal(size=len(used))
        scale = 1e-7 * np.abs(dU).max()
        numeric = (terms.wall(dU + scale * direction)[0] - terms.wall(dU - scale * direction)[0]) / (2 * scale)
        exact = stiffness @ direction
        assert np.linalg.norm(numeric - exact) <= 1e-6 * np.linalg.norm(exact), step
        statuses.add(int(terms.accept(dU)[0]["status"][0]))
    assert statuses == {STICK, SLIP}
