"""Every bad input gets exit code 2 and one line naming the value and what is allowed."""
import time
from pathlib import Path

import pytest

from studies.cli import main

ROOT = Path(__file__).resolve().parents[2]

SOLVE_CASES = [
    (["--angle", "nan"], "angle nan"),
    (["--angle", "inf"], "angle inf"),
    (["--angle", "-5"], "angle -5"),
    (["--angle", "360"], "angle 360"),
    (["--angle", "thirty"], "'thirty'"),
    (["--cell", "0"], "cell size 0"),
    (["--cell", "-1"], "cell size -1"),
    (["--cell", "nan"], "cell size nan"),
    (["--cell", "0.01"], "cell size 0.01"),
    (["--ppc", "0"], "ppc 0"),
    (["--ppc", "-2"], "ppc -2"),
    (["--ppc", "1.5"], "'1.5'"),
    (["--ppc", "17"], "ppc 17"),
    (["--delta-rel", "0"], "delta-rel 0"),
    (["--delta-rel=-1e-3"], "delta-rel -0.001"),
    (["--delta-rel", "2"], "delta-rel 2"),
    (["--delta-rel", "nan"], "delta-rel nan"),
    (["--nu", "0.5"], "nu=0.5"),
    (["--nu", "0.7"], "nu=0.7"),
    (["--nu", "-1"], "nu=-1"),
    (["--E", "0"], "E=0"),
    (["--E", "-5"], "E=-5"),
    (["--E", "nan"], "E=nan"),
    (["--offset", "1", "0"], "offset (1.0, 0.0)"),
    (["--offset", "0.2", "nan"], "offset (0.2, nan)"),
    (["--offset", "-0.1", "0"], "offset (-0.1, 0.0)"),
    (["--offset", "0.2"], "--offset"),
    (["--problem", "confined-blok"], "did you mean 'confined-block'"),
    (["--method", "ibn"], "did you mean 'ibm'"),
    (["--load", "0"], "load 0"),
    (["--load", "nan"], "load nan"),
    (["--beta0", "10"], "beta0 is not a parameter of method 'ibm'"),
    (["--frobnicate"], "--frobnicate"),
    (["--solver", "amgx"], "invalid choice: 'amgx'"),
    (["--problem-file", "/nonexistent/problem.toml"], "problem file /nonexistent/problem.toml cannot be read"),
    (["--problem-file", "/dev/null", "--kinematics", "large"], "problem file /dev/null: body: missing"),
    (["--kinematics", "large", "--band", "curved"], "band 'curved' is not allowed; allowed: auto, finite, linearised"),
    (["--band", "linearised"], "band 'linearised' is for method 'ibm' in the load steps"),
    (["--kinematics", "large", "--method", "penalty", "--band", "finite"], "band 'finite' is for method 'ibm'"),
    (["--dim", "3", "--kinematics", "large", "--problem", "column", "--method", "penalty", "--band", "finite"],
     "band 'finite' is for method 'ibm'; leave it 'auto' for 'penalty'"),
    (["--dim", "3", "--band", "linearised"], "band 'linearised' is for method 'ibm' in the load steps"),
    (["--dim", "3", "--kinematics", "large", "--problem", "column", "--band", "curved"],
     "band 'curved' is not allowed; allowed: auto, finite, linearised"),
    (["--dim", "4"], "--dim 4 is not allowed"),
    (["--tilt", "20"], "tilt 20 needs dim = 3"),
    (["--dim", "3", "--method", "nodal"], "method 'nodal' needs every essential face on a grid plane; face 0"),
    (["--dim", "3", "--method", "ibm-limit", "--kinematics", "large", "--problem", "column"],
     "method 'ibm-limit' refuses large kinematics in 3D"),
    (["--dim", "3", "--problem", "l-shape"], "problem 'l-shape' is not available with dim = 3"),
    (["--dim", "3", "--offset", "0.1", "0.2"], "--offset takes three numbers in 3D"),
    (["--dim", "3", "--kinematics", "large"], "problem 'confined-block' has no exact finite-strain solution in 3D"),
    (["--dim", "3", "--kinematics", "large", "--problem", "column", "--basis", "gmp"],
     "basis 'gmp' is not allowed; allowed: mpm, gimp"),
    (["--dim", "3", "--locking", "fbar"], "locking 'fbar' is not available with dim = 3"),
    (["--dim", "3", "--checkpoint", "ckpt"], "--checkpoint is for load steps (--kinematics large); a 3D small-strain"),
    (["--dim", "3", "--kinematics", "large", "--problem", "column", "--checkpoint", "/proc/ckpt"],
     "cannot write to output folder '/proc/ckpt'"),
    (["--dim", "3", "--kinematics", "large", "--problem", "column", "--locking", "fbar"],
     "locking 'fbar' needs --basis mpm (a cell's points share its nodes), not 'gimp'"),
    # method factors out of range ("-1e6" is a value, not an option)
    (["--method", "nitsche", "--gamma", "-1"], "gamma -1.0 is not allowed; it must be a number > 0"),
    (["--method", "nitsche", "--gamma", "0"], "gamma 0.0 is not allowed; it must be a number > 0"),
    (["--method", "nitsche", "--gamma", "-inf"], "gamma -inf is not allowed; it must be a number > 0"),
    (["--method", "penalty", "--beta0", "0"], "beta0 0.0 is not allowed; it must be a number > 0"),
    (["--method", "penalty", "--beta0", "-1e6"], "beta0 -1000000.0 is not allowed; it must be a number > 0"),
    (["--method", "penalty", "--beta0", "inf"], "beta0 inf is not allowed; it must be a number > 0"),
    (["--support-threshold", "0.7"], "support-threshold 0.7 is not allowed; it must be in [0, 0.5]"),
    # geometry, loading, material
    (["--height", "0"], "body height 0.0 is not allowed; it must be > 0"),
    (["--height", "nan"], "body height nan is not allowed; it must be > 0"),
    (["--width", "-5"], "body width -5.0 is not allowed; it must be > 0"),
    (["--load-type", "shear"], "load type 'shear' is not allowed; allowed: pressure, settlement"),
    (["--kinematics", "huge"], "kinematics 'huge' is not allowed; allowed: small, large"),
    (["--kinematics", "large", "--steps", "0"], "steps 0 is not allowed; it must be an integer from 1 to 10000"),
    (["--material", "rubber"], "material 'rubber' is not allowed; allowed: elastic, von-mises, j2"),
    (["--yield-stress", "5"], "yield-stress 5 is for --material von-mises (or j2), not material 'elastic'"),
    (["--footing", "bumpy"], "footing 'bumpy' is not allowed; allowed: smooth, rough"),
    # checkpoints the run cannot take (refused before the folder is made)
    (["--problem", "hill-cylinder", "--method", "fem", "--steps", "5", "--checkpoint", "/proc/ibm-ckpt"],
     "--checkpoint is not available for method 'fem'"),
    (["--problem", "ample-collapse", "--checkpoint", "/proc/ibm-ckpt"],
     "--checkpoint is not available for 'ample-collapse' yet"),
    # 3D: the options it does not take yet
    (["--dim", "3", "--material", "von-mises"], "material 'von-mises' is not available with dim = 3"),
    (["--dim", "3", "--problem-file", str(ROOT / "examples" / "bracket.toml")],
     "is not available with dim = 3 (problem files are 2D outlines)"),
    (["--dim", "3", "--kinematics", "huge"], "kinematics 'huge' is not allowed; allowed: small, large"),
    (["--dim", "3", "--kinematics", "large", "--problem", "column", "--vtk", "/proc/ibm-vtk"],
     "--vtk is not available with --dim 3 --kinematics large yet"),
]


