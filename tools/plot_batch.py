"""Throughput against batch size from ``tools/batch_bench.py``'s ``batch.json`` files: design-steps
per second (log-log), one line per file, labelled by its name.

    python tools/plot_batch.py OUT.png LABEL=PATH/batch.json [LABEL=PATH/batch.json ...]

Rows of several files with one label are joined (a batch size measured twice keeps the first).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 2 or any("=" not in a for a in args[1:]):
        print(__doc__)
        return 2
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    series: dict[str, dict[int, float]] = {}
    for arg in args[1:]:
        label, path = arg.split("=", 1)
        for row in json.loads(Path(path).read_text())["rows"]:
            series.setdefault(label, {}).setdefault(int(row["designs"]), float(row["design_steps_per_s"]))
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for label, points in series.items():
        sizes = sorted(points)
        ax.plot(sizes, [points[s] for s in sizes], "o-", label=label)
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("designs stepped together (worlds of one model)")
    ax.set_ylabel("design-steps per second")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args[0], dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
