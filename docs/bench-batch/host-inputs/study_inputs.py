"""The actuators' own inputs of 1024 Diamonds (one 30 mm mesh, 4096 cable schedules) read at 20
times: the per-actuator loop as it was (old) against ``warpsoft.step.own_inputs`` (new), three
alternated rounds, median ms. Run from the repository's root: ``python
docs/bench-batch/host-inputs/study_inputs.py`` (CPU device)."""

import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "tools"))

from batch_bench import designs  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft import step as stepping  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402

wp.config.quiet = True


def old_way(sim: ws.Simulator, t: float) -> np.ndarray:
    """Each actuator's ``input_at``, one after the other (the loop before the change)."""
    rows = sim.rows
    values = [0.0] * rows.num_rows
    for acts, start in zip(rows.actuators, rows.world_row_start.tolist(), strict=False):  # (starts: worlds + 1)
        for j, a in enumerate(acts):
            values[start + j] = a.input_at(t)
    return np.array(values)


def main() -> None:
    params = designs(1024, 1)
    for p in params:
        p["mesh_size"] = 0.03
    scenes = [build_scene(ROOT / "scenes/diamond.py", p) for p in params]
    sim = ws.Simulator(ws.finalize(scenes, "cpu"), solver="pcg", preconditioner="blocks", share_tolerance=0.01)
    controls = [None] * len(scenes)
    out: dict[str, list[float]] = {}
    for name in ["old", "new"] * 3:
        times = []
        for k in range(20):
            t = 0.02 * (k + 1)
            t0 = time.perf_counter()
            if name == "new":
                stepping.actuator_values(sim, t, controls)
            else:
                old_way(sim, t)
            times.append(time.perf_counter() - t0)
        out.setdefault(name, []).append(round(1e3 * float(np.median(times)), 2))
    print(out)


if __name__ == "__main__":
    main()
