"""The Simulator: holds a model, its state and the step's work buffers, and steps every world
(see :mod:`warpsoft.step` for the step itself)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import warp as wp

from warpsoft.kernels import integrate
from warpsoft.kernels.rows import mapping

from . import step as stepping
from .drive import DrivenNodes
from .elastic import element_model
from .errors import SceneError, SimulationError
from .launch import launch
from .linear import SOLVERS, SystemOperator, choose, make_solver
from .linear.guess import Extrapolation
from .linear.operator import ASSEMBLED_FROM, OPERATORS
from .model import Model
from .newton import Newton
from .readback import Readback
from .resolve import GaussSeidel, kinematic_jacobian
from .resolve.contact_set import ContactSet
from .resolve.inverse_device import NMAX, DeviceInverse
from .reuse import FactorReuse
from .rigid import RigidBodies
from .rows import Rows
from .scene import Scene
from .state import Control, State
from .stats import ConvergenceWarning, StepStats, WorldStats

__all__ = ["ConvergenceWarning", "Simulator", "StepStats", "WorldStats"]

WARM_STARTS = {"extrapolate": "extrapolate", True: "extrapolate", "last": "last", "none": None, False: None}
AUTO_DEVICE_QP = 4  # qp="auto" on CUDA: the device QP for worlds of up to this many actuators (measured faster)


class Simulator:
    """Steps a scene, or every world of a model, on a device.

    Args:
        scene: the scene, a list of scenes (one world each, stepped together) or an already
            built :class:`Model` (:func:`warpsoft.finalize`).
        device: Warp device ("cpu", "cuda", "cuda:0"); Warp's default if None.
        solver: "auto" (``direct`` on the CPU device, ``pcg`` on CUDA), "pcg" (CG preconditioned
            by the warped rest factorization, the loop on the device), "direct" (assembled sparse
            Cholesky on the host, the CPU path and the accuracy reference) or "jacobi" (v1's
            block-Jacobi CG, kept for comparison). See :mod:`warpsoft.linear`.
        tolerance: CG relative residual |r| / |b|.
        max_iterations: CG iteration cap (reaching it is a warning in the step stats).
        warm_start: where each step's first solve starts: "extrapolate" (default; True): the
            quadratic through the last three steps' solutions in a dynamic model (``pcg`` and
            ``jacobi``: fewer iterations, see :mod:`warpsoft.linear.guess`; ``direct`` needs no
            start). A quasi-static step's solution is a correction toward equilibrium, not a
            smooth motion, and contacts and scheduled frames turn a world's motion abruptly: those
            start from the last solution. "last": the last step's solution, "none" (False): zero.
        timing: synchronize the device around stages to time them (CUDA only matters).
        check_every: ``jacobi`` only: the residual is read back every this many iterations
            (default: 1 on the CPU, where reading is free; 16 on CUDA).
        graphs: on CUDA, replay captured graphs (``pcg``: the device part of the whole step,
            one graph, or two around the host QP of the inverse model, stages then timed per graph;
            ``jacobi``: runs of ``check_every`` iterations).
        factorization: ``direct`` only: "cholmod" (default) or "superlu" (v1's).
        preconditioner: ``pcg`` only: how the warped factorization is applied, "host" (sparse
            solves), "dense" (a dense inverse of the whole model on the device), "blocks" (a dense
            inverse per world, shared by worlds equal up to a factor), "factors" (CHOLMOD's sparse
            factor per world instead, its triangular solves run on the device level by level: 60-90
            times fewer numbers than a dense inverse, made in milliseconds instead of seconds,
            for batches of many different meshes; a world's factor is made anew when its CG grows,
            by worker processes beside the steps: :data:`~warpsoft.linear.factors.WORLD_FLOOR`) or
            "auto" ("factors" on CUDA for several worlds, "dense" on CUDA for one, "host" on the CPU).
        precision: ``pcg`` with a dense inverse: its storage, "float32" (default: half the memory
            and bytes per iteration; the CG itself runs in float64, so the solution meets the
            same tolerance, at the cost of 0-2 more iterations on the reference scenes) or "float64".
        qp: the inverse model's QP: "piqp" (on the host through qpsolvers, the reference) or
            "device" (an exact dual active-set method on the device, one thread per world, up
            to 16 actuators: the inverse step stays one graph). "auto": the device QP on CUDA
            when no world has more than ``AUTO_DEVICE_QP`` (4) actuators, piqp otherwise and on
            the CPU. Measured on the H200: the device QP takes 87-127 us for 4 actuators (the
            Diamond: steps 1.69 -> 1.38 ms) but 0.6 ms for the Trunk's 8, more than piqp and its
            round trip (docs/performance.md).
        newton_iterations: most linearizations per step (Newton iterations; 1: one linearization,
            as v1). Most steps need one: the step iterates only when the nonlinear residual after
            it says so (a large time step against the motion, a body turning fast).
        newton_tolerance: the nonlinear residual along the last correction, relative to the
            correction's own (``|R . e| / e . A e``, see :mod:`warpsoft.newton`), at which a world's
            step is done; above it after ``newton_iterations``, the step warns. None (default):
            0.1 (quasi-static, implicit Euler); 1e-4 with the trapezoid, whose energy a looser step
            leaks. The README gives the measured energy errors.
        line_search: most shortened retries of a Newton step that overshot (0: full steps only).
        lazy_contacts: direct model with contacts, Gauss-Seidel on the host's CPU (the CPU device;
            on CUDA, between two graphs): resolve only the contacts that bear, found lazily
            (:mod:`warpsoft.resolve.contact_set`). With ``direct`` on the CPU, ``W`` is formed
            between them alone; elsewhere ``W`` holds every contact and only the sweeps shrink.
            False resolves every contact in contact distance (the same solution, for comparison).
        factor_reuse: ``direct`` only, opt-in: a world may solve a step with the factorization of
            an earlier linearization (a modified Newton step) when its step before converged in
            one iteration, without a line search, leaving a nonlinear residual at most this (the
            measure of ``newton_tolerance``; see :mod:`warpsoft.reuse`). Such a step must end
            within this residual too, or it iterates on a fresh factorization, and the world then
            asks more of its steps before it tries again; an iteration after a step's first always
            factorizes. Each world decides on its own history (one factor per world), so it steps
            in a batch as it does alone. 0 (default): a factorization at every linearization.
            Off by default because its error is not bounded by the Newton tolerance: the residual
            is measured with the kept tangent, which a spinning body turns away from, and drains
            its angular momentum unseen (``tests/test_integrator.py``, docs/performance.md).
        share_tolerance: ``pcg`` with ``preconditioner="blocks"`` or ``"factors"``: worlds of one mesh and supports
            share a dense inverse when their systems differ from multiples of each other by at most
            this (the largest entry's difference, relative). The default shares exact multiples only
            (quasi-static designs that differ in Young's modulus), so that each world iterates as it
            does alone; a larger value (0.01) also shares dynamic designs whose mass term is small
            against their stiffness, trading a few CG iterations for fewer host inversions and less
            device memory.
        block_cg: ``pcg`` only: a world's right-hand sides (its free motion and its actuators'
            compliance columns, up to 16) share one search space (block CG): one iteration moves
            every column along every column's direction, so the soft modes each column's CG
            finds on its own are found once (a sagging Diamond: 19 iterations against 37-44).
            Each world's columns then iterate until all of them reached the tolerance. Solves of
            contact columns, whose number changes, stay column by column. None (default): for a
            model of several worlds only. Measured on the H200 (docs/performance.md): 1024
            Diamonds step 1.18-1.29 times faster with it, one Diamond or Finger 0.1-1.2 ms
            slower (its small solves run on one thread, and an iteration takes two more launches).
        directions: ``pcg`` with the block CG: how its search directions ``P`` and ``Z = P^-1 R`` are
            stored, "float64", "float32" (half their bytes; the solution meets the same tolerance:
            ``X``, ``R`` and ``A P`` stay float64) or "auto" (default): float32 with
            ``preconditioner="factors"`` in float32 and the assembled operator (a batch on CUDA),
            float64 elsewhere.
        operator: how the iterative solvers apply ``A``: "matrix_free" (element by element, each
            product; what the direct solver's model has), "assembled" (its 3x3 node blocks
            gathered at each linearization, each product one pass over them for every column:
            :class:`~warpsoft.linear.operator.AssembledBlocks`) or "auto": assembled for the
            iterative solvers on CUDA from ``ASSEMBLED_FROM`` elements (a batch of designs; H200,
            1024 Diamonds: the product 3.46 -> 0.94 ms, the step 161.70 -> 133.56 ms), matrix-free
            elsewhere (one robot on the H200 was slower assembled: the refresh costs more than its
            few products save).
    """

    def __init__(self, scene: Scene | Sequence[Scene] | Model, device: str | None = None, solver: str = "auto",
                 tolerance: float = 1e-6, max_iterations: int = 2000, warm_start: bool | str = "extrapolate",
                 timing: bool = True, check_every: int | None = None, graphs: bool = True,
                 factorization: str = "cholmod", preconditioner: str = "auto", precision: str = "float32",
                 qp: str = "auto", newton_iterations: int = 10, newton_tolerance: float | None = None,
                 line_search: int = 4, lazy_contacts: bool = True, factor_reuse: float = 0.0,
                 share_tolerance: float = 1e-10, block_cg: bool | None = None, operator: str = "auto",
                 directions: str = "auto"):
        if solver not in SOLVERS:
            raise SceneError(f"Simulator: solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
        if not (0.0 < float(tolerance) < 1.0):
            raise SceneError(f"Simulator: tolerance must lie in (0, 1), got {tolerance!r}")
        if directions not in ("auto", "float64", "float32"):
            raise SceneError(f"Simulator: directions must be 'auto', 'float64' or 'float32', got {directions!r}")
        if int(max_iterations) < 1:
            raise SceneError(f"Simulator: max_iterations must be >= 1, got {max_iterations!r}")
        if qp not in ("auto", "piqp", "device"):
            raise SceneError(f"Simulator: qp must be 'auto', 'piqp' or 'device', got {qp!r}")
        if not isinstance(warm_start, (bool, str)) or warm_start not in WARM_STARTS:
            raise SceneError(f"Simulator: warm_start must be 'extrapolate', 'last', 'none', True or False, "
                             f"got {warm_start!r}")
        if not (0.0 <= float(factor_reuse) < 1.0):
            raise SceneError(f"Simulator: factor_reuse must lie in [0, 1), got {factor_reuse!r}")
        if not (0.0 <= float(share_tolerance) < 1.0):
            raise SceneError(f"Simulator: share_tolerance must lie in [0, 1), got {share_tolerance!r}")
        if operator not in OPERATORS:
            raise SceneError(f"Simulator: operator must be one of {', '.join(OPERATORS)}, got {operator!r}")
        if check_every is not None and int(check_every) < 1:
            raise SceneError(f"Simulator: check_every must be >= 1, got {check_every!r}")
        self.model = scene if isinstance(scene, Model) else Model(scene, device)
        m, d = self.model, self.model.device
        self.solver_name, self.warm_start, self.timing = choose(solver, d), WARM_STARTS[warm_start], bool(timing)
        self.factor_reuse = float(factor_reuse)
        if self.factor_reuse and self.solver_name != "direct":
            raise SceneError(f"Simulator: factor_reuse keeps the direct solver's factorization; solver "
                             f"{self.solver_name!r} has none (its preconditioner refreshes itself)")
        self.reuse = FactorReuse(self.factor_reuse, m.num_worlds)  # which worlds keep a factorization, step by step
        self.state, self.next = m.state(), m.state()
        self.time, self.step_index = 0.0, 0

        # Data: the step's work buffers
        n = m.num_nodes
        self.elastic = element_model(m)
        self.rot = wp.zeros(self.elastic.num_elements, dtype=wp.mat33d, device=d)  # element rotations
        self.f_int = wp.zeros(n, dtype=wp.vec3d, device=d)  # N
        self.f_ext = wp.zeros(n, dtype=wp.vec3d, device=d)  # N
        if m.f_const is not None:
            wp.copy(self.f_ext, m.f_const)
        self.dx = wp.zeros(n, dtype=wp.vec3d, device=d)  # a Newton iteration's correction (m)
        self.health_flag = wp.zeros(m.num_worlds, dtype=wp.int32, device=d)  # per world: non-finite nodes
        self.health_step = wp.zeros(m.num_worlds, dtype=wp.float64, device=d)  # per world: largest |dx|^2 (m^2)
        self.inverted = wp.zeros(m.num_worlds, dtype=wp.int32, device=d)  # elements with det F <= 0, per world
        # every probe's position (m), made once: a launch on the same arrays is replayed (launch.py)
        self.probes = wp.zeros(len(m.probe_names), dtype=wp.vec3d, device=d)
        self.size = float(np.linalg.norm(np.ptp(m.rest_np, axis=0)))  # model size (m) for step-size warnings

        h = m.dt
        # the share k of the step's end in its forces: implicit Euler takes them there (k = 1), the
        # trapezoid the mean of both ends (k = 1/2), which puts k^2 h^2 K, k h D in A and k h^2
        # before the rows' forces (the multipliers are the step's mean forces)
        self.end_share = 0.5 if m.integrator == "trapezoidal" else 1.0
        k = self.end_share
        if m.static:
            self.mass_scale, self.stiffness_scale = 0.0, 1.0
        else:  # A = M + k h D + k^2 h^2 K with D = a M + b K
            self.mass_scale = 1.0 + k * h * m.rayleigh_mass
            self.stiffness_scale = (k * h) ** 2 + k * h * m.rayleigh_stiffness
        assembled = operator == "assembled" or (operator == "auto" and d.is_cuda and self.solver_name != "direct"
                                                and self.elastic.num_elements >= ASSEMBLED_FROM)
        self.operator = SystemOperator(m, self.rot, self.elastic, assembled=assembled)
        self.operator.set_scales(self.mass_scale, self.stiffness_scale)

        self.driven = DrivenNodes(m) if m.driven else None  # fixed regions carried by a motion

        # constraint rows exist only when some world declares actuators, effectors or obstacles
        self.rows = None
        self.constraint_scale = 1.0 if m.static else k * h * h  # dx = dx_free + s X lambda, W = s H X
        ncol = 0
        if any(s.actuators or s.effectors or s.touches for s in m.scenes):
            self.rows = Rows(m)
            ncol = self.rows.num_columns
            self.gauss_seidel = GaussSeidel(self.rows)
            self.effector_weights = [np.concatenate([np.full(len(e.axes), e.weight) for e in effs]) if effs
                                     else np.zeros(0) for effs in self.rows.effectors]
        self.rigid = RigidBodies(m, self.rows) if m.num_rigid else None  # (their rows are contacts)
        self.device_inverse = None  # the inverse model's QP on the device, when asked for or faster
        # the inverse-model worlds with actuators (a step with any of them resolves a QP)
        self.inverse_worlds = inverse_worlds = [w for w, s in enumerate(m.scenes) if s.inverse and self.rows is not None
                                                and self.rows.world_actuators[w]]
        small = bool(inverse_worlds) and max(self.rows.world_actuators[w] for w in inverse_worlds) <= AUTO_DEVICE_QP
        # their QPCC runs on the host
        touching = [w for w in inverse_worlds if m.scenes[w].touches]
        if touching and qp == "device":
            raise SceneError(f"Simulator: qp='device' has no contacts, but inverse world {touching[0]} has "
                             "contacts (its QPCC runs on the host); use qp='piqp' or 'auto'")
        if inverse_worlds and not touching and (qp == "device" or (qp == "auto" and d.is_cuda and small)):
            self.device_inverse = DeviceInverse(self.rows, m.scenes, self.effector_weights)
            if not self.device_inverse.usable:
                raise SceneError(f"Simulator: qp='device' takes at most {NMAX} actuators per world, got "
                                 f"{int(max(self.rows.world_actuators))}; use qp='piqp'")
        # On CUDA, direct-model worlds with contacts sweep their Gauss-Seidel on the host, between
        # two graphs (as the host QP): one device thread sweeping a hundred contact rows takes 10
        # times what the host takes (the Grasper on an H200: 0.28 against 0.026 ms a sweep,
        # tools/gs_sweep.py; its step 74.9 -> 16-20 ms, docs/performance.md)
        self.host_gauss_seidel = d.is_cuda and self.rows is not None and any(
            not s.inverse and self.rows.world_contacts[w] for w, s in enumerate(m.scenes))
        self.last_effector_error: dict[int, float] = {}  # per inverse world, m (is its target getting closer?)
        self.episodes: dict[str, np.ndarray] = {}  # what -> whether a warning about it is in force, per world
        self.row_delta_prev = np.zeros(self.rows.num_rows if self.rows is not None else 0)  # rows after the last step
        self.report_layout = None  # where each world's named rows are (warpsoft.record.Layout), at the first step
        self._stepped = False
        self.values = None  # the actuator inputs of the current step, (rows,)
        self.own_inputs = None  # the actuators' own inputs laid out (warpsoft.inputs.own_inputs), at the first step
        # on CUDA, the device part of a step is replayed as graphs when the solver allows it
        self.capture = bool(graphs) and d.is_cuda
        self.graphs: dict = {}

        # One batched solve per step: column 0 is the free solve A dx_free = b, columns 1..
        # the compliance A X = H_a^T of each world's actuators (effectors alone need no column).
        # Both are warm-started from the last steps (see warm_start).
        self.rhs = wp.zeros((1 + ncol, n), dtype=wp.vec3d, device=d)
        self.sol = wp.zeros((1 + ncol, n), dtype=wp.vec3d, device=d)
        self.b, self.dx_free = self.rhs[0:1], self.sol[0:1]
        if ncol:
            self.columns, self.X = self.rhs[1:], self.sol[1:]
        self.solver = make_solver(self.solver_name, self.operator, 1 + ncol, tolerance, max_iterations, graphs,
                                  check_every, factorization, preconditioner, precision, share_tolerance,
                                  m.num_worlds > 1 if block_cg is None else bool(block_cg), directions)
        self.guess = None  # the extrapolated warm starts (iterative solvers)
        if self.warm_start == "extrapolate" and self.solver_name != "direct" and not m.static:
            held = (self.rows.world_actuators + self.rows.world_bilateral if self.rows is not None
                    else np.zeros(m.num_worlds, dtype=np.int32))
            # contacts and frames carried by a schedule turn a world's motion abruptly: it starts from
            # the last solutions (the Grasper on the H200: 2 CG iterations a step from them, 3-4 extrapolated)
            rough = [s.touches or any(f.motion is not None for f in s.fixtures) for s in m.scenes]
            self.guess = Extrapolation(1 + ncol, n, np.where(rough, -1, held), m.node_world, d)
        if ncol and self.rows.kind("contact") is not None and hasattr(self.solver, "bound"):
            self.solver.bound(self.rows.force_columns, 1)  # the free solve and the columns of the contacts in use
        if getattr(self.solver, "factor_compliance", False) and ncol:  # the correction's solve (no columns X)
            self.row_force = wp.zeros((1, n), dtype=wp.vec3d, device=d)  # s H^T lambda (N)
            self.row_motion = wp.zeros((1, n), dtype=wp.vec3d, device=d)  # A^-1 of it (m)
        # the Gauss-Seidel on the host's CPU (the CPU device, or between two graphs on CUDA) resolves
        # the contacts that bear, found lazily
        self.contact_set = None
        if (lazy_contacts and ncol and self.rows.kind("contact") is not None and not inverse_worlds
                and (d.is_cpu or self.host_gauss_seidel)):
            self.contact_set = ContactSet(self)
        self.solve_result = None  # the last solve's outcome, when it ran outside a graph
        if newton_tolerance is None:
            newton_tolerance = 1e-4 if m.integrator == "trapezoidal" and not m.static else 0.1
        self.newton = Newton(self, newton_iterations, newton_tolerance, line_search)
        self.operator.moving = self.newton.moving_flag  # a later iteration relinearizes the worlds that moved alone
        if hasattr(self.solver, "hold"):  # a world Newton holds in place (alpha 0) is not solved again
            self.solver.hold(self.newton.alpha)

        # what the host reads of a step, in one transfer each: before the inverse model's QP, and
        # after the step (the solver's outcome, health, rows at the new state)
        after = {"health_flag": self.health_flag, "health_step": self.health_step, "inverted": self.inverted,
                 "newton": self.newton.sums, "newton_slope": self.newton.slope0}
        if self.newton.moments.shape[0]:  # (a world free to move as a whole)
            after["newton_moments"] = self.newton.moments
        after |= getattr(self.solver, "readback_arrays", dict)()
        self.before_qp = None
        if self.rows is not None:
            after["delta"], after["points"] = self.rows.delta, self.rows.points
            if self.rows.num_columns:
                gs = self.gauss_seidel
                after |= {"lam": gs.lam, "resolve": gs.result, "W": self.rows.W, "delta_free": self.rows.delta_free,
                          "force_rows": self.rows.world_force_rows}
                if self.device_inverse is not None:
                    after["qp"] = self.device_inverse.result
                self.before_qp = Readback({"W": self.rows.W, "delta_free": self.rows.delta_free,
                                           "delta": self.newton.delta_start, "lam": gs.lam,
                                           "force_rows": self.rows.world_force_rows, "friction": gs.friction}, d)
            contact = self.rows.kind("contact")
            if contact is not None:
                after["contacts_found"] = contact.found
        if self.rigid is not None:
            after |= {"rigid_p": self.rigid.pose_p, "rigid_r": self.rigid.pose_r}
        self.after_step = Readback(after, d)

    # ---- the step ------------------------------------------------------------------------
    def step(self, control: Control | Sequence[Control | None] | None = None) -> StepStats:
        """Advance every world by one step; on a non-finite result raise and keep the old state.

        ``control`` overrides actuator inputs for this step (by actuator name): one Control for a
        one-world model, a list with one Control (or None) per world otherwise.
        """
        controls = self._controls(control)
        try:
            stats = stepping.step(self, controls)
        except SceneError:
            raise
        except SimulationError:
            self.forget_warm_starts()
            raise
        except (RuntimeError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            self.forget_warm_starts()
            raise SimulationError(f"step {self.step_index + 1} (t = {self.time + self.model.dt:g} s) failed in a "
                                  f"solver: {type(exc).__name__}: {exc}; the state before the step is kept") from exc
        self._stepped = True
        return stats

    def _controls(self, control) -> list[Control | None]:
        worlds = self.model.num_worlds
        if control is None or isinstance(control, Control):
            if control is not None and worlds > 1:
                raise SceneError(f"control: this model has {worlds} worlds: give a list of {worlds} Controls")
            return [control] * worlds
        controls = list(control)
        if len(controls) != worlds or not all(c is None or isinstance(c, Control) for c in controls):
            raise SceneError(f"control: expected {worlds} Control(s) or None, one per world, got {control!r:.80}")
        return controls

    def world_label(self, world: int | Sequence[int]) -> str:
        """" (world w)", or " (worlds a, b)" for several, in messages of a model of several
        worlds; "" with one."""
        if self.model.num_worlds == 1:
            return ""
        worlds = [world] if isinstance(world, (int, np.integer)) else list(world)
        return f" (world{'s' if len(worlds) > 1 else ''} {', '.join(map(str, worlds))})"

    def forget_warm_starts(self) -> None:
        """A poisoned warm start would spoil the next attempt: the solutions and, since a captured
        step runs to its end before its result is read, the multipliers too."""
        self.sol.zero_()
        if self.guess is not None:
            self.guess.forget()
        if self.rows is not None:
            self.gauss_seidel.lam.zero_()

    # ---- what a step leaves ----------------------------------------------------------------
    @property
    def lam(self) -> np.ndarray:
        """Multipliers of the actuator rows (N, Pa) after the last step, in row order (all worlds)."""
        if self.rows is None or not self.rows.num_actuators:
            return np.zeros(0)
        lam = self.gauss_seidel.lam.numpy()
        return np.concatenate([lam[self.rows.actuator_rows(w)] for w in range(self.model.num_worlds)])

    @property
    def last_W(self) -> np.ndarray | None:
        """Compliance of the last step (m/N, m^3/Pa), ``(rows, columns)``: each row against its
        own world's actuator columns; None before the first step or without actuators."""
        if self.rows is None or not self.rows.num_actuators or not self._stepped:
            return None
        return self.rows.W.numpy().copy()

    def constraint_geometry(self, world: int = 0) -> dict:
        """Rows of ``world`` at the current state: cable polylines (m, pull point first) by cable
        name, effector positions and targets (m) by effector name, the pose
        ``(rotation, translation)`` that carries each moving obstacle and rigid body from where it
        was declared, by name, and with contacts the contacts in use: ``(points (k, 3) m,
        forces (k, 3) N)``, the force on the touching point."""
        rows = self.rows
        moving = {e.name: e.pose(self.time) for e in self.model.scenes[world].obstacles if e.motion is not None}
        moving |= self.rigid_motions(world)
        if rows is None:
            return {"cables": {}, "effectors": {}, "targets": {}, "obstacles": moving}
        rows.evaluate(self.state.q, self.state)
        targets = rows.set_time(self.time)
        out = {"cables": rows.cable_paths(world), "effectors": rows.effector_positions(world),
               "targets": rows.targets(targets, world), "obstacles": moving}
        contact = rows.kind("contact")
        if contact is not None:
            out["contacts"] = contact.forces(rows, world, self.gauss_seidel.lam.numpy())
        return out

    def rigid_poses(self, world: int | None = None, state: State | None = None) -> dict[str, tuple]:
        """``name -> (rotation 3x3, centre of mass (3,) m)`` of each rigid body (of ``world`` only,
        if given), read from the device; {} without rigid bodies."""
        if self.rigid is None:
            return {}
        return self.rigid.poses(state or self.state, world)

    def rigid_motions(self, world: int = 0) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """``name -> (rotation, translation)``: the rigid motion that carries each rigid body of
        ``world`` from where it was declared to where it is (``x -> R (x - c0) + c``)."""
        centers = {rb.name: rb.center for w, rb in self.model.rigid if w == world}
        return {name: (rot, p - rot @ centers[name]) for name, (rot, p) in self.rigid_poses(world).items()}

    def kinematic_jacobian(self, world: int = 0) -> np.ndarray:
        """``W_ea W_aa^-1`` of the last step: effector-axis motion (m) per unit actuator
        displacement of ``world``, ``(effector rows, actuators)``."""
        rows, W = self.rows, self.last_W
        if rows is None or not rows.world_actuators[world] or not rows.effectors[world] or W is None:
            raise SceneError("kinematic_jacobian: needs actuators, effectors and one step")
        na = int(rows.world_actuators[world])
        return kinematic_jacobian(W[rows.effector_rows(world), :na], W[rows.actuator_rows(world), :na])

    def positions(self, world: int = 0, state: State | None = None) -> np.ndarray:
        """Node positions (m) of ``world``, ``(n_world, 3)``, a copy."""
        return (state or self.state).q.numpy()[self.model.world_nodes(world)].copy()

    def probe_positions(self, state: State | None = None, world: int | None = None) -> dict[str, np.ndarray]:
        """Current position (m) of each probe point, by name (of ``world`` only, if given; with
        several worlds, names must then be told apart by world)."""
        m = self.model
        if m.probe_nodes is None:
            return {}
        if world is None and m.num_worlds > 1:
            raise SceneError(f"probe_positions: this model has {m.num_worlds} worlds: say which (world=...)")
        return {name: p for name, p, w in zip(m.probe_names, self.probe_array(state), m.probe_world, strict=True)
                if world is None or w == world}

    def probe_array(self, state: State | None = None) -> np.ndarray:
        """Every probe of every world at once (m), ``(probes, 3)`` in the model's order
        (``model.probe_names``, ``model.probe_world``): one launch and one read."""
        m = self.model
        if m.probe_nodes is None:
            return np.zeros((0, 3))
        launch(mapping.interpolate_points, len(m.probe_names),
               inputs=[(state or self.state).q, m.probe_nodes, m.probe_weights], outputs=[self.probes],
               device=m.device)
        return self.probes.numpy().copy()  # (on the CPU device a view of the buffer: the caller keeps a copy)

    def internal_forces(self, state: State | None = None) -> np.ndarray:
        """Internal forces (N), ``(n, 3)``, at ``state`` (current by default)."""
        m = self.model
        f = wp.zeros(m.num_nodes, dtype=wp.vec3d, device=m.device)
        rot = wp.zeros(self.elastic.num_elements, dtype=wp.mat33d, device=m.device)
        self.elastic.linearize((state or self.state).q, rot, f)
        return f.numpy()

    def energy(self, state: State | None = None) -> dict[str, float]:
        """Kinetic, elastic and gravitational potential energy (J) of ``state``, all worlds."""
        m, s = self.model, state or self.state
        acc = wp.zeros(2, dtype=wp.float64, device=m.device)
        self.elastic.energy(s.q, acc[0:1])
        if m.mass is not None and not m.static:
            launch(integrate.kinetic_energy, m.num_nodes, inputs=[s.v, m.mass], outputs=[acc[1:2]],
                   device=m.device)
        elastic, kinetic = (float(v) for v in acc.numpy())
        potential = 0.0
        if m.has_gravity:
            g = np.array([sc.gravity for sc in m.scenes])[m.node_world_np]
            potential = -float(np.sum(m.mass_np[:, None] * s.q.numpy() * g))
        return {"kinetic": kinetic, "elastic": elastic, "gravity": potential,
                "total": kinetic + elastic + potential}
