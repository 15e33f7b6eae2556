"""What one Newton iteration of the large-deformation loop costs, part by part, against the numerical
factorization it contains (the target: an iteration <= 1.5x that refactorization at ~500k unknowns).

The case is the settlement of the confined block at 30 degrees (IBM, GIMP, Hencky, one load step):
`ibm-study solve --problem confined-block --method ibm --angle 30 --kinematics large --load-type
settlement --load 2 --cell H --steps 1`. Timed inside the process, per iteration from the second on
(the first factorization also orders and analyses the matrix): the forces and tangent of every point
(`evaluate`: kinematics, constitutive update, blocks), the tangent's assembly into the reduced CSR
matrix, PARDISO's numerical refactorization (its ordering and symbolic factors reused) and the
substitution. Once a step: the step's pattern and point sets. As in the `ibm-study` command, the
process keeps freed memory for reuse (studies.run.allocator); --plain-allocator leaves malloc as it is.

    python -m benchmarks.newton_iteration [--cell 0.2] [--material elastic|von-mises] [--plain-allocator] [--json]
"""
from __future__ import annotations

import argparse
import json
import sys
from contextlib import ExitStack
from time import perf_counter
from unittest import mock

from ibm.large import equilibrium, newton
from studies.run.allocator import keep_freed_memory
from studies.run.case import CaseSpec, run_case


def measure(cell: float = 0.2, material: str = "elastic") -> dict:
    """Per-iteration times (s) of the parts of Newton's loop, and their ratios to the refactorization."""
    spent = {"evaluate": [], "assemble": [], "pattern": [], "solves": []}
    evaluate, matrix, pattern_of, solve = (newton.evaluate, equilibrium.ReducedPattern.matrix,
                                           equilibrium.ReducedPattern.of.__func__, newton.solve_system)

    def timed(name, function):
        def wrapper(*args, **kwargs):
            start = perf_counter()
            result = function(*args, **kwargs)
            spent[name].append(perf_counter() - start)
            return result
        return wrapper

    def solved(*args, **kwargs):
        x, info = solve(*args, **kwargs)
        spent["solves"].append(info)
        return x, info

    extra = dict(material="von-mises", yield_stress=20.0) if material == "von-mises" else {}
    spec = CaseSpec(problem="confined-block", method="ibm", angle=30.0, kinematics="large", load_type="settlement",
                    load=2.0, cell=cell, steps=1, **extra)
    with ExitStack() as stack:
        stack.enter_context(mock.patch.object(newton, "evaluate", timed("evaluate", evaluate)))
        stack.enter_context(mock.patch.object(equilibrium.ReducedPattern, "matrix", timed("assemble", matrix)))
        stack.enter_context(mock.patch.object(equilibrium.ReducedPattern, "of",
                                              classmethod(timed("pattern", pattern_of))))
        stack.enter_context(mock.patch.object(newton, "solve_system", solved))
        start = perf_counter()
        record = run_case(spec)
        total = perf_counter() - start
    later = [info for info in spent["solves"] if info.get("reused")]
    if not later:
        raise SystemExit("no refactorization happened (Newton converged in one solve); try a larger --cell load")
    n = len(later)
    # the iterations that refactor: evaluations and assemblies after the first solve
    per = {"evaluate": sum(spent["evaluate"][-n:]) / n, "assemble": sum(spent["assemble"][-n:]) / n,
           "refactor": sum(i["time_factorize"] for i in later) / n,
           "substitute": sum(i["time_substitute"] for i in later) / n,
           "prepare": sum(i["time_prepare"] for i in later) / n}
    iteration = sum(per.values())
    first = spent["solves"][0]
    return {"cell": cell, "material": material, "ndof": record.get("ndof"), "npoints": record.get("npoints"),
            "solves": len(spent["solves"]), "refactorizations": n, "per_iteration": per,
            "iteration": iteration, "iteration_vs_refactor": iteration / per["refactor"],
            "first_factorization": first["time_factorize"], "pattern": sum(spent["pattern"]),
            "total": total, "status": record.get("status", "ok")}


def report(row: dict) -> str:
    per = row["per_iteration"]
    parts = ", ".join(f"{name} {value:.2f} s" for name, value in per.items())
    return (f"{row['ndof']:,} unknowns, {row['npoints']:,} points ({row['material']}), {row['solves']} solves: "
            f"per iteration {row['iteration']:.2f} s ({parts}) = {row['iteration_vs_refactor']:.2f}x the numerical "
            f"refactorization (target <= 1.5x); first factorization with ordering {row['first_factorization']:.2f} s; "
            f"the step's pattern {row['pattern']:.2f} s; whole case {row['total']:.1f} s")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cell", type=float, default=0.2)
    parser.add_argument("--material", choices=["elastic", "von-mises"], default="elastic")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--plain-allocator", action="store_true", help="do not keep freed memory for reuse")
    args = parser.parse_args(argv)
    if not args.plain_allocator:
        keep_freed_memory()
    row = measure(args.cell, args.material)
    print(json.dumps(row) if args.json else report(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
