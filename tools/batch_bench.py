"""Throughput of many robot designs stepped as the worlds of one model: design-steps per second
against the batch size, and a batch against the same designs stepped one at a time.

    python tools/batch_bench.py --device cuda [--sizes 1 16 64 256] [--steps 20] [--alone 16]

The designs are Diamonds driven directly by their four cables (a step input held; ``--mode inverse``:
each following the scene's effector circle, its cables found by a QP every step), each its own
leg radius (``--meshes`` different meshes, cycled) and Young's modulus (log-spaced over 0.1-0.3
MPa). Per batch size: the model's DOFs, the step's median (ms) after ``--warmup`` steps, and the
design-steps per second (designs / step time), and over the whole run (designs / the timed steps'
mean: what a sweep of that many steps gets, its refactorizations included). ``--alone K``: the
first K designs one at a time (the sum of their medians) against the batch of the same K.
``--kernels`` (CUDA): after the timed steps, one more step uncaptured with each kernel and copy
timed (batch.json's ``kernels``, and kernels.md). Under each batch line, the setup's parts (the
model, the simulator, the first step and its longest stages, the rest of the warm-up) and the
kernel modules it loaded, compiled or from Warp's cache. Writes batch.json and batch.md.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np
import warp as wp

try:
    import resource  # (Unix)
except ImportError:
    resource = None

import warpsoft as ws
from warpsoft.io.compiling import ModuleLoads
from warpsoft.io.runner import build_scene
from warpsoft.io.sweep import premesh
from warpsoft.linear import factors
from warpsoft.linear.assembly import ORDERINGS

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
from bench import kernel_table  # noqa: E402  (a sibling tool: the per-kernel table of one step)

GRAPHS = ("device_step", "newton_step", "line_search", "device_before_qp", "newton_before_qp", "device_after_qp")
LEG_RADII = (0.009, 0.010, 0.011, 0.012, 0.013, 0.014, 0.015, 0.016)  # m: one mesh each


def leg_radii(meshes: int) -> list[float]:
    """The leg radii (m) of ``meshes`` different meshes: :data:`LEG_RADII`'s first ones, or past
    them, ``meshes`` values evenly over the same 9-16 mm (a sweep of distinct meshes)."""
    if meshes <= len(LEG_RADII):
        return list(LEG_RADII[:meshes])
    return [round(float(r), 7) for r in np.linspace(LEG_RADII[0], LEG_RADII[-1], meshes)]


def designs(count: int, meshes: int, mode: str = "direct") -> list[dict]:
    """``count`` Diamond designs: leg radius cycling over ``meshes`` values, modulus log-spaced.
    ``mode="direct"``: two cables shortened (4 and 2 mm over 50 ms) and held; ``"inverse"``: the
    scene's own effector circle, each world's cables found by its QP every step."""
    moduli = np.geomspace(1e5, 3e5, count)
    radii = leg_radii(meshes)
    drive = {"cable_displacements": (0.004, 0.0, 0.002, 0.0), "ramp_time": 0.05} if mode == "direct" else {"mode": mode}
    return [{"leg_radius": radii[k % meshes], "young_modulus": float(moduli[k]), **drive} for k in range(count)]


def _job_times(info: dict) -> str:
    """The workers' refactorizations in the timed steps (median, p90 and longest), for the report."""
    if "refactor_job_ms" not in info:
        return ""
    median, p90, most = info["refactor_job_ms"]
    landed = info["refactor_landing_ms"][1]
    return f"; a job {median:.1f} ms (p90 {p90:.1f}, most {most:.1f}), its blocks landed within {landed:.1f} ms"


def _switches() -> int:
    """The calling thread's involuntary context switches so far (another process took its core; 0
    where the platform does not count them per thread)."""
    who = getattr(resource, "RUSAGE_THREAD", None)  # (Linux)
    return resource.getrusage(who).ru_nivcsw if who is not None else 0


