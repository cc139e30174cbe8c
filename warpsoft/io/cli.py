"""Command line: ``warpsoft run SCENE.py [--steps N] [--device cpu|cuda] [--usd OUT] [--report OUT.json]
[--param key=value ...]``, ``warpsoft sweep SCENE.py --grid ... | --random N ... --out DIR`` (see
:mod:`warpsoft.io.sweep`), ``warpsoft optimize SCENE.py --space ... --minimize METRIC --out DIR`` (see
:mod:`warpsoft.io.optimize`), ``warpsoft params SCENE.py``, ``warpsoft plot REPORT.json``,
``warpsoft --version``."""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

from ..errors import SceneError, WarpsoftError


def _parser() -> argparse.ArgumentParser:
    from .. import __version__

    p = argparse.ArgumentParser(prog="warpsoft", description="Simulate and control soft robots with NVIDIA Warp.")
    p.add_argument("--version", action="version", version=f"warpsoft {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    ps = sub.add_parser("params", help="list a scene file's parameters, their defaults and its documentation")
    ps.add_argument("scene", help="path of the scene file")
    pl = sub.add_parser("plot", help="PNG figures of a run report: effectors and targets, actuators, timings")
    pl.add_argument("report", help="a JSON report written by warpsoft run --report")
    pl.add_argument("--out", default=None, help="folder of the figures (default: the report's)")
    r = sub.add_parser("run", help="run a scene file (a Python file defining build(**params) -> Scene)")
    r.add_argument("scene", help="path of the scene file")
    r.add_argument("--steps", type=int, default=None, help="number of steps (default: the scene's)")
    r.add_argument("--device", default=None, help="Warp device: cpu, cuda, cuda:0 (default: Warp's default)")
    r.add_argument("--usd", default=None, help="write a USD animation (.usda text or .usdc binary)")
    r.add_argument("--usd-contacts", action="store_true",
                   help="with --usd: also the contact points and their forces, per frame")
    r.add_argument("--report", default=None, help="write a JSON report")
    r.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help="scene parameter; VALUE is a Python or JSON literal (repeatable)")
    r.add_argument("--solver", choices=["auto", "pcg", "direct", "jacobi"], default="auto",
                   help="linear solver (default: auto, the fastest measured on the device: direct on cpu, pcg on cuda)")
    r.add_argument("--tolerance", type=float, default=1e-6, help="CG relative residual (default: 1e-6)")
    r.add_argument("--newton-iterations", type=int, default=10, metavar="N",
                   help="most linearizations per step; 1: one, as SOFA's implicit Euler (default: 10, used only "
                        "when the residual says so)")
    r.add_argument("--newton-tolerance", type=float, default=None,
                   help="nonlinear residual left along a step's correction, relative to it, at which the step is "
                        "done (default: 0.1 with implicit Euler, 1e-4 with the trapezoid; 1e-3 resolves an "
                        "implicit Euler step fully)")
    r.add_argument("--flush-every", type=int, default=50, metavar="N",
                   help="write the report and the USD every N steps as the run goes (default: 50)")
    r.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    sw = sub.add_parser("sweep", help="run many designs of a scene (its parameters over a grid or random ranges), "
                                      "batched as the worlds of one model; a results table and a plot")
    sw.add_argument("--grid", action="append", default=[], metavar="NAME=[V1,V2,...]",
                    help="a swept parameter and its values; several --grid make every combination")
    sw.add_argument("--random", nargs="+", default=None, metavar="N | NAME=LO:HI[:log]",
                    help="N designs spread over the ranges by a Latin hypercube (log: uniform in the logarithm); "
                         "with --grid, each grid point takes the same N")
    sw.add_argument("--seed", type=int, default=0, help="of --random (default: 0)")
    sw.add_argument("--plot", default=None, metavar="METRIC",
                    help="plot this metric over the swept parameters (default: the first metric)")
    _batch_arguments(sw, batch=256, out="folder of results.csv, the plot and the mesh cache")
    sw.add_argument("--append", action="store_true",
                    help="--out holds another sweep's results: add these designs to its table")
    sw.add_argument("--overwrite", action="store_true",
                    help="clear --out's results first (by default the same command resumes, skipping the designs "
                         "it finished)")
    op = sub.add_parser("optimize", help="search a scene's design space with Optuna for the best designs by its "
                                         "metrics, a batch of designs at a time; resumable; the best ones to USD")
    op.add_argument("--space", action="append", default=[], metavar="NAME=LO:HI[:log|:int] | NAME=[A,B,...]",
                    help="a design parameter and its range or choices (repeatable)")
    op.add_argument("--minimize", dest="objectives", action="append", type=lambda m: (m, "minimize"),
                    metavar="METRIC", help="an objective: a metric of the scene to make small (repeatable)")
    op.add_argument("--maximize", dest="objectives", action="append", type=lambda m: (m, "maximize"),
                    metavar="METRIC", help="an objective to make large (repeatable; several: a Pareto front)")
    op.add_argument("--trials", type=int, default=64, help="trials of the study in all, resumed ones included "
                                                           "(default: 64)")
    op.add_argument("--parallel", type=int, default=None,
                    help="batches run at once per round (default: 1; with --ray, the cluster's GPUs or CPUs)")
    op.add_argument("--seed", type=int, default=0, help="of the sampler (default: 0)")
    op.add_argument("--best", type=int, default=1, help="best designs run again to USD (default: 1)")
    op.add_argument("--study-name", default="warpsoft", help="name of the study in its storage (default: warpsoft)")
    op.add_argument("--storage", default=None, help="Optuna storage URL (default: sqlite in --out)")
    _batch_arguments(op, batch=16, out="folder of the study, trials.csv, the plot, the best designs' USD")
    return p


