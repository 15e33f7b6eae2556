"""ibm-study: command-line entry point.

    ibm-study solve --problem confined-block --method ibm --angle 30 [--json]
    ibm-study solve --problem column --kinematics large --steps 40 --checkpoint DIR   (resumable)
    ibm-study solve --problem ample-collapse --method nodal --cell 2 --json   (AMPLE-m's collapse)
    ibm-study seed  [--json]
    ibm-study compare [--json]
    ibm-study converge --problem manufactured --method ibm --angle 30 --levels 5 [--delta-law "c*h^2"] [--json]
    ibm-study run SPEC.toml [--out DIR] [--jobs N] [--scheduler ADDRESS]
    ibm-study report DIR

Bad arguments exit with code 2 and one line naming the bad value and what is allowed; so do
output folders that cannot be written. A run that fails on its way (a solve, a full disk, an
unreachable scheduler) exits with code 3 and one line; Ctrl-C or SIGTERM, in every subcommand,
with 130 and one line (solve --checkpoint names the checkpoint that keeps the finished steps).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import sys
from pathlib import Path

from baselines.registry import METHODS, method_parameters
from ibm.discretise.grid import Grid
from ibm.exceptions import InputError, RunError, SolveError
from ibm.solvers.backends import SOLVERS
from studies.problems import registry
from studies.problems.problem_file import load_problem_file
from studies.run import comparison, convergence, seed
from studies.run.allocator import keep_freed_memory
from studies.run.case import DIMS, CaseSpec, check_checkpoint, run_case, validate
from studies.run.identity import case_id
from studies.run.interrupts import terminate_as_interrupt
from studies.run.solid import write_vtk


class Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # "-1e6" and "-inf" are values too (argparse's own pattern takes only -1 and -.5 forms), so
        # "--beta0 -1e6" reaches the check that names it rather than "expected one argument"
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)(e[+-]?\d+)?$|^-(inf|nan)$", re.IGNORECASE)

    def error(self, message):   # one line, exit 2 (argparse prints usage too)
        self.exit(2, f"{self.prog}: error: {message}\n")


def problem_names() -> list[str]:
    """Every problem's name, in 2D and 3D (studies.problems.registry)."""
    return registry.names(None)


def catalogue() -> str:
    """The problems (2D, then 3D) and the boundary methods, a line each with its summary: the epilog of
    the commands that solve cases (argparse's %-formatting escaped)."""
    def block(title, items):
        width = max(len(name) for name, _ in items) + 2
        return [title] + [f"  {name.ljust(width)}{summary}" for name, summary in items]
    lines = [*block("problems (--problem):", [(n, registry.get(n, 2).summary) for n in registry.names(2)]),
             *block("problems with --dim 3:", [(n, registry.get(n, 3).summary) for n in registry.names(3)]),
             *block("boundary methods (--method):", [(n, m.summary) for n, m in METHODS.items()])]
    return "\n".join(lines).replace("%", "%%")


