"""The tiled product of shared blocks against the streamed one, and K x element-major against a
thread per column and element, on the same designs in one process (H200; output in
ab_streamed_tiled.json).

    python docs/bench-batch/cuda-tiled/ab_streamed_tiled.py OUT 256 1024

It ran on the tree of this change before its last edit, where the operator's choice was a module
switch (``ELEMENT_MAJOR``); here it is ``ELEMENT_MAJOR_FROM``, set to 0 (element-major) or past
any model (a thread per column and element), which is the same choice.
"""

import json
import sys
import time
from pathlib import Path

import warp as wp

sys.path.insert(0, "tools")
import batch_bench as bb  # noqa: E402

import warpsoft as ws  # noqa: E402
import warpsoft.elastic.corotational as cr  # noqa: E402
import warpsoft.linear.blocks as blk  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402


def main() -> None:
    out, sizes = Path(sys.argv[1]), [int(a) for a in sys.argv[2:]]
    scenes = [build_scene(Path("scenes/diamond.py"), d) for d in bb.designs(max(sizes), 4)]
    res = []

    def keep(row: dict) -> None:
        print(json.dumps(row), flush=True)
        res.append(row)

    for n in sizes:
        for tiled_from in (10**9, 8):  # streamed, tiled
            blk.TILED_FROM = tiled_from
            t0 = time.perf_counter()
            med, dofs, info = bb.step_median(scenes[:n], "cuda", 10, 3, solver="auto", preconditioner="auto",
                                             share_tolerance=0.01)
            keep({"designs": n, "tiled_from": tiled_from, "step_ms": 1e3 * med, "dsps": n / med, **info,
                  "wall": time.perf_counter() - t0})
    n = max(sizes)
    blk.TILED_FROM = 8
    sim = ws.Simulator(ws.finalize(scenes[:n], "cuda"), device="cuda", share_tolerance=0.01)
    for _ in range(3):
        sim.step()
    solver = sim.solver
    solver.scal.zero_()
    for element_major in (False, True, False, True):
        cr.ELEMENT_MAJOR_FROM = 0 if element_major else 1 << 40
        ms = 1e3 * bb._median_call(lambda: sim.operator.apply(solver.p, solver.ap), "cuda")
        keep({"designs": n, "operator_element_major": element_major, "A_ms": ms})
    for tile, threads in (((64, 64, 64), 128), ((64, 64, 64), 256), ((128, 64, 32), 256), ((64, 128, 32), 256),
                          ((32, 64, 64), 128)):
        blk.TILE, blk.TILE_THREADS = tile, threads
        pre = blk.WorldBlocks(sim.operator, solver.r.shape[0], "float32", share_tolerance=0.01)
        pre.watch(solver.scal)
        t0 = time.perf_counter()
        pre.prepare()
        prepare = time.perf_counter() - t0
        pre.apply(solver.r, solver.z)
        wp.synchronize()
        ms = 1e3 * bb._median_call(lambda: pre.apply(solver.r, solver.z), "cuda")  # noqa: B023
        keep({"designs": n, "tile": tile, "threads": threads, "P_ms": ms, "prepare_s": prepare})
    (out / "exp50.json").write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