def _batch_arguments(p: argparse.ArgumentParser, batch: int, out: str) -> None:
    """The options ``sweep`` and ``optimize`` share: the scene, how designs run, where results go."""
    p.add_argument("scene", help="path of the scene file")
    p.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help="a scene parameter fixed for every design (repeatable)")
    p.add_argument("--steps", type=int, default=None, help="steps per design (default: the scene's)")
    p.add_argument("--batch", type=int, default=batch, help=f"designs stepped together as one model (default: {batch})")
    p.add_argument("--device", default=None, help="Warp device: cpu, cuda, cuda:0 (default: Warp's default)")
    p.add_argument("--solver", choices=["auto", "pcg", "direct", "jacobi"], default="auto")
    p.add_argument("--share-tolerance", type=float, default=1e-10,
                   help="pcg on CUDA: designs of one mesh share a preconditioner block when their systems are "
                        "multiples to within this (default 1e-10: exact multiples; 0.01 also shares dynamic "
                        "designs of one mesh, for less setup and memory)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes meshing the designs first (default: the CPU count; 1: in this process)")
    p.add_argument("--ray", nargs="?", const=True, default=False, metavar="ADDRESS",
                   help="run the batches as Ray tasks, one per GPU (or CPU) of the cluster at ADDRESS (alone: "
                        "RAY_ADDRESS's, else a new one on this machine)")
    p.add_argument("--parquet", action="store_true", help="also write the table as Parquet (needs pyarrow)")
    p.add_argument("--out", required=True, help=out)


def optimize_command(args) -> int:
    """``warpsoft optimize``: the study run or resumed, the table, the plot, the best designs' USD."""
    from .optimize import optimize, parse_space
    from .runner import check_device, parse_params

    check_device(args.device)
    if not args.objectives:
        raise SceneError("optimize: give an objective: --minimize METRIC or --maximize METRIC")
    study, best = optimize(args.scene, parse_space(args.space), args.objectives, args.trials, args.out,
                           batch=args.batch, steps=args.steps, device=args.device, fixed=parse_params(args.param),
                           workers=args.workers, ray=args.ray, parallel=args.parallel, seed=args.seed, best=args.best,
                           study_name=args.study_name, storage=args.storage, parquet=args.parquet, progress=True,
                           solver=args.solver, share_tolerance=args.share_tolerance)
    out = Path(args.out)
    failed = sum(t.state.name == "FAIL" for t in study.trials)
    print(f"warpsoft optimize: {len(study.trials)} trials ({failed} failed); table: {out / 'trials.csv'}")
    for rank, b in enumerate(best, start=1):
        values = ", ".join(f"{m} = {v:.6g}" for (m, _), v in zip(args.objectives, b.values, strict=True))
        print(f"  best {rank}: trial {b.trial} {b.params}: {values}; USD: {b.usd}")
    return 0


