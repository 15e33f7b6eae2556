"""ibm-study: command-line entry point.

    ibm-study solve --problem confined-block --method ibm --angle 30 [--json]
    ibm-study seed  [--json]

Bad arguments exit with code 2 and one line naming the bad value and what is allowed.
"""
from __future__ import annotations

import argparse
import json
import sys

from ibm.geometry import InputError
from ibm.solve import SolveError
from studies.case import CaseSpec, run_case


class Parser(argparse.ArgumentParser):
    def error(self, message):   # one line, exit 2 (argparse prints usage too)
        self.exit(2, f"{self.prog}: error: {message}\n")


def _add_case_arguments(p: argparse.ArgumentParser) -> None:
    d = CaseSpec()
    p.add_argument("--problem", default=d.problem, help="problem name (default %(default)s)")
    p.add_argument("--method", default=d.method, help="boundary method (default %(default)s)")
    p.add_argument("--angle", type=float, default=d.angle, help="inclination in degrees, 90 = grid-aligned")
    p.add_argument("--cell", type=float, default=d.cell, help="grid cell size h (default %(default)s)")
    p.add_argument("--ppc", type=int, default=d.ppc, help="material points per cell per direction")
    p.add_argument("--delta-rel", type=float, default=None, help="IBM band width delta/h (default 1e-5)")
    p.add_argument("--beta0", type=float, default=None, help="penalty factor: beta = beta0 M / h")
    p.add_argument("--gamma", type=float, default=None, help="Nitsche factor: gamma M / h")
    p.add_argument("--offset", type=float, nargs=2, default=d.offset, metavar=("OX", "OY"),
                   help="base corner at (grid node + offset h), offset in [0, 1)^2")
    p.add_argument("--E", type=float, default=d.E, help="Young's modulus")
    p.add_argument("--nu", type=float, default=d.nu, help="Poisson's ratio")
    p.add_argument("--load", type=float, default=d.load, help="load scale (pressure p)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def spec_from(args) -> CaseSpec:
    parameters = {k: getattr(args, k) for k in ("delta_rel", "beta0", "gamma") if getattr(args, k) is not None}
    return CaseSpec(problem=args.problem, method=args.method, angle=args.angle, cell=args.cell,
                    ppc=args.ppc, offset=tuple(args.offset), E=args.E, nu=args.nu, load=args.load,
                    method_parameters=parameters)


def command_solve(args) -> int:
    record = run_case(spec_from(args))
    if args.json:
        print(json.dumps(record))
    else:
        width = max(map(len, record))
        for key, value in record.items():
            print(f"{key:<{width}}  {value:.6g}" if isinstance(value, float) else f"{key:<{width}}  {value}")
    return 0


def command_seed(args) -> int:
    from studies import seed
    if args.json:
        print(json.dumps({"seed": seed.seed_table(), "delta": seed.delta_sweep(), "offset": seed.offset_sweep()}))
    else:
        print(seed.report())
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = Parser(prog="ibm-study", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    solve = sub.add_parser("solve", help="solve one case and print its errors")
    _add_case_arguments(solve)
    solve.set_defaults(run=command_solve)
    seed = sub.add_parser("seed", help="reproduce the seed paper's validation table")
    seed.add_argument("--json", action="store_true")
    seed.set_defaults(run=command_seed)
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except InputError as error:
        print(f"ibm-study: error: {error}", file=sys.stderr)
        return 2
    except SolveError as error:
        print(f"ibm-study: solve failed: {error}", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