def _add_case_arguments(p: argparse.ArgumentParser) -> None:
    d = CaseSpec()
    p.add_argument("--problem", default=d.problem, help="problem: one of those listed below (default %(default)s)")
    p.add_argument("--problem-file", default=d.problem_file, metavar="FILE.toml",
                   help="a problem of your own (outline, material, loads, optional exact field): see docs/geometry.md")
    p.add_argument("--method", default=d.method, help="boundary method: one of those listed below (default %(default)s)")
    p.add_argument("--angle", type=float, default=d.angle, help="inclination in degrees, 90 = grid-aligned")
    p.add_argument("--cell", type=float, default=d.cell, help="grid cell size h (default %(default)s)")
    p.add_argument("--ppc", type=int, default=d.ppc, help="material points per cell per direction")
    for name, declarations in method_parameters().items():     # every method's declared parameters
        first = declarations[0]
        owners = [m.name for m in METHODS.values() if any(p is first or p.name == name for p in m.parameters)]
        p.add_argument(first.flag, type=float, default=None, metavar=first.symbol or "X",
                       help=f"{first.meaning}; {first.allowed}; default {first.default:g}"
                            + (f", {first.load_step_default:g} in the load steps" if first.load_step_default is not None
                               else "") + f" (methods: {', '.join(owners)}; a problem may set its own)")
    p.add_argument("--dim", type=int, default=2, help="2 (plane strain) or 3 (the box problems)")
    p.add_argument("--tilt", type=float, default=0.0, help="3D: tilt in degrees about the body's own xi axis")
    p.add_argument("--offset", type=float, nargs="+", default=d.offset, metavar="O",
                   help="base corner at (grid node + offset h): two numbers in [0, 1) in 2D, three in 3D")
    p.add_argument("--E", type=float, default=d.E, help="Young's modulus")
    p.add_argument("--nu", type=float, default=d.nu, help="Poisson's ratio")
    p.add_argument("--load", type=float, default=None,
                   help=f"load scale: pressure p (default {d.load:g}), or a settlement (problem hertz: 0.02 width)")
    p.add_argument("--load-type", default=None,
                   help="pressure (load is a stress) or settlement (load is a prescribed displacement); "
                        "default pressure, or the problem's only loading")
    p.add_argument("--width", type=float, default=d.width, help="body width along its base (default %(default)s)")
    p.add_argument("--height", type=float, default=d.height, help="body height (default %(default)s)")
    p.add_argument("--kinematics", default=d.kinematics,
                   help="small (one linear step) or large (load steps, updated Lagrangian, Hencky); default %(default)s")
    p.add_argument("--steps", type=int, default=d.steps, help="load steps (large kinematics; default %(default)s)")
    p.add_argument("--basis", default=d.basis, help="point basis of large kinematics: mpm or gimp (default %(default)s)")
    p.add_argument("--band", default=d.band,
                   help="the IBM's band in the load steps: finite, linearised (about the step start), or auto "
                        "(linearised in 3D, finite in 2D; default %(default)s)")
    p.add_argument("--locking", default=d.locking,
                   help="none, or fbar: B-bar, the cell's mean dilatation, at small strain (needs --basis mpm); "
                        "default %(default)s")
    p.add_argument("--footing", default=d.footing,
                   help="problem footing: smooth (slides: a roller), rough (fixed) or rigid (a rigid body in contact, "
                        "frictionless unless --friction or --adhesion); default %(default)s")
    p.add_argument("--material", default=d.material,
                   help="elastic, von-mises (also j2), mohr-coulomb or drucker-prager (matched to Mohr-Coulomb in "
                        "plane strain): load steps at small kinematics, on Hencky at large; default %(default)s")
    p.add_argument("--yield-stress", type=float, default=d.yield_stress, help="J2 yield stress (material von-mises)")
    p.add_argument("--hardening", type=float, default=d.hardening, help="J2 linear hardening modulus (material von-mises)")
    p.add_argument("--cohesion", type=float, default=d.cohesion, metavar="C",
                   help="cohesion (materials mohr-coulomb, drucker-prager)")
    p.add_argument("--friction-angle", type=float, default=d.friction_angle, metavar="PHI",
                   help="friction angle in degrees, in [0, 90) (materials mohr-coulomb, drucker-prager)")
    p.add_argument("--dilation-angle", type=float, default=d.dilation_angle, metavar="PSI",
                   help="dilation angle in degrees, in [0, PHI]; default: PHI (associated flow)")
    p.add_argument("--friction", type=float, default=d.friction, metavar="MU",
                   help="Coulomb friction coefficient of a contact wall (problem frictional-block); default 0: none")
    p.add_argument("--adhesion", type=float, default=d.adhesion, metavar="TAU",
                   help="Tresca bound of a contact wall, a stress (an undrained interface's adhesion); default 0: none")
    p.add_argument("--unit-weight", type=float, default=d.unit_weight, metavar="GAMMA",
                   help="the soil's weight per unit volume (problem passive-wall); default 0: weightless")
    p.add_argument("--surcharge", type=float, default=d.surcharge, metavar="Q0",
                   help="a pressure on the soil's free top beside the footing (problem footing); default 0: none")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def spec_from(args) -> CaseSpec:
    dim = args.dim
    if dim not in DIMS:
        raise InputError(f"--dim {dim} is not allowed; allowed: 2 or 3")
    parameters = {k: getattr(args, k) for k in method_parameters() if getattr(args, k) is not None}
    problem = args.problem
    if args.problem_file and dim == 2:   # a user's problem goes by the name its file gives
        problem = load_problem_file(args.problem_file).name
    load_type = args.load_type
    if load_type is None:      # the problem's own (an unknown problem is named by validate)
        known = registry.FROM_FILE[0] if args.problem_file and dim == 2 else registry.PROBLEMS.get((problem, dim))
        load_type = known.default_load_type() if known is not None else "pressure"
    load = args.load
    if load is None:          # the problem's own, where it has one
        known = registry.FROM_FILE[0] if args.problem_file and dim == 2 else registry.PROBLEMS.get((problem, dim))
        load = known.default_load(args.width, args.height) if known is not None else None
        load = CaseSpec.load if load is None else load
    spec = CaseSpec(problem=problem, method=args.method, angle=args.angle, cell=args.cell,
                    ppc=args.ppc, offset=tuple(args.offset), E=args.E, nu=args.nu, load=load,
                    load_type=load_type, width=args.width, height=args.height,
                    kinematics=args.kinematics, steps=args.steps, basis=args.basis, band=args.band, material=args.material,
                    locking=args.locking, footing=args.footing,
                    yield_stress=args.yield_stress, hardening=args.hardening, cohesion=args.cohesion,
                    friction_angle=args.friction_angle, dilation_angle=args.dilation_angle, friction=args.friction,
                    adhesion=args.adhesion, unit_weight=args.unit_weight, surcharge=args.surcharge,
                    problem_file=args.problem_file,
                    dim=dim, tilt=args.tilt, method_parameters=parameters)
    if len(spec.offset) != dim:          # CaseSpec reads the 2D default offset as the 3D one
        raise InputError(f"--offset takes {'two' if dim == 2 else 'three'} numbers in {dim}D "
                         f"({'ox oy' if dim == 2 else 'ox oy oz'}); got {len(args.offset)}")
    return spec


