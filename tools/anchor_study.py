"""Cables fastened at a point or over an anchor, linear or 10-node elements: does the robot converge?

    python tools/anchor_study.py [--radius 0.0025] [--scenes finger diamond] [--device cpu]

Quasi-static, from rest: the Finger pulled by 4 mm of cable, and the Diamond with cables 0-2
pulled 6, 4 and 2 mm (SoftRobots' mesh sizes: 4 and 10 mm). Each is solved with linear elements
on its mesh split 0, 1 and 2 times and with 10-node elements split 0 and 1 times, its cables
fastened at a point (``anchor_radius=0``) and over ``--radius`` (m; the Diamond's corners take
twice it). Prints the effector's position (m), the cables' tensions (N), the DOFs and the median
step time (ms) of each: a row per mesh, to read the error against the finest 10-node mesh.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from warpsoft import Simulator
from warpsoft.io.runner import build_scene

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "finger": ("scenes/finger.py", "fingertip", 1.0,
               {"static": True, "dt": 1.0, "ramp_time": 1.0, "gravity": 0.0, "cable_displacement": 0.004}),
    "diamond": ("scenes/diamond.py", "effector", 2.0,
                {"static": True, "dt": 1.0, "ramp_time": 1.0, "gravity": 0.0, "mesh_size": 0.01,
                 "cable_displacements": (0.006, 0.004, 0.002, 0.0)}),
}
MESHES = (("corotational", (0, 1, 2)), ("quadratic", (0, 1)))


def solve(path: str, effector: str, params: dict, device: str) -> tuple[np.ndarray, np.ndarray, int, float]:
    """Effector position (m), tensions (N), DOFs and median step time (ms) after the ramp."""
    sim = Simulator(build_scene(ROOT / path, params), device=device, solver="direct" if device == "cpu" else "auto")
    for _ in range(5):
        stats = sim.step()
    times = []
    for _ in range(3):
        start = time.perf_counter()
        stats = sim.step()
        times.append(time.perf_counter() - start)
    tensions = np.array(list(stats.actuator_lambda.values()))
    return stats.effectors[effector], tensions, 3 * sim.model.num_nodes, 1e3 * float(np.median(times))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--radius", type=float, default=0.0025)
    ap.add_argument("--scenes", nargs="*", default=list(CASES))
    ap.add_argument("--device", default="cpu")
    args = ap.parse_args(argv)
    for name in args.scenes:
        path, effector, scale, params = CASES[name]
        for radius in (0.0, scale * args.radius):
            for element, refines in MESHES:
                for refine in refines:
                    at, tensions, dofs, ms = solve(path, effector, params | {"element": element, "refine": refine,
                                                                            "anchor_radius": radius}, args.device)
                    print(f"{name:8s} anchor {radius * 1e3:4.1f} mm  {element:12s} refine {refine}  {dofs:7d} DOFs  "
                          f"effector {np.round(at * 1e3, 3).tolist()} mm  tensions {np.round(tensions, 3).tolist()} N  "
                          f"{ms:8.1f} ms", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
