"""The host's share of a batch step, function by function (CPU VM): 1024 Diamonds of 4 coarse
meshes (mesh_size 0.03: the host's work depends on the worlds and rows, not on the elements),
each listed host function timed over STEPS steps after two warm-up steps.

    ROOT=<tree> PYTHONPATH=<tree> WARPSOFT_MESH_CACHE=<dir> python study_host.py 1024 4
"""

import functools
import os
import sys
import time
from pathlib import Path

import warp as wp

ROOT = Path(os.environ.get("ROOT", Path(__file__).resolve().parents[3]))
sys.path.insert(0, str(ROOT / "tools"))
wp.config.quiet = True

import batch_bench as bb  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft import record as R  # noqa: E402
from warpsoft import step as S  # noqa: E402
from warpsoft import watch as W  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402


def wrap(mod, name: str, times: dict) -> None:
    """Time ``mod.name`` into ``times[name]`` (s, summed over its calls)."""
    f = getattr(mod, name)

    @functools.wraps(f)
    def timed(*a, **k):
        t0 = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            times[name] = times.get(name, 0) + time.perf_counter() - t0
    setattr(mod, name, timed)


def wrap_all(step_names: list[str], times: dict) -> None:
    """Time ``step_names`` of warpsoft.step, and the report's functions (record, watch)."""
    for name in step_names:
        wrap(S, name, times)
    for name in ["record_rows", "keep_gaps"]:
        wrap(R, name, times)
    for name in ["health", "inverted_elements"]:
        wrap(W, name, times)


def main() -> None:
    n = int(sys.argv[1])
    steps = int(sys.argv[2]) if len(sys.argv) > 2 else 2
    scenes = [build_scene(ROOT / "scenes/diamond.py", {**d, "mesh_size": 0.03}) for d in bb.designs(n, 4)]
    sim = ws.Simulator(ws.finalize(scenes, "cpu"), device="cpu", solver="pcg", preconditioner="factors",
                       share_tolerance=0.01)
    T = {}
    wrap_all(["host_inputs", "reuse_factor", "record_newton", "finish_solve", "record_device_qp"], T)
    for _ in range(2):
        sim.step()
    T.clear()
    for _ in range(steps):
        sim.step()
        t1 = time.perf_counter()  # what making the step's per-world stats costs
        if hasattr(S, "Worlds"):
            S.StepStats(1, 0.0, worlds=S.Worlds(S.WorldRecord(n)))
        else:
            S.StepStats(1, 0.0, worlds=[S.WorldStats() for _ in range(n)])
        T["StepStats"] = T.get("StepStats", 0) + time.perf_counter() - t1
    print({k: round(v / steps * 1e3, 2) for k, v in T.items()}, "ms/step")


if __name__ == "__main__":
    main()
