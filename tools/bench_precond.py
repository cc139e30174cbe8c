"""Cost of one application of the warped preconditioner's dense inverse on CUDA, per product
(streamed or tiled), its shape and precision, replayed from a graph, against its floor (the
inverse's bytes / bandwidth).

    python tools/bench_precond.py [--scene scenes/diamond.py] [--columns 5] [--repeat 200]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

from warpsoft import Simulator
from warpsoft.io.runner import build_scene
from warpsoft.linear import WarpedFactor

ROOT = Path(__file__).resolve().parents[1]
# tiles: rows, inner, threads, splits
VARIANTS = [("tiles", (16, 32, 128, 1)), ("tiles", (8, 128, 128, 1)), ("tiles", (8, 128, 128, 4)),
            ("stream", (64, 2, 2)), ("stream", (64, 4, 2)), ("stream", (64, 1, 2)), ("stream", (64, 4, 4)),
            ("stream", (32, 4, 1)), ("stream", (32, 4, 2)), ("stream", (128, 2, 2)),
            ("stream", (128, 4, 4))]  # segments, unrolled loads, numbers per load
BANDWIDTH = 4.0e12  # bytes/s, about what an H200 streams from its memory


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default="scenes/diamond.py")
    ap.add_argument("--columns", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=200)
    ap.add_argument("--products", nargs="*", default=["stream", "tiles"])
    ap.add_argument("--precisions", nargs="*", default=["float64", "float32"])
    ap.add_argument("--variants", nargs="*", default=None,
                    help="shapes to try instead of the list: stream segments,unroll,width (e.g. 64,4,2) or "
                         "tiles:rows,inner,threads,splits (e.g. tiles:8,32,128,1)")
    args = ap.parse_args(argv)
    sim = Simulator(build_scene(ROOT / args.scene), device="cuda", solver="direct")
    sim.step()
    n, d = sim.model.num_nodes, sim.model.device
    r = wp.array(np.random.default_rng(0).standard_normal((args.columns, n, 3)), dtype=wp.vec3d, device=d)
    z = wp.zeros_like(r)
    print(f"{args.scene}: {3 * n} DOFs, {args.columns} columns")
    variants = VARIANTS if args.variants is None else [
        ("tiles", tuple(int(v) for v in x[6:].split(","))) if x.startswith("tiles:")
        else ("stream", tuple(int(v) for v in x.split(","))) for x in args.variants]
    for precision in args.precisions:
        ref = None
        for product, shape in [v for v in variants if v[0] in args.products]:
            pre = WarpedFactor(sim.operator, args.columns, "dense", precision, product=product,
                               **{"tiles" if product == "tiles" else "stream": shape})
            pre.prepare()
            pre.apply(r, z)
            with wp.ScopedCapture(device=d) as cap:
                for _ in range(args.repeat):
                    pre.apply(r, z)
            wp.synchronize_device(d)
            times = []
            for _ in range(5):
                t0 = time.perf_counter()
                wp.capture_launch(cap.graph)
                wp.synchronize_device(d)
                times.append((time.perf_counter() - t0) / args.repeat)
            out = z.numpy()
            ref = out if ref is None else ref
            floor = pre.memory_bytes / BANDWIDTH
            shown = pre.stream if product == "stream" else shape
            print(f"  {precision} {product} {shown}: {1e6 * np.median(times):8.1f} us per apply "
                  f"(floor {1e6 * floor:.1f} us),"
                  f" max diff to first {np.abs(out - ref).max():.2e}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
