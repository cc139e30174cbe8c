"""What a step did: StepStats (the whole step) and WorldStats (each world's rows)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .errors import SceneError


class ConvergenceWarning(UserWarning):
    """An iterative solve stopped at its iteration cap above its tolerance."""


# a world's fields and their defaults (a type: a new one for each world, made when first read)
FIELDS: dict[str, object] = {
    "cg_iterations": 0, "resolve_iterations": 0, "resolve_residual": 0.0, "qp_status": "", "qp_seconds": 0.0,
    "qp_pivots": 0, "inverted_elements": 0, "linearization_error": 0.0, "newton_iterations": 0,
    "newton_residual": 0.0, "contacts": 0, "contact_force": 0.0, "friction_force": 0.0, "penetration": 0.0,
    "actuator_residual": dict, "effector_error": dict, "actuator_delta": dict, "actuator_lambda": dict,
    "effectors": dict, "targets": dict, "rigid_bodies": dict, "attachments": dict}


class WorldRecord:
    """Every world's share of one step as the step made it, for all worlds at once: a number per
    world in ``columns`` (name -> ``(worlds,)`` array), or in ``makers`` a function of the world
    that makes its value (its dictionaries by name). A world's :class:`WorldStats` reads its own
    when first asked, so a step of many worlds builds no per-world Python objects unless they
    are read (1024 Diamonds, CPU VM: the report's loops over the worlds took about 11 ms a
    step; docs/performance.md)."""

    def __init__(self, worlds: int):
        self.worlds = worlds
        self.columns: dict[str, np.ndarray] = {}
        self.makers: dict[str, Callable[[int], object]] = {}

    def add(self, name: str, values: np.ndarray | list) -> None:
        """Add ``values`` ``(worlds,)`` to column ``name`` (a step's Newton iterations add up)."""
        old = self.columns.get(name)
        self.columns[name] = np.array(values) if old is None else old + np.asarray(values)

    def value(self, name: str, w: int) -> object:
        """World ``w``'s ``name`` as the step recorded it, or :data:`MISSING`."""
        column = self.columns.get(name)
        if column is not None:
            return column[w].item()  # (a Python number, as the fields always were)
        maker = self.makers.get(name)
        return MISSING if maker is None else maker(w)


MISSING = object()  # a field the step did not record for all worlds: set on the world, or its default


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

    __slots__ = ("_record", "_world", "_values")

    def __init__(self, record: WorldRecord | None = None, world: int = 0, **values):
        unknown = set(values) - FIELDS.keys()
        if unknown:
            raise TypeError(f"WorldStats: no field named {', '.join(sorted(unknown))}")
        self._record, self._world, self._values = record, world, values

    def _get(self, name: str) -> object:
        """The field ``name``: set on this world, else recorded for all worlds, else its default
        (kept once made, so that a dictionary read twice is the same one and takes changes)."""
        if name in self._values:
            return self._values[name]
        value = MISSING if self._record is None else self._record.value(name, self._world)
        if value is MISSING:
            default = FIELDS[name]
            value = default() if isinstance(default, type) else default
        self._values[name] = value
        return value

    def as_dict(self) -> dict[str, object]:
        """Every field, by name."""
        return {name: self._get(name) for name in FIELDS}

    def __repr__(self) -> str:
        return "WorldStats(" + ", ".join(f"{k}={v!r}" for k, v in self.as_dict().items()) + ")"


def _world_field(name: str) -> property:
    def get(self: WorldStats):
        return self._get(name)

    def put(self: WorldStats, value) -> None:
        self._values[name] = value

    return property(get, put, doc=f"The world's ``{name}`` (see :class:`WorldStats`).")


for _name in FIELDS:
    setattr(WorldStats, _name, _world_field(_name))


class Worlds(Sequence):
    """``StepStats.worlds``: each world's :class:`WorldStats`, made when first read from the
    step's :class:`WorldRecord` (then kept: what is set on it stays)."""

    def __init__(self, record: WorldRecord):
        self.record = record
        self._made: list[WorldStats | None] = [None] * record.worlds

    def __len__(self) -> int:
        return self.record.worlds

    def __getitem__(self, w):
        if isinstance(w, slice):
            return [self[i] for i in range(*w.indices(len(self)))]
        w = range(len(self))[w]  # (negative indices; out of range raises IndexError)
        ws = self._made[w]
        if ws is None:
            ws = self._made[w] = WorldStats(self.record, w)
        return ws


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
    worlds: Sequence[WorldStats] = field(default_factory=list)

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
