"""Per-step cost of the reference scenes: the paper's Table 1, measured here.

    python tools/bench.py --device cpu [--steps 10] [--solver direct] [--compare] [--out out/bench]

For each scene in SCENES (a new scene joins by being listed): DOFs, elements, actuators,
contacts, direct or inverse model, median and p90 step time and the median of each stage,
with warm-up steps (kernel compilation, the first factorizations) excluded. ``--compare``
runs the matrix-free CG path and the assembled direct path in the same run and gives their
ratio. Writes bench.json and bench.md.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

from warpsoft import Simulator
from warpsoft.report import percentiles
from warpsoft.runner import build_scene

ROOT = Path(__file__).resolve().parents[1]

# name, scene file, parameters
SCENES = [
    ("finger", "scenes/finger.py", {}),
    ("pneunet", "scenes/pneunet.py", {}),
    ("diamond", "scenes/diamond.py", {}),
    ("diamond_inverse", "scenes/diamond.py", {"mode": "inverse"}),
    ("trunk", "scenes/trunk.py", {}),
]

# SOFA SoftRobots, Table 1 of Coevoet et al. 2017 (Intel i5-4590, one thread), ms per step
PAPER_MS = {"diamond_inverse": 22.0, "trunk": 29.0}


def measure(name: str, path: str, params: dict, device: str, solver: str, steps: int, warmup: int,
            **options) -> dict:
    scene = build_scene(ROOT / path, params)
    sim = Simulator(scene, device=device, solver=solver, **options)
    for _ in range(warmup):
        sim.step()
    stats = [sim.step() for _ in range(steps)]
    m, cs = sim.model, sim.constraints
    stages = sorted({k for s in stats for k in s.stages})
    return {
        "scene": name, "params": params, "device": str(m.device), "solver": solver,
        "dofs": m.num_dofs, "elements": m.num_elements,
        "actuators": cs.num_actuators if cs is not None else 0, "contacts": 0,
        "model": "inverse" if scene.inverse else "direct", "static": m.static,
        "step_ms": {k: 1e3 * v for k, v in percentiles([s.total for s in stats]).items() if k != "count"},
        "stages_ms": {k: 1e3 * float(np.median([s.stages.get(k, 0.0) for s in stats])) for k in stages},
        "cg_iterations_median": float(np.median([s.cg_iterations for s in stats])),
        "compliance_iterations_median": float(np.median([s.compliance_iterations for s in stats])),
        "steps": steps, "warmup": warmup, "options": options,
    }


def markdown(rows: list[dict], compare: bool) -> str:
    head = ("| scene | model | DOFs | elements | actuators | contacts | solver | step median (ms) | p90 (ms) "
            "| stages, median (ms) | CG its (free / compliance) | paper (ms) |")
    out = [head, "|" + "---|" * 12]
    for r in rows:
        st = ", ".join(f"{k} {v:.1f}" for k, v in r["stages_ms"].items())
        its = (f"{r['cg_iterations_median']:.0f} / {r['compliance_iterations_median']:.0f}"
               if r["solver"] == "cg" else "-")
        out.append(f"| {r['scene']} | {r['model']} | {r['dofs']} | {r['elements']} | {r['actuators']} | "
                   f"{r['contacts']} | {r['solver']} | {r['step_ms']['median']:.1f} | {r['step_ms']['p90']:.1f} | "
                   f"{st} | {its} | {PAPER_MS.get(r['scene'], '')} |")
    if compare:
        out += ["", "| scene | CG median (ms) | direct median (ms) | CG / direct |", "|---|---|---|---|"]
        by = {(r["scene"], r["solver"]): r for r in rows}
        for name in dict.fromkeys(r["scene"] for r in rows):
            cg, di = by.get((name, "cg")), by.get((name, "direct"))
            if cg and di:
                out.append(f"| {name} | {cg['step_ms']['median']:.1f} | {di['step_ms']['median']:.1f} | "
                           f"{cg['step_ms']['median'] / di['step_ms']['median']:.1f} |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--solver", choices=["cg", "direct"], default=None,
                    help="default: direct on cpu (the fast CPU path), cg elsewhere")
    ap.add_argument("--compare", action="store_true", help="run both solvers and give their ratio")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--scenes", nargs="*", default=None, help="names from SCENES (default: all)")
    ap.add_argument("--out", default="out/bench")
    ap.add_argument("--check-every", type=int, default=None, help="CG residual read-back period (see Simulator)")
    ap.add_argument("--no-graphs", action="store_true", help="launch CG iterations one by one on CUDA")
    args = ap.parse_args(argv)
    options = {"check_every": args.check_every, "graphs": not args.no_graphs}
    solvers = ["cg", "direct"] if args.compare else [args.solver or ("direct" if args.device == "cpu" else "cg")]
    chosen = [s for s in SCENES if args.scenes is None or s[0] in args.scenes]
    rows = []
    for name, path, params in chosen:
        for solver in solvers:
            t0 = time.perf_counter()
            rows.append(measure(name, path, params, args.device, solver, args.steps, args.warmup, **options))
            r = rows[-1]
            print(f"{name:16s} {solver:6s} {r['dofs']:6d} DOFs  median {r['step_ms']['median']:8.1f} ms  "
                  f"p90 {r['step_ms']['p90']:8.1f} ms  ({time.perf_counter() - t0:.0f} s)", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"date": date.today().isoformat(), "device": args.device, "machine": platform.processor() or
            platform.machine(), "python": sys.version.split()[0], "command": " ".join(["python tools/bench.py",
                                                                                     *(argv or sys.argv[1:])])}
    (out / "bench.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))
    (out / "bench.md").write_text(f"{meta['date']}, device {meta['device']}, `{meta['command']}`\n\n"
                                  + markdown(rows, args.compare))
    print((out / "bench.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
