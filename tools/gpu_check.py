"""Once per change of the step, on a CUDA machine: the CUDA step equals the CPU one, the
captured (graph-replayed) step equals the uncaptured one, and a model of three worlds steps
each world as it steps alone.

    python tools/gpu_check.py [--steps 20] [--scenes scenes/trunk.py scenes/finger.py:dt=0.5 ...]
                              [--out out/gpu_check] [--no-worlds]

A scene is a path, optionally followed by ``:key=value,key=value`` (its parameters, Python
literals). For each scene: probe trajectories of (a) ``direct`` on the CPU device, (b) ``pcg`` on CUDA
with the step's device part replayed as graphs, (c) ``pcg`` on CUDA launched kernel by kernel,
(d) ``pcg`` on CUDA with a float32 dense inverse; the largest probe differences (m) between them,
and the median CG iterations and the most Newton iterations of a step (the finger at dt = 0.5 s
iterates: its graphs of later iterations and line searches are checked too; Hertz and the
Trunk between two posts check contacts, the latter the QPCC around the graphs; the Grasper, fast
closing, rigid bodies and kinematic frames: its cube's centre counts as a probe; the swinging
payload, an attachment; the pebble, a rigid cube's points on a slab's triangles; the swinging
cantilever, 10-node elements; the Stifface, Neo-Hookean elements under the inverse model). Then the three
worlds of tests/test_worlds.py (an inverse Diamond, an inverse Trunk, a Diamond driven
directly) on CUDA, together and alone. Then the conformance checks of the CPU suite, on CUDA with
each solver and preconditioner a user can pick (``--conformance``, on by default): a free spinning
cube keeps its angular momentum (to 1e-4), implicit Euler does not raise its energy at its default
Newton tolerance, and the Diamond with a doubled cable reaches its target with the device QP as
with piqp. Writes gpu_check.json; exits 1 if a check fails or raises.
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
import traceback
from pathlib import Path

import numpy as np

from warpsoft import Simulator
from warpsoft.io.runner import build_scene

ROOT = Path(__file__).resolve().parents[1]
SCENES = ["scenes/finger.py", "scenes/trunk.py", "scenes/diamond.py", "scenes/finger.py:dt=0.5,mesh_size=0.005",
          "scenes/validation/column.py", "scenes/validation/hertz.py", "scenes/trunk.py:obstacles=True,period=1.0",
          "scenes/grasper.py:dt=0.02,close=0.016", "scenes/validation/payload.py:swing=0.05",
          "scenes/validation/stack.py", "scenes/validation/pebble.py",
          "scenes/validation/cantilever.py:element='quadratic',mesh_size=0.005,static=False,gravity=9.81",
          "scenes/stifface.py"]
RUNS = {
    "cpu_direct": ("cpu", "direct", {}),
    "cuda_pcg_graph": ("cuda", "pcg", {}),
    "cuda_pcg_nograph": ("cuda", "pcg", {"graphs": False}),
    "cuda_pcg_fp64": ("cuda", "pcg", {"precision": "float64"}),
}


def scene_arg(text: str) -> tuple[str, dict]:
    """``path[:key=value,...]`` -> (path, parameters)."""
    path, _, params = text.partition(":")
    pairs = (item.split("=", 1) for item in params.split(",") if item)
    return path, {k.strip(): ast.literal_eval(v.strip()) for k, v in pairs}


def trajectory(spec: str, device: str, solver: str, steps: int, tolerance: float, **options) -> dict:
    path, params = scene_arg(spec)
    sim = Simulator(build_scene(ROOT / path, params), device=device, solver=solver, tolerance=tolerance, **options)
    probes, its, newton = [], [], []
    for _ in range(steps):
        stats = sim.step()
        rigid = [centre for _, centre in sim.rigid_poses().values()]  # rigid bodies count as probes
        probes.append(np.concatenate(list(sim.probe_positions().values()) + rigid))
        its.append(stats.cg_iterations)
        newton.append(stats.newton_iterations)
    return {"probes": np.array(probes), "iterations": float(np.median(its)), "newton": int(max(newton))}


def worlds_check(device: str, steps: int = 6) -> dict:
    """Largest node difference (m) between each world stepped in a 3-world model and alone."""
    import warpsoft as ws

    diamond, trunk = ROOT / "scenes/diamond.py", ROOT / "scenes/trunk.py"

    def scenes():
        return [build_scene(diamond, {"mesh_size": 0.02, "mode": "inverse", "circle_period": 0.2}),
                build_scene(trunk, {"mesh_size": 0.014, "rayleigh_stiffness": 0.1, "period": 0.2}),
                build_scene(diamond, {"mesh_size": 0.017, "cable_displacements": (0.004, 0.0, 0.002, 0.0),
                                      "ramp_time": 0.06})]
    together = ws.Simulator(ws.finalize(scenes(), device), solver="pcg")
    for _ in range(steps):
        together.step()
    row = {}
    for w, scene in enumerate(scenes()):
        alone = ws.Simulator(scene, device=device, solver="pcg")
        for _ in range(steps):
            alone.step()
        row[f"world{w}_vs_alone_m"] = float(np.abs(together.positions(w) - alone.positions()).max())
        row[f"world{w}_motion_m"] = float(np.abs(alone.positions() - alone.model.rest_np).max())
    return row


CONFORMANCE_SOLVERS = {"pcg": {"solver": "pcg"}, "pcg_dense": {"solver": "pcg", "preconditioner": "dense"},
                       "pcg_blocks": {"solver": "pcg", "preconditioner": "blocks"},
                       "pcg_factors": {"solver": "pcg", "preconditioner": "factors"}, "jacobi": {"solver": "jacobi"}}


def spinning_cube(device: str, dt: float, rate: float, steps: int, **options) -> dict:
    """A free 2 cm cube (1 MPa) spun at ``rate`` (rad/s) in zero gravity: the relative change of
    its angular momentum and its largest total energy over ``steps``, relative to the start."""
    import warp as wp

    import warpsoft as ws

    scene = ws.Scene("spin", gravity=(0, 0, 0), dt=dt)
    scene.add_body("cube", ws.box_grid((-0.01, -0.01, -0.01), (0.02, 0.02, 0.02), (2, 2, 2)),
                   ws.Material(1e6, 0.45, 1000.0), element="corotational")
    sim = Simulator(scene, device=device, **options)
    x, m = sim.model.rest_np, sim.model.mass_np
    sim.state.v.assign(wp.array(np.cross([0.0, 0.0, rate], x - x.mean(axis=0)), dtype=wp.vec3d, device=device))

    def momentum():
        q, v = sim.state.q.numpy(), sim.state.v.numpy()
        c = (m[:, None] * q).sum(axis=0) / m.sum()
        return (m[:, None] * np.cross(q - c, v)).sum(axis=0)

    start, e0, rise = momentum(), sim.energy()["total"], 0.0
    for _ in range(steps):
        sim.step()
        rise = max(rise, sim.energy()["total"] / e0 - 1.0)
    return {"momentum_change": float(np.linalg.norm(momentum() - start) / np.linalg.norm(start)),
            "energy_rise": float(rise)}


def twin_cables(device: str) -> dict:
    """The Diamond (inverse, quasi-static) with its first cable doubled: the effector's distance
    (m) to its target with the device QP and with piqp, and between them."""
    import warpsoft as ws

    reached = {}
    for qp in ("device", "piqp"):
        scene = build_scene(ROOT / "scenes/diamond.py", {"mesh_size": 0.014, "gravity": 0.0, "static": True,
                                                         "dt": 1.0, "mode": "inverse", "max_cable_step": 0.02,
                                                         "target": (0.0, -0.0072, 0.1311)})
        first = scene.cables[0]
        scene.add_cable("twin", scene.bodies[0], points=first.points, pull_point=first.pull_point,
                        min_displacement=0.0, max_displacement=first.max_displacement, max_step=first.max_step)
        sim = ws.Simulator(scene, device=device, qp=qp)
        for _ in range(10):
            stats = sim.step()
        reached[qp] = (stats.effectors["effector"], stats.effector_error["effector"], stats.qp_status)
    return {"device_error_m": float(reached["device"][1]), "piqp_error_m": float(reached["piqp"][1]),
            "device_status": reached["device"][2],
            "device_vs_piqp_m": float(np.linalg.norm(reached["device"][0] - reached["piqp"][0]))}


def conformance(device: str) -> tuple[dict, bool]:
    """The CPU suite's physics checks on ``device``: measured values and whether each holds."""
    out, ok = {}, True
    for name, options in CONFORMANCE_SOLVERS.items():
        spin = spinning_cube(device, 5e-4, 20.0, 100, **options)
        fast = spinning_cube(device, 1.5e-3, 20.0, 100, **options)
        row = {"momentum_change": spin["momentum_change"], "energy_rise_1.5ms": fast["energy_rise"]}
        row["pass"] = spin["momentum_change"] < 1e-4 and fast["energy_rise"] < 1e-6
        ok &= row["pass"]
        out[name] = row
    twin = twin_cables(device)
    twin["pass"] = (twin["device_status"] == "optimal" and twin["device_error_m"] < 2e-5
                    and twin["device_vs_piqp_m"] < 1e-5)
    out["twin_cables"] = twin
    return out, ok and twin["pass"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", nargs="*", default=SCENES)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--tolerance", type=float, default=1e-8)
    ap.add_argument("--out", default="out/gpu_check")
    ap.add_argument("--worlds", action=argparse.BooleanOptionalAction, default=True,
                    help="also step the three worlds together and alone")
    ap.add_argument("--conformance", action=argparse.BooleanOptionalAction, default=True,
                    help="also run the physics conformance checks on CUDA")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary, ok = {}, True
    for path in args.scenes:
        runs, row = {}, {}
        for name, (device, solver, options) in RUNS.items():
            try:
                runs[name] = trajectory(path, device, solver, args.steps, args.tolerance, **options)
                row[f"{name}_iterations"] = runs[name]["iterations"]
                row[f"{name}_newton_max"] = runs[name]["newton"]
            except Exception as exc:  # report and go on: one failure must not hide the other checks
                ok = False
                row[f"{name}_error"] = f"{type(exc).__name__}: {exc}"
                traceback.print_exc()
        ref = runs.get("cpu_direct")
        if ref is not None:
            scale = float(np.abs(ref["probes"] - ref["probes"][0]).max())
            row["motion_m"] = scale
            for name, r in runs.items():
                if name != "cpu_direct":
                    row[f"{name}_vs_cpu_m"] = float(np.abs(r["probes"] - ref["probes"]).max())
        if "cuda_pcg_graph" in runs and "cuda_pcg_nograph" in runs:
            row["graph_vs_nograph_m"] = float(np.abs(runs["cuda_pcg_graph"]["probes"]
                                                     - runs["cuda_pcg_nograph"]["probes"]).max())
        summary[path] = row
        print(path, json.dumps(row, indent=1), flush=True)
    if args.worlds:
        try:
            summary["worlds"] = worlds_check("cuda")
            print("worlds", json.dumps(summary["worlds"], indent=1), flush=True)
        except Exception as exc:
            ok = False
            summary["worlds"] = {"error": f"{type(exc).__name__}: {exc}"}
            traceback.print_exc()
    if args.conformance:
        try:
            summary["conformance"], passed = conformance("cuda")
            ok &= passed
            print("conformance", json.dumps(summary["conformance"], indent=1), flush=True)
        except Exception as exc:
            ok = False
            summary["conformance"] = {"error": f"{type(exc).__name__}: {exc}"}
            traceback.print_exc()
    (out / "gpu_check.json").write_text(json.dumps(summary, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
