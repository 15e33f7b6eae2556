"""Which boundary methods keep algebraic multigrid effective: AMG-preconditioned CG iterations per
method and method parameter against h, and the solve time beside the direct solvers'.

    python -m benchmarks.amg_study [--cells 10 5 2.5 1.25] [--crossover 1.0 0.5 0.25]
    python -m benchmarks.amg_study --dim 3 [--cells 25 12.5 6.25]

Problem: the manufactured field at 30 degrees, two points per cell (the convergence study's).
Each case is solved twice in one process, `--solver amg` and `--solver auto` (SuperLU below 20k
unknowns, PARDISO above), and the table gives the CG iterations (to a relative residual of 1e-10
on the scaled system; "stalls" when 2000 are not enough) and both solve times. The crossover
part times the confined block at 30 degrees with fem and nitsche at growing sizes. With --dim 3
the problem is the 3D manufactured field at (theta, psi) = (30, 20), one point per cell (the 3D
rates' cases), the near-null space the six rigid modes, and there is no crossover part.
"""
from __future__ import annotations

import argparse

from ibm.exceptions import SolveError
from studies.run.case import CaseSpec, run_case

CONFIGURATIONS = [("ibm", {"delta_rel": 1e-5}), ("ibm", {"delta_rel": 1e-3}), ("ibm", {"delta_rel": 1e-1}),
                  ("penalty", {"beta0": 1e2}), ("penalty", {"beta0": 1e4}), ("penalty", {"beta0": 1e6}),
                  ("nitsche", {"gamma": 10.0}), ("nitsche", {"gamma": 100.0}), ("nitsche", {"gamma": 1000.0}),
                  ("fem", {})]


def solve(spec: CaseSpec, solver: str) -> dict:
    return _attempt(lambda: run_case(spec, solver=solver))


def solve_3d(method: str, parameters: dict, cell: float, solver: str) -> dict:
    from studies.run.case import OFFSET_3D
    from studies.run.solid import solve_box_case
    return _attempt(lambda: solve_box_case("manufactured", method, 30.0, 20.0, OFFSET_3D, cell, solver=solver,
                                           **parameters))


def _attempt(run) -> dict:
    """The CG iterations, solve time and unknowns of one case's record, or the SolveError's message."""
    try:
        record = run()
        return {"iterations": record.get("amg_iterations"), "time": record["time_solve"], "ndof": record["ndof"]}
    except SolveError as error:
        return {"iterations": None, "time": None, "error": str(error)}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=float, nargs="+", default=[10.0, 5.0, 2.5, 1.25])
    parser.add_argument("--crossover", type=float, nargs="+", default=[1.0, 0.5, 0.25])
    parser.add_argument("--dim", type=int, choices=(2, 3), default=2)
    args = parser.parse_args(argv)
    if args.dim == 3 and args.cells == parser.get_default("cells"):
        args.cells = [25.0, 12.5, 6.25]
    header = "| method | parameter | " + " | ".join(f"h = {h:g}" for h in args.cells) + " |"
    print(header)
    print("|" + "---|" * (2 + len(args.cells)))
    for method, parameters in CONFIGURATIONS:
        if args.dim == 3 and method == "fem":     # the 3D reference solves with scikit-fem's own solver
            continue
        cells = []
        for h in args.cells:
            if args.dim == 3:
                amg, direct = solve_3d(method, parameters, h, "amg"), solve_3d(method, parameters, h, "auto")
            else:
                spec = CaseSpec(problem="manufactured", method=method, angle=30.0, cell=h, ppc=2,
                                method_parameters=parameters)
                amg, direct = solve(spec, "amg"), solve(spec, "auto")
            if amg["iterations"] is None:
                cells.append("refused (not positive definite)" if "needs a symmetric positive definite" in
                             amg.get("error", "") else "stalls")
            else:
                direct_time = "-" if direct["time"] is None else f"{direct['time']:.2f} s"
                cells.append(f"{amg['iterations']} ({amg['time']:.2f} s / {direct_time})")
        label = ", ".join(f"{k} = {v:g}" for k, v in parameters.items()) or "-"
        print(f"| {method} | {label} | " + " | ".join(cells) + " |", flush=True)
    if args.dim == 3:
        return
    print()
    print("| method | h | unknowns | AMG iterations | AMG solve (s) | direct solve (s) |")
    print("|---|---|---|---|---|---|")
    for method, parameters in [("fem", {}), ("nitsche", {"gamma": 100.0})]:
        for h in args.crossover:
            spec = CaseSpec(method=method, angle=30.0, cell=h, ppc=1, method_parameters=parameters)
            amg, direct = solve(spec, "amg"), solve(spec, "auto")
            its = "stalls" if amg["iterations"] is None else amg["iterations"]
            amg_time = "-" if amg["time"] is None else f"{amg['time']:.2f}"
            print(f"| {method} | {h:g} | {direct['ndof']} | {its} | {amg_time} | {direct['time']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
