"""Scaling study: time and peak memory of the IBM solve against the number of unknowns.

Each size runs in a fresh process (so the peak resident memory is that size's own, native
solver memory included) on confined-block at 30 degrees, and reports the phases
separately: material points, assembly (band quadrature, stiffness, loads), the linear
solver's factorization + substitution, and the whole solve. Exponents p of time ~ ndof^p
are fitted by least squares in log-log over the sizes with at least FIT_MIN unknowns
(FIT_MIN_3D in 3D). `--dim 3` measures the cube at (30, 20) instead of the square at 30 degrees.

    scaling_table(cells=...) -> list of dicts (one per size)
    fitted_exponents(table)  -> {phase: p}
    scaling_figure(table, path) -> path of the PNG (time and memory, log-log)
    load_table(folder)       -> the table stored by `python -m studies.run.scaling` (make bench)
"""
from __future__ import annotations

import argparse
import json
import multiprocessing
import resource
from pathlib import Path
from time import perf_counter

import numpy as np

SIZE = 100.0
# cells across the body: ~2 n^2 unknowns, from ~5k to ~1M
CELLS = (50, 100, 200, 350, 500, 710)
# 3D: ~3 n^3 unknowns, from ~1k to ~100k with PARDISO (its factors grow as n^1.43: 28 GB at 1M);
# docs/performance.md adds 1.1M with --solver amg --delta-rel 0.1
CELLS_3D = (5, 10, 15, 20, 30)
FIT_MIN = 20_000
FIT_MIN_3D = 5_000
PHASES = {"time_total": "whole solve (points to fields)", "time_setup": "everything but the linear solver",
          "time_linear": "factorization + substitution", "time_assemble": "assembly (band, stiffness, loads)"}


def _placed(n_cells: int, angle: float, dim: int, tilt: float):
    """(body, material, loads) of confined-block with n_cells across: the square at `angle` (2D)
    or the cube at (angle, tilt) with the 3D offset (3D)."""
    h = SIZE / n_cells
    if dim == 2:
        from studies.run.case import CaseSpec, instance_of
        instance = instance_of(CaseSpec(angle=angle, cell=h, width=SIZE, height=SIZE))
        return instance.body, instance.parameters.material, instance.loads
    from ibm.models.elastic import Elastic
    from studies.problems.box_fields import place_box
    from studies.problems.library import Parameters
    from studies.run.case import OFFSET_3D
    parameters = Parameters(Elastic(1e4, 0.3), 10.0, width=SIZE, height=SIZE, depth=SIZE)
    placed = place_box("confined-block", parameters, angle, tilt, OFFSET_3D, h)
    return placed.body, parameters.material, placed.loads