def sweep_command(args) -> int:
    """``warpsoft sweep``: the designs from --grid / --random, run, the table and the plot."""
    from .runner import check_device, parse_params
    from .sweep import grid, parse_grid, parse_ranges, plot_sweep, random_designs, sweep

    check_device(args.device)
    if not args.grid and not args.random:
        raise SceneError("sweep: give the designs: --grid NAME=[...] and/or --random N NAME=lo:hi")
    # what the options need, said before any design runs (a plot is only skipped)
    for wanted, module in ((args.parquet, "pyarrow"), (args.ray, "ray")):
        if wanted and importlib.util.find_spec(module) is None:
            extra = "ray" if module == "ray" else "sweep"
            raise SceneError(f"sweep: {'--parquet' if module == 'pyarrow' else '--ray'} needs {module}: "
                             f"pip install 'warpsoft[{extra}]'")
    designs = grid(parse_grid(args.grid)) if args.grid else [{}]
    if args.random:
        try:
            count = int(args.random[0])
        except ValueError:
            raise SceneError(f"sweep: --random starts with the number of designs, got {args.random[0]!r}") from None
        ranges = parse_ranges(args.random[1:])
        designs = [g | r for g in designs for r in random_designs(count, ranges, args.seed)]
    swept = list(designs[0])
    results = sweep(args.scene, designs, steps=args.steps, batch=args.batch, device=args.device,
                    fixed=parse_params(args.param), workers=args.workers, out=args.out, progress=True,
                    ray=args.ray, parquet=args.parquet, append=args.append, overwrite=args.overwrite,
                    solver=args.solver, share_tolerance=args.share_tolerance)
    out = Path(args.out)
    print(f"warpsoft sweep: {sum(r.status == 'completed' for r in results)} of {len(results)} designs completed; "
          f"table: {out / 'results.csv'}")
    for r in results:
        if r.status != "completed":
            print(f"  design {r.index} {r.params}: {r.status}: {r.error}")
    metrics = next((list(r.metrics) for r in results if r.metrics), [])
    metric = args.plot or (metrics[0] if metrics else None)
    if metric is not None and swept:
        if importlib.util.find_spec("matplotlib") is None:
            print("  no plot: matplotlib is not installed (pip install 'warpsoft[sweep]')")
        else:
            try:
                print(f"  plot: {plot_sweep(results, metric, swept[:2], out / f'{metric}.png')}")
            except SceneError as exc:  # the sweep ran and its table is written: the plot is only skipped
                print(f"  no plot: {exc}")
    return 0


def scene_params(path: str) -> str:
    """The text ``warpsoft params`` prints: the scene's documentation, then each parameter of its
    ``build`` with its default."""
    import inspect

    from .runner import load_scene_module

    module = load_scene_module(path)
    lines = [f"{path}:"]
    doc = inspect.getdoc(module.build) or inspect.getdoc(module)
    if doc:
        lines += ["  " + line for line in doc.splitlines()] + [""]
    for name, p in inspect.signature(module.build).parameters.items():
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        lines.append(f"  {name} = {p.default!r}" if p.default is not p.empty else f"  {name} (required)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from .runner import build_scene, parse_params, run

    try:
        if args.command == "params":
            print(scene_params(args.scene))
            return 0
        if args.command == "plot":
            from .plot import plot_report

            for path in plot_report(args.report, args.out):
                print(path)
            return 0
        if args.command == "sweep":
            return sweep_command(args)
        if args.command == "optimize":
            return optimize_command(args)
        params = parse_params(args.param)
        started = time.perf_counter()
        if not args.quiet:  # meshing may take a while: say what is going on
            print(f"warpsoft: building {args.scene} (meshing, or the mesh cache)...", file=sys.stderr, flush=True)
        scene = build_scene(args.scene, params)
        if not args.quiet:
            print(f"warpsoft: scene '{scene.name}' built in {time.perf_counter() - started:.1f} s", file=sys.stderr,
                  flush=True)
        rep = run(scene, steps=args.steps, device=args.device, usd=args.usd, report=args.report,
                  solver=args.solver, tolerance=args.tolerance, progress=not args.quiet, scene_file=args.scene,
                  flush_every=args.flush_every, newton_iterations=args.newton_iterations,
                  newton_tolerance=args.newton_tolerance, usd_contacts=args.usd_contacts)
    except WarpsoftError as exc:
        print(f"warpsoft: error: {exc}", file=sys.stderr)
        return 2
    if rep.status == "interrupted":
        print(f"warpsoft: {rep.error}; the outputs hold every finished step", file=sys.stderr)
        return 130
    if not args.quiet:
        d = rep.to_dict()
        t = d["timings"]["step"]
        print(f"{d['scene']}: {d['steps']} steps on {d['device']}, {d['dofs']} DOFs, {d['elements']} elements; "
              f"step median {1e3 * t['median']:.2f} ms, p90 {1e3 * t['p90']:.2f} ms")
        for name, pts in d["points"].items():
            print(f"  {name}: {[round(v, 6) for v in pts[-1]]} m")
        for w in d["warnings"][:5]:
            print(f"  warning: {w}")
        if args.usd:
            print(f"  USD: {args.usd}")
        if args.report:
            print(f"  report: {args.report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
