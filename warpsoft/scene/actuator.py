"""What every actuator shares: an input (imposed displacement or imposed force) and bounds."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import SceneError, call_user

MODES = ("displacement", "force")


def _number(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{what} must be a number, got {value!r}")
    if math.isnan(value):
        raise SceneError(f"{what} must not be NaN")
    return float(value)


@dataclass
class Actuator:
    """An actuator row: ``delta`` is its displacement, ``lambda`` its force.

    Args:
        name: unique label.
        mode: "displacement" (``delta`` imposed) or "force" (``lambda`` imposed).
        value: the input, a number or a function of time ``t -> number``.
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
