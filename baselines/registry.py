"""Every boundary method by name: the built-in ones and those of installed packages.

A package adds methods through the entry-point group `ibm_mpm.methods`, each entry naming a
BoundaryMethod instance (ibm.boundary_method), e.g. in its pyproject.toml:

    [project.entry-points."ibm_mpm.methods"]
    penalty-particles = "my_package.method:PENALTY_PARTICLES"

Tests and studies parametrize over METHODS; `METHODS[name](model, **settings)` solves with the
method's own parameters read from `settings`.
"""
from __future__ import annotations

from importlib.metadata import entry_points

from baselines.fem.method import FEM
from baselines.lagrange import LAGRANGE
from baselines.lagrange_nodal import LAGRANGE_NODAL
from baselines.limit import IBM_LIMIT
from baselines.nitsche import NITSCHE
from baselines.nodal import NODAL
from baselines.penalty import PENALTY
from ibm.boundary_method import BoundaryMethod
from ibm.exceptions import InputError
from ibm.implicit_boundary import IMPLICIT_BOUNDARY
from ibm.large.treatment import BAND_KINEMATICS

GROUP = "ibm_mpm.methods"
BUILT_IN = (IMPLICIT_BOUNDARY, IBM_LIMIT, PENALTY, NITSCHE, LAGRANGE, LAGRANGE_NODAL, NODAL, FEM)


def installed(group: str, kind: type, what: str) -> list:
    """The objects of installed packages' entry-point group `group`, each checked to be a `kind` named
    as its entry; a broken plug-in is one line naming it (`what`: method or problem), not a traceback."""
    found = []
    for entry in entry_points(group=group):
        try:
            item = entry.load()
        except Exception as error:
            raise InputError(f"the {what} plug-in {entry.name!r} ({entry.value}) cannot be loaded: {error}") from None
        if not isinstance(item, kind) or item.name != entry.name:
            raise InputError(f"the {what} plug-in {entry.name!r} ({entry.value}) is not a {kind.__name__} named "
                             f"{entry.name!r}")
        found.append(item)
    return found


METHODS: dict[str, BoundaryMethod] = {}


def register(method: BoundaryMethod) -> BoundaryMethod:
    """Add `method` under its name; a name already taken is refused in one line."""
    if method.name in METHODS and METHODS[method.name] is not method:
        raise InputError(f"method {method.name!r} is registered twice ({METHODS[method.name]!r} and {method!r})")
    METHODS[method.name] = method
    return method


for _method in (*BUILT_IN, *installed(GROUP, BoundaryMethod, "method")):
    register(_method)


def supporting(capability: str) -> list[str]:
    """The methods that support `capability` (ibm.boundary_method.CAPABILITIES)."""
    return [n for n, m in METHODS.items() if capability in m.supports]


def in_load_steps(dim: int) -> list[str]:
    """The methods that run the load steps in `dim` dimensions."""
    return supporting("load-steps" if dim == 2 else "load-steps-3d")


def in_3d() -> list[str]:
    return supporting("3d")


def require(name: str, capability: str) -> None:
    """InputError in one line unless method `name` supports `capability`: its reason, and the methods that do."""
    METHODS[name].require(capability, supporting(capability))


def method_parameters() -> dict[str, list]:
    """Every declared parameter name -> its declarations (one per method declaring it), in method order."""
    found: dict[str, list] = {}
    for method in METHODS.values():
        for parameter in method.parameters:
            found.setdefault(parameter.name, []).append(parameter)
    return found


def treatment(name: str, parameters: dict, dim: int = 2):
    """The named method's walls in the load steps with the given parameters (None: the default);
    InputError in one line for a method that refuses the load steps."""
    method = METHODS[name]
    require(name, "load-steps" if dim == 2 else "load-steps-3d")
    return method.treatment(**{k: v for k, v in parameters.items() if v is not None})


def check_band(band: str, name: str, in_load_steps: bool) -> None:
    """InputError unless `band` is one of ibm.large.treatment.BAND_KINEMATICS and, when not "auto", is asked
    of a method that takes it (Supports.band_kinematics) in the load steps of large kinematics or
    plasticity (not the collapse problems)."""
    takers = [n for n, m in METHODS.items() if m.supports.band_kinematics]
    if band not in BAND_KINEMATICS:
        raise InputError(f"band {band!r} is not allowed; allowed: {', '.join(BAND_KINEMATICS)}")
    if band != "auto" and name not in takers:
        raise InputError(f"band {band!r} is for method {' or '.join(map(repr, takers))}; leave it 'auto' for {name!r}")
    if band != "auto" and not in_load_steps:
        raise InputError(f"band {band!r} is for method {' or '.join(map(repr, takers))} in the load steps of large "
                         "kinematics or material von-mises (not the collapse problems); leave it 'auto' here")
