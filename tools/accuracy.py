"""What accuracy costs in time, v2: errors against analytic solutions or converged references.

    python tools/accuracy.py [--quick] [--device cpu|cuda] [--studies NAME ...] [--gpu-csv CSV]
                             [--softrobots DIR] [--out docs/accuracy]

Each study sweeps the settings a user chooses (mesh size, element model, Poisson ratio, solver
and its tolerance, time step and integrator, and on CUDA the preconditioner's precision) and
measures, per setting, the error of a quantity of interest, the step time (median) and the
memory of the simulator's Warp arrays (on CUDA a world of up to 12k free DOFs adds its dense
preconditioner, 4 n^2 bytes in float32):

- ``cantilever``: tip deflection under a small tip load against Timoshenko's beam;
- ``cable_bar``: the mid-point of a bar compressed by its cable against ``T (L/2) / (E A)``;
- ``sphere``: the cavity growth of a pressurised thick sphere against Lame's solution;
  (each at nu 0.3, 0.45 and 0.49, with linear corotational, 10-node and Neo-Hookean tetrahedra;
  the beam and bar references are one-dimensional theories: their clamps add a 3D effect that
  no mesh removes, measured as the floor the finest meshes reach);
- ``finger``: the Finger's tip pulled by 4 mm of cable, split 0-2 times, 10-node elements on the
  two coarser meshes, against the extrapolation of the linear ones;
- ``pneunet``: the PneuNet's tip under 3 kPa (a distributed load bending 2.5 mm walls), its 7 mm
  mesh split 0-2 times in linear elements and 0-1 times in 10-node ones, against the
  extrapolation of the two 10-node meshes at an assumed order 1 (a third split, 1.1M DOFs, does
  not fit);
- ``swing``: the cantilever falling under gravity, its tip's trajectory over 0.2 s against a
  trapezoid reference at 0.25 ms, by time step and integrator;
- ``figure8_*``: the paper's Figure 8, the Diamond's effector with three of its four cables
  driven by displacement and the same motion driven by force (the tensions the finest mesh
  needs), on warpsoft's Diamond (its gmsh mesh at 10 mm) and on SoftRobots' ``diamond.vtk``,
  each split 0, 1 and 2 times: errors against the Richardson extrapolation of the three meshes,
  whose own error estimate the summary states (or that they do not converge monotonically);
  10-node elements on the two coarser meshes, against the same reference.

On CUDA the settings the CPU solves directly are solved by the device's default solver (CG to
1e-6, preconditioned by the rest factorization: ``solver="auto"``), their step time is what a
user of the GPU gets; the CG axis adds the preconditioner's precision (float32, float64); the
Poisson ratio is left at 0.45 (the time does not depend on it).

Writes accuracy.csv, accuracy.png (error against step time per study, its Pareto front),
figure8.png and summary.md (what each setting costs, the recommended defaults). ``--gpu-csv``:
the CSV of the same sweep run with ``--device cuda``, whose step times and memory join the table.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import warp as wp

from warpsoft import Simulator
from warpsoft.io.runner import build_scene, load_scene_module

sys.path.insert(0, str(Path(__file__).resolve().parent))
from accuracy_report import BASE, plot_figure8, plot_pareto, summary  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SOFTROBOTS = ROOT.parent / "shared" / "reference" / "softrobots"  # SoftRobots' meshes (--softrobots)
NUS = (0.3, 0.45, 0.49)
ELEMENTS = ("corotational", "quadratic", "neohookean")
DIAMOND_PULL = (0.006, 0.003, 0.004)  # the three driven cables' shortening (m); the fourth is free


@dataclass
class Study:
    """A swept scene: ``grid`` maps each scene parameter to its values (one solve per
    combination, on every mesh); ``quantity(sim, stats)`` is what is compared (m, m^3);
    ``reference(params)`` the analytic value, or None for a Richardson extrapolation over the
    three finest meshes (``mesh_param`` ``refine``: nested, ratio 2; else sizes in a ratio)."""

    name: str
    scene: str
    params: dict
    steps: int
    quantity: object
    reference: object | None
    meshes: list
    grid: dict = field(default_factory=dict)
    solvers: list = field(default_factory=lambda: [("direct", 0.0)])
    mesh_param: str = "mesh_size"
    compared: int | None = None  # the quantity's leading components compared (None: all)
    drive: str = ""  # Figure 8: "displacement" or "force"
    others: dict = field(default_factory=dict)  # element -> meshes, scored against the sweep's reference
    # the order of convergence assumed where only the two finest meshes of the sweep can be solved (their
    # extrapolation at that order is the reference, and its distance to the finest that mesh's stated error)
    order: float | None = None

    @property
    def sweep(self) -> str:
        """The element of the sweep whose meshes give the reference."""
        return self.grid.get("element", ("corotational",))[0]


def tip(sim, stats):
    return sim.probe_positions()["tip"] - np.array([0.1, 0.0, 0.0])


def mid(sim, stats):
    return sim.probe_positions()["mid"] - np.array([0.05, 0.0, 0.0])


def finger_tip(sim, stats):
    """The fingertip's motion (m), then the cable's tension (N): compared on the first three."""
    motion = sim.probe_positions()["tip"] - np.array([-0.085, 0.0075, 0.01])
    return np.concatenate([motion, [stats.actuator_lambda["cable"]]])


def pneunet_tip(sim, stats):
    """The PneuNet's tip motion (m), then its cavity's volume growth (m^3): compared on the first three."""
    motion = sim.probe_positions()["tip"] - np.array([0.115, 0.01, 0.0025])
    return np.concatenate([motion, [stats.actuator_delta["chambers"]]])


def cavity(sim, stats):
    return np.array([stats.actuator_delta["cavity"]])


def effector(sim, stats):
    """The effector's motion (m), then the three driven cables' tensions (N): compared on the first three."""
    motion = sim.constraint_geometry()["effectors"]["effector"] - np.array([0.0, 0.0, 0.125])
    return np.concatenate([motion, [stats.actuator_lambda[f"cable{i}"] for i in range(3)]])


def analytic(scene: str, function: str, keys: tuple, sign: float = 1.0, axis: int | None = None):
    module = load_scene_module(ROOT / scene)

    def reference(params: dict) -> np.ndarray:
        value = sign * getattr(module, function)(**{k: params[k] for k in keys if k in params})
        if axis is None:
            return np.array([value])
        out = np.zeros(3)
        out[axis] = value
        return out
    return reference


def bar_reference(params: dict) -> np.ndarray:
    # compressed by the cable's tension T: the mid-point moves T (L/2) / (E A) toward the clamp
    return np.array([-params["cable_force"] * 0.05 / (params["young_modulus"] * 1e-4), 0.0, 0.0])


def studies(quick: bool, softrobots: Path = SOFTROBOTS) -> list[Study]:
    elastic = {"poisson_ratio": NUS, "element": ELEMENTS}
    cg = [("direct", 0.0), ("pcg", 1e-4), ("pcg", 1e-6), ("pcg", 1e-8)]
    diamond = {"static": True, "dt": 1.0, "gravity": 0.0, "ramp_time": 1.0,
               "cable_displacements": (*DIAMOND_PULL, 0.0), "cable_forces": (None, None, None, 0.0)}
    if quick:
        return [
            Study("cantilever", "scenes/validation/cantilever.py", {"tip_force": 0.001, "young_modulus": 1e6},
                  1, tip, analytic("scenes/validation/cantilever.py", "timoshenko_tip_deflection",
                                   ("length", "width", "height", "young_modulus", "poisson_ratio", "tip_force"),
                                   -1.0, 2),
                  [0.005, 0.0033], {"poisson_ratio": (0.45,), "element": ("corotational", "quadratic")},
                  [("direct", 0.0), ("pcg", 1e-6)]),
            Study("cantilever_nested", "scenes/validation/cantilever.py",
                  {"tip_force": 0.001, "young_modulus": 1e6, "mesh_size": 0.005}, 1, tip, None, [0, 1, 2],
                  {"poisson_ratio": (0.3,)}, mesh_param="refine"),
            Study("figure8_warpsoft", "scenes/diamond.py", diamond | {"mesh_size": 0.03}, 1, effector, None,
                  [0, 1], mesh_param="refine", compared=3, drive="displacement", others={"quadratic": [0]}),
        ]
    return [
        Study("cantilever", "scenes/validation/cantilever.py", {"tip_force": 0.001, "young_modulus": 1e6}, 1, tip,
              analytic("scenes/validation/cantilever.py", "timoshenko_tip_deflection",
                       ("length", "width", "height", "young_modulus", "poisson_ratio", "tip_force"), -1.0, 2),
              [0.005, 0.0033, 0.0025, 0.002], elastic, cg),
        Study("cable_bar", "scenes/validation/cable_bar.py", {"cable_force": 0.05, "young_modulus": 1e6}, 1, mid,
              bar_reference, [0.005, 0.0033, 0.0025, 0.002], elastic),
        Study("cantilever_nested", "scenes/validation/cantilever.py",
              {"tip_force": 0.001, "young_modulus": 1e6, "mesh_size": 0.005}, 1, tip, None, [0, 1, 2],
              {"poisson_ratio": NUS}, mesh_param="refine"),
        Study("sphere", "scenes/validation/pressure_sphere.py", {}, 1, cavity,
              analytic("scenes/validation/pressure_sphere.py", "lame_volume_growth",
                       ("inner_radius", "outer_radius", "young_modulus", "poisson_ratio", "pressure")),
              [0.005, 0.0033, 0.0025, 0.00167], elastic),
        Study("finger", "scenes/finger.py", {"static": True, "dt": 1.0, "ramp_time": 1.0, "gravity": 0.0,
                                              "cable_displacement": 0.004}, 1, finger_tip, None, [0, 1, 2],
              mesh_param="refine", compared=3, others={"quadratic": [0, 1]}),
        # the reference: 10-node meshes (the linear ones lock in the 2.5 mm walls); a third split (1.1M DOFs)
        # did not fit (docs/performance.md), so the two are extrapolated at order 1, about the order the
        # chambers' 270-degree re-entrant edges leave a displacement (h^1.09)
        Study("pneunet", "scenes/pneunet.py", {"static": True, "dt": 1.0, "ramp_time": 1.0, "mesh_size": 0.007}, 1,
              pneunet_tip, None, [0, 1], {"element": ("quadratic",)}, mesh_param="refine", compared=3,
              others={"corotational": [0, 1, 2]}, order=1.0),
        Study("figure8_warpsoft", "scenes/diamond.py", diamond | {"mesh_size": 0.01}, 1, effector, None,
              [0, 1, 2], mesh_param="refine", compared=3, drive="displacement", others={"quadratic": [0, 1]}),
        Study("figure8_softrobots", "scenes/diamond.py", diamond | {"mesh": str(softrobots / "diamond.vtk")}, 1,
              effector, None, [0, 1, 2], mesh_param="refine", compared=3, drive="displacement",
              others={"quadratic": [0, 1]}),
    ]


# ---- one solve ----------------------------------------------------------------------------
def memory_bytes(sim: Simulator) -> int:
    """Bytes of the distinct Warp buffers the simulator holds (its model, state, work buffers,
    solver; not a host factorization's)."""
    seen, sizes = set(), {}

    def walk(obj, depth: int) -> None:
        if id(obj) in seen or depth > 6:
            return
        seen.add(id(obj))
        if isinstance(obj, wp.array):
            if obj.ptr:
                sizes[obj.ptr] = max(sizes.get(obj.ptr, 0), obj.capacity)
        elif isinstance(obj, dict):
            for v in obj.values():
                walk(v, depth + 1)
        elif isinstance(obj, (list, tuple)):
            for v in obj:
                walk(v, depth + 1)
        elif type(obj).__module__.startswith("warpsoft") and hasattr(obj, "__dict__"):
            for v in vars(obj).values():
                walk(v, depth + 1)
    walk(sim, 0)
    return sum(sizes.values())


def solve(study: Study, params: dict, device: str, solver: str, tol: float, precision: str = "float32",
          timed: int = 3) -> dict:
    """Run ``study.steps`` steps from rest and read the quantity; then ``timed`` more solves from
    rest (the CG started from 0) at the default Newton tolerance, whose median is the step time
    (ms; one solve above 100k DOFs). (The quantity's Newton iterations run to 1e-4: its error is
    the discretization's, not a step's.)"""
    d = wp.get_device(device)
    # "auto": the device's default solver at its default tolerance (CUDA: CG to 1e-6)
    sim = Simulator(build_scene(ROOT / study.scene, params), device=device, solver=solver,
                    tolerance=tol or (1e-6 if solver == "auto" else 1e-8), max_iterations=20000, precision=precision,
                    newton_tolerance=1e-4, newton_iterations=30)
    rest_q, rest_v = wp.clone(sim.state.q), wp.clone(sim.state.v)
    for _ in range(study.steps):
        stats = sim.step()
    value, converged = study.quantity(sim, stats), bool(stats.converged)
    times, its = [], []
    sim.newton.tolerance = 0.1  # timed as a step of the default setting goes
    for _ in range(timed if sim.model.num_dofs < 100_000 else 1):
        sim.time, sim.step_index = 0.0, 0
        wp.copy(sim.state.q, rest_q)
        wp.copy(sim.state.v, rest_v)
        sim.sol.zero_()
        t0 = time.perf_counter()
        st = sim.step()
        wp.synchronize_device(d)
        times.append(1e3 * (time.perf_counter() - t0))
        its.append(st.cg_iterations)
    return {"dofs": sim.model.num_dofs, "value": value, "step_ms": float(np.median(times)),
            "cg_iterations": float(np.median(its)), "converged": converged, "memory_mb": memory_bytes(sim) / 2 ** 20}


def richardson(values: list[np.ndarray], ratio: float) -> tuple[np.ndarray, float, float, bool]:
    """The extrapolated quantity from three meshes, coarse to fine, their sizes in ``ratio``;
    the observed order (2 where the three do not converge monotonically), the error of the
    finest mesh it implies, relative, and whether they converge monotonically (the successive
    changes in one direction and shrinking: else the extrapolation is a trend, not a reference)."""
    q1, q2, q3 = values
    d12, d23 = np.linalg.norm(q1 - q2), np.linalg.norm(q2 - q3)
    monotone = bool(0 < d23 < d12 and np.dot(q1 - q2, q2 - q3) > 0)
    order = float(np.log(d12 / d23) / np.log(ratio)) if monotone else 2.0
    order = min(max(order, 0.5), 4.0)
    extrapolated = q3 + (q3 - q2) / (ratio ** order - 1.0)
    return extrapolated, order, float(np.linalg.norm(q3 - extrapolated) / np.linalg.norm(extrapolated)), monotone


# ---- a study ------------------------------------------------------------------------------
def combinations(grid: dict) -> list[dict]:
    combos = [{}]
    for key, values in grid.items():
        combos = [c | {key: v} for c in combos for v in values]
    return combos


def base_solver(device: str) -> str:
    """The solver a study's references come from: the CPU's direct solve, CUDA's default."""
    return "auto" if wp.get_device(device).is_cuda else "direct"


def run_study(study: Study, device: str, precisions: tuple) -> list[dict]:
    """Every setting of ``study`` on every mesh, each row scored against the reference of its
    combination's direct solves (on CUDA: the default solver's), then ``study.others``'
    elements against that same reference."""
    base = base_solver(device)
    rows = []
    for combo in combinations(study.grid):
        settings = [(base if s == "direct" else s, t, p) for s, t in study.solvers
                    for p in (precisions if s == "pcg" else ("",))]
        if combo.get("element", "corotational") != "corotational" or combo.get("poisson_ratio", 0.45) != 0.45:
            settings = [x for x in settings if x[0] == base]  # the solver axis: corotational, nu 0.45
        here, results = [], {}
        for mesh in study.meshes:
            for solver, tol, precision in settings:
                r = solve(study, study.params | combo | {study.mesh_param: mesh}, device, solver, tol,
                          precision or "float32")
                results[(mesh, solver, tol, precision)] = r
                here.append(row(study, combo, mesh, r, solver, tol, precision))
        ref = reference(study, combo, [results[(m, base, 0.0, "")] for m in study.meshes])
        for element, meshes in study.others.items():
            for mesh in meshes:
                other = combo | {"element": element}
                r = solve(study, study.params | other | {study.mesh_param: mesh}, device, base, 0.0)
                here.append(row(study, other, mesh, r, base, 0.0, ""))
        score(here, ref, study.compared)
        rows += here
    return rows


def row(study: Study, combo: dict, mesh, r: dict, solver: str, tol: float, precision: str) -> dict:
    print(f"  {study.name} {study.drive} {combo} {study.mesh_param} {mesh}: {r['dofs']} DOFs {solver} {tol or ''} "
          f"{precision} {r['value']} ({r['step_ms']:.1f} ms)", flush=True)
    return {"study": study.name, "element": combo.get("element", "corotational"),
            "poisson_ratio": (study.params | combo).get("poisson_ratio", 0.45), "drive": study.drive, "mesh": mesh,
            "dofs": r["dofs"], "solver": solver, "tolerance": tol or "", "precision": precision, "dt": "",
            "integrator": "", "value": r["value"], "step_ms": r["step_ms"], "cg_iterations": r["cg_iterations"],
            "converged": r["converged"], "memory_mb": r["memory_mb"]}


def reference(study: Study, combo: dict, base: list[dict]) -> tuple:
    """The reference of a combination, from its base solves on ``study.meshes`` (coarse to fine):
    ``(value, kind, the finest mesh's estimated error, observed (or assumed) order, the element of
    the meshes it comes from)``."""
    n = study.compared
    if study.reference is not None:
        return study.reference(study.params | combo), "analytic", "", "", ""
    if len(base) < (2 if study.order else 3):  # too few for an extrapolation: the finest mesh
        return base[-1]["value"][:n], "finest", "", "", study.sweep
    # the element sizes' ratio: 2 for nested splits; for gmsh meshes, from their node counts
    ratio = 2.0 if study.mesh_param == "refine" else (base[-1]["dofs"] / base[-2]["dofs"]) ** (1.0 / 3.0)
    if len(base) == 2:  # two meshes: Richardson at the assumed order
        q1, q2 = (b["value"][:n] for b in base)
        value = q2 + (q2 - q1) / (ratio ** study.order - 1.0)
        estimate = float(np.linalg.norm(q2 - value) / np.linalg.norm(value))
        return value, "assumed order", estimate, study.order, study.sweep
    value, order, estimate, monotone = richardson([b["value"][:n] for b in base[-3:]], ratio)
    return value, "extrapolated" if monotone else "not monotone", estimate, order, study.sweep


def score(rows: list[dict], ref: tuple, n: int | None) -> None:
    """Each row's error against ``ref`` (see :func:`reference`), relative, and signed along it."""
    value, kind, estimate, order, element = ref
    for r in rows:
        diff = r["value"][:n] - value
        r["error"] = float(np.linalg.norm(diff) / np.linalg.norm(value))
        r["signed_error"] = float(np.dot(diff, value) / np.dot(value, value))  # along the reference (- : too stiff)
        r["reference"], r["reference_error"], r["order"], r["reference_value"] = kind, estimate, order, value
        r["reference_element"] = element


def by_force(study: Study, rows: list[dict]) -> Study:
    """Figure 8's second drive: the same motion driven by force, each mesh pulled by the
    tensions the finest displacement-driven mesh needed (the fourth cable free)."""
    finest = max((r for r in rows if r["solver"] in BASE and r["element"] == "corotational"),
                 key=lambda r: r["dofs"])
    forces = (*(float(f) for f in finest["value"][3:6]), 0.0)
    return Study(study.name, study.scene, study.params | {"cable_forces": forces}, study.steps, study.quantity, None,
                 study.meshes, {"element": ("corotational",)}, [("direct", 0.0)], study.mesh_param, study.compared,
                 "force")


def swing(quick: bool, device: str) -> list[dict]:
    """The cantilever (corotational, 2.5 mm) falling under gravity from rest: its tip every
    8 ms over 0.2 s against a trapezoid run at 0.25 ms."""
    steps_of = {0.008: 25, 0.004: 50, 0.002: 100, 0.001: 200, 0.00025: 800}
    dts = (0.008, 0.002) if quick else (0.008, 0.004, 0.002, 0.001)

    def trajectory(integrator: str, dt: float):
        scene = build_scene(ROOT / "scenes/validation/cantilever.py",
                            {"static": False, "dt": dt, "gravity": 9.81, "integrator": integrator,
                             "young_modulus": 1e5, "mesh_size": 0.005 if quick else 0.0025})
        # Newton to 1e-8: the trajectories differ by their integrators, not by what a step leaves
        # (on CUDA the default solver, its CG to 1e-10)
        sim = Simulator(scene, device=device, tolerance=1e-10, newton_tolerance=1e-8, newton_iterations=30)
        every, out, times = round(0.008 / dt), [], []
        for k in range(steps_of[dt]):
            t0 = time.perf_counter()
            sim.step()
            times.append(1e3 * (time.perf_counter() - t0))
            if (k + 1) % every == 0:
                out.append(sim.probe_positions()["tip"].copy())
        wp.synchronize_device(device)
        return np.array(out), float(np.median(times[1:])), sim.model.num_dofs, memory_bytes(sim)

    ref, *_ = trajectory("trapezoidal", 0.00025)
    amplitude = np.abs(ref - np.array([0.1, 0.0, 0.0])).max()
    rows = []
    for integrator in ("implicit_euler", "trapezoidal"):
        for dt in dts:
            traj, ms, dofs, memory = trajectory(integrator, dt)
            err = float(np.abs(traj - ref).max() / amplitude)
            rows.append({"study": "swing", "element": "corotational", "poisson_ratio": 0.3, "drive": "",
                         "mesh": 0.005 if quick else 0.0025, "dofs": dofs, "tolerance": "",
                         "solver": base_solver(device),
                         "precision": "", "dt": dt, "integrator": integrator, "value": traj[-1], "step_ms": ms,
                         "cg_iterations": 0, "converged": True, "memory_mb": memory / 2 ** 20, "error": err,
                         "signed_error": "", "reference": "trapezoid 0.25 ms", "reference_error": "", "order": ""})
            print(f"  swing {integrator} dt {dt}: error {100 * err:.3f} % of {1e3 * amplitude:.1f} mm, {ms:.1f} ms",
                  flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="a few settings of two studies: a minute, for CI")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--studies", nargs="*", default=None)
    ap.add_argument("--gpu-csv", default=None, help="the same sweep's CSV on CUDA: its times join the table")
    ap.add_argument("--softrobots", default=str(SOFTROBOTS), help="the folder of SoftRobots' diamond.vtk")
    ap.add_argument("--from-csv", default=None,
                    help="re-render the table, plots and summary from an earlier run's accuracy.csv, no solves")
    ap.add_argument("--max-refine", type=int, default=None,
                    help="nested studies: the most splits run (fewer than three meshes: no extrapolation; for "
                         "timing runs)")
    ap.add_argument("--out", default="out/accuracy")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cuda = wp.get_device(args.device).is_cuda
    if args.from_csv:
        write(load(Path(args.from_csv), Path(args.softrobots)), out, args)
        return 0
    rows = []
    for study in studies(args.quick, Path(args.softrobots)):
        if args.studies is not None and study.name not in args.studies:
            continue
        if "mesh" in study.params and not Path(study.params["mesh"]).exists():
            print(f"{study.name}: {study.params['mesh']} is missing; skipped", flush=True)
            continue
        if cuda and "poisson_ratio" in study.grid:  # the step time does not depend on it
            study.grid["poisson_ratio"] = (0.45,)
        if args.max_refine is not None and study.mesh_param == "refine":
            study.meshes = [m for m in study.meshes if m <= args.max_refine]
            study.others = {e: [m for m in ms if m <= args.max_refine] for e, ms in study.others.items()}
        found = run_study(study, args.device, ("float32", "float64") if cuda else ("",))
        if study.drive == "displacement":
            found += run_study(by_force(study, found), args.device, ())
        rows += found
    if args.studies is None or "swing" in args.studies:
        rows += swing(args.quick, args.device)
    write(rows, out, args)
    return 0


FIELDS = ["study", "element", "poisson_ratio", "drive", "mesh", "dofs", "solver", "tolerance", "precision", "dt",
          "integrator", "error", "signed_error", "reference", "reference_element", "reference_error", "order",
          "step_ms", "cg_iterations", "converged", "memory_mb", "value"]


def load(path: Path, softrobots: Path) -> list[dict]:
    """The rows of an earlier run's CSV, numbers parsed, the extrapolated references computed
    again from their groups' linear direct solves (as :func:`run_study` does)."""
    def number(text: str):
        return "" if text == "" else int(text) if text.isdigit() else float(text)

    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            r.pop("step_ms_gpu", None)
            for k in ("poisson_ratio", "mesh", "dofs", "tolerance", "dt", "error", "signed_error", "reference_error",
                      "order", "step_ms", "cg_iterations", "memory_mb"):
                r[k] = number(r[k])
            r["converged"], r["value"] = r["converged"] == "True", np.array(r["value"].split(), float)
            rows.append(r)
    by_name = {s.name: s for s in studies(False, softrobots)} | {s.name: s for s in studies(True, softrobots)}
    groups: dict = {}
    for r in rows:
        if r["reference"] in ("extrapolated", "not monotone", "assumed order"):
            groups.setdefault((r["study"], r["drive"], r["poisson_ratio"]), []).append(r)
    for (name, _, _), sub in groups.items():
        study = by_name[name]
        base = sorted((r for r in sub if r["element"] == study.sweep and r["solver"] in BASE),
                      key=lambda r: r["dofs"])
        score(sub, reference(study, {}, base), study.compared)
    return rows


def write(rows: list[dict], out: Path, args) -> None:
    gpu, gpu_rows = {}, []
    if args.gpu_csv:
        with open(args.gpu_csv) as f:
            gpu_rows = list(csv.DictReader(f))
        gpu = {key(g): g for g in gpu_rows if g["precision"] in ("", "float32")}  # the default precision
    for r in rows:
        g = gpu.get(key(r))
        r["step_ms_gpu"] = float(g["step_ms"]) if g else ""
    with open(out / "accuracy.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS + ["step_ms_gpu"], extrasaction="ignore")
        writer.writeheader()
        writer.writerows([r | {"value": " ".join(f"{v:.9g}" for v in np.ravel(r["value"]))} for r in rows])
    plot_pareto(rows, out / "accuracy.png")
    if any(r["study"].startswith("figure8") for r in rows):
        plot_figure8(rows, out / "figure8.png")
    command = " ".join(["python tools/accuracy.py", *(args_list(args))])
    (out / "summary.md").write_text(summary(rows, args.device, command, gpu_rows))
    print((out / "summary.md").read_text().split("\n| study")[0])


def args_list(args) -> list[str]:
    out = ["--quick"] if args.quick else []
    out += ["--device", args.device] if args.device != "cpu" else []
    out += ["--studies", *args.studies] if args.studies else []
    out += ["--gpu-csv", args.gpu_csv] if args.gpu_csv else []
    out += ["--softrobots", args.softrobots] if args.softrobots != str(SOFTROBOTS) else []
    out += ["--max-refine", str(args.max_refine)] if args.max_refine is not None else []
    out += ["--from-csv", args.from_csv] if args.from_csv else []
    return out + ["--out", args.out]


def key(r: dict) -> tuple:
    """A setting's identity across the CPU and GPU tables (the precision aside: the CPU has one;
    the GPU's default solver, "auto", stands where the CPU solves directly)."""
    solver = "direct" if r["solver"] in BASE else r["solver"]
    return tuple(str(r[k]) for k in ("study", "element", "poisson_ratio", "drive", "mesh")) + (solver,) + tuple(
        str(r[k]) for k in ("tolerance", "dt", "integrator"))


if __name__ == "__main__":
    sys.exit(main())
