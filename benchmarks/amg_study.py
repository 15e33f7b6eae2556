"""Which boundary methods keep algebraic multigrid effective: AMG-preconditioned CG iterations per
method and method parameter against h, and the solve time beside the direct solvers'.

    python -m benchmarks.amg_study [--cells 10 5 2.5 1.25] [--crossover 1.0 0.5 0.25]

Problem: the manufactured field at 30 degrees, two points per cell (the convergence study's).
Each case is solved twice in one process, `--solver amg` and `--solver auto` (SuperLU below 20k
unknowns, PARDISO above), and the table gives the CG iterations (to a relative residual of 1e-10
on the scaled system; "stalls" when 2000 are not enough) and both solve times. The crossover
part times the confined block at 30 degrees with fem and nitsche at growing sizes.
"""
from __future__ import annotations

import argparse

from ibm.solve import SolveError
from studies.case import CaseSpec, run_case

CONFIGURATIONS = [("ibm", {"delta_rel": 1e-5}), ("ibm", {"delta_rel": 1e-3}), ("ibm", {"delta_rel": 1e-1}),
                  ("penalty", {"beta0": 1e2}), ("penalty", {"beta0": 1e4}), ("penalty", {"beta0": 1e6}),
                  ("nitsche", {"gamma": 10.0}), ("nitsche", {"gamma": 100.0}), ("nitsche", {"gamma": 1000.0}),
                  ("fem", {})]


def solve(spec: CaseSpec, solver: str) -> dict:
    try:
        record = run_case(spec, solver=solver)
        return {"iterations": record.get("amg_iterations"), "time": record["time_solve"], "ndof": record["ndof"]}
    except SolveError as error:
        return {"iterations": None, "time": None, "error": str(error)}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=float, nargs="+", default=[10.0, 5.0, 2.5, 1.25])
    parser.add_argument("--crossover", type=float, nargs="+", default=[1.0, 0.5, 0.25])
    args = parser.parse_args(argv)
    header = "| method | parameter | " + " | ".join(f"h = {h:g}" for h in args.cells) + " |"
    print(header)
    print("|" + "---|" * (2 + len(args.cells)))
    for method, parameters in CONFIGURATIONS:
        cells = []
        for h in args.cells:
            spec = CaseSpec(problem="manufactured", method=method, angle=30.0, cell=h, ppc=2,
                            method_parameters=parameters)
            amg, direct = solve(spec, "amg"), solve(spec, "auto")
            if amg["iterations"] is None:
                cells.append("stalls")
            else:
                cells.append(f"{amg['iterations']} ({amg['time']:.2f} s / {direct['time']:.2f} s)")
        label = ", ".join(f"{k} = {v:g}" for k, v in parameters.items()) or "-"
        print(f"| {method} | {label} | " + " | ".join(cells) + " |", flush=True)
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
