"""Study specs: expansion of sweeps into cases, case identity, and one-line errors for bad specs."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from ibm.exceptions import InputError
from studies.run.case import CaseSpec
from studies.run.identity import case_id
from studies.run.spec import load, parse

SPECS = Path(__file__).resolve().parents[3] / "studies" / "specs"


def spec(body: str) -> str:
    return textwrap.dedent(body)


GOOD = spec("""
    title = "t"
    [base]
    cell = 20.0
    [[sweep]]
    name = "a"
    angle = [0, 30]
    delta_rel = [1e-3, 1e-5]
    """)


def test_sweep_is_the_product_of_its_axes():
    study = parse(GOOD)
    cases = study.sweeps[0].cases
    assert len(cases) == 4
    assert [(c.angle, c.method_parameters["delta_rel"]) for c in cases] == [
        (0.0, 1e-3), (0.0, 1e-5), (30.0, 1e-3), (30.0, 1e-5)]
    assert all(c.cell == 20.0 and c.method == "ibm" for c in cases)
    assert study.sweeps[0].axes["angle"] == (0.0, 30.0)


def test_large_deformation_keys_sweep():
    study = parse(spec("""
        [[sweep]]
        name = "column"
        problems = ["column"]
        methods = ["nodal"]
        kinematics = "large"
        steps = [10, 40]
        basis = ["mpm", "gimp"]
        width = 3.125
        height = [50, 25]
        """))
    cases = study.sweeps[0].cases
    assert len(cases) == 8 and all(c.kinematics == "large" and c.width == 3.125 for c in cases)
    assert {(c.steps, c.basis, c.height) for c in cases} == {
        (s, b, h) for s in (10, 40) for b in ("mpm", "gimp") for h in (50.0, 25.0)}
    assert len({case_id(c) for c in cases}) == 8


def test_ranges_laws_and_random_offsets():
    study = parse(spec("""
        [[sweep]]
        name = "r"
        angle = {from = 0, to = 90, step = 15}
        cell = {from = 40, to = 5, count = 4, spacing = "log"}
        delta_law = {coefficient = 1e-3, power = 2}
        random_offsets = {count = 5, seed = 3}
        """))
    sweep = study.sweeps[0]
    assert sweep.axes["angle"] == (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0)
    assert sweep.axes["cell"] == (40.0, 20.0, 10.0, 5.0)
    assert len(sweep.cases) == 7 * 4 * 5
    for case in sweep.cases:   # delta = 1e-3 h^2  ->  delta_rel = 1e-3 h
        assert case.method_parameters["delta_rel"] == pytest.approx(1e-3 * case.cell, rel=1e-12)
    offsets = np.array(sweep.axes["offset"])
    assert offsets.shape == (5, 2) and np.all((offsets >= 0) & (offsets < 1))
    again = parse(spec("""
        [[sweep]]
        name = "r"
        random_offsets = {count = 5, seed = 3}
        """)).sweeps[0].axes["offset"]
    assert again == sweep.axes["offset"]      # the seed fixes the placements


def test_case_identity():
    a = CaseSpec(angle=30.0, method_parameters={"delta_rel": 1e-5})
    assert case_id(a) == case_id(CaseSpec(angle=30, method_parameters={"delta_rel": 1e-5}))
    assert case_id(a) != case_id(a.with_(angle=30.000001))
    assert case_id(a) != case_id(a.with_(method_parameters={"delta_rel": 1e-4}))
    # an explicit default and an omitted one give the same case
    explicit = parse(GOOD.replace("[base]", "[base]\nnu = 0.3\n")).cases()
    assert [case_id(c) for c in explicit] == [case_id(c) for c in parse(GOOD).cases()]


def test_cases_shared_by_sweeps_run_once():
    study = parse(GOOD + spec("""
        [[sweep]]
        name = "b"
        angle = 30
        delta_rel = 1e-5
        """))
    assert len(study.sweeps[1].cases) == 1 and len(study.cases()) == 4


def test_checked_in_specs_load():
    smoke, paper = load(SPECS / "smoke.toml"), load(SPECS / "paper.toml")
    assert 10 <= len(smoke.cases()) <= 60
    assert len(paper.cases()) > len(smoke.cases())
    assert {"seed"} <= {t for s in paper.sweeps for t in s.tables}


def test_three_d_sweeps_expand_with_their_own_methods_offsets_and_orientations():
    from studies.problems.box_fields import BOXES
    from baselines.registry import in_3d
    from studies.run.identity import case_settings
    METHODS_3D = tuple(in_3d())
    study = parse(spec("""
        [[sweep]]
        name = "solid"
        dim = 3
        methods = "all"
        problems = "all"
        orientation = [[90, 0], [30, 20], [30, 20]]
        cell = 25
        [[sweep]]
        name = "tilts"
        dim = 3
        angle = 30
        tilt = [0, 20, 40]
        random_offsets = {count = 2, seed = 5}
        """))
    solid, tilts = study.sweeps
    assert solid.axes["method"] == METHODS_3D and solid.axes["problem"] == tuple(BOXES)
    assert solid.axes["orientation"] == ((90.0, 0.0), (30.0, 20.0))
    assert len(solid.cases) == len(METHODS_3D) * len(BOXES) * 2
    assert {c.offset for c in solid.cases} == {(0.37, 0.29, 0.11)} and {c.dim for c in solid.cases} == {3}
    assert [(c.angle, c.tilt) for c in solid.cases[:2]] == [(90.0, 0.0), (30.0, 20.0)]
    assert len(tilts.cases) == 3 * 2 and all(len(c.offset) == 3 for c in tilts.cases)
    assert tilts.axes["tilt"] == (0.0, 20.0, 40.0) and len({case_id(c) for c in tilts.cases}) == 6
    # a 3D case's id holds dim and tilt; a 2D case's settings are the ones from before 3D
    three = solid.cases[0]
    assert case_settings(three)["dim"] == 3 and case_settings(three)["tilt"] == 0.0
    assert case_id(three) != case_id(three.with_(tilt=1e-9))
    assert not {"dim", "tilt", "solver"} & set(case_settings(CaseSpec()))
    assert case_settings(CaseSpec(solver="amg"))["solver"] == "amg"
    assert CaseSpec(dim=3).offset == (0.37, 0.29, 0.11) and CaseSpec(dim=3, offset=(0.5, 0.5)).offset == (0.5, 0.5)


def collapse_sweep(**keys) -> str:
    """A sweep of a collapse problem with the settings it needs, `keys` added or replacing them."""
    import json
    settings = {"name": "c", "methods": ["lagrange"], "cell": 40, "steps": 20, "ppc": 2, "basis": "mpm",
                "locking": "fbar", **keys}
    return "[[sweep]]\n" + "".join(f"{key} = {json.dumps(value)}\n" for key, value in settings.items())


BAD = [   # (spec text, words the one-line message must contain)
    ("[[sweep]]\nname = 'a'\nangel = 30\n", ["angel", "did you mean 'angle'"]),
    ("titel = 'x'\n[[sweep]]\nname = 'a'\n", ["titel", "title"]),
    ("[base]\nnu = 'soft'\n[[sweep]]\nname = 'a'\n", ["base.nu", "number"]),
    ("[base]\nppc = 1.5\n[[sweep]]\nname = 'a'\n", ["base.ppc", "integer"]),
    ("[base]\nhh = 1\n[[sweep]]\nname = 'a'\n", ["[base]", "hh"]),
    ("[[sweep]]\nname = 'a'\nangle = 400\n", ["sweep 'a'", "angle 400", "[0, 360)"]),
    ("[[sweep]]\nname = 'a'\ncell = [10, -1]\n", ["sweep 'a'", "cell size -1", "> 0"]),
    ("[[sweep]]\nname = 'a'\nnu = 0.5\n", ["sweep 'a'", "0.5"]),
    ("[[sweep]]\nname = 'a'\nE = 0\n", ["sweep 'a'", "E"]),
    ("[[sweep]]\nname = 'a'\nppc = 0\n", ["ppc 0", "1 to 16"]),
    ("[[sweep]]\nname = 'a'\ndelta_rel = 2.0\n", ["delta-rel 2.0", "(0, 1]"]),
    ("[[sweep]]\nname = 'a'\ndelta_rel = -1e-3\n", ["delta-rel", "(0, 1]"]),
    ("[[sweep]]\nname = 'a'\noffset = [0.5, 1.2]\n", ["offset", "[0, 1)"]),
    ("[[sweep]]\nname = 'a'\noffset = [0.5]\n", ["offset", "pair"]),
    ("[[sweep]]\nname = 'a'\nmethods = ['ibn']\n", ["methods", "'ibn'", "did you mean 'ibm'"]),
    ("[[sweep]]\nname = 'a'\nproblems = ['confined-blok']\n", ["problems", "confined-block"]),
    ("[[sweep]]\nname = 'a'\nangle = []\n", ["angle", "empty"]),
    ("[[sweep]]\nname = 'a'\nangle = {from = 0, to = 90}\n", ["angle", "step", "count"]),
    ("[[sweep]]\nname = 'a'\nangle = {from = 90, to = 0, step = 5}\n", ["angle", "from <= to"]),
    ("[[sweep]]\nname = 'a'\ncell = {from = 0, to = 10, count = 3, spacing = 'log'}\n", ["cell", "from > 0"]),
    ("[[sweep]]\nname = 'a'\nangle = {from = 0, to = 90, step = 5, spacing = 'cubic'}\n", ["spacing", "linear, log"]),
    ("[[sweep]]\nname = 'a'\nrandom_offsets = {count = 0}\n", ["random_offsets.count", "1 to 1000"]),
    ("[[sweep]]\nname = 'a'\nrandom_offsets = {count = 3, seed = -1}\n", ["seed", ">= 0"]),
    ("[[sweep]]\nname = 'a'\nrandom_offsets = {count = 3}\noffset = [0.1, 0.1]\n", ["either offset or random_offsets"]),
    ("[[sweep]]\nname = 'a'\ndelta_law = {coefficient = 1e-3}\ndelta_rel = 1e-3\n", ["either delta_rel or delta_law"]),
    ("[[sweep]]\nname = 'a'\ndelta_law = {coefficient = -1}\n", ["delta_law.coefficient", "> 0"]),
    ("[[sweep]]\nname = 'a'\ntables = ['convergense']\n", ["tables", "convergence"]),
    ("[[sweep]]\nname = 'a'\nfigures = ['error-vs-h']\n", ["error-vs-h", "cell", "two values"]),
    ("[[sweep]]\nname = 'a'\nfigures = ['error-maps']\n", ["error-maps", "fields = true"]),
    ("[[sweep]]\nname = 'a'\nfields = 'yes'\n", ["fields", "true or false"]),
    ("[[sweep]]\nname = 'a'\ntables = ['seed']\n", ["seed", "90"]),
    ("[[sweep]]\nname = 'a'\n[[sweep]]\nname = 'a'\n", ["'a'", "unique"]),
    ("[[sweep]]\nname = 'Bad Name'\n", ["name", "lower-case"]),
    ("title = 'x'\n", ["at least one [[sweep]]"]),
    ("[[sweep]]\nname = 'a'\nangle = 30\nangle = 40\n", ["not valid TOML"]),
    ("[[sweep]]\nname = 'a'\nangle = nan\n", ["angle", "finite number"]),
    ("[[sweep]]\nname = 'a'\nangle = true\n", ["angle", "finite number"]),
    ("[output]\nvtk = 1\n[[sweep]]\nname = 'a'\n", ["output.vtk", "true or false"]),
    ("[[sweep]]\nname = 'a'\nkinematics = 'huge'\n", ["kinematics 'huge'", "small, large"]),
    ("[[sweep]]\nname = 'a'\nkinematics = 'large'\nsteps = 0\n", ["steps 0", "1 to 10000"]),
    ("[[sweep]]\nname = 'a'\nkinematics = 'large'\nbasis = 'mls'\n", ["basis 'mls'", "mpm, gimp"]),
    ("[[sweep]]\nname = 'a'\nkinematics = 'large'\nband = 'curved'\n", ["band 'curved'", "auto, finite, linearised"]),
    ("[[sweep]]\nname = 'a'\nband = 'linearised'\n", ["band 'linearised'", "load steps", "leave it 'auto'"]),
    ("[[sweep]]\nname = 'a'\nwidth = -1\n", ["width -1", "> 0"]),
    ("[[sweep]]\nname = 'a'\nsteps = 4\n", ["steps 4", "small kinematics"]),
    ("[[sweep]]\nname = 'a'\nfigures = ['error-vs-step']\n", ["error-vs-step", "large"]),
    ("[[sweep]]\nname = 'a'\nkinematics = 'large'\nfigures = ['snapshots']\n", ["snapshots", "fields = true"]),
    ("[[sweep]]\nname = 'a'\nkinematics = 'large'\nfields = true\nfigures = ['error-maps']\n",
     ["error-maps", "small kinematics only"]),
    # the collapse problems
    (collapse_sweep(problems=["footing", "confined-block"]), ["sweep 'c'", "own", "without confined-block"]),
    (collapse_sweep(problems=["footing"], tables=["method-angle"]), ["method-angle", "exact field", "collapse"]),
    (collapse_sweep(problems=["hill-cylinder"], figures=["load-settlement"]), ["load-settlement", "'footing'"]),
    (collapse_sweep(problems=["footing"], figures=["pressure-expansion"]), ["pressure-expansion", "'hill-cylinder'"]),
    (collapse_sweep(problems=["footing"], figures=["locking"]), ["figure locking", "none", "fbar"]),
    (collapse_sweep(problems=["footing"], figures=["plastic-zones"]), ["plastic-zones", "fields = true"]),
    (collapse_sweep(problems=["footing"], E=2e5), ["problem 'footing' has its own material", "E cannot be set"]),
    (collapse_sweep(problems=["hill-cylinder"], steps=4), ["steps 4", "'hill-cylinder'", ">= 5"]),
    (collapse_sweep(problems=["footing"], methods=["nodal"]), ["method 'nodal' refuses walls off the grid lines",
                                                               "allowed: ibm, ibm-limit, penalty"]),
    (collapse_sweep(problems=["footig"]), ["problems", "did you mean 'footing'"]),
    ("[[sweep]]\nname = 'a'\ntables = ['collapse']\n", ["collapse", "hill-cylinder, footing", "confined-block"]),
    # 3D
    ("[[sweep]]\nname = 'a'\ndim = 4\n", ["sweep 'a'", "dim 4", "allowed: 2, 3"]),
    ("[[sweep]]\nname = 'a'\ndim = 3.5\n", ["dim", "integer", "3.5"]),
    ("[base]\ndim = 'three'\n[[sweep]]\nname = 'a'\n", ["base.dim", "integer"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nmethods = ['lagrange-nodal']\n",
     ["method 'lagrange-nodal'", "dim = 3", "allowed: ibm, ibm-limit, penalty, nitsche, lagrange, nodal, fem"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nproblems = ['l-shape']\n",
     ["problem 'l-shape'", "dim = 3", "allowed: confined-block, column, manufactured"]),
    ("[[sweep]]\nname = 'a'\ntilt = 20\n", ["tilt 20", "needs dim = 3"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\ntilt = 400\n", ["tilt 400", "[0, 360)"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\ntilt = 'steep'\n", ["tilt", "finite number"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\noffset = [0.5, 0.5, 1.5]\n", ["offset (0.5, 0.5, 1.5)", "all three", "[0, 1)"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\noffset = [0.5, 0.5]\n", ["offset (0.5, 0.5)", "dim = 3", "give 3 components"]),
    ("[[sweep]]\nname = 'a'\noffset = [0.1, 0.2, 0.3]\n", ["offset (0.1, 0.2, 0.3)", "dim = 2", "give 2 components"]),
    ("[[sweep]]\nname = 'a'\noffset = [0.1, 0.2, 0.3, 0.4]\n", ["offset", "pair", "[x, y, z]"]),
    ("[[sweep]]\nname = 'a'\nsolver = 'cg'\n", ["solver 'cg'", "allowed: auto, pardiso, superlu, amg"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nkinematics = 'large'\n", ["kinematics 'large'", "dim = 3", "'small'"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nload_type = 'settlement'\n", ["load type 'settlement'", "dim = 3"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nmethods = ['lagrange']\naugment = -2\n",
     ["augment -2", "a number >= 0"]),       # 3D takes every declared parameter, checked as in 2D
    ("[[sweep]]\nname = 'a'\ndim = 3\norientation = [[30]]\n", ["orientation", "[angle, tilt] pairs", "[30]"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\norientation = [[30, 20]]\nangle = 45\n",
     ["either orientation or angle and tilt"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\norientation = [[30, 400]]\n", ["tilt 400", "[0, 360)"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nfields = true\nfigures = ['error-maps']\n",
     ["figure error-maps", "2D sweeps only", "error-view-3d"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nmethods = ['ibm']\norientation = [[90, 0], [45, 0], [30, 0]]\n"
     "tables = ['seed']\n", ["table seed", "2D sweeps only"]),
    ("[[sweep]]\nname = 'a'\nfields = true\nfigures = ['error-view-3d']\n",
     ["figure error-view-3d", "dim = 3 in every case"]),
    ("[[sweep]]\nname = 'a'\ndim = [2, 3]\nangle = [0, 30]\ntables = ['method-orientation']\n",
     ["table method-orientation", "dim = 3 in every case"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\ntables = ['method-orientation']\n",
     ["method-orientation", "orientation (angle, tilt)", "two values"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nfigures = ['error-view-3d']\n", ["error-view-3d", "fields = true"]),
    ("[[sweep]]\nname = 'a'\ndim = 3\nfields = true\nvtk = true\n", ["vtk = true", "dim = 3", "--vtk"]),
    ("[[sweep]]\nname = 'a'\ndim = [2, 3]\nrandom_offsets = {count = 2}\n", ["random_offsets", "one dim"]),
    # material, loading, geometry and method parameters
    ("[[sweep]]\nname = 'a'\nmaterial = 'rubber'\n", ["material 'rubber'", "allowed: elastic, von-mises, j2"]),
    ("[[sweep]]\nname = 'a'\nload_type = 'settlement'\nmaterial = 'von-mises'\nyield_stress = -5\n",
     ["yield-stress -5.0", "finite number >= 0"]),
    ("[[sweep]]\nname = 'a'\nload_type = 'settlement'\nmaterial = 'von-mises'\nyield_stress = 0\n",
     ["yield-stress 0.0", "material von-mises", "> 0"]),
    ("[[sweep]]\nname = 'a'\nyield_stress = 10\n", ["yield-stress 10", "von-mises", "material 'elastic'"]),
    ("[[sweep]]\nname = 'a'\nload_type = 'settlement'\nmaterial = 'von-mises'\nyield_stress = 10\nhardening = -1\n",
     ["hardening -1.0", "finite number >= 0"]),
    ("[[sweep]]\nname = 'a'\nlocking = 'bbar'\n", ["locking 'bbar'", "allowed: none, fbar"]),
    ("[[sweep]]\nname = 'a'\nlocking = 'fbar'\n", ["locking 'fbar'", "yielding bodies"]),
    (collapse_sweep(problems=["footing"], footing="bumpy"), ["footing 'bumpy'", "allowed: smooth, rough"]),
    ("[[sweep]]\nname = 'a'\nfooting = 'rough'\n", ["footing 'rough'", "problem 'footing'", "'confined-block'"]),
    ("[[sweep]]\nname = 'a'\nload = 0\n", ["load 0.0", "finite non-zero number"]),
    ("[[sweep]]\nname = 'a'\nload = 'heavy'\n", ["load", "finite number", "'heavy'"]),
    ("[[sweep]]\nname = 'a'\nheight = -5\n", ["height -5.0", "> 0"]),
    ("[[sweep]]\nname = 'a'\nload_type = 'shear'\n", ["load type 'shear'", "allowed: pressure, settlement"]),
    ("[[sweep]]\nname = 'a'\nmethods = ['penalty']\nbeta0 = 0\n", ["beta0 0.0", "a number > 0"]),
    ("[[sweep]]\nname = 'a'\nmethods = ['ibm']\nbeta0 = 1e6\n",
     ["beta0 is not a parameter of any method in this sweep", "ibm: delta_rel, support_threshold"]),
    ("[[sweep]]\nname = 'a'\nmethods = ['nitsche']\ngamma = -1\n", ["gamma -1.0", "a number > 0"]),
    ("[[sweep]]\nname = 'a'\nmethods = ['nitsche']\ngamma = inf\n", ["gamma", "finite number", "inf"]),
    ("[[sweep]]\nname = 'a'\nsupport_threshold = 0.7\n", ["support-threshold 0.7", "[0, 0.5]"]),
    ("[[sweep]]\nname = 'a'\nmethods = ['lagrange']\naugment = -1\n", ["augment -1.0", "a number >= 0"]),
]


@pytest.mark.parametrize("text, words", BAD, ids=[str(i) for i in range(len(BAD))])
def test_bad_spec_gives_one_line_naming_the_key(text, words):
    with pytest.raises(InputError) as caught:
        parse(text)
    message = str(caught.value)
    assert "\n" not in message
    for word in words:
        assert word in message, f"{word!r} missing from: {message}"


def test_parameter_of_another_method_is_rejected():
    from studies.run.spec import load_registries
    methods, _ = load_registries()
    others = sorted({p for m in methods.values() for p in m.names} - set(methods["ibm"].names))
    if not others:
        pytest.skip("only the ibm method is registered")
    with pytest.raises(InputError, match=f"{others[0]} is not a parameter of any method in this sweep"):
        parse(f"[[sweep]]\nname = 'a'\nmethods = ['ibm']\n{others[0]} = [1.0, 2.0]\n")


def test_missing_file_is_reported():
    with pytest.raises(InputError, match="does not exist"):
        load("no/such/spec.toml")


def test_case_id_changes_with_the_code(monkeypatch):
    """A stored result computed by other code must never be reused."""
    from studies.run import identity
    from studies.run.case import CaseSpec
    before = identity.case_id(CaseSpec())
    assert identity.case_id(CaseSpec()) == before
    monkeypatch.setattr(identity, "code_fingerprint", lambda: "other code")
    assert identity.case_id(CaseSpec()) != before


def test_large_kinematics_cases_take_the_loops_defaults():
    study = parse(spec("""
        [[sweep]]
        name = "a"
        methods = ["ibm", "nitsche"]
        kinematics = ["small", "large"]
        steps = 1
        """))
    thresholds = {(c.method, c.kinematics): c.method_parameters["support_threshold"] for c in study.sweeps[0].cases}
    assert thresholds == {("ibm", "small"): 1e-4, ("nitsche", "small"): 1e-4,
                          ("ibm", "large"): 0.1, ("nitsche", "large"): 0.1}


def test_material_keys_sweep_and_are_checked():
    study = parse(spec("""
        [[sweep]]
        name = "plastic"
        methods = ["nitsche"]
        load_type = "settlement"
        load = 30
        kinematics = "large"
        steps = 10
        material = "j2"
        yield_stress = [10, 20]
        hardening = 200
        """))
    cases = study.sweeps[0].cases
    assert [(c.material, c.yield_stress, c.hardening) for c in cases] == [("j2", 10.0, 200.0), ("j2", 20.0, 200.0)]
    # at small kinematics j2 runs load steps on the initial configuration (radial return)
    small = parse("[[sweep]]\nname = 'a'\nproblems = ['confined-block']\nload_type = 'settlement'\n"
                  "material = 'j2'\nyield_stress = 10\nsteps = 4\n").sweeps[0].cases
    assert {(c.kinematics, c.material, c.steps) for c in small} == {("small", "j2", 4)}


PLASTIC = spec("""
    [[sweep]]
    name = "footing"
    problems = ["footing"]
    methods = ["lagrange", "ibm", "fem"]
    angle = [90, 30]
    cell = [40, 20]
    steps = 20
    ppc = 2
    basis = "mpm"
    locking = ["none", "fbar"]
    fields = true
    tables = ["collapse"]
    figures = ["load-settlement", "plastic-zones", "locking"]
    [[sweep]]
    name = "hill"
    problems = ["hill-cylinder"]
    methods = ["nitsche", "fem"]
    angle = 30
    cell = 10
    steps = 20
    ppc = 2
    basis = "mpm"
    locking = "fbar"
    tables = ["collapse"]
    figures = ["pressure-expansion"]
    """)


def test_collapse_sweep_expands_and_fem_takes_no_locking():
    study = parse(PLASTIC)
    footing, hill = study.sweeps
    # 2 grid methods x 2 angles x 2 sizes x 2 lockings, and fem once per angle and size (locking none)
    assert len(footing.cases) == 2 * 2 * 2 * 2 + 2 * 2
    assert {c.locking for c in footing.cases if c.method == "fem"} == {"none"}
    assert {(c.method, c.locking) for c in footing.cases} == {
        ("lagrange", "none"), ("lagrange", "fbar"), ("ibm", "none"), ("ibm", "fbar"), ("fem", "none")}
    assert all((c.problem, c.steps, c.ppc, c.basis) == ("footing", 20, 2, "mpm") for c in footing.cases)
    assert footing.axes["cell"] == (40.0, 20.0) and footing.axes["locking"] == ("none", "fbar")
    assert [(c.method, c.locking) for c in hill.cases] == [("nitsche", "fbar"), ("fem", "none")]
    assert len(study.cases()) == 20 + 2
    from studies.run.spec import locking_pairs
    pairs = locking_pairs(footing.cases)
    assert len(pairs) == 8 and all((a.locking, b.locking) == ("none", "fbar") and a.with_(locking="fbar") == b
                                   for a, b in pairs)
    # "all" problems are the ones with exact fields: never a collapse run
    everything = parse("[[sweep]]\nname = 'a'\nproblems = 'all'\n").sweeps[0].axes["problem"]
    assert "footing" not in everything and "hill-cylinder" not in everything and "confined-block" in everything


def test_collapse_case_ids_are_stable_and_follow_their_sources(monkeypatch):
    from pathlib import Path

    from studies.run.identity import code_fingerprint
    first = [case_id(c) for c in parse(PLASTIC).cases()]
    assert first == [case_id(c) for c in parse(PLASTIC).cases()] and len(set(first)) == len(first) == 22
    # a case shared with another sweep, in another order of keys, is the same case
    alone = parse(PLASTIC.split("[[sweep]]")[0] + "[[sweep]]" + PLASTIC.split("[[sweep]]")[2]).cases()
    assert case_id(alone[0]) in first
    # the runs of the collapse problems are among the sources a case id hashes
    read = Path.read_bytes
    monkeypatch.setattr(Path, "read_bytes", lambda self: read(self) + (b"#" if self.name == "footing.py" else b""))
    code_fingerprint.cache_clear()
    try:
        assert not set(first) & {case_id(c) for c in parse(PLASTIC).cases()}
    finally:
        monkeypatch.undo()
        code_fingerprint.cache_clear()
    assert [case_id(c) for c in parse(PLASTIC).cases()] == first
