"""What every actuator shares: an input (imposed displacement or imposed force) and bounds."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError, call_user

MODES = ("displacement", "force")


def _number(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{what} must be a number, got {value!r}")
    if math.isnan(value):
        raise SceneError(f"{what} must not be NaN")
    return float(value)


@dataclass(frozen=True)
class Ramp:
    """An actuator input that goes linearly from ``initial`` at time ``start`` to ``value`` at
    ``start + duration`` (s), held before and after: ``Ramp(0.004, 0.05)`` pulls a cable 4 mm
    over 50 ms. A function of time like any other schedule, but one the step evaluates for every
    ramped actuator of a batch at once (1024 Diamonds' 4096 cable inputs, CPU VM: a Python call
    each took about 4.7 ms a step).

    Args:
        value: the input reached (the actuator's units: cable m or N, cavity m^3 or Pa).
        duration: the ramp's length (s, >= 0; 0: a step from ``initial`` to ``value`` at ``start``).
        start: when it begins (s).
        initial: the input before it begins.
    """

    value: float
    duration: float
    start: float = 0.0
    initial: float = 0.0

    def __post_init__(self) -> None:
        for attr in ("value", "duration", "start", "initial"):
            v = _number(getattr(self, attr), f"Ramp: {attr}")
            if math.isinf(v):
                raise SceneError(f"Ramp: {attr} must be finite, got {v}")
            object.__setattr__(self, attr, v)
        if self.duration < 0.0:
            raise SceneError(f"Ramp: duration must be >= 0 s, got {self.duration}")

    def __call__(self, t: float) -> float:
        value, duration, start, initial = self.value, self.duration, self.start, self.initial
        if duration == 0.0:
            return value if t >= start else initial
        return initial + (value - initial) * min(max((t - start) / duration, 0.0), 1.0)

    @staticmethod
    def at(ramps: np.ndarray, t: float) -> np.ndarray:
        """Many ramps at time ``t``: ``ramps`` ``(n, 4)`` rows of (value, duration, start,
        initial), as :meth:`__call__` computes each (to the bit)."""
        value, duration, start, initial = ramps.T
        steady = duration > 0.0
        frac = np.where(steady, np.clip((t - start) / np.where(steady, duration, 1.0), 0.0, 1.0),
                        (t >= start).astype(np.float64))
        return np.where(steady, initial + (value - initial) * frac, np.where(frac > 0.0, value, initial))

    def row(self) -> tuple[float, float, float, float]:
        """The ramp as a row of :meth:`at`'s ``ramps``."""
        return (self.value, self.duration, self.start, self.initial)


@dataclass
class Actuator:
    """An actuator row: ``delta`` is its displacement, ``lambda`` its force.

    Args:
        name: unique label.
        mode: "displacement" (``delta`` imposed) or "force" (``lambda`` imposed).
        value: the input, a number or a function of time ``t -> number`` (a :class:`Ramp`: the
            step evaluates a batch's ramps at once).
        min_force, max_force: bounds on ``lambda`` (a cable cannot push: ``min_force >= 0``).
        min_displacement, max_displacement: bounds on ``delta``; they bind also in force mode.
        max_step: bound on the change of ``delta`` in one step (> 0).
    Units depend on the kind: cable m and N; cavity m^3 and Pa.
    """

    name: str
    mode: str
    value: float | Callable[[float], float]
    min_force: float
    max_force: float
    min_displacement: float
    max_displacement: float
    max_step: float
    kind = "actuator"

    def __post_init__(self) -> None:
        label = f"{self.kind} '{self.name}'"
        if self.mode not in MODES:
            raise SceneError(f"{label}: mode must be 'displacement' or 'force', got {self.mode!r}")
        if not callable(self.value):
            self.value = _number(self.value, f"{label}: value")
            if math.isinf(self.value):
                raise SceneError(f"{label}: value must be finite, got {self.value}")
        for attr in ("min_force", "max_force", "min_displacement", "max_displacement", "max_step"):
            setattr(self, attr, _number(getattr(self, attr), f"{label}: {attr}"))
        if self.min_force > self.max_force:
            raise SceneError(f"{label}: min_force {self.min_force} > max_force {self.max_force}")
        if self.min_displacement > self.max_displacement:
            raise SceneError(f"{label}: min_displacement {self.min_displacement} > max_displacement "
                             f"{self.max_displacement}")
        if not self.max_step > 0:
            raise SceneError(f"{label}: max_step must be > 0, got {self.max_step}")

    def input_at(self, t: float) -> float:
        """The input at time ``t`` (s); a non-finite value is an error naming the actuator."""
        v = call_user(self.value, t, f"{self.kind} '{self.name}': its input schedule") if callable(self.value) \
            else self.value
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise SceneError(f"{self.kind} '{self.name}': value({t:g}) must be a number, got {v!r}") from None
        if not math.isfinite(v):
            raise SceneError(f"{self.kind} '{self.name}': value({t:g}) must be finite, got {v}")
        return v
