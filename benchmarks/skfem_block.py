"""scikit-fem's own body-fitted confined block (MeshQuad, Q1 elasticity, condense, skfem.solve):
the reference the benchmarks time beside the IBM. It imports numpy, scipy and scikit-fem only, so
that run as a process it is what a scikit-fem user would time:

    python -m benchmarks.skfem_block --cells 502      # ~505k unknowns; prints one JSON line
"""
from __future__ import annotations

import argparse
import json
import sys
from time import perf_counter

import numpy as np
import scipy.sparse as sp

SIZE = 100.0


def skfem_basis(n_cells: int):
    """Body-fitted Q1 basis of the square (scikit-fem's own mesh and element)."""
    from skfem import Basis, ElementQuad1, ElementVector, MeshQuad
    s = np.linspace(0.0, SIZE, n_cells + 1)
    mesh = MeshQuad.init_tensor(s, s).with_boundaries({
        "left": lambda x: x[0] < 1e-9 * SIZE, "right": lambda x: x[0] > SIZE * (1 - 1e-9),
        "bottom": lambda x: x[1] < 1e-9 * SIZE, "top": lambda x: x[1] > SIZE * (1 - 1e-9)})
    return Basis(mesh, ElementVector(ElementQuad1()))


def skfem_assembly(basis, E: float = 1e4, nu: float = 0.3) -> sp.csr_matrix:
    """scikit-fem's Q1 elasticity: skfem.models.elasticity.linear_elasticity, BilinearForm.assemble."""
    from skfem.models.elasticity import lame_parameters, linear_elasticity
    return linear_elasticity(*lame_parameters(E, nu)).assemble(basis)


def skfem_solve(basis, K: sp.csr_matrix, load: float = 10.0) -> np.ndarray:
    """The body-fitted confined block with scikit-fem's defaults: rollers by condense, skfem.solve.

    Solved in the block's own frame: a body-fitted mesh of the block turned by 30 degrees
    gives the same matrix up to an orthogonal change of variables, so the same cost.
    """
    from skfem import LinearForm, condense, solve
    from skfem.helpers import dot

    @LinearForm
    def pressure(v, w):
        return dot(v, w.n) * (-load)

    from skfem import FacetBasis
    top = FacetBasis(basis.mesh, basis.elem, facets=basis.mesh.boundaries["top"])
    f = pressure.assemble(top)
    rollers = np.concatenate([basis.get_dofs("left").nodal["u^1"], basis.get_dofs("right").nodal["u^1"],
                              basis.get_dofs("bottom").nodal["u^2"]])
    return solve(*condense(K, f, D=rollers))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.skfem_block", description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, required=True, help="cells across the square")
    args = parser.parse_args(argv)
    start = perf_counter()
    basis = skfem_basis(args.cells)
    K = skfem_assembly(basis)
    u = skfem_solve(basis, K)
    print(json.dumps({"cells": args.cells, "ndof": int(K.shape[0]), "time_s": perf_counter() - start,
                      "max_displacement": float(np.abs(u).max())}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
