"""Run scenes on several Warp devices and compare: same probe trajectories, step times.

    python tools/devices.py --devices cpu cuda --steps 100 --out out/devices scenes/finger.py

Writes one JSON report per scene and device, and ``devices.json`` with, per scene, the
median / p90 step time on each device (step 1, which compiles kernels, excluded) and the
largest probe difference (m) between each device and the first.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from warpsoft.io.runner import build_scene, parse_params, run


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--devices", nargs="+", default=["cpu"])
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--solver", default="auto")
    ap.add_argument("--param", action="append", default=[])
    ap.add_argument("--out", default="out/devices")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary = {}
    for path in args.scenes:
        rows = {}
        first = None
        for device in args.devices:
            scene = build_scene(path, parse_params(args.param))
            rep = run(scene, steps=args.steps, device=device, solver=args.solver,
                      report=out / f"{Path(path).stem}_{device.replace(':', '')}.json", scene_file=path).to_dict()
            pts = {k: np.array(v) for k, v in rep["points"].items()}
            first = first or pts
            diff = max((float(np.abs(pts[k] - first[k]).max()) for k in pts), default=0.0)
            rows[device] = {"dofs": rep["dofs"], "step_median_ms": 1e3 * rep["timings"]["step"]["median"],
                            "step_p90_ms": 1e3 * rep["timings"]["step"]["p90"],
                            "stages_median_ms": {k: 1e3 * v["median"] for k, v in rep["timings"]["stages"].items()},
                            "cg_iterations_median": float(np.median(rep["cg"]["iterations"])),
                            "max_probe_difference_m": diff}
            print(f"{Path(path).stem:12s} {device:7s} {rep['dofs']:6d} DOFs  step median "
                  f"{rows[device]['step_median_ms']:8.2f} ms  p90 {rows[device]['step_p90_ms']:8.2f} ms  "
                  f"CG its {rows[device]['cg_iterations_median']:.0f}  probe diff vs {args.devices[0]} {diff:.2e} m",
                  flush=True)
        summary[Path(path).stem] = rows
    (out / "devices.json").write_text(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