def checkpoint_file(spec: CaseSpec, folder) -> "Path":
    """The checkpoint of `spec` in `folder` (created): FOLDER/<case id>.npz. The case id hashes the
    settings and the code (studies.run.identity.case_id), so other code never resumes from it."""
    from studies.run.store import output_folder
    validate(spec)
    check_checkpoint(spec)
    return output_folder(folder) / f"{case_id(spec)}.npz"


def _kept(checkpoint) -> str:
    """What the interrupted line adds for a solve: the checkpoint that keeps the finished steps."""
    if checkpoint is None:
        return ""
    return f"; checkpoint {str(checkpoint)!r} keeps the finished load steps, run the same command again to resume"


def _print(record: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(record))
        return
    width = max(map(len, record))
    for key, value in record.items():
        if key == "history":
            continue
        print(f"{key:<{width}}  {value:.6g}" if isinstance(value, float) else f"{key:<{width}}  {value}")


@contextlib.contextmanager
def results_only_on_stdout():
    """While a case runs, what native libraries print on the process's standard output (LAPACK's "illegal
    value" notes from a step that fails and is cut) goes to standard error, so that standard output holds
    the result alone (--json)."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:                      # no standard output to keep apart
        yield
        return
    try:
        os.dup2(2, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def command_solve(args) -> int:
    spec = spec_from(args)
    if args.vtk:    # before solving, not after
        from studies.run.store import output_folder
        validate(spec)
        refusal = registry.problem_of(spec).fields_refusal(spec)
        if refusal:
            raise InputError(refusal)
        output_folder(args.vtk)
    checkpoint = checkpoint_file(spec, args.checkpoint) if args.checkpoint else None
    resumed = checkpoint is not None and checkpoint.exists()
    args.kept = _kept(checkpoint)
    # load steps as a progress bar only for a person at a terminal (never with --json)
    show = args.kinematics == "large" and not args.json and sys.stderr.isatty()
    with results_only_on_stdout():
        record = run_case(spec, keep_fields=bool(args.vtk), solver=args.solver, progress=show, checkpoint=checkpoint)
    if checkpoint is not None:
        print(f"ibm-study: {'resumed from' if resumed else 'saved every step to'} checkpoint {str(checkpoint)!r}",
              file=sys.stderr)
    if args.vtk:
        paths = _write_vtk(spec, record.pop("fields"), args.vtk)
        if spec.dim == 3:
            record["vtk"] = [str(p) for p in paths]
        else:
            print(f"VTK files: {', '.join(str(p) for p in paths)}", file=sys.stderr)
    _print(record, args.json)
    return 0


def _write_vtk(spec: CaseSpec, fields: dict, folder: str) -> list:
    """The case's ParaView files in `folder` (studies.report.vtk in 2D, studies.run.solid.write_vtk in 3D)."""
    if spec.dim == 3:
        grid = Grid(float(fields["grid_h"]), tuple(int(v) for v in fields["grid_lower"]),
                    tuple(int(v) for v in fields["grid_shape"]))
        stem = f"{spec.problem}_{spec.method}_angle{spec.angle:g}_tilt{spec.tilt:g}_h{spec.cell:g}"
        return write_vtk(folder, stem, grid, fields)
    from studies.report import vtk
    from studies.run.runner import point_fields
    stem = f"{spec.problem}_{spec.method}_angle{spec.angle:g}_h{spec.cell:g}"
    return vtk.write_case(point_fields(fields), folder, stem)


