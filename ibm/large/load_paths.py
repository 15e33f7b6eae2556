"""Load paths that are not proportional: a quantity given at a few load fractions and linear between
them (a block pressed first and sheared after, a tool that moves one way and then another)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.exceptions import InputError


@dataclass(frozen=True, eq=False)
class LoadPath:
    """values (k, ...) at load fractions times (k,), 0 = times[0] < ... < times[-1] = 1, linear between."""

    times: np.ndarray
    values: np.ndarray

    def __post_init__(self):
        times = np.asarray(self.times, float)
        values = np.asarray(self.values, float)
        if times.ndim != 1 or len(times) < 2 or times[0] != 0 or times[-1] != 1 or np.any(np.diff(times) <= 0):
            raise InputError(f"a load path's times {times.tolist()} are not allowed; they must rise from 0 to 1")
        if len(values) != len(times) or not np.all(np.isfinite(values)):
            raise InputError(f"a load path needs one finite value for each of its {len(times)} times")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)

    def at(self, t: float) -> np.ndarray:
        """The value at load fraction t in [0, 1] (its shape is a value's)."""
        k = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2))
        weight = (t - self.times[k]) / (self.times[k + 1] - self.times[k])
        return (1 - weight) * self.values[k] + weight * self.values[k + 1]

    def key(self) -> tuple:
        """What a checkpoint's fingerprint hashes: the times and the values, exactly."""
        return (self.times.tolist(), self.values.shape, self.values.ravel().tolist())
