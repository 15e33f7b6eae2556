"""The CLI's standard output holds its result alone: what a native library prints on file descriptor 1
while a case runs (LAPACK's "illegal value" notes from a failing step) goes to standard error."""
import json
import subprocess
import sys

SCRIPT = """
import json, os
from studies.cli import results_only_on_stdout
with results_only_on_stdout():
    os.write(1, b" ** On entry to DTRSV  parameter number  6 had an illegal value\\n")   # as native code does
    print("a Python print inside goes there too")
print(json.dumps({"q_over_c": 27.99}))
"""


def test_native_notes_go_to_stderr_and_stdout_is_the_json():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120, check=True)
    assert json.loads(done.stdout) == {"q_over_c": 27.99}
    assert "DTRSV" in done.stderr and "a Python print inside" in done.stderr