def step_median(scenes: list, device: str, steps: int, warmup: int, kernels: bool = False,
                **options) -> tuple[float, int, dict]:
    """Median step time (s) of ``scenes`` as one model, its DOFs, and what the solve did: the CG
    iterations of a step and the mean of its worlds' (medians over the timed steps), and the
    preconditioner's distinct blocks and device memory when it keeps them per world; with
    ``kernels`` (CUDA), one more step uncaptured, each kernel and copy timed (``info["kernels"]``);
    and each timed step's time, its graphs' and its CG iterations (the host's share is the first
    less the second); and the stepping thread's CPU time and involuntary context switches (Linux),
    a step's mean: a host whose cores other processes share shows it there. The setup's parts
    (``setup_parts_s``): the model, the simulator, the first step (and its stages), the other
    warm-up steps, the refactorizer's settling; and the kernel modules loaded in all of it
    (``module_loads``: compiled or from the cache, their count and ms)."""
    t0 = time.perf_counter()
    setup_parts, first_stages = {}, {}
    with ModuleLoads() as loads:
        model = ws.finalize(scenes, device)
        setup_parts["model"] = time.perf_counter() - t0
        sim = ws.Simulator(model, device=device, **options)
        setup_parts["simulator"] = time.perf_counter() - t0 - sum(setup_parts.values())
        for k in range(warmup):
            stats = sim.step()
            if k == 0:
                setup_parts["first_step"] = time.perf_counter() - t0 - sum(setup_parts.values())
                first_stages = dict(stats.stages)
        setup_parts["warmup_rest"] = time.perf_counter() - t0 - sum(setup_parts.values())
        pre = getattr(sim.solver, "precond", None)
        refactor = getattr(pre, "refactorizer", None)  # a world's own refresh: its workers' analyses ahead,
        settled = refactor.settle() if refactor is not None else 0.0  # done before the timed steps as in a long run
        answered = len(refactor.working) if refactor is not None else 0
    setup = time.perf_counter() - t0
    setup_parts["settle"] = setup - sum(setup_parts.values())
    times, its, world_its, graphs, refresh = [], [], [], [], []
    refreshed = getattr(pre, "world_refreshes", 0)
    cpu0, switched0 = time.thread_time(), _switches()
    for _ in range(steps):
        t0 = time.perf_counter()
        stats = sim.step()
        times.append(time.perf_counter() - t0)
        graphs.append(sum(t for name, t in stats.stages.items() if name in GRAPHS))
        its.append(stats.cg_iterations)
        world_its.append(np.mean([w.cg_iterations for w in stats.worlds]))
        refresh.append(stats.stages.get("refresh_worlds", 0.0))
    refreshed = getattr(pre, "world_refreshes", 0) - refreshed  # (the timed steps')
    thread = {"thread_cpu_ms": 1e3 * (time.thread_time() - cpu0) / steps,
              "involuntary_switches": (_switches() - switched0) / steps}
    waited = {"refactor_waited_s": refactor.waited, "refactor_submitted": refactor.submitted,
              "refactor_page_locked": refactor.page_locked, "refactor_settle_s": settled} if refactor else {}
    if refactor is not None and len(refactor.working) > answered:  # the timed steps' jobs, in the workers
        work, land = 1e3 * np.array(refactor.working[answered:]), 1e3 * np.array(refactor.landing[answered:])
        waited |= {"refactor_job_ms": [float(np.median(work)), float(np.percentile(work, 90)), float(work.max())],
                   "refactor_landing_ms": [float(np.median(land)), float(land.max())]}
    if kernels and sim.model.device.is_cuda:
        parts = {"kernels": uncaptured_kernels(sim)}
    else:
        parts = {}
    if pre is not None and getattr(pre, "capturable", False):  # a CG iteration's two big products, alone
        solver = sim.solver
        solver.scal.zero_()  # no world done: the product runs for all of them
        parts |= {"precond_ms": 1e3 * _median_call(lambda: pre.apply(solver.r, solver.bz), sim.model.device),
                  "operator_ms": 1e3 * _median_call(lambda: sim.operator.apply(solver.bp, solver.ap), sim.model.device)}
        if sim.operator.blocks is not None:  # the assembled operator's refresh, at each linearization
            parts["assemble_ms"] = 1e3 * _median_call(lambda: sim.operator.linearized(), sim.model.device)
    if sim.timing and sim.model.device.is_cuda:  # the graphs' own time (synchronized), the rest is the host's
        parts["graph_ms"] = 1e3 * float(np.median(graphs))
    info = {**parts, "step_times_ms": [1e3 * t for t in times], "graph_times_ms": [1e3 * t for t in graphs],
            "step_cg_iterations": its, "step_mean_ms": 1e3 * float(np.mean(times)),
            "world_refreshes": refreshed, "refresh_ms": 1e3 * float(np.mean(refresh)), **waited, **thread,
            "cg_iterations": float(np.median(its)), "world_cg_iterations": float(np.median(world_its)),
            "setup_s": setup, "setup_parts_s": setup_parts, "first_step_stages_s": first_stages,
            "module_loads": {"count": loads.count, "ms": loads.ms}, "preconditioner": type(pre).__name__,
            "blocks": getattr(pre, "blocks", None), "precond_mb": getattr(pre, "memory_bytes", 0) / 1e6}
    return float(np.median(times)), sim.model.num_dofs, info


