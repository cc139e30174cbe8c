"""What a step did: StepStats (the whole step) and WorldStats (each world's rows)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import SceneError


class ConvergenceWarning(UserWarning):
    """An iterative solve stopped at its iteration cap above its tolerance."""


@dataclass
class WorldStats:
    """One world's share of a step: the iterations of its linear solve (when the solver counts
    them per world), its multipliers' resolution (Gauss-Seidel sweeps and last change, or the
    QP status and time in s: 0 for the device QP, which runs inside the step's graph and gives
    its active-set iterations as ``resolve_iterations``; with contacts, the QPCC's pivots on its
    contact set, ``qp_pivots``), and its rows after the step by name:
    actuator ``delta`` (cable m, cavity m^3) and ``lambda`` (N, Pa), effector positions and
    targets (m) and the distance between them on the controlled axes (m); its elements turned
    inside out after the step (``det F <= 0``); ``linearization_error`` (m, m^3), how far its
    rows ended from the last linear prediction ``delta_free + W lambda``; its Newton iterations
    (linear solves) and final relative nonlinear residual (see :mod:`warpsoft.newton`); with
    obstacles, its contacts carrying a force, their total normal and friction forces (N, sums of
    each contact's) and its deepest penetration (m); in the direct model, how far each
    displacement-driven actuator is from its command this step (cable m, cavity m^3); with rigid
    bodies, each one's centre of mass (m) and orientation (unit quaternion x, y, z, w) after the
    step, by name; with attachments, the force each puts on its soft nodes (N, their sum; its
    rigid body takes the opposite), by name."""

    cg_iterations: int = 0
    resolve_iterations: int = 0
    resolve_residual: float = 0.0
    qp_status: str = ""
    qp_seconds: float = 0.0
    qp_pivots: int = 0
    inverted_elements: int = 0
    linearization_error: float = 0.0
    newton_iterations: int = 0
    newton_residual: float = 0.0
    contacts: int = 0
    contact_force: float = 0.0
    friction_force: float = 0.0
    penetration: float = 0.0
    actuator_residual: dict[str, float] = field(default_factory=dict)
    effector_error: dict[str, float] = field(default_factory=dict)
    actuator_delta: dict[str, float] = field(default_factory=dict)
    actuator_lambda: dict[str, float] = field(default_factory=dict)
    effectors: dict[str, np.ndarray] = field(default_factory=dict)
    targets: dict[str, np.ndarray] = field(default_factory=dict)
    rigid_bodies: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    attachments: dict[str, np.ndarray] = field(default_factory=dict)


def _of_the_world(name: str):
    def get(self: StepStats):
        if len(self.worlds) != 1:
            raise SceneError(f"step stats: {name} belongs to a world; this model has {len(self.worlds)}: "
                             f"read stats.worlds[w].{name}")
        return getattr(self.worlds[0], name)
    get.__doc__ = f"``worlds[0].{name}`` of a one-world model."
    return property(get)


@dataclass
class StepStats:
    """What one step did: solver statistics and the wall time (s) of each stage that ran.

    Stages (summed over the step's Newton iterations): ``linearize`` (rotations, forces,
    the preconditioner's update, rows and their columns ``H^T``, the nonlinear residual,
    the health check), ``free_solve`` (the motion and, with actuators, their compliance columns,
    solved together in one batched solve; with ``direct``, the factorization of the last
    linearization, made when this first solve needs it), ``compliance`` (``delta_free`` and ``W`` from the
    solved columns), ``resolve`` (the multipliers), ``correct`` (the correction and the update);
    on CUDA the captured graphs instead (``device_step``, ``newton_step``, ``line_search``, and
    around a host QP ``device_before_qp``, ``newton_before_qp``, ``device_after_qp``).
    ``cg_iterations`` counts the iterations of the step's solves (0 for a direct solve; per
    solve, the most any world needed); ``compliance_iterations`` is the same count when
    actuators rode along, else 0. ``newton_iterations`` is the most linearizations a world
    needed, ``newton_residual`` the largest final relative residual of a world, and
    ``line_searches`` the shortened steps tried; ``factorizations`` counts the direct solver's
    numeric factorizations in the step, a world's block counting one (fewer than its worlds'
    linearizations with ``factor_reuse``). ``worlds``
    holds each world's rows; with one world, its fields read as attributes of the step too
    (``stats.actuator_delta`` and so on).
    """

    index: int
    time: float
    cg_iterations: int = 0
    cg_residual: float = 0.0
    converged: bool = True
    stages: dict[str, float] = field(default_factory=dict)
    total: float = 0.0
    warnings: list[str] = field(default_factory=list)
    compliance_iterations: int = 0
    newton_iterations: int = 0
    newton_residual: float = 0.0
    line_searches: int = 0
    factorizations: int = 0
    worlds: list[WorldStats] = field(default_factory=list)

    resolve_iterations = _of_the_world("resolve_iterations")
    resolve_residual = _of_the_world("resolve_residual")
    qp_status = _of_the_world("qp_status")
    qp_seconds = _of_the_world("qp_seconds")
    qp_pivots = _of_the_world("qp_pivots")
    effector_error = _of_the_world("effector_error")
    actuator_delta = _of_the_world("actuator_delta")
    actuator_lambda = _of_the_world("actuator_lambda")
    effectors = _of_the_world("effectors")
    targets = _of_the_world("targets")
    inverted_elements = _of_the_world("inverted_elements")
    linearization_error = _of_the_world("linearization_error")
    contacts = _of_the_world("contacts")
    contact_force = _of_the_world("contact_force")
    friction_force = _of_the_world("friction_force")
    penetration = _of_the_world("penetration")
    actuator_residual = _of_the_world("actuator_residual")
    rigid_bodies = _of_the_world("rigid_bodies")
    attachments = _of_the_world("attachments")
