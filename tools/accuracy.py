"""What accuracy costs in time: mesh refinement and CG tolerance against error and step time.

    python tools/accuracy.py [--quick] [--device cpu] [--out out/accuracy]

Studies (a new one joins by being listed in STUDIES): the cantilever under a tip load and
the Diamond pulled by two cables, both quasi-static. For each mesh size and solver setting
(CG at several tolerances, and the direct solve) the quantity of interest (tip or effector
displacement, m) is compared with the finest mesh solved by the direct path; the step time
is the median over the steps after a warm-up. Writes accuracy.csv, accuracy.png (error vs
DOFs, time vs DOFs, error vs time, as in Figure 8 of the SoftRobots paper) and summary.md,
whose recommended default is the cheapest setting within the error budget.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

from warpsoft import Simulator
from warpsoft.io.runner import build_scene

ROOT = Path(__file__).resolve().parents[1]
BUDGET = 0.05  # relative error the recommended default must stay within


def cantilever_quantity(sim: Simulator) -> np.ndarray:
    return sim.probe_positions()["tip"] - np.array([0.1, 0.0, 0.0])


def diamond_quantity(sim: Simulator) -> np.ndarray:
    return sim.constraint_geometry()["effectors"]["effector"] - np.array([0.0, 0.0, 0.125])


# name, scene file, fixed parameters, steps to equilibrium, quantity, (full sizes, reference), (quick ...)
STUDIES = [
    ("cantilever", "scenes/validation/cantilever.py", {"tip_force": 0.01}, 2, cantilever_quantity,
     ([0.005, 0.0033, 0.0025, 0.002, 0.00167], 0.00125), ([0.005, 0.0033], 0.0025)),
    ("diamond", "scenes/diamond.py", {"static": True, "dt": 1.0, "gravity": 0.0,
                                      "cable_displacements": (0.006, 0.0, 0.003, 0.0)}, 8, diamond_quantity,
     ([0.016, 0.013, 0.011, 0.009], 0.007), ([0.016], 0.013)),
]
TOLERANCES = {"full": [1e-2, 1e-4, 1e-6, 1e-8], "quick": [1e-4, 1e-8]}


def solve(path: str, params: dict, steps: int, quantity, device: str, solver: str, tol: float) -> dict:
    sim = Simulator(build_scene(ROOT / path, params), device=device, solver=solver, tolerance=tol,
                    max_iterations=20000)
    times, its = [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        stats = sim.step()
        times.append(time.perf_counter() - t0)
        its.append(stats.cg_iterations)  # free and compliance columns share one solve
    return {"dofs": sim.model.num_dofs, "value": quantity(sim), "step_ms": 1e3 * float(np.median(times)),
            "cg_iterations": float(np.median(its)), "converged": bool(stats.converged)}


def run_study(study, quick: bool, device: str) -> list[dict]:
    name, path, params, steps, quantity, full, short = study
    sizes, ref_size = short if quick else full
    ref = solve(path, params | {"mesh_size": ref_size}, steps, quantity, device, "direct", 1e-8)
    print(f"{name}: reference mesh {ref_size} m, {ref['dofs']} DOFs, quantity {ref['value']}", flush=True)
    rows = []
    settings = [("direct", 0.0)] + [("pcg", t) for t in TOLERANCES["quick" if quick else "full"]]
    for size in sizes:
        for solver, tol in settings:
            r = solve(path, params | {"mesh_size": size}, steps, quantity, device, solver, tol or 1e-8)
            err = float(np.linalg.norm(r["value"] - ref["value"]) / np.linalg.norm(ref["value"]))
            rows.append({"study": name, "mesh_size": size, "dofs": r["dofs"], "solver": solver,
                         "tolerance": tol if solver == "pcg" else "", "error": err, "step_ms": r["step_ms"],
                         "cg_iterations": r["cg_iterations"] if solver == "pcg" else 0, "converged": r["converged"],
                         "reference_dofs": ref["dofs"]})
            print(f"  h {size:.4f} {r['dofs']:6d} DOFs {solver:6s} tol {tol or '-':>6} error {100 * err:7.3f} %"
                  f"  step {r['step_ms']:8.1f} ms", flush=True)
    return rows


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    studies = list(dict.fromkeys(r["study"] for r in rows))
    fig, axes = plt.subplots(len(studies), 3, figsize=(14, 4 * len(studies)), squeeze=False)
    for i, name in enumerate(studies):
        sub = [r for r in rows if r["study"] == name]
        for (solver, tol) in dict.fromkeys((r["solver"], r["tolerance"]) for r in sub):
            pts = sorted((r for r in sub if (r["solver"], r["tolerance"]) == (solver, tol)), key=lambda r: r["dofs"])
            label = "direct" if solver == "direct" else f"CG tol {tol:g}"
            d, e, t = ([r[k] for r in pts] for k in ("dofs", "error", "step_ms"))
            e = [max(v, 1e-12) for v in e]
            axes[i, 0].loglog(d, e, "o-", label=label)
            axes[i, 1].loglog(d, t, "o-", label=label)
            axes[i, 2].loglog(t, e, "o-", label=label)
        for ax, (x, y) in zip(axes[i], [("DOFs", "relative error"), ("DOFs", "step time (ms)"),
                                        ("step time (ms)", "relative error")], strict=True):
            ax.set_xlabel(x)
            ax.set_ylabel(y)
            ax.set_title(f"{name}: {y} vs {x}")
            ax.grid(True, which="both", alpha=0.3)
        axes[i, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def summary(rows: list[dict], device: str, command: str) -> str:
    lines = [f"# Accuracy vs time ({date.today().isoformat()}, device {device})", "", f"Command: `{command}`", "",
             f"Error: relative to the finest mesh solved by the direct path. Budget: {100 * BUDGET:.0f} %.", ""]
    for name in dict.fromkeys(r["study"] for r in rows):
        sub = [r for r in rows if r["study"] == name]
        ok = [r for r in sub if r["error"] <= BUDGET and r["converged"]]
        lines.append(f"## {name} (reference {sub[0]['reference_dofs']} DOFs)")
        if ok:
            best = min(ok, key=lambda r: r["step_ms"])
            tol = f" at CG tolerance {best['tolerance']:g}" if best["solver"] == "pcg" else ""
            lines.append(f"Recommended: mesh size {best['mesh_size']} m ({best['dofs']} DOFs), {best['solver']}{tol}: "
                         f"error {100 * best['error']:.2f} %, {best['step_ms']:.1f} ms per step, the cheapest "
                         f"setting within the budget.")
            cg_ok = [r for r in ok if r["solver"] == "pcg"]
            if cg_ok:
                c = min(cg_ok, key=lambda r: r["step_ms"])
                lines.append(f"Cheapest CG setting within the budget (the path on GPUs): mesh {c['mesh_size']} m, "
                             f"tolerance {c['tolerance']:g}, error {100 * c['error']:.2f} %, {c['step_ms']:.1f} ms.")
        else:
            lines.append("No setting reached the budget: refine further.")
        tols = sorted({r["tolerance"] for r in sub if r["solver"] == "pcg"})
        if tols:
            finest = min(r["mesh_size"] for r in sub)
            at = {r["tolerance"]: r for r in sub if r["solver"] == "pcg" and r["mesh_size"] == finest}
            lines.append("On the finest swept mesh, CG tolerance against error: " + ", ".join(
                f"{t:g}: {100 * at[t]['error']:.3f} %" for t in tols if t in at) + ".")
        lines.append("")
    lines += ["| study | mesh size (m) | DOFs | solver | tolerance | error (%) | step (ms) | CG its |",
              "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['study']} | {r['mesh_size']} | {r['dofs']} | {r['solver']} | {r['tolerance']} | "
              f"{100 * r['error']:.3f} | {r['step_ms']:.1f} | {r['cg_iterations']:.0f} |" for r in rows]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="two meshes and two tolerances: a minute, for CI")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--studies", nargs="*", default=None)
    ap.add_argument("--out", default="out/accuracy")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for study in STUDIES:
        if args.studies is None or study[0] in args.studies:
            rows += run_study(study, args.quick, args.device)
    with open(out / "accuracy.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    plot(rows, out / "accuracy.png")
    command = " ".join(["python tools/accuracy.py", *(argv if argv is not None else sys.argv[1:])])
    (out / "summary.md").write_text(summary(rows, args.device, command))
    print((out / "summary.md").read_text().split("| study")[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