def _setup_parts(info: dict) -> str:
    """The setup's parts, the first step's three longest stages and the kernel modules' loads (s)."""
    parts = ", ".join(f"{name} {s:.1f}" for name, s in info["setup_parts_s"].items())
    stages = sorted(info["first_step_stages_s"].items(), key=lambda kv: -kv[1])[:3]
    loads = info["module_loads"]
    return (f"{parts} s (the first step's longest stages: {', '.join(f'{k} {s:.1f}' for k, s in stages)} s); "
            f"kernel modules: {loads['count']['compiled']} compiled in {loads['ms']['compiled'] / 1e3:.1f} s, "
            f"{loads['count']['cached']} from the cache in {loads['ms']['cached'] / 1e3:.1f} s")


def uncaptured_kernels(sim) -> dict:
    """One step of ``sim`` with its graphs off, each kernel and copy timed on the device: the
    step's wall time (ms), its CG iterations and the table of :func:`bench.kernel_table`."""
    graph, capture = getattr(sim.solver, "graph", None), sim.capture
    if graph is not None:
        sim.solver.graph = False
    sim.capture = False
    wp.synchronize_device(sim.model.device)
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL | wp.TIMING_MEMCPY | wp.TIMING_MEMSET)
    t0 = time.perf_counter()
    stats = sim.step()
    wall = time.perf_counter() - t0
    table = kernel_table(wp.timing_end())
    if graph is not None:
        sim.solver.graph = graph
    sim.capture = capture
    return {"step": stats.index, "wall_ms": 1e3 * wall, "cg_iterations": stats.cg_iterations, "table": table}


