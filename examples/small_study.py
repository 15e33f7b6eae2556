"""
A study from Python: a spec (the same TOML as `ibm-study run`), its results table and report.
=============================================================================================

Two methods on the confined block at three angles, run on two worker processes, stored in OUT
(resumable: run it again and nothing is recomputed), with the HTML report at OUT/index.html.

    python examples/small_study.py [OUT]
"""
import sys

from studies.run.runner import read_results, run_study
from studies.run.spec import parse

SPEC = """
title = "Two methods, three angles"
description = "The confined block (linear exact solution) for the IBM and Nitsche."

[[sweep]]
name = "angles"
summary = "The confined block at 0, 45 and 90 degrees."
methods = ["ibm", "nitsche"]
angle = [0, 45, 90]
cell = 20
tables = ["method-angle"]
figures = ["error-vs-angle"]
"""


def main(out: str = "reports/small-study"):
    summary = run_study(parse(SPEC, "small_study.py"), out, jobs=2, progress=False)
    table = read_results(out)
    print(table.sort_values(["method", "angle"])[["method", "angle", "err_u", "err_sigma"]].to_string(index=False))
    return summary, table


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "reports/small-study")
