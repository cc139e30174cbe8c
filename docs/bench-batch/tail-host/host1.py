"""One robot's host functions, timed by wrappers over 60 steps after 10 (the tree on PYTHONPATH).

    PYTHONPATH=<tree> python host1.py <tree> diamond_inverse|finger [cuda|cpu]
"""

import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

import warpsoft as ws
from warpsoft.io.runner import build_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host-lazy"))
from study_host import wrap_all  # noqa: E402  (the timing wrappers of the batch's study)

wp.config.quiet = True
root, name = sys.argv[1], sys.argv[2]
device = sys.argv[3] if len(sys.argv) > 3 else "cuda"
path = {"diamond_inverse": "scenes/diamond.py", "finger": "scenes/finger.py"}[name]
sim = ws.Simulator(build_scene(f"{root}/{path}", {"mode": "inverse"} if name == "diamond_inverse" else {}),
                   device=device)
T = {}


wrap_all(["host_inputs", "record_newton", "finish_solve", "iterate", "record_device_qp", "resolve_on_host"], T)
for _ in range(10):
    sim.step()
T.clear()
steps = []
for _ in range(60):
    t0 = time.perf_counter()
    _ = sim.step().actuator_delta  # (read as a user would)
    steps.append(time.perf_counter() - t0)
print(name, root, f"step median {1e3 * np.median(steps):.3f} ms", {k: round(v / 60 * 1e3, 3) for k, v in T.items()})