def _median_call(call, device, repeats: int = 20) -> float:
    """Median wall time (s) of ``call`` run to completion on ``device``."""
    times = []
    for _ in range(repeats):
        wp.synchronize_device(device)
        t0 = time.perf_counter()
        call()
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--sizes", type=int, nargs="*", default=[1, 16, 64])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--meshes", type=int, default=4,
                    help=f"different meshes (past {len(LEG_RADII)}: leg radii evenly over 9-16 mm)")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes that mesh the designs first into WARPSOFT_MESH_CACHE (set it)")
    ap.add_argument("--alone", type=int, default=0, help="also step the first K designs one at a time")
    ap.add_argument("--mode", default="direct", choices=["direct", "inverse"],
                    help="the Diamonds' model: cables driven, or the effector's circle followed (a QP a world)")
    ap.add_argument("--solver", default="auto")
    ap.add_argument("--preconditioner", default="auto", help="pcg's: auto, blocks, factors, dense, host")
    ap.add_argument("--share-tolerance", type=float, default=1e-10,
                    help="blocks, factors: when worlds of one mesh share")
    ap.add_argument("--precision", default="float32", choices=["float32", "float64"],
                    help="pcg's dense inverses or factors")
    ap.add_argument("--column-cg", action="store_true", help="pcg: each column its own CG (block_cg=False)")
    ap.add_argument("--operator", default="auto", choices=["auto", "matrix_free", "assembled"],
                    help="how the iterative solvers apply A")
    ap.add_argument("--tolerance", type=float, default=1e-6, help="CG relative residual")
    ap.add_argument("--directions", default="auto", choices=["auto", "float64", "float32"],
                    help="pcg's block CG: the storage of its search directions")
    ap.add_argument("--warm-start", default="extrapolate", choices=["extrapolate", "last", "none"],
                    help="where each step's first solve starts (the Simulator's warm_start)")
    ap.add_argument("--factor-ordering", default=None, choices=list(ORDERINGS),
                    help="factors: their ordering (default warpsoft.linear.factors.ORDERING)")
    ap.add_argument("--factor-layout", default=None, choices=["rows", "panels"],
                    help="factors: how a level's work is cut (default warpsoft.linear.factors.LAYOUT)")
    ap.add_argument("--world-floor", type=int, default=None,
                    help="factors: the CG iterations past which a world's factor is made anew alone "
                         "(default warpsoft.linear.factors.WORLD_FLOOR; 0: never)")
    ap.add_argument("--world-lag", type=int, default=None,
                    help="factors: the step boundaries between a world's factor sent to a worker and its "
                         "installation (default warpsoft.linear.factors.WORLD_LAG)")
    ap.add_argument("--world-batch", type=int, default=None,
                    help="factors: the most worlds' factors sent to be made anew at one step boundary, the "
                         "slowest first (default warpsoft.linear.factors.WORLD_BATCH; 0: every one due)")
    ap.add_argument("--world-ratio", type=float, default=None,
                    help="factors: how many times its first solve's iterations a world's CG must take for its "
                         "factor to be made anew (default warpsoft.linear.factors.WORLD_RATIO)")
    ap.add_argument("--wide", default=None,
                    help="factors, CUDA: in the tail, the mean columns from which a level's panels take a block "
                         "of threads each, and the block, FROM,LANES, or none (default "
                         "warpsoft.linear.factors.WIDE_FROM, WIDE_LANES)")
    ap.add_argument("--kernels", action="store_true",
                    help="CUDA: time each kernel and copy of one more step, uncaptured (kernels.md)")
    ap.add_argument("--out", default="out/batch")
    args = ap.parse_args(argv)
    if args.factor_ordering:
        factors.ORDERING = args.factor_ordering  # (WorldFactors reads it when made)
    if args.factor_layout:
        factors.LAYOUT = args.factor_layout
    if args.world_floor is not None:
        factors.WORLD_FLOOR = args.world_floor or None
    if args.world_lag is not None:
        factors.WORLD_LAG = args.world_lag
    if args.world_batch is not None:
        factors.WORLD_BATCH = args.world_batch or None
    if args.world_ratio is not None:
        factors.WORLD_RATIO = args.world_ratio
    if args.wide is not None:
        wide = None if args.wide == "none" else args.wide.split(",")
        factors.WIDE_FROM = None if wide is None else float(wide[0])
        factors.WIDE_LANES = factors.WIDE_LANES if wide is None else int(wide[1])
    everything = designs(max(args.sizes + [args.alone]), args.meshes, args.mode)
    if args.workers > 1 and not os.environ.get("WARPSOFT_MESH_CACHE"):
        ap.error("--workers meshes ahead into the mesh cache: set WARPSOFT_MESH_CACHE to a folder")
    t0 = time.perf_counter()
    premesh(ROOT / "scenes/diamond.py", everything, args.workers)
    scenes = [build_scene(ROOT / "scenes/diamond.py", d) for d in everything]
    print(f"{len(scenes)} designs built in {time.perf_counter() - t0:.1f} s", flush=True)
    rows, alone = [], None
    out = Path(args.out)
    meta = {"date": date.today().isoformat(), "device": args.device, "mode": args.mode, "command": " ".join(sys.argv)}
    options = {"solver": args.solver, "preconditioner": args.preconditioner, "share_tolerance": args.share_tolerance,
               "precision": args.precision, "tolerance": args.tolerance, "operator": args.operator,
               "warm_start": args.warm_start}
    if args.solver in ("pcg", "auto"):
        options["block_cg"] = not args.column_cg
        options["directions"] = args.directions
    for n in args.sizes:
        t0 = time.perf_counter()
        median, dofs, info = step_median(scenes[:n], args.device, args.steps, args.warmup, args.kernels, **options)
        rows.append({"designs": n, "dofs": dofs, "step_ms": 1e3 * median, "design_steps_per_s": n / median,
                     "run_design_steps_per_s": 1e3 * n / info["step_mean_ms"],
                     "wall_s": time.perf_counter() - t0, **info})
        print(f"batch {n:5d}: {dofs:8d} DOFs  step {1e3 * median:8.2f} ms  {n / median:9.1f} design-steps/s  "
              f"CG {info['cg_iterations']:.0f} (a world's mean {info['world_cg_iterations']:.1f})  "
              f"{info['preconditioner']} blocks {info['blocks']} "
              f"{info['precond_mb']:.0f} MB  setup {info['setup_s']:.1f} s  "
              f"P^-1 {info.get('precond_ms', 0):.2f} ms  A {info.get('operator_ms', 0):.2f} ms  "
              f"assembly {info.get('assemble_ms', 0):.2f} ms  "
              f"graphs {info.get('graph_ms', 0):.2f} ms  mean step {info['step_mean_ms']:.2f} ms "
              f"({1e3 * n / info['step_mean_ms']:.1f} design-steps/s over the run)  "
              f"world refreshes {info['world_refreshes']} ({info['refresh_ms']:.2f} ms a step, "
              f"waited {info.get('refactor_waited_s', 0):.2f} s in all; the stepping thread's CPU "
              f"{info['thread_cpu_ms']:.2f} ms and {info['involuntary_switches']:.1f} switches a step"
              f"{_job_times(info)}"
              f"{', page-locked' if info.get('refactor_page_locked') else ''})", flush=True)
        print(f"  setup: {_setup_parts(info)}", flush=True)
        _write(out, meta, rows, alone)  # (each batch size kept as it is measured: a later one may fail)
    if args.alone:
        k = args.alone
        one = [step_median([s], args.device, args.steps, args.warmup, **options)[0] for s in scenes[:k]]
        together = step_median(scenes[:k], args.device, args.steps, args.warmup, **options)[0]
        alone = {"designs": k, "one_at_a_time_ms": 1e3 * sum(one), "batched_ms": 1e3 * together,
                 "ratio": sum(one) / together}
        print(f"{k} designs: one at a time {1e3 * sum(one):.2f} ms per step of all, batched {1e3 * together:.2f} ms: "
              f"{sum(one) / together:.1f}x", flush=True)
    _write(out, meta, rows, alone)
    if args.kernels:
        (out / "kernels.md").write_text(kernels_markdown(rows))
    return 0


