"""What keeping the direct solver's factorization (``Simulator(factor_reuse=...)``) costs in
accuracy and saves in time, per reference scene.

    python tools/factor_reuse.py [--values 0 0.005 0.01 0.02] [--scenes grasper ...] [--out DIR]

Each scene runs the same steps with each ``factor_reuse`` value and once converged (Newton
tolerance 1e-4, up to 20 iterations: the implicit step solved, whatever the tangent). Per run:
factorizations and Newton iterations per step, the step's median time (the last three quarters
of the steps, CPU device), and the largest and median distance of any node from the converged
run over the steps (m), also relative to the scene's largest motion. The default run
(``factor_reuse = 0``) shows what the Newton tolerance alone leaves. Writes factor_reuse.csv and
factor_reuse.md.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

from warpsoft import Simulator
from warpsoft.io.runner import build_scene

ROOT = Path(__file__).resolve().parents[1]

# name, scene file, parameters, steps (from the start: the reuse depends on the motion's history)
SCENES = [
    ("grasper", "scenes/grasper.py", {}, 200),
    ("finger", "scenes/finger.py", {}, 100),
    ("diamond_inverse", "scenes/diamond.py", {"mode": "inverse"}, 60),
    ("trunk_obstacles", "scenes/trunk.py", {"obstacles": True}, 60),
    ("octoleg", "scenes/octoleg.py", {}, 100),
    ("pneunet", "scenes/pneunet.py", {"element": "corotational", "mesh_size": 0.0035}, 60),  # as measured
]


def trajectory(path: str, params: dict, steps: int, **options) -> tuple[np.ndarray, list, list[float]]:
    """Node positions after each step ``(steps, n, 3)`` (m), the steps' stats and times (s)."""
    sim = Simulator(build_scene(ROOT / path, params), device="cpu", solver="direct", **options)
    q, stats, times = [], [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        stats.append(sim.step())
        times.append(time.perf_counter() - t0)
        q.append(sim.state.q.numpy().copy())
    return np.array(q), stats, times


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--values", type=float, nargs="*", default=[0.0, 0.005, 0.01, 0.02])
    ap.add_argument("--scenes", nargs="*", default=None, help="names from SCENES (default: all)")
    ap.add_argument("--out", default="out/factor_reuse")
    args = ap.parse_args(argv)
    rows = []
    for name, path, params, steps in SCENES:
        if args.scenes is not None and name not in args.scenes:
            continue
        converged, _, _ = trajectory(path, params, steps, newton_tolerance=1e-4, newton_iterations=20, factor_reuse=0.0)
        motion = float(np.linalg.norm(converged - converged[0], axis=2).max())
        for value in args.values:
            q, stats, times = trajectory(path, params, steps, factor_reuse=value)
            distance = np.linalg.norm(q - converged, axis=2).max(axis=1)  # (steps,): the farthest node
            rows.append({"scene": name, "factor_reuse": value, "steps": steps,
                         "factorizations_per_step": sum(s.factorizations for s in stats) / steps,
                         "newton_per_step": sum(s.newton_iterations for s in stats) / steps,
                         "step_ms": 1e3 * float(np.median(times[steps // 4:])),
                         "max_m": float(distance.max()), "median_m": float(np.median(distance)),
                         "max_rel": float(distance.max()) / motion, "motion_m": motion})
            r = rows[-1]
            print(f"{name:16s} reuse {value:<6g} factorizations {r['factorizations_per_step']:.2f}/step  Newton "
                  f"{r['newton_per_step']:.2f}/step  {r['step_ms']:6.2f} ms  from converged: max {r['max_m']:.2e} m "
                  f"({100 * r['max_rel']:.2f} % of {motion:.3g} m), median {r['median_m']:.2e} m", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "factor_reuse.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = ["| scene | factor_reuse | factorizations / step | Newton its / step | step median (ms) "
             "| from converged, max (m) | max / motion | median (m) |", "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['scene']} | {r['factor_reuse']:g} | {r['factorizations_per_step']:.2f} | "
              f"{r['newton_per_step']:.2f} | {r['step_ms']:.2f} | {r['max_m']:.2e} | {100 * r['max_rel']:.2f} % | "
              f"{r['median_m']:.2e} |" for r in rows]
    (out / "factor_reuse.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
