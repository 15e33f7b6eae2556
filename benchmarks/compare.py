"""Side by side with scikit-fem, ratios taken in the same run (against the targets):

- assembly: IBM material-point stiffness + band correction + loads into CSR, against
  scikit-fem's Q1 elasticity (linear_elasticity, BilinearForm.assemble on MeshQuad with
  ElementVector(ElementQuad1)) at the same number of unknowns: >= 10x faster, and
  >= 1 million quadrature points per second;
- end to end: the IBM solve of confined-block at 30 degrees (material points to fields)
  against scikit-fem's body-fitted problem of the same size with its defaults
  (Basis, assemble, condense, skfem.solve): <= 0.2x; and against the bare
  factorization + substitution of the linear solver it used: <= 1.5x.

    python -m benchmarks.compare [--ndof 500000]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
from time import perf_counter

from benchmarks.common import (cells_for, ibm_assembly, ibm_model, ibm_quadratures, skfem_assembly,
                               skfem_basis, skfem_solve)
from ibm import solvers
from ibm.method import solve_ibm

ASSEMBLY_ROUNDS = 7
TARGETS = {"assembly_speedup": (">=", 10.0), "points_per_second": (">=", 1e6),
           "end_to_end_vs_skfem": ("<=", 0.2), "end_to_end_vs_solver": ("<=", 1.5)}


def best_of(function, rounds: int, *args):
    best, result = float("inf"), None
    for _ in range(rounds):
        start = perf_counter()
        result = function(*args)
        best = min(best, perf_counter() - start)
    return best, result


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def compare(ndof: int = 500_000, solver: str = "auto", rounds: int = 3) -> dict:
    n = cells_for(ndof)
    row = {"ndof_target": ndof, "cells": n, "machine": machine()}

    # assembly, same number of unknowns; a fraction of a second each, so best of more rounds
    q = ibm_quadratures(n)
    row["time_ibm_assembly"], (K, _) = best_of(ibm_assembly, max(rounds, ASSEMBLY_ROUNDS), q)
    row["ibm_points"] = len(q.points) + len(q.band)
    q4 = ibm_quadratures(n, 4)   # 4 points per cell: the per-point part weighs more
    time_4, _ = best_of(ibm_assembly, max(rounds, ASSEMBLY_ROUNDS), q4)
    row["points_per_second_4ppc"] = (len(q4.points) + len(q4.band)) / time_4
    del q4
    basis_time, basis = best_of(skfem_basis, 1, n)
    row["time_skfem_assembly"], K_fem = best_of(skfem_assembly, max(1, rounds - 1), basis)
    row["ndof_ibm_grid"], row["ndof_skfem"] = K.shape[0], K_fem.shape[0]
    row["assembly_speedup"] = row["time_skfem_assembly"] / row["time_ibm_assembly"]
    row["points_per_second"] = row["ibm_points"] / row["time_ibm_assembly"]

    # end to end: the IBM from material points to fields, fresh model each round
    def ibm_end_to_end():
        ibm_model.cache_clear()
        start = perf_counter()
        model = ibm_model(n)
        with solvers.choice(solver):
            solution = solve_ibm(model)
        return perf_counter() - start, solution.info

    runs = [ibm_end_to_end() for _ in range(rounds)]
    total, info = min(runs, key=lambda r: r[0])
    row.update(time_ibm_total=total, ndof_ibm=int(info["ndof"]), solver=info["solver"],
               structure=info["structure"], time_ibm_solver=info["time_factorize"] + info["time_substitute"])
    row["end_to_end_vs_solver"] = total / row["time_ibm_solver"]

    def skfem_end_to_end():
        b = skfem_basis(n)
        return skfem_solve(b, skfem_assembly(b))

    row["time_skfem_total"], _ = best_of(skfem_end_to_end, 1)
    row["end_to_end_vs_skfem"] = total / row["time_skfem_total"]
    row["targets_met"] = {k: (row[k] >= v if op == ">=" else row[k] <= v) for k, (op, v) in TARGETS.items()}
    return row


def report(row: dict) -> str:
    lines = [f"machine: {row['machine']}",
             f"assembly at {row['ndof_skfem']:,} unknowns: IBM {row['time_ibm_assembly']:.3f} s "
             f"({row['ibm_points']:,} points, {row['points_per_second'] / 1e6:.2f} M points/s; "
             f"{row['points_per_second_4ppc'] / 1e6:.2f} M points/s at 4 points per cell), "
             f"scikit-fem {row['time_skfem_assembly']:.3f} s -> {row['assembly_speedup']:.1f}x faster",
             f"end to end at {row['ndof_ibm']:,} unknowns: IBM {row['time_ibm_total']:.2f} s "
             f"(solver {row['solver']}/{row['structure']}: {row['time_ibm_solver']:.2f} s), "
             f"scikit-fem body-fitted {row['time_skfem_total']:.2f} s",
             f"ratios: IBM / scikit-fem = {row['end_to_end_vs_skfem']:.3f} (target <= 0.2), "
             f"IBM / bare solver = {row['end_to_end_vs_solver']:.2f} (target <= 1.5)"]
    met = row["targets_met"]
    lines.append("targets: " + ", ".join(f"{k} {'met' if v else 'MISSED'}" for k, v in met.items()))
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.compare", description=__doc__.splitlines()[0])
    parser.add_argument("--ndof", type=int, default=500_000)
    parser.add_argument("--solver", default="auto")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", default=None, help="also write the row to this file")
    args = parser.parse_args(argv)
    row = compare(args.ndof, args.solver, args.rounds)
    print(report(row))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(row, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
