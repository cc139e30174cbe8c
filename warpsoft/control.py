"""Control: what drives a step besides the scene's own schedules."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Control:
    """Actuator inputs for the direct model, by actuator name: the imposed displacement or
    force (per the actuator's mode; cable m or N, cavity m^3 or Pa). An actuator not named
    here follows its scene ``value``."""

    inputs: dict[str, float] = field(default_factory=dict)
