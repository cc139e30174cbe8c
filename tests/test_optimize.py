"""Design optimization with Optuna: designs asked a batch at a time and run as worlds, the study
stored and resumed, failures kept with their reason, the best design run again to USD; and the
same sweep and study through Ray (a Ray instance on this machine's CPU)."""

import csv
import json

import numpy as np
import optuna
import pytest

import warpsoft as ws
from warpsoft.io.cli import main
from warpsoft.io.optimize import optimize, parse_space
from warpsoft.io.sweep import sweep

from .test_sweep import BEAM


@pytest.fixture
def beam(tmp_path):
    path = tmp_path / "beam.py"
    path.write_text(BEAM.replace('if result.params.get("tip_force") == 0.02:', "if False:"))
    return path


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_design_space_parsing():
    space = parse_space(["E=1e5:1e6:log", "n=2:5:int", "r=0.002:0.004", "kind=['a', 'b']"])
    assert space["E"].log and (space["E"].low, space["E"].high) == (1e5, 1e6)
    assert isinstance(space["n"], optuna.distributions.IntDistribution) and space["n"].high == 5
    assert not space["r"].log and space["kind"].choices == ("a", "b")
    with pytest.raises(ws.SceneError, match=r"optimize: range of 'E' must be finite with lo < hi .* got 0.0:1.0"):
        parse_space(["E=0:1:log"])
    with pytest.raises(ws.SceneError, match=r"integer range of 'n' needs whole bounds, got 2.5:5.0"):
        parse_space(["n=2.5:5:int"])
    with pytest.raises(ws.SceneError, match=r"--space expects NAME=LO:HI\[:log\|:int\] .* got 'E=1:2:cube'"):
        parse_space(["E=1:2:cube"])


def test_a_study_runs_in_batches_resumes_and_exports_its_best_design(beam, tmp_path):
    """Maximize a cantilever's deflection over E and the tip load: every trial obeys the linear
    beam (deflection E / F the same for all), the best is the largest F / E seen, its design run
    again alone ends where its trial ended; the study resumes where it stopped."""
    out = tmp_path / "study"
    space = parse_space(["young_modulus=5e5:2e6:log", "tip_force=0.005:0.01"])
    study, best = optimize(beam, space, [("deflection", "maximize")], trials=6, out=out, batch=3, workers=1,
                           solver="direct")
    table = rows(out / "trials.csv")
    assert [r["state"] for r in table] == ["COMPLETE"] * 6
    e = np.array([float(r["young_modulus"]) for r in table])
    f = np.array([float(r["tip_force"]) for r in table])
    d = np.array([float(r["deflection"]) for r in table])
    assert np.ptp(d * e / f) < 1e-3 * np.mean(d * e / f) and d.min() > 1e-4
    assert best[0].trial == int(np.argmax(f / e)) and best[0].values[0] == pytest.approx(d.max(), rel=1e-12)
    report = json.loads(best[0].report.read_text())
    assert -report["points"]["tip"][-1][2] == pytest.approx(d.max(), rel=1e-9)  # run alone again: the same
    assert best[0].usd.stat().st_size > 1000 and (out / "history.png").stat().st_size > 5000
    assert json.loads((out / "best.json").read_text())[0]["trial"] == best[0].trial
    # resumed: the 6 trials kept, 4 more; an interrupted run's unfinished trial asked again first, and not
    # counted toward the 10 (before, it used one up)
    left = optuna.load_study(study_name="warpsoft", storage=f"sqlite:///{out / 'study.db'}")
    left.ask({"young_modulus": optuna.distributions.FloatDistribution(5e5, 2e6, log=True),
              "tip_force": optuna.distributions.FloatDistribution(0.005, 0.01)})
    study, _ = optimize(beam, space, [("deflection", "maximize")], trials=10, out=out, batch=3, workers=1,
                        solver="direct")
    again = rows(out / "trials.csv")
    assert again[:6] == table and [r["state"] for r in again[6:]] == ["FAIL"] + ["COMPLETE"] * 4
    assert again[6]["status"] == "interrupted" and "asked again" in again[6]["error"]
    assert again[7]["young_modulus"] == again[6]["young_modulus"]  # the unfinished design, run
    assert not study.get_trials(states=(optuna.trial.TrialState.WAITING, optuna.trial.TrialState.RUNNING))
    with pytest.raises(ws.SceneError, match=r"another setup \(objectives: \[\['deflection', 'maximize'\]\] then, "
                                            r"\[\['deflection', 'minimize'\]\] now\)"):
        optimize(beam, space, [("deflection", "minimize")], trials=12, out=out, workers=1)


