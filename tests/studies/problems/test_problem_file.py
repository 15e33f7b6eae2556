"""Problems users define in a TOML file: parsing, checks, placement, derived loads, the fem reference."""
import json
from pathlib import Path

import numpy as np
import pytest

from ibm.exceptions import InputError
from studies.run.case import CaseSpec, run_case
from studies.cli import main
from studies.problems.problem_file import load_problem_file

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"

LINEAR = """
name = "notched-linear"
[body]
start = [10.0, 5.0]
pieces = [
  {to = [40.0, 5.0], kind = "traction"},
  {to = [80.0, 5.0], kind = "fixed"},
  {to = [110.0, 5.0], kind = "traction"},
  {to = [110.0, 105.0], kind = "traction"},
  {to = [60.0, 105.0], kind = "traction"},
  {to = [60.0, 65.0], kind = "traction"},
  {to = [10.0, 65.0], kind = "traction"},
  {to = [10.0, 5.0], kind = "traction"},
]
[material]
E = 2e4
nu = 0.25
[exact]
u = ["2e-3 * (y - 5)", "-1e-3 * (y - 5)"]
"""


def write(tmp_path, text: str, name: str = "problem.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("method", ["nitsche", "lagrange", "fem"])
@pytest.mark.parametrize("angle,offset", [(90.0, (0.0, 0.0)), (30.0, (0.37, 0.29)), (71.3, (0.52, 0.88))])
def test_linear_exact_field_on_a_non_convex_user_body_is_reproduced(tmp_path, method, angle, offset):
    path = write(tmp_path, LINEAR)
    record = run_case(CaseSpec(problem_file=str(path), method=method, angle=angle, offset=offset, cell=10.0, ppc=2))
    assert record["problem"] == "notched-linear" and record["reference"] == "exact"
    assert (record["E"], record["nu"]) == (2e4, 0.25)                     # the file's material
    assert record["err_u"] < 1e-9 and record["err_sigma"] < 1e-8 and record["err_l2"] < 1e-9


def test_inhomogeneous_essential_data_come_from_the_exact_field_through_a_bubble_lift(tmp_path):
    text = LINEAR.replace('u = ["2e-3 * (y - 5)", "-1e-3 * (y - 5)"]',
                          'u = ["1e-3 * sin(pi * x / 100) + 2e-4 * y", "5e-4 * cos(pi * y / 100)"]')
    from studies.problems.file_placement import place_file
    from ibm.models.elastic import Elastic
    instance = place_file(load_problem_file(write(tmp_path, text)), Elastic(1e4, 0.3), 30.0, (0.37, 0.29), 10.0)
    k = instance.body.essential_edges[0]
    x = instance.body.starts[k] + np.linspace(0, 1, 9)[:, None] * instance.body.tangents[k]
    u_a, _ = instance.loads.lift(x)
    assert np.abs(u_a - instance.exact(x)[0]).max() < 1e-15          # the data on the fixed piece
    inside = np.array([[60.0, 40.0]]) @ instance.frame.T
    assert np.abs(instance.loads.lift(inside)[0] - instance.exact(inside)[0]).max() > 1e-5   # not the field itself
    # and the lift's gradient is its derivative
    eps = 1e-6
    for j in range(2):
        e = np.zeros(2)
        e[j] = eps
        fd = (instance.loads.lift(inside + e)[0] - instance.loads.lift(inside - e)[0]) / (2 * eps)
        assert instance.loads.lift(inside)[1][0, :, j] == pytest.approx(fd[0], rel=1e-6, abs=1e-12)
    levels = [run_case(CaseSpec(problem_file=str(write(tmp_path, text)), method="nitsche", angle=30.0, cell=h,
                                ppc=2)) for h in (20.0, 10.0, 5.0)]
    l2 = [r["err_l2"] for r in levels]
    assert np.polyfit(np.log([20, 10, 5]), np.log(l2), 1)[0] > 1.8


PATCH = EXAMPLES / "patch_test.toml"


@pytest.mark.parametrize("method", ["ibm", "ibm-limit", "nitsche", "lagrange", "fem"])
@pytest.mark.parametrize("angle,offset", [(30.0, (0.37, 0.29)), (71.3, (0.52, 0.88))])
def test_with_the_exact_lift_a_linear_field_is_a_patch_test_every_consistent_method_passes(method, angle, offset):
    """examples/patch_test.toml: a linear field with non-zero data on a fixed side and a roller base of an
    L-shape, lift = "exact": u^h = 0 is the discrete solution, so the field is reproduced to round-off."""
    record = run_case(CaseSpec(problem_file=str(PATCH), method=method, angle=angle, offset=offset, cell=5.0, ppc=2))
    assert record["reference"] == "exact"
    assert record["err_u"] < 1e-12 and record["err_sigma"] < 1e-12 and record["err_l2"] < 1e-12


def test_with_the_bubble_lift_the_same_linear_field_is_no_patch_test(tmp_path):
    """The default lift leaves beta u, which is not linear: neither the IBM nor fem reproduces the field."""
    text = PATCH.read_text().replace('lift = "exact"', 'lift = "bubble"')
    path = write(tmp_path, text)
    for method, floor in (("ibm", 1e-3), ("fem", 1e-4)):
        record = run_case(CaseSpec(problem_file=str(path), method=method, angle=30.0, cell=5.0, ppc=2))
        assert record["err_sigma"] > floor


def test_without_an_exact_field_errors_are_against_a_converged_fem_reference():
    record = run_case(CaseSpec(problem_file=str(EXAMPLES / "bracket.toml"), method="nitsche", angle=30.0,
                               cell=10.0, ppc=2))
    assert record["reference"] == "fem" and record["reference_converged"]
    assert record["reference_err_l2"] * 10 <= record["err_l2"]
    assert record["reference_err_energy"] * 10 <= record["err_energy"]
    assert 1e-4 < record["err_l2"] < 0.2


def test_problem_file_through_the_cli(capsys):
    code = main(["solve", "--problem-file", str(EXAMPLES / "notched_patch.toml"), "--method", "lagrange",
                 "--angle", "30", "--offset", "0.2", "0.7", "--cell", "10", "--json"])
    assert code == 0
    record = json.loads(capsys.readouterr().out)
    assert record["problem"] == "notched-patch" and record["reference"] == "exact"
    assert record["problem_file"].endswith("notched_patch.toml") and 1e-3 < record["err_l2"] < 0.15


PIECES = '''[body]
start = [0.0, 0.0]
pieces = [{to = [100.0, 0.0], kind = "fixed"}, {to = [100.0, 100.0], kind = "traction"},
          {to = [0.0, 100.0], kind = "free"}, {to = [0.0, 0.0], kind = "roller"}]
'''


@pytest.mark.parametrize("text,message", [
    ("nmae = 'x'\n" + PIECES, "top level: unknown key 'nmae' (did you mean 'name'?)"),
    ("[body]\nstart = [0, 0]\n", "body.pieces: give a list of at least three pieces"),
    (PIECES.replace('"fixed"', '"fixd"'), "body.pieces[0].kind: 'fixd' is not one of roller, fixed, traction, "
                                           "free (did you mean 'fixed'?)"),
    (PIECES.replace("to = [0.0, 0.0]", "to = [0.0, 5.0]"), "the outline must close"),
    (PIECES.replace("{to = [100.0, 100.0]", "{to = [0.0, 100.0]").replace("{to = [0.0, 100.0], kind = \"free\"}",
                                                                      "{to = [100.0, 100.0], kind = \"free\"}"),
     "body: the outline intersects itself"),
    (PIECES.replace("kind = \"roller\"}", "kind = \"roller\", centre = [0, 0]}"),
     "body.pieces[3]: unknown key 'centre' (did you mean 'center'?)"),
    (PIECES + "[loads]\nbody_force = ['0', '-z']\n", "loads.body_force: '-z' names z; only x and y are allowed"),
    (PIECES + "[loads]\nbody_force = ['0', '-(x']\n", "loads.body_force: '-(x' does not parse"),
    (PIECES + "[loads]\ntraction = {0 = ['1', '0']}\n", "loads.traction.0: piece 0 is 'fixed'; traction is for "
                                                         "traction pieces"),
    (PIECES + "[loads]\ntraction = {7 = ['1', '0']}\n", "loads.traction.7: piece index '7' is not one of 0 .. 3"),
    (PIECES + "[loads]\ndisplacement = {1 = ['1', '0']}\n", "piece 1 is 'traction'; displacement is for roller or "
                                                           "fixed pieces"),
    (PIECES + "[material]\nE = -1\nnu = 0.3\n", "material: Young's modulus E=-1.0 is not allowed"),
    (PIECES + "[exact]\nu = ['0', 'x']\n", "piece 3 is a roller, but the field's tangential traction"),
    (PIECES + "[exact]\nu = ['x', '0']\nlift = 'exakt'\n", "exact.lift: 'exakt' is not one of bubble, exact "
                                                            "(did you mean 'exact'?)"),
    ("name = [", "not valid TOML"),
])
def test_bad_problem_files_are_named_in_one_line(tmp_path, capsys, text, message):
    path = write(tmp_path, text)
    code = main(["solve", "--problem-file", str(path), "--json"])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1 and str(path) in err


def test_a_missing_problem_file_is_one_line(tmp_path, capsys):
    assert main(["solve", "--problem-file", str(tmp_path / "none.toml")]) == 2
    err = capsys.readouterr().err
    assert "cannot be read" in err and err.count("\n") == 1


def test_the_case_id_follows_the_file_content(tmp_path):
    from studies.run.identity import case_id
    path = write(tmp_path, LINEAR)
    spec = CaseSpec(problem_file=str(path))
    first = case_id(spec)
    path.write_text(LINEAR.replace("2e-3", "3e-3"))
    assert case_id(spec) != first
    with pytest.raises(InputError):
        load_problem_file(tmp_path / "missing.toml")


def test_a_spec_sweeps_problem_files_named_beside_it(tmp_path):
    from studies.report.page import write_report
    from studies.run.runner import run_study
    from studies.run.store import read_results
    folder = tmp_path / "specs"
    folder.mkdir()
    write(folder, LINEAR, "linear.toml")
    (folder / "user.toml").write_text('[[sweep]]\nname = "user"\nproblem_file = ["linear.toml", "'
                                      + str(EXAMPLES / "notched_patch.toml") + '"]\nmethods = ["nitsche"]\n'
                                      'angle = [90, 30]\nppc = 2\ntables = ["method-angle"]\n')
    out = tmp_path / "out"
    run_study(folder / "user.toml", out, jobs=1, progress=False, report=False)
    results = read_results(out)
    assert sorted(set(results["problem"])) == ["notched-linear", "notched-patch"]
    assert (results["status"] == "ok").all() and results.loc[results["problem"] == "notched-linear", "err_u"].max() < 1e-9
    assert write_report(out).exists()                 # the report resolves the files as the run did


def test_a_missing_problem_file_in_a_spec_is_one_line(tmp_path):
    from studies.run.spec import load
    (tmp_path / "user.toml").write_text('[[sweep]]\nname = "user"\nproblem_file = "nowhere.toml"\n')
    with pytest.raises(InputError, match="sweep 'user': problem file .*nowhere.toml cannot be read"):
        load(tmp_path / "user.toml")


def test_problem_file_sweeps_give_the_same_table_whatever_the_number_of_workers(tmp_path):
    from tests.studies.run.test_runner import same_table_with_one_and_two_workers
    one = same_table_with_one_and_two_workers(
        '[[sweep]]\nname = "user"\nproblem_file = ["' + str(EXAMPLES / "bracket.toml") + '", "'
        + str(EXAMPLES / "notched_patch.toml") + '"]\nmethods = ["ibm", "nitsche", "lagrange"]\n'
        'angle = [90, 30]\nppc = 2\n', tmp_path)
    assert len(one) == 12 and (one["status"] == "ok").all()


def test_a_problem_file_is_labelled_by_its_name_in_the_report():
    """Error-map panels name a problem file by its name, not by the folder the spec was run from."""
    from studies.run.case import CaseSpec
    from studies.report.sweep_figures import _value
    case = CaseSpec(problem_file="/far/away/examples/bracket.toml")
    assert _value(case, "problem_file") == "bracket.toml"
    assert _value(CaseSpec(), "problem_file") == "-"