def command_compare(args) -> int:
    if args.json:
        print(json.dumps({"compare": comparison.comparison_table()}))
    else:
        print(comparison.report())
    return 0


def command_seed(args) -> int:
    if args.json:
        print(json.dumps({"seed": seed.seed_table(), "delta": seed.delta_sweep(), "offset": seed.offset_sweep()}))
    else:
        print(seed.report())
    return 0


def command_run(args) -> int:

    from studies.run.runner import run_study
    out = args.out or str(Path("reports") / Path(args.spec).stem)
    args.kept = "; finished cases are stored, run again to resume"     # when stopped outside the cases' loop
    summary = run_study(args.spec, out, jobs=args.jobs, scheduler=args.scheduler,
                        progress=not args.quiet, retry_failed=args.retry_failed, report=not args.no_report)
    return 130 if summary.interrupted else 0


def command_report(args) -> int:
    from studies.report.page import write_report
    print(write_report(args.directory))
    return 0


def command_results_page(args) -> int:
    from studies.report.results_page import write_results_page
    print(write_results_page(args.directory, args.out))
    return 0


def command_converge(args) -> int:
    with results_only_on_stdout():
        result = convergence.converge(spec_from(args), args.levels, args.delta_law, coarse=args.cell)
    print(json.dumps(result) if args.json else convergence.table(result))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = Parser(prog="ibm-study", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    solve = sub.add_parser("solve", help="solve one case and print its errors", epilog=catalogue(),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(solve)
    solve.add_argument("--vtk", metavar="DIR", default=None,
                       help="also write the points, grid and body as VTK files (ParaView) into DIR")
    solve.add_argument("--checkpoint", metavar="DIR", default=None,
                       help="(load steps: large kinematics, von Mises, the collapse problems) save every "
                            "converged load step to DIR/<case id>.npz; "
                            "the same command resumes a killed run from it, with the same result")
    solve.add_argument("--solver", default="auto", choices=SOLVERS,
                       help="linear solver: auto (PARDISO where installed, else SuperLU), pardiso, superlu, or amg "
                            "(CG with smoothed-aggregation multigrid, pyamg; SPD systems)")
    solve.set_defaults(run=command_solve)
    run = sub.add_parser("run", help="run a study spec (TOML), store results, write the HTML report")
    run.add_argument("spec", help="study spec, e.g. studies/specs/paper.toml")
    run.add_argument("--out", default=None, help="output folder (default reports/<spec name>)")
    run.add_argument("--jobs", type=int, default=None, help="worker processes (default: number of CPUs)")
    run.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="run the cases on this dask.distributed scheduler instead (e.g. tcp://host:8786)")
    run.add_argument("--retry-failed", action="store_true", help="run again the cases stored as failed")
    run.add_argument("--no-report", action="store_true", help="do not write the HTML report at the end")
    run.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    run.set_defaults(run=command_run)
    report = sub.add_parser("report", help="(re)write DIR/index.html from a study's stored results")
    report.add_argument("directory", help="output folder of `ibm-study run`")
    report.set_defaults(run=command_report)
    results_page = sub.add_parser("results-page", help="write a documentation page (Markdown) of a study's verdict "
                                  "and tables from its stored results")
    results_page.add_argument("directory", help="output folder of `ibm-study run`")
    results_page.add_argument("--out", required=True, metavar="PAGE",
                              help="the page to write, e.g. docs/results/paper.md")
    results_page.set_defaults(run=command_results_page)
    seed = sub.add_parser("seed", help="reproduce the seed paper's validation table")
    seed.add_argument("--json", action="store_true")
    seed.set_defaults(run=command_seed)
    compare = sub.add_parser("compare", help="every boundary method on the seed's cases (90, 45, 30 degrees)")
    compare.add_argument("--json", action="store_true")
    compare.set_defaults(run=command_compare)
    converge = sub.add_parser("converge", help="refine h by halving and fit convergence rates", epilog=catalogue(),
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(converge)
    converge.set_defaults(problem="manufactured", ppc=2, cell=None, run=command_converge)
    for action in converge._actions:
        if action.dest == "cell":
            action.help = "coarsest cell size, halved at each level (default size / 10)"
        if action.dest == "ppc":
            action.help = "material points per cell per direction (default 2: one point per cell leaves hourglass modes)"
    converge.add_argument("--levels", type=int, default=5, help="number of cell sizes (default %(default)s)")
    converge.add_argument("--delta-law", default=None,
                          help='band width law "c*h" or "c*h^2" (c a number, or c = delta/h at the coarsest level)')
    args = parser.parse_args(argv)
    try:
        with terminate_as_interrupt():
            return args.run(args)
    except KeyboardInterrupt as stop:    # Ctrl-C, or SIGTERM (terminate_as_interrupt)
        by = f" by {stop}" if str(stop) else ""
        print(f"ibm-study: interrupted{by}{getattr(args, 'kept', '')}", file=sys.stderr)
        return 130
    except InputError as error:
        print(f"ibm-study: error: {error}", file=sys.stderr)
        return 2
    except SolveError as error:
        print(f"ibm-study: {'run' if isinstance(error, RunError) else 'solve'} failed: {error}", file=sys.stderr)
        return 3
    except OSError as error:    # any other file or network fault: one line too
        from studies.run.store import reason
        where = f": {error.filename!r}" if error.filename else ""
        print(f"ibm-study: failed: {reason(error)}{where}", file=sys.stderr)
        return 3


def entry() -> int:
    """The console command `ibm-study`: main() in a process whose allocator keeps freed memory for
    reuse (studies.run.allocator)."""
    keep_freed_memory()
    return main()


if __name__ == "__main__":
    sys.exit(entry())
