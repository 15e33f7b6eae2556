"""studies.run.allocator: the `ibm-study` command's process keeps freed memory for reuse (glibc)."""
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]

PROBE = """
import sys
import numpy as np
from studies.run.allocator import keep_freed_memory

def resident():
    return next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmRSS")) / 1024

taken = keep_freed_memory() if sys.argv[1] == "kept" else False
block = np.ones(50_000_000)          # 400 MB: above any mmap threshold
before = resident()
del block
print(taken, before - resident())
"""


@pytest.mark.skipif(not Path("/proc/self/status").exists() or sys.platform != "linux", reason="needs Linux's /proc")
def test_freed_memory_stays_mapped_for_reuse_only_when_asked():
    def freed(mode):
        out = subprocess.run([sys.executable, "-c", PROBE, mode], capture_output=True, text=True, check=True,
                             cwd=ROOT).stdout.split()
        return out[0] == "True", float(out[1])
    taken, returned = freed("kept")
    default_taken, default_returned = freed("default")
    assert not default_taken and default_returned > 350        # glibc unmaps a freed 400 MB block at once
    assert taken and returned < 5                              # kept: its pages stay for the next block


def test_the_console_command_sets_the_allocator():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["ibm-study"] == "studies.cli:entry"
