"""Problems users define: a TOML file with the body's outline, material, loads and (optionally) the exact field.

    name = "bracket"
    [body]
    start = [0.0, 0.0]
    pieces = [                                  # counter-clockwise, each from the previous point
      {to = [100.0, 0.0], kind = "fixed"},
      {to = [100.0, 40.0], kind = "traction"},
      {to = [80.0, 60.0], kind = "free", center = [100.0, 60.0], clockwise = true},   # an arc
      {to = [80.0, 100.0], kind = "free"},
      {to = [0.0, 100.0], kind = "traction"},
      {to = [0.0, 0.0], kind = "roller"},
    ]
    [material]                                  # optional: else the case's E and nu
    E = 1e4
    nu = 0.3
    [loads]                                     # sympy expressions in the body's frame (x, y)
    body_force = ["0", "-1"]
    traction = {1 = ["10", "0"], 4 = ["0", "-5"]}   # by piece index, 0-based; other traction pieces are free
    displacement = {0 = ["0", "0"], 5 = ["0", "0"]}   # roller pieces take the normal component
    [exact]                                     # optional
    u = ["1e-3*x + 2e-4*y", "-3e-4*x + 1e-3*y"]
    lift = "bubble"                             # or "exact": the field itself carries the essential data

An arc runs counter-clockwise about its `center` unless `clockwise = true` (at most 180 degrees
each); an essential (roller or fixed) arc must meet its neighbours at right angles.

This module reads and checks a file (load_problem_file); studies.problems.file_fields checks and
compiles its expressions, and studies.problems.file_placement places it in the grid (loads, lift,
exact field) as the problem a case's problem_file names.
"""
from __future__ import annotations

import hashlib
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ibm.exceptions import InputError
from ibm.geometry.arcs import Arc
from ibm.geometry.frames import frame_of_angle
from ibm.geometry.outline import EDGE_KINDS, ESSENTIAL_KINDS, Body
from ibm.models.elastic import Elastic
from studies.problems.file_fields import expression, fail
from studies.problems.library import closest

KEYS = {"": ("name", "body", "material", "loads", "exact"), "body": ("start", "pieces"),
        "piece": ("to", "kind", "center", "clockwise"), "material": ("E", "nu"),
        "loads": ("body_force", "traction", "displacement"), "exact": ("u", "lift")}
LIFTS = ("bubble", "exact")      # what carries the essential data of a file with [exact]


@dataclass(frozen=True, eq=False)
class UserProblem:
    """A parsed problem file: outline in the file's frame, kinds, material, expressions."""

    path: str
    name: str
    start: np.ndarray              # (2,)
    vertices: np.ndarray           # (n, 2) piece start points, the file's frame
    kinds: tuple[str, ...]
    material: Elastic | None
    body_force: tuple[str, str] | None
    traction: dict[int, tuple[str, str]]
    displacement: dict[int, tuple[str, str]]
    exact: tuple[str, str] | None
    digest: str                    # sha256 of the file's bytes
    arcs: tuple = ()               # per piece an Arc (centre in the file's frame) or None; () if none
    lift: str = "bubble"           # one of LIFTS (studies.problems.file_placement)

    def body(self, angle: float, corner: np.ndarray) -> Body:
        R = frame_of_angle(angle)
        corner = np.asarray(corner, float)
        arcs = tuple(None if arc is None else Arc(corner + (np.asarray(arc.center) - self.start) @ R.T, arc.clockwise)
                     for arc in self.arcs)
        return Body(corner + (self.vertices - self.start) @ R.T, self.kinds, frame=R, arcs=arcs)


def _check_keys(path, table: dict, where: str, allowed: tuple[str, ...]) -> None:
    for key in table:
        if key not in allowed:
            fail(path, where or "top level", f"unknown key {key!r}{closest(str(key), allowed)}; "
                 f"allowed: {', '.join(allowed)}")


def _point(path, value, key: str) -> np.ndarray:
    ok = isinstance(value, list) and len(value) == 2 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in value)
    if not ok:
        fail(path, key, f"{value!r} is not a point; give two finite numbers, e.g. [0.0, 0.0]")
    return np.array(value, float)


def _vector(path, value, key: str) -> tuple[str, str]:
    """Two sympy expressions in x and y, checked now (parse, symbols) so a case never fails on them later."""
    if not (isinstance(value, list) and len(value) == 2 and all(isinstance(v, (str, int, float)) for v in value)):
        fail(path, key, f"{value!r} is not a vector; give two expressions in x and y, e.g. [\"0\", \"-1\"]")
    text = tuple(str(v) for v in value)
    for item in text:
        expression(path, key, item)
    return text


def _indexed(path, table, key: str, n: int, kinds, allowed_kinds) -> dict[int, tuple[str, str]]:
    if not isinstance(table, dict):
        fail(path, key, f"{table!r} is not a table of piece index = [expression, expression]")
    out = {}
    for index, value in table.items():
        if not (str(index).isdigit() and int(index) < n):
            fail(path, f"{key}.{index}", f"piece index {index!r} is not one of 0 .. {n - 1}")
        k = int(index)
        if kinds[k] not in allowed_kinds:
            fail(path, f"{key}.{index}", f"piece {k} is {kinds[k]!r}; {key.split('.')[-1]} is for "
                 f"{' or '.join(allowed_kinds)} pieces")
        out[k] = _vector(path, value, f"{key}.{index}")
    return out


