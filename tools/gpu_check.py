"""Once per change of the step, on a CUDA machine: the CUDA step equals the CPU one, and the
captured (graph-replayed) solve equals the uncaptured one.

    python tools/gpu_check.py [--steps 20] [--scenes scenes/trunk.py ...] [--out out/gpu_check]

For each scene: probe trajectories of (a) ``direct`` on the CPU device, (b) ``pcg`` on CUDA
with the solve captured as a graph, (c) ``pcg`` on CUDA launched kernel by kernel, (d) ``pcg``
on CUDA with a float32 dense inverse; the largest probe differences (m) between them, and the
median CG iterations. Writes gpu_check.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import traceback
from pathlib import Path

import numpy as np

from warpsoft import Simulator
from warpsoft.io.runner import build_scene

ROOT = Path(__file__).resolve().parents[1]
SCENES = ["scenes/finger.py", "scenes/trunk.py", "scenes/diamond.py"]
RUNS = {
    "cpu_direct": ("cpu", "direct", {}),
    "cuda_pcg_graph": ("cuda", "pcg", {}),
    "cuda_pcg_nograph": ("cuda", "pcg", {"graphs": False}),
    "cuda_pcg_fp32": ("cuda", "pcg", {"precision": "float32"}),
}


def trajectory(path: str, device: str, solver: str, steps: int, tolerance: float, **options) -> dict:
    sim = Simulator(build_scene(ROOT / path), device=device, solver=solver, tolerance=tolerance, **options)
    probes, its = [], []
    for _ in range(steps):
        stats = sim.step()
        probes.append(np.concatenate(list(sim.probe_positions().values())))
        its.append(stats.cg_iterations)
    return {"probes": np.array(probes), "iterations": float(np.median(its))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", nargs="*", default=SCENES)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--tolerance", type=float, default=1e-8)
    ap.add_argument("--out", default="out/gpu_check")
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
    (out / "gpu_check.json").write_text(json.dumps(summary, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
