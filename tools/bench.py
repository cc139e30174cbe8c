"""Per-step cost of the reference scenes: the paper's Table 1, measured here.

    python tools/bench.py --device cpu|cuda [--steps 10] [--solver auto|pcg|direct|jacobi] [--compare]

For each scene in SCENES (a new scene joins by being listed): DOFs, elements, actuators,
contacts, direct or inverse model, median and p90 step time and the median of each stage,
with warm-up steps (kernel compilation, the first factorizations) excluded. ``--compare``
runs v1's default path for the device (CPU: SuperLU direct; CUDA: block-Jacobi CG) and v2's
(CPU: CHOLMOD direct; CUDA: warped-factorization PCG) in the same run and gives their ratio.
Per row: CG iterations, kernel launches and host transfers per step (counted in one extra,
uncaptured step, which also times the stages one by one), the launch floor (launches x graph
replay cost) and, on CUDA, the peak
device memory per DOF. Writes bench.json and bench.md.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

from warpsoft import Simulator
from warpsoft.io.report import percentiles
from warpsoft.io.runner import build_scene

ROOT = Path(__file__).resolve().parents[1]

PNEUNET_LINEAR = {"element": "corotational", "mesh_size": 0.0035}  # the PneuNet as measured before 2026-11-23
SWINGING_BEAM = {"static": False, "gravity": 9.81, "poisson_ratio": 0.45}
# name, scene file, parameters[, steps run before the warmup (to time a later phase)]
SCENES = [
    ("finger", "scenes/finger.py", {}),
    ("pneunet", "scenes/pneunet.py", {}),  # 10-node elements at 7 mm (its default since 2026-11-23)
    ("pneunet_linear", "scenes/pneunet.py", PNEUNET_LINEAR),  # the earlier default: linear at 3.5 mm
    # at 60 kPa its chambers meet across their gaps: self-contact, timed once they touch
    ("pneunet_self_contact", "scenes/pneunet.py",
     PNEUNET_LINEAR | {"pressure": 60e3, "ramp_time": 0.2, "self_contact": True}, 30),
    ("diamond", "scenes/diamond.py", {}),
    ("diamond_inverse", "scenes/diamond.py", {"mode": "inverse"}),
    ("diamond_inverse_softrobots_mesh", "scenes/diamond.py",  # SoftRobots.Inverse's own mesh: 4884 DOFs
     {"mode": "inverse", "mesh": str(ROOT.parent / "shared" / "reference" / "softrobots" / "diamond.vtk")}),
    ("trunk", "scenes/trunk.py", {}),
    ("trunk_obstacles", "scenes/trunk.py", {"obstacles": True}),  # between two posts: contacts, QPCC
    # three fingers on a moving palm lifting a rigid cube by friction: timed as it rises in their grip
    ("grasper", "scenes/grasper.py", {}, 120),
    ("octoleg", "scenes/octoleg.py", {}, 30),  # an arm folded over a cylinder onto the floor by its cable
    # the finger at a time step too large for one linearization: what its Newton iterations cost
    ("finger_dt_0.5", "scenes/finger.py", {"dt": 0.5}),
    # the beam swinging under gravity: linear tetrahedra at the default mesh (15 % too stiff at
    # nu 0.45) against 10-node ones at 5 mm (2.6 %): what the element costs at its accuracy
    ("cantilever", "scenes/validation/cantilever.py", SWINGING_BEAM),
    ("cantilever_quadratic", "scenes/validation/cantilever.py", SWINGING_BEAM | {"element": "quadratic",
                                                                                 "mesh_size": 0.005}),
    # the fingertip pressing the silicone block while the inverse model pulls its cables: stable
    # Neo-Hookean elements, then the same scene on corotational ones (what the material costs)
    ("stifface", "scenes/stifface.py", {}, 20),
    ("stifface_corotational", "scenes/stifface.py", {"element": "corotational"}, 20),
]

# SOFA SoftRobots, Table 1 of Coevoet et al. 2017 (Intel i5-4590, one thread), ms per step
PAPER_MS = {"diamond_inverse": 22.0, "diamond_inverse_softrobots_mesh": 22.0, "trunk": 29.0, "trunk_obstacles": 29.0,
            "grasper": 5.0, "octoleg": 1.7}

# v1 and v2 per device: the solver (and options) each release used by default there
CONFIGS = {
    "v1": {"cpu": ("direct", {"factorization": "superlu", "qp": "piqp", "newton_iterations": 1, "factor_reuse": 0.0}),
           "cuda": ("jacobi", {"qp": "piqp", "newton_iterations": 1})},
    "v2": {"cpu": ("direct", {}), "cuda": ("pcg", {})},
}

LAUNCH_FLOOR_US = 1.3  # replay cost of one kernel in a CUDA graph, measured on the GPU machine


class Counter:
    """Counts kernel launches and host transfers (``numpy()``, ``assign``, and ``wp.copy`` between
    the host and a device) while active."""

    def __init__(self):
        import warp as wp

        self.wp, self.launches, self.transfers, self._saved = wp, 0, 0, None

    def __enter__(self):
        wp = self.wp
        self._saved = (wp.launch, wp.launch_tiled, wp.array.numpy, wp.array.assign, wp.copy, wp.Launch.launch)

        def count(kind, f):
            def wrapped(*a, **k):
                setattr(self, kind, getattr(self, kind) + 1)
                return f(*a, **k)
            return wrapped

        launch = wp.launch

        def counted_launch(*a, **k):  # a recorded command counts when it runs (Launch.launch)
            if not k.get("record_cmd"):
                self.launches += 1
            return launch(*a, **k)

        wp.launch, wp.launch_tiled = counted_launch, count("launches", wp.launch_tiled)
        wp.Launch.launch = count("launches", wp.Launch.launch)  # replays (warpsoft.launch on the CPU)
        wp.array.numpy, wp.array.assign = count("transfers", wp.array.numpy), count("transfers", wp.array.assign)
        copy = wp.copy

        def counted_copy(dest, src, *a, **k):
            if dest.device != src.device:  # host <-> device
                self.transfers += 1
            return copy(dest, src, *a, **k)

        wp.copy = counted_copy
        return self

    def __exit__(self, *exc):
        (self.wp.launch, self.wp.launch_tiled, self.wp.array.numpy, self.wp.array.assign,
         self.wp.copy, self.wp.Launch.launch) = self._saved


def kernel_table(results) -> list[dict]:
    """Per kernel (or copy) name: launches and summed device time (us) in one step, largest first."""
    table: dict[str, dict] = {}
    for r in results:
        e = table.setdefault(r.name, {"name": r.name, "launches": 0, "us": 0.0})
        e["launches"] += 1
        e["us"] += 1e3 * r.elapsed
    return sorted(table.values(), key=lambda e: -e["us"])


def measure(name: str, path: str, params: dict, device: str, solver: str, steps: int, warmup: int,
            profile: bool = False, **options) -> dict:
    import warp as wp

    scene = build_scene(ROOT / path, params)
    sim = Simulator(scene, device=device, solver=solver, **options)
    for _ in range(warmup):
        sim.step()
    stats = [sim.step() for _ in range(steps)]
    # one more step, uncaptured, to count what a step launches and moves (graphs replay the same
    # kernels) and to time its stages one by one (a captured step is timed per graph)
    graph, capture = getattr(sim.solver, "graph", None), sim.capture
    if graph is not None:
        sim.solver.graph = False
    sim.capture = False
    kernels = None
    with Counter() as counter:
        if profile and wp.get_device(device).is_cuda:  # device time of each kernel and copy of this step
            wp.timing_begin(cuda_filter=wp.TIMING_KERNEL | wp.TIMING_MEMCPY | wp.TIMING_MEMSET)
            uncaptured = sim.step()
            kernels = kernel_table(wp.timing_end())
        else:
            uncaptured = sim.step()
    if graph is not None:
        sim.solver.graph = graph
    sim.capture = capture
    m, cs = sim.model, sim.rows
    detection = detection_cost(sim, stats)
    stages = sorted({k for s in stats for k in s.stages})
    d = wp.get_device(device)
    peak = wp.get_mempool_used_mem_high(d) if d.is_cuda and wp.is_mempool_enabled(d) else None
    return {
        "scene": name, "params": params, "device": str(m.device), "solver": sim.solver_name,
        "options": {k: v for k, v in options.items() if v is not None},
        "dofs": m.num_dofs, "elements": m.num_elements,
        "actuators": cs.num_actuators if cs is not None else 0,
        "contacts": [int(np.median([s.contacts for s in stats])), int(max(s.contacts for s in stats))],
        "detection": detection, "qp_pivots": int(sum(s.qp_pivots for s in stats)),
        "model": "inverse" if scene.inverse else "direct", "static": m.static,
        "step_ms": {k: 1e3 * v for k, v in percentiles([s.total for s in stats]).items() if k != "count"},
        "stages_ms": {k: 1e3 * float(np.median([s.stages.get(k, 0.0) for s in stats])) for k in stages},
        "stages_uncaptured_ms": {k: 1e3 * v for k, v in uncaptured.stages.items()},
        "cg_iterations_median": float(np.median([s.cg_iterations for s in stats])),
        "newton_iterations": [int(np.median([s.newton_iterations for s in stats])),
                              int(max(s.newton_iterations for s in stats))],
        "launches_per_step": counter.launches, "host_transfers_per_step": counter.transfers,
        "launch_floor_ms": 1e-3 * LAUNCH_FLOOR_US * counter.launches,
        "peak_device_bytes_per_dof": None if peak is None else peak / m.num_dofs,
        "refreshes": getattr(getattr(sim.solver, "precond", None), "refreshes", None),
        "factorizations_per_step": float(np.mean([s.factorizations for s in stats])),
        "steps": steps, "warmup": warmup, "kernels": kernels,
    }


def detection_cost(sim: Simulator, stats: list) -> dict | None:
    """Contact detection alone (median of 20, synchronized): its time (us), per candidate (a
    surface node against an obstacle) and per contact found (the steps' median)."""
    import warp as wp

    table = sim.rows.kind("contact") if sim.rows is not None else None
    if table is None:
        return None
    times = []
    for _ in range(20):
        wp.synchronize_device(sim.model.device)
        t0 = time.perf_counter()
        sim.rows.detect(sim.state.q, sim.gauss_seidel.lam, sim.gauss_seidel.friction, sim.state)
        wp.synchronize_device(sim.model.device)
        times.append(time.perf_counter() - t0)
    us = 1e6 * float(np.median(times))
    contacts = max(float(np.median([s.contacts for s in stats])), 1.0)
    return {"us": us, "candidates": table.num_candidates, "us_per_candidate": us / max(table.num_candidates, 1),
            "us_per_contact": us / contacts}


def markdown(rows: list[dict]) -> str:
    head = ("| scene | config | model | DOFs | solver | step median (ms) | p90 (ms) | stages, median (ms) "
            "| stages, one uncaptured step (ms) | CG its | Newton its (median / most) "
            "| launches / transfers per step | launch floor (ms) | bytes/DOF | paper (ms) |")
    out = [head, "|" + "---|" * 15]
    for r in rows:
        st = ", ".join(f"{k} {v:.2f}" for k, v in r["stages_ms"].items())
        un = ", ".join(f"{k} {v:.2f}" for k, v in r["stages_uncaptured_ms"].items())
        mem = "" if r["peak_device_bytes_per_dof"] is None else f"{r['peak_device_bytes_per_dof']:.0f}"
        out.append(f"| {r['scene']} | {r['config']} | {r['model']} | {r['dofs']} | {r['solver']} | "
                   f"{r['step_ms']['median']:.2f} | {r['step_ms']['p90']:.2f} | {st} | {un} | "
                   f"{r['cg_iterations_median']:.0f} | {r['newton_iterations'][0]} / {r['newton_iterations'][1]} | "
                   f"{r['launches_per_step']} / {r['host_transfers_per_step']} | {r['launch_floor_ms']:.2f} | {mem} | "
                   f"{PAPER_MS.get(r['scene'], '')} |")
    by = {(r["scene"], r["config"]): r for r in rows}
    pairs = [(n, by[(n, "v1")], by[(n, "v2")]) for n in dict.fromkeys(r["scene"] for r in rows)
             if (n, "v1") in by and (n, "v2") in by]
    if pairs:
        out += ["", "| scene | v1 median (ms) | v2 median (ms) | v1 / v2 |", "|---|---|---|---|"]
        for n, a, b in pairs:
            out.append(f"| {n} | {a['step_ms']['median']:.2f} | {b['step_ms']['median']:.2f} | "
                       f"{a['step_ms']['median'] / b['step_ms']['median']:.1f} |")
    touching = [r for r in rows if r.get("detection")]
    if touching:
        out += ["", "| scene | config | contacts (median / most) | QPCC pivots | detection (us) | candidates "
                "| us per candidate | us per contact |", "|---|---|---|---|---|---|---|---|"]
        for r in touching:
            d = r["detection"]
            out.append(f"| {r['scene']} | {r['config']} | {r['contacts'][0]} / {r['contacts'][1]} | {r['qp_pivots']} | "
                       f"{d['us']:.0f} | {d['candidates']} | {d['us_per_candidate']:.3f} | {d['us_per_contact']:.1f} |")
    return "\n".join(out) + "\n"


def kernels_markdown(rows: list[dict]) -> str:
    """One table per run: the uncaptured step's kernels and copies by device time."""
    out = []
    for r in rows:
        if not r.get("kernels"):
            continue
        total = sum(k["us"] for k in r["kernels"])
        out += [f"## {r['scene']} ({r['config']}, {r['solver']}): {total:.0f} us of device time in "
                f"{sum(k['launches'] for k in r['kernels'])} launches and copies", "",
                "| kernel or copy | launches | us | us per launch |", "|---|---|---|---|"]
        out += [f"| {k['name']} | {k['launches']} | {k['us']:.1f} | {k['us'] / k['launches']:.1f} |"
                for k in r["kernels"]]
        out.append("")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--solver", choices=["auto", "pcg", "direct", "jacobi"], default="auto")
    ap.add_argument("--compare", action="store_true", help="run v1's and v2's default paths and give their ratio")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--scenes", nargs="*", default=None, help="names from SCENES (default: all)")
    ap.add_argument("--out", default="out/bench")
    ap.add_argument("--qp", choices=["auto", "piqp", "device"], default="auto", help="v2's inverse-model QP")
    ap.add_argument("--kernels", action="store_true",
                    help="CUDA: time each kernel and copy of the uncaptured step (kernels.md)")
    ap.add_argument("--precision", choices=["float32", "float64"], default="float32",
                    help="pcg's dense warped inverse")
    ap.add_argument("--preconditioner", choices=["auto", "host", "dense", "blocks", "factors"], default="auto",
                    help="pcg's warped preconditioner (auto: dense on CUDA up to 12k free DOFs, host above)")
    ap.add_argument("--factor-reuse", type=float, default=None,
                    help="direct: the Simulator's factor_reuse (0: a factorization at every linearization; "
                         "default: the Simulator's)")
    cg = ap.add_mutually_exclusive_group()
    cg.add_argument("--column-cg", action="store_const", dest="block_cg", const=False,
                    help="pcg: each column its own CG (block_cg=False)")
    cg.add_argument("--block-cg", action="store_const", dest="block_cg", const=True,
                    help="pcg: a world's columns in one block CG (block_cg=True); default: the Simulator's choice")
    ap.add_argument("--operator", choices=["auto", "matrix_free", "assembled"], default="auto",
                    help="how the iterative solvers apply A")
    args = ap.parse_args(argv)
    kind = "cuda" if args.device.startswith("cuda") else "cpu"
    if args.compare:
        runs = [("v1", *CONFIGS["v1"][kind]), ("v2", CONFIGS["v2"][kind][0], {"qp": args.qp})]
    else:
        pcg = {"precision": args.precision, "preconditioner": args.preconditioner, "block_cg": args.block_cg,
               "operator": args.operator}
        runs = [("v2", args.solver, {"qp": args.qp} | (pcg if args.solver in ("pcg", "auto") else {}))]
    if args.factor_reuse is not None:
        runs = [(config, solver, options | {"factor_reuse": args.factor_reuse}) for config, solver, options in runs
                if config == "v2"]
    chosen = [s for s in SCENES if args.scenes is None or s[0] in args.scenes]
    rows = []
    for name, path, params, *skip in chosen:
        if "mesh" in params and not Path(params["mesh"]).is_file():
            print(f"{name:16s} skipped: {params['mesh']} not found", flush=True)
            continue
        for config, solver, options in runs:
            t0 = time.perf_counter()
            rows.append({"config": config} | measure(name, path, params, args.device, solver, args.steps,
                                                     args.warmup + sum(skip), profile=args.kernels, **options))
            r = rows[-1]
            print(f"{name:16s} {config} {r['solver']:6s} {r['dofs']:6d} DOFs  median {r['step_ms']['median']:8.2f} ms"
                  f"  p90 {r['step_ms']['p90']:8.2f} ms  its {r['cg_iterations_median']:.0f}  launches "
                  f"{r['launches_per_step']}  factorizations {r['factorizations_per_step']:.2f}"
                  f"  ({time.perf_counter() - t0:.0f} s)", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"date": date.today().isoformat(), "device": args.device, "machine": platform.processor() or
            platform.machine(), "python": sys.version.split()[0], "command": " ".join(["python tools/bench.py",
                                                                                     *(argv or sys.argv[1:])])}
    (out / "bench.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))
    (out / "bench.md").write_text(f"{meta['date']}, device {meta['device']}, `{meta['command']}`\n\n"
                                  + markdown(rows))
    if args.kernels:
        (out / "kernels.md").write_text(kernels_markdown(rows))
    print((out / "bench.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