def test_failed_designs_are_failed_trials_with_their_reason(beam, tmp_path, capsys):
    """Designs the scene refuses (negative moduli, queued in the study before it runs) are failed
    trials, named, and the others complete; designs that all fail end in a clear error with the
    table kept; an objective the scene does not give is an error naming the metrics it gives."""
    out = tmp_path / "bad"
    out.mkdir()
    queued = optuna.create_study(study_name="warpsoft", storage=f"sqlite:///{out / 'study.db'}")
    for e in (-1.0, 1e6, -5.0):
        queued.enqueue_trial({"young_modulus": e})
    code = main(["optimize", str(beam), "--space", "young_modulus=-1e6:2e6", "--minimize", "deflection",
                 "--trials", "5", "--batch", "4", "--workers", "1", "--out", str(out)])
    assert code == 0
    table = rows(out / "trials.csv")
    assert [r["state"] for r in table[:3]] == ["FAIL", "COMPLETE", "FAIL"]
    assert all("young_modulus must be > 0 Pa" in table[k]["error"] for k in (0, 2))
    assert "best 1: trial" in capsys.readouterr().out
    assert main(["optimize", str(beam), "--space", "young_modulus=5e5:2e6", "--param", "tip_force=1e30",
                 "--minimize", "deflection", "--trials", "2", "--workers", "1", "--out", str(tmp_path / "all")]) == 2
    assert "no trial completed (2 trials)" in capsys.readouterr().err
    assert all(r["state"] == "FAIL" and "moved" in r["error"] for r in rows(tmp_path / "all" / "trials.csv"))
    assert main(["optimize", str(beam), "--space", "young_modulus=5e5:2e6", "--minimize", "sag", "--trials", "2",
                 "--workers", "1", "--out", str(tmp_path / "typo")]) == 2
    assert "gives no metric 'sag' (it gives: deflection)" in capsys.readouterr().err


@pytest.mark.slow
def test_ray_runs_the_same_sweep_and_a_study(beam, tmp_path):
    """Batches as Ray tasks (a Ray instance on this machine): the same table as in this process,
    and a study's trials run the same way."""
    pytest.importorskip("ray")
    from warpsoft.io.cluster import ray_session

    designs = [{"young_modulus": 1e6}, {"tip_force": 1e30}, {"young_modulus": -1.0}, {"young_modulus": 4e6},
               {"tip_force": 0.015}]
    here = sweep(beam, designs, batch=2, workers=1, out=tmp_path / "here", solver="direct")
    with ray_session():
        there = sweep(beam, designs, batch=2, workers=1, out=tmp_path / "ray", solver="direct", ray=True,
                      parquet=True)
        study, best = optimize(beam, parse_space(["young_modulus=5e5:2e6:log"]), [("deflection", "maximize")],
                               trials=4, out=tmp_path / "study", batch=2, workers=1, ray=True, solver="direct")
    assert [r.status for r in there] == ["completed", "failed", "invalid", "completed", "completed"]
    assert [r.status for r in here] == [r.status for r in there]
    drop = lambda table: [{k: v for k, v in r.items() if k != "seconds"} for r in table]  # noqa: E731
    assert drop(rows(tmp_path / "ray" / "results.csv")) == drop(rows(tmp_path / "here" / "results.csv"))
    import pyarrow.parquet as pq

    parquet = pq.read_table(tmp_path / "ray" / "results.parquet").to_pylist()
    assert [r["deflection"] for r in parquet] == [r.metrics.get("deflection") for r in there]
    assert len(study.trials) == 4 and all(t.state.name == "COMPLETE" for t in study.trials)
    assert best[0].params["young_modulus"] == min(t.params["young_modulus"] for t in study.trials)
