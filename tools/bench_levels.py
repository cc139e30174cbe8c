"""Cost of the sparse factors' ``P^-1`` in a batch of different Diamonds (CUDA): at full load, and
over one solve's sequence of running worlds (those of the last warm-up step: at CG iteration
``i`` the worlds that took more than ``i``), each replayed from a graph, for each ``--tail``,
``--loads``, ``--lanes``, ``--unroll``, ``--short-lanes``, ``--tail-lanes`` and ``--entries``, for each
``--layout`` (rows or panels: the factors made again; ``--panel-rows``, ``--panel-spread``,
``--panel-unroll``, ``--wide``) (and the
product's largest difference from the first's, with every world running and with the last
iteration's).

    python tools/bench_levels.py --designs 1024 [--entries int32/float32 uint16/float32]
        [--tail default none 0.25,0.05] [--loads indexed whole]
        [--lanes 16 32] [--unroll 1 4] [--short-lanes 1 4] [--tail-lanes 1 32,32,8] [--device cuda]
        [--out out/levels.json]

The designs are ``batch_bench.py``'s with as many meshes as designs (set WARPSOFT_MESH_CACHE to
the meshes made ahead of time: meshing 1024 Diamonds takes minutes).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp
from warpsoft.kernels.linear.cg import DONE

import warpsoft as ws
from warpsoft.io.runner import build_scene
from warpsoft.linear import factors

sys.path.insert(0, str(Path(__file__).resolve().parent))
import batch_bench  # noqa: E402


def replayed(call, device: str, repeats: int, rounds: int) -> float:
    """Median time (ms) of ``call`` captured ``repeats`` times in a graph, replayed ``rounds`` times
    (on the CPU: called ``repeats`` times)."""
    def calls():
        for _ in range(repeats):
            call()
    run = calls
    if wp.get_device(device).is_cuda:
        with wp.ScopedCapture(device=device) as capture:
            calls()
        run = lambda: wp.capture_launch(capture.graph)  # noqa: E731
    return 1e3 * batch_bench._median_call(run, device, rounds) / repeats


def retype(pre, made: tuple, index, value) -> None:
    """The factors' entries as made (``made``: their solves and types) in the types ``index`` and
    ``value`` (new arrays). float16 values (clipped to its range) time their bytes only: as a
    preconditioner they were tried and not kept (a design's CG diverged, docs/performance.md)."""
    solves, *_ = made
    pre.solves = []
    for tasks, col, val, levels, spans in solves:
        v = val.numpy().astype(np.float64)
        if value == wp.float16:
            top = float(np.finfo(np.float16).max)
            v = np.clip(v, -top, top)
        c = col.numpy().astype(wp.dtype_to_numpy(index))
        pre.solves.append((tasks, wp.array(c, dtype=index, device=col.device),
                           wp.array(v.astype(wp.dtype_to_numpy(value)), dtype=value, device=val.device), levels, spans))
    pre.index_dtype, pre.value_dtype = index, value


def level_table(pre, columns: int, tier: int = 0) -> list[dict]:
    """Per launch of the panels' levels with every world's tasks (forward, then backward): its
    panels, values, columns read (each an index and an operand row of ``columns`` numbers), the
    lanes a panel takes at ``tier`` (0: every world's tasks; a wide level's: its block) and the
    longest lane's walk (columns), and the bytes it reads at least (each value and column index
    once; the operand rows, which a supernode's panels share, not counted)."""
    out = []
    vsize = np.dtype(wp.dtype_to_numpy(pre.value_dtype)).itemsize
    isize = np.dtype(wp.dtype_to_numpy(pre.index_dtype)).itemsize
    for direction, (tasks, _col, _val, levels, _spans) in zip(("forward", "backward"), pre.solves, strict=True):
        t = tasks.numpy()
        for j, (first, count, reads, _most) in enumerate(levels):
            part = t[first:first + count]
            width = part[:, 4] + part[:, 5]
            lanes = pre.panel_lanes(reads, tier)
            if tier and pre.wide_from is not None and reads >= pre.wide_from:
                lanes = pre.wide_lanes
            values, walk = int((part[:, 1] * width).sum()), np.ceil(width / lanes)
            out.append({"direction": direction, "level": j, "panels": int(count), "lanes": lanes,
                        "values": values, "columns": int(width.sum()), "walk_mean": float(walk.mean()),
                        "walk_max": int(walk.max()),
                        "bytes": values * vsize + int(width.sum()) * isize,
                        "operand_bytes": int(width.sum()) * columns * vsize})
    return out


LEVEL_KERNELS = ("factor_panel", "factor_wide_panel")  # (the levels' launches)


def per_level(pre, r, z, device: str, repeats: int = 5, tier: int = 0) -> tuple[list[dict], float]:
    """:func:`level_table` with each level's median device time (ms) over ``repeats`` products with
    the running worlds pre watches (``tier``: the tail's tier they launch at, 0 for every world's
    tasks), launched one by one (not from a graph) and timed by CUDA events; and their median sum (ms)."""
    table = level_table(pre, r.shape[0], tier)
    pre.apply(r, z)
    wp.synchronize_device(device)
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
    for _ in range(repeats):
        pre.apply(r, z)
    timed = [t for t in wp.timing_end() if any(name in t.name for name in LEVEL_KERNELS)]
    if len(timed) != repeats * len(table):
        raise RuntimeError(f"per_level: {len(timed)} level launches timed, {repeats * len(table)} expected")
    ms = np.array([t.elapsed for t in timed]).reshape(repeats, len(table))
    for row, t in zip(table, np.median(ms, axis=0), strict=True):
        row["ms"] = float(t)
        row["gb_per_s"] = row["bytes"] / t / 1e6
    return table, float(np.median(ms.sum(axis=1)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--designs", type=int, default=1024)
    ap.add_argument("--unroll", type=int, nargs="*", default=[1, 4], help="entries a level's thread loads at a time")
    ap.add_argument("--loads", nargs="*", default=["indexed"], choices=["indexed", "whole"],
                    help="operand rows indexed number by number (CUDA's) or read from their address (the CPU's)")
    ap.add_argument("--lanes", type=int, nargs="*", default=None,
                    help="threads a long row (a power of 2 up to 32; default: the preconditioner's)")
    ap.add_argument("--short-lanes", type=int, nargs="*", default=None,
                    help="threads a short row (the sliced levels') with every world's tasks (default: the "
                         "preconditioner's)")
    ap.add_argument("--tail-lanes", nargs="*", default=None,
                    help="threads a short row in the tail, a number per tier, comma-separated (32,32,8; the "
                         "last serves any more tiers; default: the preconditioner's)")
    ap.add_argument("--entries", nargs="*", default=None,
                    help="the factors' column and value types, index/value: int32/float32, uint16/float16, ... "
                         "(default: the preconditioner's)")
    ap.add_argument("--layout", nargs="*", default=None, choices=["rows", "panels"],
                    help="how a level's work is cut (default: the preconditioner's; another factorizes again)")
    ap.add_argument("--panel-spread", nargs="*", default=None,
                    help="panels: the columns a lane takes at full load and in the tail, comma-separated (4,1)")
    ap.add_argument("--panel-rows", type=int, nargs="*", default=None, help="panels: rows a panel at most")
    ap.add_argument("--panel-unroll", type=int, nargs="*", default=None, help="panels: columns a lane loads at a time")
    ap.add_argument("--wide", nargs="*", default=None,
                    help="panels: in the tail, the mean columns from which a level's panels take a block of "
                         "threads each, and the block, comma-separated (256,128), or none (default: the "
                         "preconditioner's)")
    ap.add_argument("--tail-running", type=int, default=50,
                    help="--per-level: the levels also timed with this many running worlds at most (the first "
                         "CG iteration of the last warm-up step with as few)")
    ap.add_argument("--unchecked", type=int, nargs="*", default=None, choices=[0, 1],
                    help="panels: 1 when every world runs, the tasks do not test their world (default: the "
                         "preconditioner's)")
    ap.add_argument("--tail", nargs="*", default=["default"],
                    help="the tiers of running worlds whose tasks launch alone: default (the preconditioner's), "
                         "none, or shares of the worlds, comma-separated (0.25,0.05)")
    ap.add_argument("--warmup", type=int, default=4, help="steps before (their last gives the running worlds)")
    ap.add_argument("--device", default="cuda", help="cuda (what it is for) or cpu (a check that it runs)")
    ap.add_argument("--per-level", action="store_true",
                    help="CUDA, panels: each variant's levels, each one's time with every world and its bytes")
    ap.add_argument("--out", default=None, help="a JSON file for the results")
    args = ap.parse_args(argv)
    device = args.device
    t0 = time.perf_counter()
    designs = batch_bench.designs(args.designs, args.designs)
    scenes = [build_scene(batch_bench.ROOT / "scenes/diamond.py", d) for d in designs]
    sim = ws.Simulator(ws.finalize(scenes, device), device=device, solver="pcg", block_cg=True,
                       preconditioner="factors", share_tolerance=0.01)
    for _ in range(args.warmup):
        stats = sim.step()
    its = np.array([w.cg_iterations for w in stats.worlds])
    print(f"set up in {time.perf_counter() - t0:.1f} s; worlds by CG iterations: {np.bincount(its).tolist()}",
          flush=True)
    m, pre, solver = sim.model, sim.solver.precond, sim.solver
    k = solver.r.shape[0]
    rng = np.random.default_rng(0)
    r = wp.array(rng.standard_normal((k, m.num_nodes, 3)) * m.mask_np, dtype=wp.vec3d, device=device)
    z = wp.zeros_like(r)
    masks = []  # per CG iteration: the worlds that still ran
    for i in range(int(its.max())):
        s = np.zeros(solver.scal.shape)
        s[:, its <= i, DONE] = 1.0
        masks.append(wp.array(s, dtype=wp.float64, device=device))
    results, first = [], None
    kept = pre.whole_rows, pre.lanes, pre.tiers, pre.short_lanes, pre.tail_lanes, pre.unchecked_full
    tail_lanes = [[int(n) for n in t.split(",")] for t in args.tail_lanes] if args.tail_lanes else [pre.tail_lanes]
    spreads = [tuple(float(n) for n in t.split(",")) for t in args.panel_spread] if args.panel_spread else [None]
    made = pre.solves, pre.index_dtype, pre.value_dtype
    entries = args.entries or [f"{made[1].__name__}/{made[2].__name__}"]
    variants = [(en, t, lo, la, u, sh, tl) for en in entries for t in args.tail for lo in args.loads
                for la in args.lanes or [pre.lanes] for u in args.unroll for sh in args.short_lanes or [pre.short_lanes]
                for tl in tail_lanes]
    # (the rows' own options, lanes to tail lanes, do not apply to panels: their first values only)
    variants = [((lay, pr), sp, pu, *v) for lay in args.layout or [pre.layout]
                for pr in (args.panel_rows or [pre.panel_rows] if lay == "panels" else [pre.panel_rows])
                for v in (variants if lay == "rows" else [u for u in variants if u[3:] == variants[0][3:]])
                for sp in (spreads if lay == "panels" else [None])
                for pu in (args.panel_unroll or [pre.panel_unroll] if lay == "panels" else [None])]
    variants = [(*v, unchecked) for v in variants for unchecked in args.unchecked or [int(pre.unchecked_full)]]
    kept_wide = pre.wide_from, pre.wide_lanes
    wides = [None if w == "none" else (float(w.split(",")[0]), int(w.split(",")[1])) for w in args.wide] \
        if args.wide else [kept_wide if kept_wide[0] is not None else None]
    variants = [(*v, wide) for v in variants for wide in (wides if v[0][0] == "panels" else [None])]
    tail_mask = next((i for i in range(len(masks)) if int((its > i).sum()) <= args.tail_running), len(masks) - 1)
    # (each layout's factors made at the same rotations)
    made_as = None if args.layout or args.panel_rows else (pre.layout, pre.panel_rows)
    for ((layout, panel_rows), spread, panel_unroll, entry, tail, loads, lanes, unroll, short, tail_short,
         unchecked, wide) in variants:
        pre.unchecked_full = bool(unchecked)
        pre.wide_from, pre.wide_lanes = wide if wide is not None else (None, kept_wide[1])
        if (layout, panel_rows) != made_as:  # the factors made again, laid out
            t1 = time.perf_counter()
            retype(pre, made, *made[1:])
            pre.layout, pre.panel_rows, pre.solves = layout, panel_rows, None
            pre.refresh()
            made, made_as = (pre.solves, pre.index_dtype, pre.value_dtype), (layout, panel_rows)
            print(f"factors made again as {layout} in {time.perf_counter() - t1:.1f} s: levels {pre.levels}, "
                  f"{pre.entries} values, {pre.memory_bytes / 2 ** 20:.0f} MiB", flush=True)
        if spread is not None:
            pre.panel_spread = spread
        if panel_unroll is not None:
            pre.panel_unroll = panel_unroll
        retype(pre, made, *(getattr(wp, name) for name in entry.split("/")))
        shares = factors.TAIL if tail == "default" else [] if tail == "none" else [float(f) for f in tail.split(",")]
        pre.tail(sorted({int(np.ceil(f * m.num_worlds)) for f in shares}))
        pre.whole_rows, pre.lanes = loads == "whole", lanes
        pre.unroll, pre.short_lanes, pre.tail_lanes = unroll, short, tail_short
        got = []
        for mask in (masks[0], masks[-1]):
            pre.watch(mask)
            z.zero_()
            pre.apply(r, z)
            got.append(z.numpy().copy())  # (on the CPU numpy() is a view of z)
        first = got if first is None else first
        # relative to the first variant's product, with every world running and in the last iteration
        differs = [float(np.abs(g - f).max() / np.abs(f).max()) for g, f in zip(got, first, strict=True)]
        pre.watch(masks[0])
        full = replayed(lambda: pre.apply(r, z), device, 10, 5)
        levels = None
        if args.per_level and layout == "panels" and wp.get_device(device).is_cuda:
            levels, _ = per_level(pre, r, z, device)
            for row in levels:
                print(f"level {row['direction'][:4]} {row['level']:2d}: {row['panels']:7d} panels, "
                      f"{row['lanes']:2d} lanes, walk {row['walk_mean']:5.1f} (most {row['walk_max']:4d}), "
                      f"{row['values'] / 1e6:7.2f} M values, {row['bytes'] / 1e6:7.1f} MB (operands "
                      f"{row['operand_bytes'] / 1e6:7.1f}): {1e3 * row['ms']:7.1f} us, {row['gb_per_s']:6.0f} GB/s",
                      flush=True)
            print(f"levels: {sum(row['ms'] for row in levels):.3f} ms in all", flush=True)
            pre.watch(masks[tail_mask])
            running = int((its > tail_mask).sum())
            tier = next((t for t in pre.tiers if running <= t), 0)
            tail_levels, tail_ms = per_level(pre, r, z, device, tier=tier)
            for row in tail_levels:
                print(f"tail ({running} running, tier {tier}) {row['direction'][:4]} {row['level']:2d}: "
                      f"{row['lanes']:3d} lanes, walk {row['walk_mean']:5.1f} (most {row['walk_max']:4d}): "
                      f"{1e3 * row['ms']:7.1f} us", flush=True)
            print(f"tail levels ({running} running, tier {tier}): {tail_ms:.3f} ms in all", flush=True)
            levels = {"full": levels, "tail": tail_levels, "tail_ms": tail_ms, "tail_running": running}
        sequence = []
        for mask in masks:
            pre.watch(mask)
            sequence.append(replayed(lambda: pre.apply(r, z), device, 5, 3))
        results.append({"layout": layout, "panel_rows": panel_rows, "panel_spread": spread, "wide": wide,
                        "panel_unroll": panel_unroll, "unchecked": unchecked,
                        "entries": entry, "tail": pre.tiers, "loads": loads, "lanes": lanes, "unroll": unroll,
                        "short_lanes": short, "tail_lanes": tail_short, "full_ms": full, "solve_ms": sum(sequence),
                        "sequence_ms": sequence, "max_difference": differs, "levels": levels})
        panels = "" if layout == "rows" else (f" of {panel_rows} rows, spread {pre.panel_spread}, unroll "
                                              f"{panel_unroll}, unchecked {unchecked}, wide {wide}")
        print(f"{layout}{panels}, entries {entry}, tail {pre.tiers}, {loads}, {lanes} lanes, unroll {unroll}, "
              f"short rows {short} lanes, "
              f"in the tail {tail_short}: P^-1 {full:.3f} ms with every world; a "
              f"solve's {len(sequence)} {sum(sequence):.2f} ms [{' '.join(f'{t:.2f}' for t in sequence)}]; "
              f"differs by {differs[0]:.3g} (every world), {differs[1]:.3g} (the last iteration)", flush=True)
    retype(pre, made, *made[1:])
    pre.unchecked_full = bool(kept[5])
    pre.wide_from, pre.wide_lanes = kept_wide
    pre.whole_rows, pre.lanes = kept[:2]
    pre.tail(kept[2])
    pre.short_lanes, pre.tail_lanes = kept[3:5]
    pre.watch(solver.scal)
    if args.out:
        Path(args.out).write_text(json.dumps({"designs": args.designs, "iterations": its.tolist(),
                                              "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
