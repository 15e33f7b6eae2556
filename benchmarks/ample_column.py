"""Side by side with the peer: AMPLE-m's self-weight column and ours, timed as whole commands.

    python -m benchmarks.ample_column [--ample-script SCRIPT] [--cells 16 32 64] [--repeat 3]

Ours is `ibm-study solve --problem column ... --method nodal --json` (docs/large-deformation.md),
timed from process start to exit, best of --repeat runs. With --ample-script (a runner that
takes NELSY LSTPS MPTYPE and prints AMPLE-m's JSON line, needing Octave and AMPLE_GIT set to
a copy of wmcoombs/AMPLE-m) the peer runs too, once per size, also timed as a whole command;
without it the peer's recorded figures (studies.report.peer) are shown. Prints a Markdown table and
writes reports/benchmarks/ample_column.json.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.common import ibm_study
from studies.report.peer import AMPLE_COLUMN


def ours(cells: int, repeat: int) -> dict:
    h = 50 / cells
    command = [*ibm_study(), "solve", "--problem", "column", "--kinematics", "large",
               "--basis", "gimp", "--steps", "40", "--E", "1e4", "--nu", "0", "--load", "40000",
               "--width", f"{h}", "--height", "50", "--cell", f"{h}", "--ppc", "2", "--angle", "90",
               "--offset", "0", "0", "--method", "nodal", "--json"]
    best, record = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
        best = min(best, time.perf_counter() - start)
        record = json.loads(out)
    return {"err_sigma_ample": record["err_sigma_ample"], "process_s": best, "time_s": record["time_s"]}


def ample(script: str, cells: int) -> dict:
    start = time.perf_counter()
    out = subprocess.run(["bash", script, str(cells), "40", "2"], check=True, capture_output=True, text=True).stdout
    elapsed = time.perf_counter() - start
    line = json.loads(out.strip().splitlines()[-1])
    return {"err_sigma_ample": line["err_sigma"], "process_s": elapsed, "time_s": line["time_s"]}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ample-script", default=None)
    parser.add_argument("--cells", type=int, nargs="+", default=[16, 32, 64])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", default="reports/benchmarks/ample_column.json")
    args = parser.parse_args(argv)
    rows = []
    for cells in args.cells:
        peer = ample(args.ample_script, cells) if args.ample_script else dict(AMPLE_COLUMN["gimp"][cells])
        peer["measured_now"] = bool(args.ample_script)
        mine = ours(cells, args.repeat)
        rows.append({"cells": cells, "ample": peer, "ours": mine,
                     "speed_up_process": peer["process_s"] / mine["process_s"],
                     "speed_up_loop": peer["time_s"] / mine["time_s"]})
    print("| cells | AMPLE-m err | ours err | AMPLE-m command (s) | ours command (s) | speed-up | "
          "AMPLE-m loop (s) | ours case (s) | speed-up |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        a, o = r["ample"], r["ours"]
        print(f"| {r['cells']} | {a['err_sigma_ample']:.6e} | {o['err_sigma_ample']:.6e} | {a['process_s']:.2f} | "
              f"{o['process_s']:.2f} | {r['speed_up_process']:.0f}x | {a['time_s']:.2f} | {o['time_s']:.3f} | "
              f"{r['speed_up_loop']:.0f}x |")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