def measure(n_cells: int, angle: float = 30.0, solver: str = "auto", dim: int = 2, tilt: float = 20.0,
            delta_rel: float | None = None) -> dict:
    """One size, in this process: phase times (s), unknowns, points and peak memory (MB).
    dim 3: the cube at (angle, tilt), n_cells^3 cells (tilt is not used in 2D). delta_rel: the
    IBM's band width over h (None: its default)."""
    from ibm.implicit_boundary import solve_ibm
    from ibm.small.model import build_model
    from ibm.solvers import backends as solvers

    h = SIZE / n_cells
    body, material, loads = _placed(n_cells, angle, dim, tilt)
    solvers.available()   # load the solver library now: a once-per-process cost, not this size's
    start = perf_counter()
    model = build_model(body, material, loads, h, 1)
    built = perf_counter()
    with solvers.choice(solver):
        options = {} if delta_rel is None else {"delta_rel": delta_rel}
        solution = solve_ibm(model, estimate_condition=dim == 2, **options)   # 3D: no estimate (as its CLI)
    done = perf_counter()
    info = solution.info
    linear = info["time_factorize"] + info["time_substitute"]
    total = done - start
    return {"dim": dim, "cells": n_cells, "h": h, "delta_rel": info["delta"] / h, "ndof": int(info["ndof"]), "npoints": len(model.points),
            "solver": info["solver"], "structure": info["structure"], "amg_iterations": info.get("amg_iterations"),
            "time_points": built - start, "time_assemble": info["time_assemble"],
            "time_factorize": info["time_factorize"], "time_substitute": info["time_substitute"],
            "time_linear": linear, "time_setup": total - linear, "time_total": total,
            "setup_ratio": total / linear, "factor_nnz": info.get("factor_nnz"),
            "solver_memory_mb": info.get("solver_memory_mb"),
            "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def _child(arguments, queue) -> None:
    queue.put(measure(*arguments))


def measure_isolated(n_cells: int, angle: float = 30.0, solver: str = "auto", dim: int = 2,
                     delta_rel: float | None = None) -> dict:
    """measure() in a fresh process: its peak memory is this size's alone."""
    context = multiprocessing.get_context("spawn")
    queue = context.Queue()
    process = context.Process(target=_child, args=((n_cells, angle, solver, dim, 20.0, delta_rel), queue))
    process.start()
    row = queue.get()
    process.join()
    return row


def scaling_table(cells=CELLS, angle: float = 30.0, solver: str = "auto", progress=None, dim: int = 2,
                  delta_rel: float | None = None) -> list[dict]:
    """One row per size (see measure), smallest first."""
    rows = []
    for n in cells:
        rows.append(measure_isolated(n, angle, solver, dim, delta_rel))
        if progress:
            progress(rows[-1])
    return rows


def _fit_min(table: list[dict]) -> int:
    return FIT_MIN_3D if table and table[0].get("dim", 2) == 3 else FIT_MIN


def fitted_exponents(table: list[dict], phases=tuple(PHASES) + ("peak_memory_mb",)) -> dict:
    """p of value ~ ndof^p per phase, least squares in log-log over sizes with ndof >= FIT_MIN
    (FIT_MIN_3D for a 3D table)."""
    rows = [r for r in table if r["ndof"] >= _fit_min(table)]
    if len(rows) < 2:
        return {}
    x = np.log([r["ndof"] for r in rows])
    return {phase: float(np.polyfit(x, np.log([r[phase] for r in rows]), 1)[0]) for phase in phases}


def scaling_figure(table: list[dict], path: str | Path) -> Path:
    """Log-log time per phase and peak memory against unknowns, fitted exponents in the legends."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from studies.report.canvas import log_labels

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    exponents = fitted_exponents(table)
    ndof = np.array([r["ndof"] for r in table])
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    for phase, label in PHASES.items():
        p = exponents.get(phase)
        left.loglog(ndof, [r[phase] for r in table], "o-", label=f"{label}" + (f" (p = {p:.2f})" if p else ""))
    left.set_xlabel("unknowns")
    left.set_ylabel("time (s)")
    left.set_title("time ~ ndof^p")
    left.legend(fontsize=7)
    left.grid(True, which="both", alpha=0.3)
    p = exponents.get("peak_memory_mb")
    right.loglog(ndof, [r["peak_memory_mb"] for r in table], "o-",
                 label="peak resident memory" + (f" (p = {p:.2f})" if p else ""))
    own = [(r["ndof"], r["solver_memory_mb"]) for r in table if r.get("solver_memory_mb") is not None]
    if own:
        right.loglog(*zip(*own), "s--", label="PARDISO's own (factors and work)")
    right.set_xlabel("unknowns")
    right.set_ylabel("memory (MB)")
    right.set_title("peak memory")
    right.legend(fontsize=7)
    right.grid(True, which="both", alpha=0.3)
    for ax in (left, right):          # the report's plain-text log labels (10⁻⁵), set once the lines are in
        log_labels(ax.xaxis)
        log_labels(ax.yaxis)
    where = "the cube at (30, 20)" if table[-1].get("dim", 2) == 3 else "the square at 30 degrees"
    figure.suptitle(f"IBM solve, confined-block, {where}, solver {table[-1]['solver']}")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def load_table(folder: str | Path = "reports/scaling") -> list[dict] | None:
    """The table a previous `python -m studies.run.scaling --out folder` (make bench) stored, or None."""
    path = Path(folder) / "scaling.json"
    return json.loads(path.read_text())["table"] if path.is_file() else None


def markdown(table: list[dict]) -> str:
    """The table (and fitted exponents) as Markdown, for docs/performance.md."""
    lines = ["| unknowns | points | points (s) | assembly (s) | factorize + solve (s) | total (s) | total / solver | peak memory (MB) |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in table:
        lines.append(f"| {r['ndof']:,} | {r['npoints']:,} | {r['time_points']:.2f} | {r['time_assemble']:.2f} | "
                     f"{r['time_linear']:.2f} | {r['time_total']:.2f} | {r['setup_ratio']:.2f} | "
                     f"{r['peak_memory_mb']:.0f} |")
    exponents = fitted_exponents(table)
    lines.append("")
    if table and table[0].get("dim", 2) == 3:
        lines.append("In 3D no condition number is estimated (as `ibm-study solve --dim 3`).")
    else:
        lines.append("Below 50,000 unknowns the solve also estimates the condition number (about ten extra "
                     "substitutions, counted in total); above it the estimate is skipped (ibm.solvers.linear.CONDITION_LIMIT).")
    if exponents:
        lines.append("")
        lines.append("Fitted exponents (ndof >= %d): " % _fit_min(table)
                     + ", ".join(f"{k.replace('time_', '').replace('_mb', '')} {v:.2f}" for k, v in exponents.items()))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.run.scaling", description=__doc__.splitlines()[0])
    parser.add_argument("--dim", type=int, default=2, choices=(2, 3), help="2: the square at 30 degrees; 3: the cube at (30, 20)")
    parser.add_argument("--cells", type=int, nargs="+", default=None,
                        help=f"cells across the body, per size (default {' '.join(map(str, CELLS))} in 2D, "
                             f"{' '.join(map(str, CELLS_3D))} in 3D)")
    parser.add_argument("--solver", default="auto", choices=("auto", "pardiso", "superlu", "amg"))
    parser.add_argument("--delta-rel", type=float, default=None, help="the IBM's band width over h (default its own)")
    parser.add_argument("--out", default="reports/scaling", help="folder for scaling.json, scaling.md, scaling.png")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cells = args.cells or list(CELLS if args.dim == 2 else CELLS_3D)
    if min(cells) < 2:
        parser.error(f"--cells {min(cells)} is not allowed; allowed: 2 or more cells across")
    if args.delta_rel is not None and not 0 < args.delta_rel < 0.5:
        parser.error(f"--delta-rel {args.delta_rel:g} is not allowed; allowed: 0 < delta-rel < 0.5")
    table = scaling_table(cells, solver=args.solver, dim=args.dim, delta_rel=args.delta_rel,
                          progress=lambda r: print(f"{r['ndof']:>9,} unknowns: total {r['time_total']:.2f} s, "
                                                   f"solver {r['time_linear']:.2f} s, peak {r['peak_memory_mb']:.0f} MB",
                                                   flush=True))
    (out / "scaling.json").write_text(json.dumps({"table": table, "exponents": fitted_exponents(table)}, indent=1))
    (out / "scaling.md").write_text(markdown(table) + "\n")
    scaling_figure(table, out / "scaling.png")
    print(markdown(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