@lru_cache(maxsize=32)
def _load_cached(path: str, digest: str) -> UserProblem:
    raw = Path(path).read_bytes()
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"problem file {path}: not valid TOML ({str(error).splitlines()[0]})") from None
    _check_keys(path, data, "", KEYS[""])
    name = data.get("name", Path(path).stem)
    if not isinstance(name, str) or not name:
        fail(path, "name", f"{name!r} is not a name; give a non-empty string")
    body = data.get("body")
    if not isinstance(body, dict):
        fail(path, "body", "missing; give [body] with start and pieces")
    _check_keys(path, body, "body", KEYS["body"])
    start = _point(path, body.get("start"), "body.start")
    pieces = body.get("pieces")
    if not isinstance(pieces, list) or len(pieces) < 3:
        fail(path, "body.pieces", "give a list of at least three pieces {to = [x, y], kind = \"...\"}")
    ends, kinds, arcs = [], [], []
    for k, piece in enumerate(pieces):
        where = f"body.pieces[{k}]"
        if not isinstance(piece, dict):
            fail(path, where, f"{piece!r} is not a piece; give {{to = [x, y], kind = \"...\"}}")
        _check_keys(path, piece, where, KEYS["piece"])
        if "to" not in piece or "kind" not in piece:
            fail(path, where, "a piece needs `to` and `kind`")
        ends.append(_point(path, piece["to"], f"{where}.to"))
        if piece["kind"] not in EDGE_KINDS:
            fail(path, f"{where}.kind", f"{piece['kind']!r} is not one of {', '.join(EDGE_KINDS)}"
                 f"{closest(str(piece['kind']), EDGE_KINDS)}")
        kinds.append(piece["kind"])
        if "clockwise" in piece and "center" not in piece:
            fail(path, f"{where}.clockwise", "is for arcs: give the arc's center too")
        if "center" in piece:
            clockwise = piece.get("clockwise", False)
            if not isinstance(clockwise, bool):
                fail(path, f"{where}.clockwise", f"{clockwise!r} is not true or false")
            arcs.append(Arc(_point(path, piece["center"], f"{where}.center"), clockwise))
        else:
            arcs.append(None)
    if np.linalg.norm(ends[-1] - start) > 1e-9 * max(1.0, float(np.abs(np.array(ends)).max())):
        fail(path, f"body.pieces[{len(pieces) - 1}].to", f"the outline must close: the last piece ends at "
             f"{tuple(ends[-1])}, not at the start {tuple(start)}")
    vertices = np.array([start] + ends[:-1])
    arcs = tuple(arcs) if any(arc is not None for arc in arcs) else ()
    try:
        Body(vertices, tuple(kinds), arcs=arcs).walls      # walls: essential arcs must meet their neighbours at 90
    except InputError as error:
        raise InputError(f"problem file {path}: body: {error}") from None
    material = None
    if "material" in data:
        table = data["material"]
        if not isinstance(table, dict):
            fail(path, "material", "give a table with E and nu")
        _check_keys(path, table, "material", KEYS["material"])
        if set(table) != {"E", "nu"}:
            fail(path, "material", "give both E and nu")
        try:
            material = Elastic(float(table["E"]), float(table["nu"]))
        except (InputError, TypeError, ValueError) as error:
            fail(path, "material", str(error))
    loads = data.get("loads", {})
    if not isinstance(loads, dict):
        fail(path, "loads", "give a table with body_force, traction, displacement")
    _check_keys(path, loads, "loads", KEYS["loads"])
    exact, lift = None, "bubble"
    if "exact" in data:
        table = data["exact"]
        if not isinstance(table, dict) or "u" not in table:
            fail(path, "exact", "give u = [expression, expression]")
        _check_keys(path, table, "exact", KEYS["exact"])
        exact = _vector(path, table["u"], "exact.u")
        lift = table.get("lift", lift)
        if lift not in LIFTS:
            fail(path, "exact.lift", f"{lift!r} is not one of {', '.join(LIFTS)}{closest(str(lift), LIFTS)}")
    n = len(kinds)
    body_force = _vector(path, loads["body_force"], "loads.body_force") if "body_force" in loads else None
    traction = _indexed(path, loads.get("traction", {}), "loads.traction", n, kinds, ("traction",))
    displacement = _indexed(path, loads.get("displacement", {}), "loads.displacement", n, kinds, ESSENTIAL_KINDS)
    return UserProblem(path, name, start, vertices, tuple(kinds), material, body_force, traction, displacement,
                       exact, digest, arcs, lift)


def file_digest(path: str | Path) -> str:
    """sha256 of the file's bytes; InputError when it cannot be read."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as error:
        raise InputError(f"problem file {path} cannot be read ({error.strerror or error})") from None


def load_problem_file(path: str | Path) -> UserProblem:
    """Parse and check a problem file (cached by content): InputError naming the file and the key."""
    return _load_cached(str(path), file_digest(path))
