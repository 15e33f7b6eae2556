"""
Bodies from problem files, compared across methods.
===================================================

`bracket.toml` is a notched bracket (non-convex, fixed base, roller on the left, loads on two
sides) with no known solution: each method's errors are measured against a body-fitted fem
reference refined until its own Richardson-estimated error is ten times smaller.
`notched_patch.toml` carries an exact field, from which its loads are derived; its base is
fixed only in the middle (a side split into traction | fixed | traction). Both are turned by
30 degrees in the grid, so no boundary follows a grid line.

    python examples/problem_file_bodies.py
"""
from pathlib import Path

import studies
from studies.run.case import CaseSpec, run_case

HERE = Path(studies.__file__).resolve().parents[1] / "examples"      # beside this file
METHODS = ("ibm", "penalty", "nitsche", "lagrange", "fem")


def main(files=("bracket.toml", "notched_patch.toml"), methods=METHODS, angle: float = 30.0,
         cell: float = 10.0) -> dict:
    results = {}
    for name in files:
        for method in methods:
            record = run_case(CaseSpec(problem_file=str(HERE / name), method=method, angle=angle, cell=cell, ppc=2))
            results[record["problem"], method] = record
    print(f"{'problem':15s} {'method':9s} {'err_l2':>10s} {'err_energy':>10s}  reference")
    for (problem, method), r in results.items():
        against = "exact" if r["reference"] == "exact" else (
            f"fem h={r['reference_cell']:g} (estimated err_l2 {r['reference_err_l2']:.1e})")
        print(f"{problem:15s} {method:9s} {r['err_l2']:10.3e} {r['err_energy']:10.3e}  {against}")
    return results


if __name__ == "__main__":
    main()
