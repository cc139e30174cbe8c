"""One robot's host time outside the step's iterations (``step.iterate``: its graphs and reads),
median over 200 steps after 10 (the tree on PYTHONPATH).

    PYTHONPATH=<tree> python share58.py diamond_inverse|finger [cuda|cpu]
"""

import sys
import time

import numpy as np
import warp as wp

import warpsoft as ws
from warpsoft import step as S
from warpsoft.io.runner import build_scene

wp.config.quiet = True
name = sys.argv[1]
path = {"diamond_inverse": "scenes/diamond.py", "finger": "scenes/finger.py"}[name]
sim = ws.Simulator(build_scene(path, {"mode": "inverse"} if name == "diamond_inverse" else {}),
                   device=sys.argv[2] if len(sys.argv) > 2 else "cpu")
inside = [0.0]
iterate = S.iterate


def timed(*a, **k):
    t0 = time.perf_counter()
    try:
        return iterate(*a, **k)
    finally:
        inside[0] += time.perf_counter() - t0


S.iterate = timed
for _ in range(10):
    sim.step()
host = []
for _ in range(200):
    inside[0] = 0.0
    t0 = time.perf_counter()
    _ = sim.step().actuator_delta
    host.append(time.perf_counter() - t0 - inside[0])
print(name, f"host outside iterate: median {1e3 * np.median(host):.3f} ms, p10 {1e3 * np.percentile(host, 10):.3f}")
