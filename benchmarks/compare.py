"""Side by side with scikit-fem, ratios taken in the same run (against the targets):

- assembly: IBM material-point stiffness + band correction + loads into CSR, against
  scikit-fem's Q1 elasticity (linear_elasticity, BilinearForm.assemble on MeshQuad with
  ElementVector(ElementQuad1)) at the same number of unknowns: >= 10x faster, and
  >= 1 million quadrature points per second;
- end to end: the IBM solve of confined-block at 30 degrees (material points to fields)
  against scikit-fem's body-fitted problem of the same size with its defaults
  (Basis, assemble, condense, skfem.solve): <= 0.2x; and against the bare
  factorization + substitution of the linear solver it used: <= 1.5x;
- whole processes, as a user times them: `ibm-study solve --problem confined-block --method ibm
  --angle 30 --cell h --ppc 2 --json` (import, points, assembly, solve, error norms, JSON) against
  `python -m benchmarks.skfem_block` at the same size (import, mesh, assembly, condense, solve):
  <= 0.2x; and against the bare factorization + substitution inside it (from its JSON): <= 1.3x.

    python -m benchmarks.compare [--ndof 500000]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
from time import perf_counter

from benchmarks.common import (ANGLE, SIZE, cells_for, ibm_assembly, ibm_model, ibm_quadratures, ibm_study,
                               skfem_assembly, skfem_basis, skfem_solve)
from ibm.solvers import backends as solvers
from ibm.implicit_boundary import solve_ibm

ASSEMBLY_ROUNDS = 7
TARGETS = {"assembly_speedup": (">=", 10.0), "points_per_second": (">=", 1e6),
           "end_to_end_vs_skfem": ("<=", 0.2), "end_to_end_vs_solver": ("<=", 1.5),
           "command_vs_skfem": ("<=", 0.2), "command_vs_solver": ("<=", 1.3)}


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


def timed_process(argv: list[str]) -> tuple[float, dict]:
    """Wall time (s) of a whole process and the JSON line it prints last."""
    start = perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, check=True)
    elapsed = perf_counter() - start
    return elapsed, json.loads(done.stdout.strip().splitlines()[-1])


def ibm_command(h: float) -> list[str]:
    """The command of docs/performance.md: the IBM on confined-block at 30 degrees, 2 x 2 points per cell."""
    return [*ibm_study(), "solve", "--problem", "confined-block", "--method", "ibm", "--angle", str(ANGLE),
            "--cell", f"{h:g}", "--ppc", "2", "--json"]


def whole_processes(n_cells: int, rounds: int = 3) -> dict:
    """The IBM's command and scikit-fem's script, each as a fresh process (best of `rounds`), at
    n_cells across the block, and the bare factorization + substitution inside the IBM's."""
    ours = min((timed_process(ibm_command(SIZE / n_cells)) for _ in range(rounds)), key=lambda r: r[0])
    theirs = min((timed_process([sys.executable, "-m", "benchmarks.skfem_block", "--cells", str(n_cells)])
                  for _ in range(max(1, rounds - 1))), key=lambda r: r[0])
    record = ours[1]
    bare = record["time_factorize"] + record["time_substitute"]
    return {"time_ibm_command": ours[0], "ndof_ibm_command": record["ndof"], "time_ibm_command_solver": bare,
            "time_ibm_command_in_process": record["time_s"],
            "time_skfem_command": theirs[0], "ndof_skfem_command": theirs[1]["ndof"],
            "command_vs_solver": ours[0] / bare, "command_vs_skfem": ours[0] / theirs[0]}


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
    del K, K_fem, basis, q
    ibm_model.cache_clear()
    ibm_quadratures.cache_clear()
    row.update(whole_processes(n, rounds))
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
             f"IBM / bare solver = {row['end_to_end_vs_solver']:.2f} (target <= 1.5)",
             f"whole processes: `ibm-study solve` at {row['ndof_ibm_command']:,} unknowns {row['time_ibm_command']:.2f} s "
             f"(in the process {row['time_ibm_command_in_process']:.2f} s, of which factorization + substitution "
             f"{row['time_ibm_command_solver']:.2f} s), scikit-fem's script at {row['ndof_skfem_command']:,} unknowns "
             f"{row['time_skfem_command']:.2f} s",
             f"ratios: command / scikit-fem's = {row['command_vs_skfem']:.3f} (target <= 0.2), "
             f"command / its bare solver = {row['command_vs_solver']:.2f} (target <= 1.3)"]
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
