"""Figures of a run report (``warpsoft plot REPORT.json``): what a run did, at a glance.

- ``effectors.png``: each effector's position (mm) against its target over time, per axis (or
  the probes', when the scene has no effector);
- ``actuators.png``: each actuator's displacement (cable mm, cavity mm^3) and force (N, Pa);
- ``timings.png``: the time of each step (ms) and the median of each stage.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import SceneError


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise SceneError("warpsoft plot needs matplotlib: pip install 'warpsoft[plot]'") from None
    matplotlib.use("Agg")  # files only, no window
    import matplotlib.pyplot as plt

    return plt


def _number(v) -> float:
    """Report values: numbers, or "nan"/"inf" strings (the report's JSON form of non-finite values)."""
    return float(v) if v is not None else float("nan")


def plot_report(report: str | Path, out: str | Path | None = None) -> list[Path]:
    """Write the figures of the report ``report`` into ``out`` (default: beside the report,
    named after it); returns their paths."""
    report = Path(report)
    try:
        d = json.loads(report.read_text())
    except (OSError, ValueError) as exc:
        raise SceneError(f"plot: cannot read the report {str(report)!r}: {exc}") from None
    if "time" not in d or "timings" not in d:
        raise SceneError(f"plot: {str(report)!r} is not a warpsoft run report (no 'time' or 'timings')")
    plt = _pyplot()
    out = Path(out) if out is not None else report.parent
    out.mkdir(parents=True, exist_ok=True)
    stem, t = report.stem, [_number(v) for v in d["time"]]
    written = []

    tracks = d.get("effectors") or d.get("points") or {}
    targets = d.get("targets", {})
    if tracks and t:
        fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
        for name, pts in tracks.items():
            for a, ax in enumerate(axes):
                line, = ax.plot(t, [1e3 * _number(p[a]) for p in pts], label=name)
                if name in targets:
                    ax.plot(t, [1e3 * _number(p[a]) for p in targets[name]], "--", color=line.get_color(),
                            label=f"{name} target")
        for a, ax in enumerate(axes):
            ax.set_ylabel(f"{'xyz'[a]} (mm)")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize="small")
        axes[0].set_title(f"{d.get('scene', stem)}: {'effectors and targets' if d.get('effectors') else 'probes'}")
        axes[-1].set_xlabel("time (s)")
        written.append(_save(fig, out / f"{stem}-effectors.png", plt))

    actuators = d.get("actuators", {})
    if actuators and t:
        fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        for name, a in actuators.items():
            unit = 1e3 if a.get("kind") == "cable" else 1e9
            top.plot(t, [unit * _number(v) for v in a["delta"]], label=f"{name} ({a.get('kind')})")
            bottom.plot(t, [_number(v) for v in a["lambda"]], label=name)
        top.set_ylabel("displacement (cable mm, cavity mm^3)")
        bottom.set_ylabel("force (cable N, cavity Pa)")
        bottom.set_xlabel("time (s)")
        top.set_title(f"{d.get('scene', stem)}: actuators")
        top.legend(fontsize="small")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
        written.append(_save(fig, out / f"{stem}-actuators.png", plt))

    per_step = d["timings"].get("per_step", [])
    if per_step:
        fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
        left.plot(range(1, len(per_step) + 1), [1e3 * _number(v) for v in per_step], ".-")
        left.set_xlabel("step")
        left.set_ylabel("step time (ms)")
        left.set_yscale("log")
        left.grid(alpha=0.3)
        stages = d["timings"].get("stages", {})
        right.barh(list(stages), [1e3 * _number(s["median"]) for s in stages.values()])
        right.set_xlabel("median time per step (ms)")
        fig.suptitle(f"{d.get('scene', stem)} on {d.get('device')}: {d.get('steps')} steps, status "
                     f"{d.get('status', '?')}")
        written.append(_save(fig, out / f"{stem}-timings.png", plt))
    return written


def _save(fig, path: Path, plt) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