def _write(out: Path, meta: dict, rows: list[dict], alone: dict | None) -> None:
    """batch.json (everything measured) and batch.md (the table) in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "batch.json").write_text(json.dumps({"meta": meta, "rows": rows, "alone": alone}, indent=1))
    lines = [f"{meta['date']}, device {meta['device']}, {meta['mode']} model: `{meta['command']}`", "",
             "| designs | DOFs | step median (ms) | design-steps / s | over the run | CG iterations | preconditioner "
             "| blocks | MB |",
             "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['designs']} | {r['dofs']} | {r['step_ms']:.2f} | {r['design_steps_per_s']:.1f} | "
              f"{r['run_design_steps_per_s']:.1f} | "
              f"{r['cg_iterations']:.0f} | {r['preconditioner']} | {r['blocks']} | {r['precond_mb']:.0f} |"
              for r in rows]
    if alone:
        lines += ["", f"{alone['designs']} designs one at a time: {alone['one_at_a_time_ms']:.2f} ms per step of "
                  f"all; batched: {alone['batched_ms']:.2f} ms; ratio {alone['ratio']:.1f}"]
    (out / "batch.md").write_text("\n".join(lines) + "\n")


def kernels_markdown(rows: list[dict]) -> str:
    """Per batch size, the uncaptured step's kernels and copies by device time."""
    out = []
    for r in rows:
        k = r.get("kernels")
        if not k:
            continue
        total = sum(e["us"] for e in k["table"])
        out += [f"## {r['designs']} designs, step {k['step']}: {total / 1e3:.2f} ms of device time in "
                f"{sum(e['launches'] for e in k['table'])} launches and copies ({k['wall_ms']:.1f} ms uncaptured, "
                f"CG {k['cg_iterations']})", "", "| kernel or copy | launches | ms | us per launch |",
                "|---|---|---|---|"]
        out += [f"| {e['name']} | {e['launches']} | {e['us'] / 1e3:.3f} | {e['us'] / e['launches']:.1f} |"
                for e in k["table"]]
        out.append("")
    return "\n".join(out)


if __name__ == "__main__":
    sys.exit(main())
