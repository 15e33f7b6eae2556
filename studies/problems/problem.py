"""What a problem is to a study: one object per problem, behind one protocol.

A problem says what it is (name, summary, the dimensions and loadings it has), checks a case of
itself (`validate`: one InputError naming the bad setting), gives its defaults (the parameters a
method takes on it), runs a case into a flat record (`run`), and lends the report what it needs
to read its numbers (a collapse problem's table, its curve beside the exact limit, the sentences
that read them). Every family is a subclass:
studies.problems.closed_form (the closed-form library at small and large strain),
studies.problems.collapse (Hill's cylinder), studies.problems.footing (Prandtl's footing),
studies.problems.ample_collapse (AMPLE's collapse), studies.problems.boxes (the 3D boxes) and
studies.problems.file_placement (a user's TOML file, studies.problems.problem_file).
studies.problems.registry finds them, and installed packages add more through the entry-point
group ``ibm_mpm.problems``.

The case runner (studies.run.case.run_case) knows only this protocol: no module outside a
problem's own switches on its name (tests/test_problem_protocol.py).
"""
from __future__ import annotations

from baselines.registry import METHODS
from ibm.exceptions import InputError
from studies.problems.library import plastic


class Problem:
    """The protocol with its defaults; a problem overrides what differs. A collapse problem also
    reads its rows for the report (studies.problems.collapse.CollapseProblem).

    Attributes
    ----------
    name, summary : str
        Its name in specs and on the command line, and one line on what it is.
    dims : tuple of int
        The dimensions it has (2: plane strain, 3: a solid).
    from_file : bool
        True for the problem that a case's problem_file defines (its name is the file's).
    in_specs : bool
        Whether a study spec may name it.
    collapse : bool
        True when it measures a collapse load and has no exact field (its own tables and figures,
        studies.run.spec).
    figures : tuple of str
        The collapse figures it can draw (kinds of studies.run.spec.COLLAPSE_FIGURES).
    own_settings : dict
        CaseSpec fields only it reads -> their allowed values (other problems keep the default).
    contact : bool
        True when it has a contact wall, whose law --friction (Coulomb) or --adhesion (Tresca) sets.
    weight : bool
        True when it takes the soil's weight (--unit-weight).
    surcharge : bool
        True when it takes a surcharge on the soil's free top (--surcharge).
    compared : dict
        A contact problem's measures beside their exact values for the report's contact table: label ->
        (record column, exact column).
    """

    name: str = ""
    summary: str = ""
    dims: tuple[int, ...] = (2,)
    from_file: bool = False
    in_specs: bool = True
    collapse: bool = False
    figures: tuple[str, ...] = ()
    own_settings: dict[str, tuple[str, ...]] = {}
    contact: bool = False
    weight: bool = False
    surcharge: bool = False
    compared: dict[str, tuple[str, str]] = {}

    # --- what it is ----------------------------------------------------------------------------
    def load_types(self) -> tuple[str, ...]:
        """Its loadings (studies.problems.library: a stress or a prescribed displacement)."""
        return ("pressure",)

    def default_load_type(self) -> str:
        """`pressure` where it has it, else its first loading."""
        types = self.load_types()
        return "pressure" if "pressure" in types or not types else types[0]

    def default_load(self, width: float, height: float) -> float | None:
        """The load a command line without --load takes (None: CaseSpec's)."""
        return None

    def size(self, spec) -> float:
        """The body's largest extent (the grid's cell is bounded by it)."""
        return max(spec.width, spec.height)

    def area(self, spec) -> float:
        """The body's area (2D), to estimate a case's material points."""
        return spec.width * spec.height

    # --- what a case of it takes ---------------------------------------------------------------
    def validate(self, spec) -> None:
        """Raise InputError naming the first setting of `spec` this problem does not take."""
        if spec.load_type not in self.load_types():
            raise InputError(f"load type {spec.load_type!r} is not allowed for problem {self.name!r}; "
                             f"allowed: {', '.join(self.load_types())}")

    def steps_allowed(self, spec) -> bool:
        """Whether the case may take more than one load step (else it is one linear step)."""
        return spec.kinematics == "large" or plastic(spec)

    def locking_applies(self, spec) -> bool:
        """Whether a remedy for locking (--locking fbar) applies: its material yields."""
        return plastic(spec)

    def takes_band(self, spec) -> bool:
        """Whether the case's --band reaches a load-step treatment it builds from the spec: where it
        takes load steps, unless the problem builds its treatment from its own defaults."""
        return self.steps_allowed(spec)

    def parameters(self, method: str) -> dict:
        """The parameters `method` takes on this problem, with their defaults."""
        return METHODS[method].defaults()

    def load_stepped(self, spec) -> bool:
        """Whether the case runs the load-step loop a checkpoint saves (ibm.large.loadsteps.run): its load
        steps, unless a body-fitted reference solves it."""
        return self.steps_allowed(spec) and not METHODS[spec.method].supports.body_fitted

    def checkpoint_refusal(self, spec) -> str:
        """Why a checkpoint cannot save this case ('' when it can)."""
        if METHODS[spec.method].supports.body_fitted:
            return (f"--checkpoint is not available for method {spec.method!r} (a body-fitted reference has no "
                    "load-step checkpoints)")
        if not self.load_stepped(spec):
            return ("--checkpoint is for load steps (large kinematics, material von-mises, or a collapse problem); "
                    "small elastic kinematics is one linear solve")
        return ""

    def takes_contact_law(self, spec) -> bool:
        """Whether the case has a contact wall or body whose law --friction and --adhesion set."""
        return self.contact

    def fields_refusal(self, spec) -> str:
        """Why the case cannot keep its fields (--vtk, a sweep's fields = true): '' when it can."""
        return ""

    # --- a case of it --------------------------------------------------------------------------
    def instance(self, spec):
        """The problem placed in the grid for a small-strain solve (studies.problems.library.Placed)."""
        raise InputError(f"problem {self.name!r} has no small-strain instance")

    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        """The case's flat record (settings, sizes, error norms or collapse loads, diagnostics, time_s);
        with keep_fields its arrays under "fields". solver: the linear solver backend (ibm.solvers.backends)
        of the method's systems; progress: the load steps as a bar on stderr; checkpoint: a file each
        converged load step is saved to (a run that finds it resumes from it)."""
        raise NotImplementedError
