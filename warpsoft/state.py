"""State (what a step changes: positions, velocities) and Control (what drives a step besides
the scene's own schedules)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp


@dataclass
class State:
    """Per-step state of every world: positions ``q`` and velocities ``v``, each ``(n,)`` vec3d
    (m, m/s), nodes of all worlds concatenated (see ``Model.world_node_start``); with rigid
    bodies (else None), each ``(bodies,)``: ``body_p`` centres of mass (m, vec3d), ``body_r``
    orientations (quatd, world from the body's frame), ``body_v`` (m/s) and ``body_w`` (rad/s,
    world axes) velocities."""

    q: wp.array
    v: wp.array
    body_p: wp.array | None = None
    body_r: wp.array | None = None
    body_v: wp.array | None = None
    body_w: wp.array | None = None

    def positions(self) -> np.ndarray:
        """A copy of the positions as a ``(n, 3)`` NumPy array (m)."""
        return self.q.numpy().copy()


@dataclass
class Control:
    """Actuator inputs for the direct model, by actuator name: the imposed displacement or
    force (per the actuator's mode; cable m or N, cavity m^3 or Pa). An actuator not named
    here follows its scene ``value``. A model of several worlds takes one Control per world."""

    inputs: dict[str, float] = field(default_factory=dict)
