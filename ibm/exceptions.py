"""Every exception of ibm-mpm, in one place.

Two families, one exit code each at the command line (studies.cli):
- InputError (exit 2): bad input; the message names the bad value and what is allowed.
- SolveError (exit 3): a run that cannot give a reliable answer; the message says why.
"""
from __future__ import annotations


class InputError(ValueError):
    """Bad input: the message names the bad value and what is allowed."""


class SolveError(RuntimeError):
    """The system cannot be solved reliably; the message says why."""


class FactorizationError(RuntimeError):
    """The backend could not factorize the matrix (singular, or not of the stated structure)."""


class NotConverged(RuntimeError):
    """Newton did not reach the tolerance within the iteration limit."""


class StepFailure(SolveError):
    """A load step failed even after the step cuts; the message names the step and the residual."""


class GridExit(SolveError):
    """A material point (or its domain) left the background grid (the grid does not grow: the run
    stops, naming the point; give the body more room with Setup.margin)."""


class DomainLost(SolveError):
    """A point's domain no longer meets the tracked outline (the run stops: exit 3)."""


class CheckpointError(InputError):
    """A checkpoint file that cannot be used: not a readable checkpoint, or one of another setup."""


class FolderBusy(InputError):
    """Another run holds the output folder."""


class OutputFolderError(InputError):
    """An output folder that cannot be created or written."""


class StoreUnreadable(InputError):
    """A results.parquet that is no results table (not parquet, or without case_id/status)."""


class RunError(SolveError):
    """The run's environment failed it (disk full, scheduler unreachable)."""