@pytest.mark.parametrize("arguments,needle", SOLVE_CASES, ids=[" ".join(a) for a, _ in SOLVE_CASES])
def test_solve_rejects_bad_input_with_one_line(arguments, needle, capsys):
    try:
        code = main(["solve", *arguments])
    except SystemExit as stop:     # argparse's own errors
        code = stop.code
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], captured.err
    assert "Traceback" not in captured.err and captured.out == ""


RUN_CASES = [
    (["--scheduler", "tcp//host:8786"], "scheduler address 'tcp//host:8786' is not allowed; give it as "
                                        "SCHEME://HOST:PORT"),
    (["--scheduler", "tcp://127.0.0.1:notaport"], "scheduler address 'tcp://127.0.0.1:notaport' is not allowed"),
    (["--scheduler", "foo://127.0.0.1:8786"], "(scheme tcp, tls, ws, wss, ucx; port 1 to 65535)"),
    (["--scheduler", "127.0.0.1:99999"], "scheduler address '127.0.0.1:99999' is not allowed"),
    (["--scheduler", "tcp://127.0.0.1"], "scheduler address 'tcp://127.0.0.1' is not allowed"),
    (["--scheduler", ""], "scheduler address '' is not allowed"),
    (["--jobs", "0"], "jobs 0 is not allowed; it must be an integer >= 1"),
]


@pytest.mark.parametrize("arguments,needle", RUN_CASES, ids=[" ".join(a) for a, _ in RUN_CASES])
def test_run_rejects_bad_input_with_one_line(arguments, needle, tmp_path, capsys):
    """Refused before anything is written, and at once (dask would wait its timeout on some)."""
    spec = tmp_path / "tiny.toml"
    spec.write_text('title = "t"\n[[sweep]]\nname = "a"\nmethods = ["ibm"]\nangle = [90]\n')
    start = time.monotonic()
    code = main(["run", str(spec), "--out", str(tmp_path / "out"), "--quiet", *arguments])
    captured = capsys.readouterr()
    assert code == 2 and time.monotonic() - start < 5
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ibm-study: error: ") and needle in lines[0], captured.err
    assert "Traceback" not in captured.err and captured.out == ""
    assert not (tmp_path / "out").exists()


def test_enough_bad_inputs_are_walked_through():
    assert len(SOLVE_CASES) >= 25


@pytest.mark.parametrize("argv,message", [
    (["--method", "lagrange"], "AMG (conjugate gradients) needs a symmetric positive definite system"),
    (["--method", "penalty", "--cell", "5"], "AMG-preconditioned conjugate gradients stopped"),
])
def test_systems_amg_cannot_take_are_one_line_with_exit_3(capsys, argv, message):
    assert main(["solve", "--solver", "amg", "--angle", "30", *argv]) == 3
    err = capsys.readouterr().err
    assert message in err and "use --solver pardiso or superlu" in err and err.count("\n") == 1
