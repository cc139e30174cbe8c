"""Design optimization: Optuna proposes designs, warpsoft runs them a batch at a time as the
worlds of one model.

    warpsoft optimize SCENE.py --space NAME=LO:HI[:log|:int] | NAME=[A,B,...] ...
                               --minimize METRIC | --maximize METRIC [...] [--trials 64] [--batch 16]
                               [--param NAME=VALUE ...] [--steps N] [--device cuda] [--ray [ADDRESS]]
                               [--best 1] --out DIR

Each round asks Optuna (ask and tell; TPE by default) for ``batch`` designs per batch run at
once (one without Ray; with Ray, one per GPU or CPU of the cluster), runs them with
:func:`warpsoft.io.sweep.evaluate` and tells Optuna each design's objectives: metrics of the
scene (its ``metrics(result)``, or the default ones of :mod:`warpsoft.io.sweep`). A design that
is invalid, fails, or gives a non-finite objective is a failed trial, with the reason kept.

The study is stored in ``DIR/study.db`` (SQLite; ``storage`` for another database), so the
same command run again resumes it: ``--trials`` is the study's total. Trials that an interrupted
run left running are failed and their designs asked again. A resumed study must keep its scene,
objectives, fixed parameters and steps (said if not).

Written to ``DIR``: ``trials.csv`` (one row per trial: parameters, objectives, metrics, state;
``trials.parquet`` on request), ``history.png`` (the first objective over the trials) and, for
the best designs (the Pareto front with several objectives), each run alone again with its USD
animation and JSON report (``best1_trial12.usda`` ...) and ``best.json``.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

from ..errors import SceneError, WarpsoftError
from .runner import build_scene, parse_value, run
from .sweep import DesignResult, check_range, evaluate, mesh_cache, write_rows

DIRECTIONS = ("minimize", "maximize")


def _optuna():
    try:
        import optuna
    except ImportError:
        raise SceneError("warpsoft optimize needs Optuna: pip install 'warpsoft[sweep]'") from None
    return optuna


def parse_space(items: Sequence[str]) -> dict:
    """``["E=1e5:1e6:log", "n=2:5:int", "r=0.002:0.004", "kind=['a', 'b']"]`` -> Optuna
    distributions (float, log float, integer, categorical)."""
    d = _optuna().distributions
    space = {}
    for item in items:
        name, sep, text = item.partition("=")
        name, text = name.strip(), text.strip()
        if not sep or not name:
            raise SceneError(f"optimize: --space expects NAME=LO:HI[:log|:int] or NAME=[A, B, ...], got {item!r}")
        if text.startswith(("[", "(")):
            choices = parse_value(text)
            if not isinstance(choices, (list, tuple)) or not choices:
                raise SceneError(f"optimize: --space {name}: a non-empty list of choices, got {text!r}")
            space[name] = d.CategoricalDistribution(list(choices))
            continue
        fields = text.split(":")
        try:
            lo, hi = float(fields[0]), float(fields[1])
            kind = fields[2] if len(fields) == 3 else ""
            if len(fields) not in (2, 3) or kind not in ("", "log", "int"):
                raise ValueError
        except (ValueError, IndexError):
            raise SceneError(f"optimize: --space expects NAME=LO:HI[:log|:int] or NAME=[A, B, ...], "
                             f"got {item!r}") from None
        check_range("optimize", name, lo, hi, kind == "log")
        if kind == "int":
            if lo != int(lo) or hi != int(hi):
                raise SceneError(f"optimize: integer range of {name!r} needs whole bounds, got {lo}:{hi}")
            space[name] = d.IntDistribution(int(lo), int(hi))
        else:
            space[name] = d.FloatDistribution(lo, hi, log=kind == "log")
    if not space:
        raise SceneError("optimize: give the design space: --space NAME=LO:HI ...")
    return space


@dataclass
class Best:
    """One of the best designs, run again alone: its trial, objectives (in the order given),
    parameters and outputs."""

    trial: int
    values: list[float]
    params: dict
    usd: Path
    report: Path


def optimize(scene_file: str | Path, space: dict, objectives: Sequence[tuple[str, str]], trials: int, out: str | Path,
             batch: int = 16, steps: int | None = None, device: str | None = None, fixed: dict | None = None,
             workers: int | None = None, ray: bool | str = False, parallel: int | None = None, seed: int = 0,
             best: int = 1, study_name: str = "warpsoft", storage: str | None = None, parquet: bool = False,
             progress: bool = False, **options):
    """Run an Optuna study of ``trials`` trials in all over ``space`` (name -> Optuna
    distribution, see :func:`parse_space`) for ``objectives`` (``(metric, "minimize" |
    "maximize")``, in order), stored under ``out`` (resumed if there). ``parallel`` batches of
    ``batch`` designs per round (default: 1, or with ``ray`` the cluster's GPUs or CPUs);
    ``fixed``, ``steps``, ``device``, ``workers``, ``options`` as for :func:`warpsoft.io.sweep.sweep`.
    The ``best`` best designs are run again with USD. Returns ``(study, [Best, ...])``."""
    optuna = _optuna()
    objectives = [(str(m), str(d)) for m, d in objectives]
    if not objectives or any(d not in DIRECTIONS for _, d in objectives):
        raise SceneError(f"optimize: give objectives as (metric, 'minimize' | 'maximize'), got {objectives!r}")
    if int(trials) < 1 or int(batch) < 1 or int(best) < 1 or (parallel is not None and int(parallel) < 1):
        raise SceneError(f"optimize: trials, batch, best and parallel must be >= 1, got {trials}, {batch}, {best}, "
                         f"{parallel}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fixed = dict(fixed or {})
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name=study_name, storage=storage or f"sqlite:///{out.resolve() / 'study.db'}",
                                load_if_exists=True, directions=[d for _, d in objectives])
    _check_resume(study, {"scene": Path(scene_file).name, "objectives": [list(o) for o in objectives],
                          "fixed": fixed, "steps": steps})
    study.sampler = optuna.samplers.TPESampler(seed=seed + len(study.trials), constant_liar=True)
    _ask_again_left_running(study)
    with ExitStack() as stack, mesh_cache(out):
        if ray:
            from .cluster import parallel_batches, ray_session

            stack.enter_context(ray_session(ray))
        per_round = int(batch) * int(parallel or (parallel_batches(device) if ray else 1))
        while (finished := len(_finished(study))) < int(trials):
            asked = [study.ask(space) for _ in range(min(per_round, int(trials) - finished))]
            results = evaluate(scene_file, [fixed | t.params for t in asked], steps, batch, device, workers, ray,
                               options)
            for t, r in zip(asked, results, strict=True):
                _tell(study, t, r, objectives)
            _write_trials(study, objectives, out, parquet)
            if progress:
                print(f"warpsoft optimize: {len(_finished(study))}/{trials} trials; {_best_text(study, objectives)}",
                      flush=True)
    _write_trials(study, objectives, out, parquet)
    _plot_history(study, objectives, out / "history.png")
    return study, export_best(study, objectives, scene_file, fixed, out, best, steps, device, options)


def _finished(study) -> list:
    """The trials that count toward ``trials``: complete, failed or pruned, but not those an
    interrupted run left unfinished (their designs are asked again)."""
    from optuna.trial import TrialState

    cut = set(study.user_attrs.get("interrupted", []))
    return [t for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.FAIL,
                                                                TrialState.PRUNED)) if t.number not in cut]


def _check_resume(study, setup: dict) -> None:
    """A new study records its setup; a resumed one must have the same."""
    before = study.user_attrs.get("setup")
    setup = json.loads(json.dumps(setup))  # as stored (tuples become lists)
    if before is None:
        study.set_user_attr("setup", setup)
        with warnings.catch_warnings():  # (experimental in Optuna: only names the values in its own views)
            warnings.simplefilter("ignore")
            study.set_metric_names([m for m, _ in setup["objectives"]])
        return
    changed = [f"{k}: {before.get(k)!r} then, {v!r} now" for k, v in setup.items() if before.get(k) != v]
    if changed:
        raise SceneError(f"optimize: the study {study.study_name!r} stored here was made with another setup "
                         f"({'; '.join(changed)}); use another --out (or --study-name) for a new study")


def _ask_again_left_running(study) -> None:
    """Trials an interrupted run left running: closed as failed (Optuna has no other end for
    them), recorded as interrupted so that they do not count toward ``trials``, and their
    designs asked again first."""
    from optuna.trial import TrialState

    cut = list(study.user_attrs.get("interrupted", []))
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        study.enqueue_trial(t.params)
        study.tell(t.number, state=TrialState.FAIL)
        cut.append(t.number)
    if cut:
        study.set_user_attr("interrupted", sorted(set(cut)))


def _tell(study, trial, r: DesignResult, objectives: list[tuple[str, str]]) -> None:
    """The design's objectives to Optuna, or a failed trial with the reason (a user attribute)."""
    from optuna.trial import TrialState

    trial.set_user_attr("status", r.status)
    trial.set_user_attr("steps", r.steps)
    trial.set_user_attr("metrics", {k: v for k, v in r.metrics.items() if math.isfinite(v)})
    missing = [m for m, _ in objectives if m not in r.metrics]
    if r.status == "completed" and missing:
        study.tell(trial, state=TrialState.FAIL)
        raise SceneError(f"optimize: the scene gives no metric {', '.join(map(repr, missing))} (it gives: "
                         f"{', '.join(r.metrics) or 'none'}); name objectives among them")
    values = [r.metrics.get(m, math.nan) for m, _ in objectives]
    if r.status == "completed" and all(math.isfinite(v) for v in values):
        study.tell(trial, values)
        return
    error = r.error or f"an objective is not finite: {dict(zip([m for m, _ in objectives], values, strict=True))}"
    trial.set_user_attr("error", error)
    study.tell(trial, state=TrialState.FAIL)


def trial_rows(study, objectives: list[tuple[str, str]]) -> list[dict]:
    """One row per trial: number, state, parameters, objectives, the other metrics, the reason of a failure."""
    rows, cut = [], set(study.user_attrs.get("interrupted", []))
    for t in study.get_trials(deepcopy=False):
        values = dict(zip([m for m, _ in objectives], t.values or [], strict=False))
        status = "interrupted" if t.number in cut else t.user_attrs.get("status", "")
        error = "stopped before it finished; its design was asked again" if t.number in cut else ""
        rows.append({"trial": t.number, "state": t.state.name, "status": status} | t.params
                    | values | t.user_attrs.get("metrics", {}) | {"error": t.user_attrs.get("error", error)})
    return rows


def _write_trials(study, objectives, out: Path, parquet: bool) -> None:
    rows = trial_rows(study, objectives)
    write_rows(rows, out / "trials.csv")
    if parquet:
        write_rows(rows, out / "trials.parquet")


def best_trials(study, objectives: list[tuple[str, str]], count: int) -> list:
    """The ``count`` best completed trials: by the objective with one, else from the Pareto front
    (ordered by the first objective)."""
    from optuna.trial import TrialState

    done = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    front = done if len(objectives) == 1 else study.best_trials
    sign = [1.0 if d == "minimize" else -1.0 for _, d in objectives]
    return sorted(front, key=lambda t: [s * v for s, v in zip(sign, t.values, strict=True)])[:count]


def export_best(study, objectives, scene_file, fixed: dict, out: Path, count: int, steps: int | None,
                device: str | None, options: dict) -> list[Best]:
    """Run each best design alone again, writing its USD and report; ``best.json`` lists them."""
    chosen = best_trials(study, objectives, count)
    if not chosen:
        raise SceneError(f"optimize: no trial completed ({len(study.trials)} trials): see {out / 'trials.csv'}")
    for old in out.glob("best*_trial*.*"):  # a resumed study's earlier best designs
        if old.suffix in (".usda", ".json"):
            old.unlink()
    found = []
    for rank, t in enumerate(chosen, start=1):
        stem = out / f"best{rank}_trial{t.number}"
        try:
            scene = build_scene(scene_file, fixed | t.params)
            run(scene, steps=steps, device=device, usd=stem.with_suffix(".usda"), report=stem.with_suffix(".json"),
                solver=options.get("solver", "auto"), tolerance=options.get("tolerance", 1e-6),
                scene_file=str(scene_file))
        except WarpsoftError as exc:  # (it completed in its batch: say so, keep the others)
            raise SceneError(f"optimize: best design of trial {t.number} {t.params} failed when run again: "
                             f"{exc}") from exc
        found.append(Best(t.number, list(t.values), dict(t.params), stem.with_suffix(".usda"),
                          stem.with_suffix(".json")))
    (out / "best.json").write_text(json.dumps(
        [{"trial": b.trial, "objectives": dict(zip([m for m, _ in objectives], b.values, strict=True)),
          "params": b.params, "fixed": fixed, "usd": b.usd.name, "report": b.report.name} for b in found], indent=1))
    return found


def _best_text(study, objectives) -> str:
    top = best_trials(study, objectives, 1)
    if not top:
        return "none completed yet"
    values = zip(objectives, top[0].values, strict=True)
    return f"best: trial {top[0].number}, {', '.join(f'{m} = {v:.6g}' for (m, _), v in values)}"


def _plot_history(study, objectives, path: Path) -> None:
    """The first objective of each completed trial, and the best so far."""
    from .plot import _pyplot

    done = [t for t in study.get_trials(deepcopy=False) if t.values]
    if not done:
        return
    plt = _pyplot()
    metric, direction = objectives[0]
    x = [t.number for t in done]
    y = [t.values[0] for t in done]
    best = [min(y[: k + 1]) if direction == "minimize" else max(y[: k + 1]) for k in range(len(y))]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(x, y, "o", label="trial")
    ax.step(x, best, where="post", label=f"best so far ({direction})")
    ax.set_xlabel("trial")
    ax.set_ylabel(metric)
    ax.legend()
    ax.set_title(f"{metric}: {len(done)} completed of {len(study.trials)} trials")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
