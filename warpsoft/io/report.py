"""Run reports: what a run did, step by step, as a JSON-ready dictionary."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import OutputError
from ..simulator import Simulator, StepStats
from .atomic import write_whole


def percentiles(values: list[float]) -> dict[str, float]:
    """Median, 90th percentile, mean, min and max of ``values`` (empty -> NaN-free zeros)."""
    if not values:
        return {"median": 0.0, "p90": 0.0, "mean": 0.0, "min": 0.0, "max": 0.0, "count": 0}
    a = np.asarray(values, dtype=float)
    return {"median": float(np.median(a)), "p90": float(np.percentile(a, 90)), "mean": float(a.mean()),
            "min": float(a.min()), "max": float(a.max()), "count": int(len(a))}


def jsonable(value):
    """Convert NumPy values and tuples to plain JSON types; non-finite floats become strings."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else str(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (str, int, bool)) or value is None:
        return value
    return repr(value)


class RunReport:
    """Collects per-step records of a simulator run, and how the run ended: ``status``
    ("running" until it ends, then "completed", "failed" or "interrupted") and ``error``.

    ``params`` are the scene parameters given, ``params_used`` all of them, defaults included;
    ``options`` the run's own settings (solver, tolerance, steps)."""

    def __init__(self, sim: Simulator, scene_file: str | None = None, params: dict | None = None,
                 params_used: dict | None = None, options: dict | None = None):
        self.sim, self.scene_file, self.params = sim, scene_file, dict(params or {})
        self.params_used = dict(params_used) if params_used is not None else dict(self.params)
        self.options = dict(options or {})
        self.status, self.error = "running", None
        self.steps: list[StepStats] = []
        self.points: dict[str, list] = {name: [] for name in sim.model.probe_names}
        self.W: list = []

    def record(self, stats: StepStats, probes: dict[str, np.ndarray]) -> None:
        self.steps.append(stats)
        for name, p in probes.items():
            self.points[name].append(np.asarray(p).tolist())
        rows = self.sim.rows
        if rows is not None and rows.num_actuators and self.sim.last_W is not None:
            self.W.append(self.sim.last_W[: rows.num_actuators].tolist())

    def _constraints(self) -> dict:
        if self.sim.rows is None:
            return {}
        acts, effs = self.sim.rows.actuators[0], self.sim.rows.effectors[0]  # a run is one world
        actuators = {a.name: {"kind": a.kind, "mode": a.mode,
                              "delta": [s.actuator_delta[a.name] for s in self.steps],
                              "lambda": [s.actuator_lambda[a.name] for s in self.steps],
                              "residual": [s.actuator_residual.get(a.name) for s in self.steps]} for a in acts}
        effectors = {e.name: [np.asarray(s.effectors[e.name]).tolist() for s in self.steps] for e in effs}
        out = {"actuators": actuators, "effectors": effectors,
               "W": self.W, "W_units": "cable m/N, cavity m^3/Pa (rows and columns in actuator order)",
               "compliance_iterations": [s.compliance_iterations for s in self.steps],
               "resolve_iterations": [s.resolve_iterations for s in self.steps],
               "resolve_residuals": [s.resolve_residual for s in self.steps],
               "linearization_error": [s.linearization_error for s in self.steps]}
        targeted = [e.name for e in effs if e.target is not None]
        if targeted:
            out["targets"] = {name: [np.asarray(s.targets[name]).tolist() for s in self.steps] for name in targeted}
            out["effector_error"] = {name: [s.effector_error[name] for s in self.steps] for name in targeted}
        if self.sim.rows.kind("contact") is not None:
            out["contacts"] = {"obstacles": [o.name for o in self.sim.model.scene.obstacles],
                               "rigid_bodies": [rb.name for rb in self.sim.model.scene.rigid_bodies],
                               "self_contact": [c.body.name for c in self.sim.model.scene.self_contacts],
                               "count": [s.contacts for s in self.steps],
                               "normal_force": [s.contact_force for s in self.steps],
                               "friction_force": [s.friction_force for s in self.steps],
                               "penetration": [s.penetration for s in self.steps],
                               "units": "forces N (sums over the contacts), penetration m"}
        if self.sim.model.rigid:
            out["rigid_bodies"] = {rb.name: {key: [np.asarray(s.rigid_bodies[rb.name][k]).tolist() for s in self.steps]
                                             for k, key in enumerate(("position", "orientation"))}
                                   for _, rb in self.sim.model.rigid}
            out["rigid_bodies_units"] = "centre of mass m; orientation a unit quaternion (x, y, z, w)"
        if self.sim.model.scene.attachments:
            out["attachments"] = {a.name: {"rigid_body": a.rigid.name, "body": a.body.name, "nodes": len(a.nodes),
                                           "force": [np.asarray(s.attachments[a.name]).tolist() for s in self.steps]}
                                  for a in self.sim.model.scene.attachments}
            out["attachments_units"] = "force N: what the rigid body puts on the held nodes (their sum)"
        if self.sim.model.scene.inverse:
            out["inverse"] = {"epsilon": self.sim.model.scene.inverse_epsilon,
                              "qp_status": [s.qp_status for s in self.steps],
                              "qp_seconds": [s.qp_seconds for s in self.steps]}
            if self.sim.model.scene.touches:  # the QPCC's pivots
                out["inverse"]["qp_pivots"] = [s.qp_pivots for s in self.steps]
        return out

    def to_dict(self) -> dict:
        m, sim = self.sim.model, self.sim
        timed = self.steps[1:] if len(self.steps) > 1 else self.steps  # step 1 compiles kernels
        stage_names = sorted({k for s in self.steps for k in s.stages})
        warnings = [w for s in self.steps for w in s.warnings]
        return jsonable({
            "scene": m.scene.name,
            "status": self.status,
            "error": self.error,
            "versions": versions(),
            "scene_file": self.scene_file,
            "params": self.params,
            "params_used": self.params_used,
            "options": self.options,
            "device": str(m.device),
            "solver": sim.solver_name,
            "static": m.static,
            "dt": m.dt,
            "dofs": m.num_dofs,
            "fixed_dofs": m.num_fixed_dofs,
            "nodes": m.num_nodes,
            "elements": m.num_elements,
            "bodies": [b.name for b in m.bodies],
            "steps": len(self.steps),
            "time": [s.time for s in self.steps],
            "points": self.points,
            "cg": {
                "tolerance": getattr(sim.solver, "tolerance", None),
                "iterations": [s.cg_iterations for s in self.steps],
                "residuals": [s.cg_residual for s in self.steps],
                "converged": [s.converged for s in self.steps],
            },
            "newton": {
                "tolerance": sim.newton.tolerance,
                "max_iterations": sim.newton.max_iterations,
                "iterations": [s.newton_iterations for s in self.steps],
                "residuals": [s.newton_residual for s in self.steps],
                "line_searches": [s.line_searches for s in self.steps],
            },
            "inverted_elements": [s.inverted_elements for s in self.steps],
            "stages_run": stage_names,
            "timings": {
                "note": "seconds; statistics exclude step 1 (kernel compilation) when there are 2+ steps",
                "step": percentiles([s.total for s in timed]),
                "stages": {k: percentiles([s.stages.get(k, 0.0) for s in timed]) for k in stage_names},
                "first_step": self.steps[0].total if self.steps else None,
                "per_step": [s.total for s in self.steps],
            },
            "warnings": warnings,
            **self._constraints(),
        })

    def write(self, path: str | Path) -> Path:
        """Write the report as JSON, atomically (a reader, or a kill mid-write, never sees half a file)."""
        path = Path(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            return write_whole(path, lambda tmp: tmp.write_text(json.dumps(self.to_dict(), indent=1)))
        except OSError as exc:  # the last whole report stays
            raise OutputError(f"report: cannot write {path}: {exc}") from exc


def versions() -> dict[str, str]:
    """warpsoft's, Warp's, NumPy's and Python's versions."""
    import platform

    import warp as wp

    from .. import __version__

    return {"warpsoft": __version__, "warp": wp.__version__, "numpy": np.__version__,
            "python": platform.python_version()}
