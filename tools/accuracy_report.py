"""Plots and summary of ``tools/accuracy.py``: error against step time (the Pareto front),
the paper's Figure 8, and what each setting costs."""

from __future__ import annotations

from datetime import date
from pathlib import Path

BUDGET = 0.05  # the error the recommended settings stay within (relative)
BASE = ("direct", "auto")  # the settings each study's reference comes from: the CPU's direct solve, CUDA's default


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def pareto(points: list[dict]) -> list[dict]:
    """The settings no other beats in both step time and error, by time."""
    front, best = [], float("inf")
    for r in sorted(points, key=lambda r: (r["step_ms"], r["error"])):
        if r["error"] < best:
            front.append(r)
            best = r["error"]
    return front


def plot_pareto(rows: list[dict], path: Path) -> None:
    """One panel per study: error against step time, colour by element (or integrator), shape by
    Poisson ratio (or drive), the Pareto front as a line."""
    plt = _plt()
    studies = list(dict.fromkeys(r["study"] for r in rows))
    fig, axes = plt.subplots(1, len(studies), figsize=(5 * len(studies), 4.2), squeeze=False)
    markers = {0.3: "o", 0.45: "s", 0.49: "^", "displacement": "o", "force": "x"}
    for ax, name in zip(axes[0], studies, strict=True):
        sub = [r for r in rows if r["study"] == name]
        for r in sub:
            colour = {"corotational": "C0", "quadratic": "C1", "neohookean": "C2"}.get(r["element"], "C0")
            if r["integrator"]:
                colour = "C3" if r["integrator"] == "trapezoidal" else "C0"
            mark = markers.get(r["drive"] or r["poisson_ratio"], "o")
            ax.loglog(r["step_ms"], max(r["error"], 1e-7), mark, color=colour, alpha=0.7, mfc="none")
        front = pareto(sub)
        ax.loglog([r["step_ms"] for r in front], [max(r["error"], 1e-7) for r in front], "k-", lw=1)
        ax.axhline(BUDGET, color="grey", ls=":", lw=1)
        ax.set_xlabel("step time (ms, CPU)")
        ax.set_ylabel("relative error")
        ax.set_title(name)
        ax.grid(True, which="both", alpha=0.3)
    handles = [plt.Line2D([], [], color=c, marker="o", ls="", mfc="none", label=lab) for c, lab in
               (("C0", "corotational / Euler"), ("C1", "quadratic"), ("C2", "Neo-Hookean"), ("C3", "trapezoid"))]
    handles += [plt.Line2D([], [], color="k", marker=m, ls="", mfc="none", label=f"nu {nu}")
                for nu, m in ((0.3, "o"), (0.45, "s"), (0.49, "^"))]
    axes[0, 0].legend(handles=handles, fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def plot_figure8(rows: list[dict], path: Path) -> None:
    """The paper's Figure 8: the effector's error and the step time against the mesh's nodes,
    driven by displacement and by force, on both meshes."""
    plt = _plt()
    fig, (ax_e, ax_t) = plt.subplots(1, 2, figsize=(11, 4.2))
    for i, name in enumerate(n for n in dict.fromkeys(r["study"] for r in rows) if n.startswith("figure8")):
        for drive, style in (("displacement", "-o"), ("force", "--x")):
            pts = sorted((r for r in rows if r["study"] == name and r["drive"] == drive and r["solver"] in BASE
                          and r["element"] == "corotational"), key=lambda r: r["dofs"])
            if not pts:
                continue
            nodes = [r["dofs"] // 3 for r in pts]
            label = f"{name.removeprefix('figure8_')}, {drive}"
            ax_e.loglog(nodes, [max(r["error"], 1e-7) for r in pts], style, color=f"C{i}", label=label)
            quad = sorted((r for r in rows if r["study"] == name and r["drive"] == drive and r["solver"] in BASE
                           and r["element"] == "quadratic"), key=lambda r: r["dofs"])
            if quad:
                ax_e.loglog([r["dofs"] // 3 for r in quad], [max(r["error"], 1e-7) for r in quad], ":^",
                            color=f"C{i}", mfc="none", label=f"{label}, 10-node")
            if drive == "displacement":
                ax_t.loglog(nodes, [r["step_ms"] for r in pts], style, color=f"C{i}", label=f"{label} (CPU)")
                gpu = [(n, r["step_ms_gpu"]) for n, r in zip(nodes, pts, strict=True) if r.get("step_ms_gpu")]
                if gpu:
                    ax_t.loglog(*zip(*gpu, strict=True), ":s", color=f"C{i}", label=f"{label} (GPU)")
    ax_e.set(xlabel="nodes", ylabel="effector error (relative)", title="Diamond: effector error (Figure 8)")
    ax_t.set(xlabel="nodes", ylabel="step time (ms)", title="Diamond: a quasi-static step from rest")
    from matplotlib.ticker import NullFormatter

    for ax in (ax_e, ax_t):
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def _pct(x) -> str:
    return f"{100 * x:+.2f} %" if x != "" else ""


def _mesh(mesh, unit: str = "") -> str:
    """A mesh setting: a size (m), or for nested studies the number of splits (an int)."""
    return f"split {mesh}" if isinstance(mesh, int) else f"{mesh}{unit}"


def _ms(r: dict) -> str:
    gpu = f" / {r['step_ms_gpu']:.2f}" if r.get("step_ms_gpu") not in (None, "") else ""
    return f"{r['step_ms']:.1f}{gpu}"


def cheapest(rows: list[dict]) -> dict | None:
    ok = [r for r in rows if r["error"] <= BUDGET and r["converged"]]
    return min(ok, key=lambda r: r["step_ms"]) if ok else None


def elastic_section(name: str, sub: list[dict]) -> list[str]:
    against = {"analytic": "the analytic solution", "extrapolated": "the Richardson extrapolation of the three "
               "finest meshes", "finest": "the finest mesh", "not monotone": "the extrapolation of three meshes "
               "that do not converge monotonically (order 2 assumed: a trend, not a converged reference)",
               "assumed order": f"the extrapolation of the two finest meshes at an assumed order "
               f"{sub[0]['order']} (a third did not fit)"}[sub[0]["reference"]]
    if sub[0].get("reference_element") not in (None, "", "corotational"):
        against = against.replace("meshes", f"{sub[0]['reference_element']} meshes", 1)
    lines = [f"## {name}: error against {against} (direct solve)", "",
             "| element | mesh (m, or splits) | DOFs | nu 0.3 | nu 0.45 | nu 0.49 | step ms (nu 0.45, CPU / GPU) "
             "| memory MB |",
             "|---|---|---|---|---|---|---|---|"]
    direct = [r for r in sub if r["solver"] in BASE]
    for element in dict.fromkeys(r["element"] for r in direct):
        for mesh in dict.fromkeys(r["mesh"] for r in direct):
            at = {r["poisson_ratio"]: r for r in direct if r["element"] == element and r["mesh"] == mesh}
            if not at:
                continue
            r45 = at.get(0.45, next(iter(at.values())))
            lines.append(f"| {element} | {_mesh(mesh)} | {r45['dofs']} | " + " | ".join(
                _pct(at[nu]["signed_error"]) if nu in at else "" for nu in (0.3, 0.45, 0.49))
                + f" | {_ms(r45)} | {r45['memory_mb']:.1f} |")
    lines.append("")
    for nu in dict.fromkeys(r["poisson_ratio"] for r in direct):
        est = [r for r in direct if r["poisson_ratio"] == nu and r["reference_error"] != ""]
        if est and est[0]["reference"] == "not monotone":
            lines.append(f"- nu {nu}: the meshes do not converge monotonically: no setting is recommended against "
                         "their trend")
            continue
        if est:
            observed = "assumed" if est[0]["reference"] == "assumed order" else "observed"
            lines.append(f"- nu {nu}: the finest mesh's own error, by the extrapolation: "
                         f"{100 * est[0]['reference_error']:.2f} % ({observed} order {est[0]['order']:.2f})")
        best = cheapest([r for r in direct if r["poisson_ratio"] == nu])
        lines.append(f"- nu {nu}: " + (f"the cheapest setting within {100 * BUDGET:.0f} % is {best['element']} at "
                                       f"{_mesh(best['mesh'], ' m')} ({best['dofs']} DOFs): "
                                       f"{_pct(best['signed_error'])}, "
                                       f"{best['step_ms']:.1f} ms" if best else "no setting within the budget"))
    cg = [r for r in sub if r["solver"] == "pcg"]
    if cg:
        lines += ["", "CG tolerance (corotational, nu 0.45), error and step time against the direct solve. (On "
                  "the CPU the CG's preconditioner is the exact factorization of the system at rest, so a "
                  "quasi-static solve from rest takes one iteration whatever the tolerance; the axis matters "
                  "on CUDA, `--device cuda`.)", "",
                  "| mesh (m) | DOFs | direct | " + " | ".join(f"CG {t:g}" for t in
                                                           sorted({r["tolerance"] for r in cg}, reverse=True)) + " |",
                  "|---|---|---|" + "---|" * len({r["tolerance"] for r in cg})]
        for mesh in dict.fromkeys(r["mesh"] for r in cg):
            d = next(r for r in direct if r["mesh"] == mesh and r["element"] == "corotational"
                     and r["poisson_ratio"] == 0.45)
            cells = [f"{_pct(r['signed_error'])}, {_ms(r)} ms ({r['cg_iterations']:.0f} its"
                     + (f", {r['precision']}" if r["precision"] else "") + ")"
                     for r in sorted((r for r in cg if r["mesh"] == mesh), key=lambda r: -r["tolerance"])]
            lines.append(f"| {mesh} | {d['dofs']} | {_pct(d['signed_error'])}, {_ms(d)} ms | " + " | ".join(cells)
                         + " |")
    return lines + [""]


def figure8_section(rows: list[dict]) -> list[str]:
    """The Figure 8 table: per mesh and element, the effector's error by drive, the displacement
    drive's cable tensions and the step time; then what the reference is worth."""
    lines = ["## The paper's Figure 8: the Diamond's effector, driven by displacement and by force", "",
             "Error of the effector's motion against the Richardson extrapolation of the three linear meshes; "
             "10-node elements on the two coarser meshes against the same reference. Tensions: the three "
             "driven cables' under the displacement drive (the force drive pulls every mesh with the finest "
             "linear mesh's).", "",
             "| mesh | element | nodes | drive | effector error | tensions (N) | step ms (CPU / GPU) | "
             "reference's own error (Richardson, order) |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["solver"] not in BASE:
            continue
        est = f"{100 * r['reference_error']:.2f} %, p = {r['order']:.2f}" if r["reference_error"] != "" else ""
        est = "not monotone (p = 2 assumed)" if r["reference"] == "not monotone" else est
        tensions = " ".join(f"{t:.2f}" for t in r["value"][3:6]) if r["drive"] == "displacement" else ""
        lines.append(f"| {r['study'].removeprefix('figure8_')} {r['mesh']} | {r['element']} | {r['dofs'] // 3} | "
                     f"{r['drive']} | {100 * r['error']:.3f} % | {tensions} | {_ms(r)} | {est} |")
    for name in dict.fromkeys(r["study"] for r in rows):
        disp = [r for r in rows if r["study"] == name and r["drive"] == "displacement" and r["solver"] in BASE]
        lin = max((r for r in disp if r["element"] == "corotational"), key=lambda r: r["dofs"])
        quad = [r for r in disp if r["element"] == "quadratic"]
        if not quad:
            continue
        q = max(quad, key=lambda r: r["dofs"])
        gap = float(((q["value"][:3] - lin["value"][:3]) ** 2).sum() ** 0.5
                    / (lin["reference_value"] ** 2).sum() ** 0.5)
        lin_all = [r for r in disp if r["element"] == "corotational"]
        lines.append(f"- {name}: the finest 10-node ({q['dofs'] // 3} nodes) and linear ({lin['dofs'] // 3} nodes) "
                     f"solutions differ by {100 * gap:.1f} % of the motion; the displacement drive's first cable "
                     f"needs " + ", ".join(f"{r['value'][3]:.2f}" for r in sorted(lin_all, key=lambda r: r["dofs"]))
                     + f" N on the {len(lin_all)} linear meshes.")
    return lines + [""]


def swing_section(rows: list[dict]) -> list[str]:
    lines = ["## Time step and integrator: the cantilever falling under gravity", "",
             "Tip trajectory every 8 ms over 0.2 s against a trapezoid run at 0.25 ms, error relative to "
             "the tip's largest motion; Newton iterations to 1e-8 (step times are those of that tolerance).",
             "", "| integrator | dt (s) | error | step ms |", "|---|---|---|---|"]
    lines += [f"| {r['integrator']} | {r['dt']} | {100 * r['error']:.3f} % | {_ms(r)} |" for r in rows]
    return lines + [""]


def cuda_section(gpu_rows: list[dict]) -> list[str]:
    """CUDA's CG axis from the GPU run's CSV: per mesh, tolerance and preconditioner precision, the
    error against Timoshenko, the iterations and the step time."""
    cg = [g for g in gpu_rows if g["solver"] == "pcg" and g["study"] == "cantilever"]
    if not cg:
        return []
    lines = ["## On CUDA: the CG's tolerance and its preconditioner's precision", "",
             "The cantilever (corotational, nu 0.45) solved from rest by the CG (preconditioned by the warped "
             "rest factorization: a dense inverse on the device up to 12k free DOFs, sparse solves on the host "
             "above), error against Timoshenko and step time on the GPU, float32 / float64 storage of the "
             "preconditioner.", "",
             "| mesh (m) | DOFs | CG tolerance | error, float32 | error, float64 | iterations | step ms (f32 / f64) |",
             "|---|---|---|---|---|---|---|"]
    for mesh in dict.fromkeys(g["mesh"] for g in cg):
        for tol in sorted({g["tolerance"] for g in cg if g["mesh"] == mesh}, key=float, reverse=True):
            at = {g["precision"]: g for g in cg if g["mesh"] == mesh and g["tolerance"] == tol}
            f32, f64 = at.get("float32"), at.get("float64")
            if not (f32 and f64):
                continue
            lines.append(f"| {mesh} | {f32['dofs']} | {float(tol):g} | {_pct(float(f32['signed_error']))} | "
                         f"{_pct(float(f64['signed_error']))} | {float(f32['cg_iterations']):.0f} / "
                         f"{float(f64['cg_iterations']):.0f} | {float(f32['step_ms']):.2f} / "
                         f"{float(f64['step_ms']):.2f} |")
    return lines + [""]


def summary(rows: list[dict], device: str, command: str, gpu_rows: list[dict] = ()) -> str:
    gpu = ("; GPU: the same step on an H200 with CUDA's default solver (CG to 1e-6 from rest, preconditioned by "
           "the warped rest factorization)" if gpu_rows else "")
    lines = [f"# What accuracy costs in time ({date.today().isoformat()}, timings on {device})", "",
             f"Command: `{command}`", "",
             "Errors are signed along the reference where it says so (negative: too stiff). Step time: a "
             "quasi-static solve from rest (linearization, solve, rows), median of three" + gpu + "; memory: the "
             f"simulator's Warp buffers. Budget: {100 * BUDGET:.0f} %.", ""]
    for name in dict.fromkeys(r["study"] for r in rows):
        sub = [r for r in rows if r["study"] == name]
        if name.startswith("figure8"):
            continue
        lines += swing_section(sub) if name == "swing" else elastic_section(name, sub)
    lines += cuda_section(list(gpu_rows))
    fig8 = [r for r in rows if r["study"].startswith("figure8")]
    if fig8:
        lines += figure8_section(fig8)
    return "\n".join(lines) + "\n"
