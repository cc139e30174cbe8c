"""Sweeps: designs from a grid or a Latin hypercube, stepped as the worlds of one model, each as
it runs alone; a failing design isolated; the results table and the plot."""

import csv
import math

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.io.cli import main
from warpsoft.io.sweep import grid, parse_grid, parse_ranges, random_designs, sweep

BEAM = '''
import warpsoft as ws


def build(young_modulus=1e6, tip_force=0.01, length=0.1):
    """A cantilever of 10 x 2 x 2 boxes, quasi-static, a tip load (N) along -z; probe ``tip``."""
    scene = ws.Scene("beam", static=True, steps=2)
    body = scene.add_body("beam", ws.box_grid((0.0, -0.005, -0.005), (length, 0.01, 0.01), (10, 2, 2)),
                          ws.Material(young_modulus, 0.3, 1000.0))
    scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)))
    scene.add_force(body, ws.OnPlane((length, 0.0, 0.0), (1.0, 0.0, 0.0)), (0.0, 0.0, -tip_force))
    scene.add_probe("tip", (length, 0.0, 0.0))
    return scene


def metrics(result):
    if result.params.get("tip_force") == 0.02:
        raise ValueError("no metric for this one")
    return {"deflection": -result.probes["tip"][-1][2]}
'''


@pytest.fixture
def beam(tmp_path):
    path = tmp_path / "beam.py"
    path.write_text(BEAM)
    return path


def test_grid_and_latin_hypercube_designs():
    assert grid({"a": [1, 2], "b": ["x", "y", "z"]})[:4] == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"},
                                                             {"a": 1, "b": "z"}, {"a": 2, "b": "x"}]
    assert len(grid(parse_grid(["a=[1, 2]", "b=(3, 4, 5)"]))) == 6
    designs = random_designs(8, parse_ranges(["E=1e5:1e6:log", "r=0.002:0.004"]), seed=3)
    e = np.array([d["E"] for d in designs])
    r = np.array([d["r"] for d in designs])
    # a Latin hypercube: each eighth of each range (of log E) holds exactly one design
    assert sorted(np.floor(8 * (np.log(e) - math.log(1e5)) / math.log(10)).astype(int)) == list(range(8))
    assert sorted(np.floor(8 * (r - 0.002) / 0.002).astype(int)) == list(range(8))
    assert random_designs(8, {"r": (0.0, 1.0)}, seed=3) != random_designs(8, {"r": (0.0, 1.0)}, seed=4)
    with pytest.raises(ws.SceneError, match=r"range of 'E' must be finite with lo < hi .* got 0.0:1.0"):
        random_designs(4, {"E": (0.0, 1.0, "log")})
    with pytest.raises(ws.SceneError, match=r"--random expects NAME=lo:hi or NAME=lo:hi:log, got 'E=1:x'"):
        parse_ranges(["E=1:x"])
    with pytest.raises(ws.SceneError, match=r"--grid expects NAME=\[v1, v2, ...\], got 'a=3'"):
        parse_grid(["a=3"])


def test_designs_batched_step_as_alone_and_a_failure_stays_with_its_design(beam, tmp_path):
    """Six designs, three per model: each completed design's trajectory equals its run alone
    (one per model) to 1e-12 m, and the deflection goes as 1 / E (linear regime). A design whose
    load blows its step up fails alone (its batch is run again design by design), one whose build
    is refused is invalid, one whose metric raises is marked: the others complete."""
    designs = [{"young_modulus": 1e6}, {"tip_force": 1e30}, {"young_modulus": 2e6},
               {"young_modulus": -1.0}, {"young_modulus": 4e6}, {"tip_force": 0.02}]
    batched = sweep(beam, designs, batch=3, workers=1, out=tmp_path / "out", solver="direct")
    alone = sweep(beam, designs, batch=1, workers=1, solver="direct")
    status = [r.status for r in batched]
    assert status == ["completed", "failed", "completed", "invalid", "completed", "failed"]
    assert status == [r.status for r in alone]
    assert "moved" in batched[1].error and "young_modulus must be > 0 Pa, got -1.0" in batched[3].error
    assert batched[5].error == "metrics(): ValueError: no metric for this one"
    for a, b in zip(batched, alone, strict=True):
        if a.status == "completed":
            assert a.steps == 2 and a.probes["tip"].shape == (3, 3)
            assert np.abs(a.probes["tip"] - b.probes["tip"]).max() < 1e-12
    d = [batched[k].metrics["deflection"] for k in (0, 2, 4)]
    assert d[0] > 1e-4
    assert d[0] / d[1] == pytest.approx(2.0, rel=1e-3) and d[1] / d[2] == pytest.approx(2.0, rel=1e-3)
    with open(tmp_path / "out" / "results.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == status
    assert float(rows[2]["deflection"]) == pytest.approx(d[1], rel=1e-12) and rows[2]["young_modulus"] == "2000000.0"
    assert rows[1]["deflection"] == "" and "moved" in rows[1]["error"]


def test_the_sweep_command_writes_the_table_and_the_plot(beam, tmp_path, capsys):
    """``warpsoft sweep`` over a grid crossed with random moduli, meshed by two processes."""
    out = tmp_path / "sweep"
    code = main(["sweep", str(beam), "--grid", "tip_force=[0.01, 0.015]", "--random", "2",
                 "young_modulus=5e5:2e6:log", "--param", "length=0.08", "--batch", "4", "--workers", "2",
                 "--out", str(out)])
    assert code == 0
    with open(out / "results.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 and all(r["status"] == "completed" and r["length"] == "0.08" for r in rows)
    # the same modulus under 1.5 times the load bends 1.5 times as far
    by = {(r["tip_force"], r["young_modulus"]): float(r["deflection"]) for r in rows}
    for (force, modulus), v in by.items():
        if force == "0.015":
            assert v / by[("0.01", modulus)] == pytest.approx(1.5, rel=1e-3)
    assert (out / "deflection.png").stat().st_size > 10_000
    said = capsys.readouterr().out
    assert "4 of 4 designs completed" in said and "a batch of 4 designs" in said  # (said before it compiles)
    assert "4/4 designs finished, 0 of them failed" in said and "design-steps/s so far" in said
    assert main(["sweep", str(beam), "--out", str(out)]) == 2  # no design given: a clear error
    assert "give the designs" in capsys.readouterr().err


def test_a_failing_world_is_named_and_the_rest_of_its_batch_runs_on_together(beam, monkeypatch):
    """Two designs of a batch of five blow up at their first step: the step names their worlds,
    they keep the error they meet alone, and the three others run again as one batch of three
    (not one by one), to the same deflections as alone."""
    import warpsoft.io.sweep as sweep_module

    built, real = [], sweep_module.Simulator
    monkeypatch.setattr(sweep_module, "Simulator",
                        lambda model, **kw: built.append(model.num_worlds) or real(model, **kw))
    designs = [{"young_modulus": 1e6}, {"tip_force": 1e30}, {"young_modulus": 2e6}, {"tip_force": 1e30},
               {"young_modulus": 4e6}]
    batched = sweep(beam, designs, batch=5, workers=1, solver="direct")
    assert built == [5, 3]
    built.clear()
    alone = sweep(beam, designs, batch=1, workers=1, solver="direct")
    assert [r.status for r in batched] == [r.status for r in alone] == ["completed", "failed"] * 2 + ["completed"]
    for a, b in zip(batched, alone, strict=True):
        assert a.error == b.error and a.steps == b.steps
        if a.status == "completed":
            assert np.abs(a.probes["tip"] - b.probes["tip"]).max() < 1e-12
    assert "(world" not in batched[1].error and "moved" in batched[1].error
    from warpsoft.io.runner import build_scene

    sim = ws.Simulator(ws.finalize([build_scene(beam, d) for d in designs[:3]], "cpu"), solver="direct")
    with pytest.raises(ws.SimulationError, match=r"step 1 \(t = [0-9.]+ s\) \(world 1\): a node moved") as info:
        sim.step()
    assert info.value.worlds == [1]


FAILING = '''
import math

import warpsoft as ws


def build(young_modulus=1e6, fails="no"):
    """A cable-pulled cantilever, 4 quasi-static steps of 10 ms; ``fails`` says how this design
    fails: "build" (a ValueError in build), "load" (its load raises at t = 0.03 s), "nan" (its load
    turns NaN at t = 0.03 s), "cable" (its cable's schedule raises at t = 0.02 s), or "no"."""
    if fails == "build":
        raise ValueError("this design cannot be built")
    scene = ws.Scene("beam", static=True, dt=0.01, steps=4)
    body = scene.add_body("beam", ws.box_grid((0.0, -0.005, -0.005), (0.1, 0.01, 0.01), (10, 2, 2)),
                          ws.Material(young_modulus, 0.3, 1000.0), element="corotational")
    scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)))

    def load(t):
        if fails == "load" and t > 0.025:
            raise RuntimeError("the load's table ends here")
        return (0.0, 0.0, math.nan if fails == "nan" and t > 0.025 else -0.01 * t / 0.04)

    def pull(t):
        if fails == "cable" and t > 0.015:
            raise KeyError("no command past 15 ms")
        return 0.001 * t / 0.04

    scene.add_force(body, ws.OnPlane((0.1, 0.0, 0.0), (1.0, 0.0, 0.0)), load)
    scene.add_cable("c", body, points=[(0.05, 0.0, 0.004), (0.09, 0.0, 0.004)], pull_point=(-0.01, 0.0, 0.004),
                    value=pull)
    scene.add_probe("tip", (0.1, 0.0, 0.0))
    return scene
'''


def test_a_design_is_the_unit_of_failure(tmp_path, capsys):
    """Eight designs in one batch, four failing in each way a user's scene can at t > 0 or at
    build: each is recorded with its error's type and message and the steps it finished; the
    other four complete with the same trajectories as alone; the command exits 0 and says how
    many failed (before: exit 2, no table, the good designs lost)."""
    path = tmp_path / "failing.py"
    path.write_text(FAILING)
    designs = [{"young_modulus": 1e6}, {"fails": "load"}, {"young_modulus": 2e6}, {"fails": "nan"},
               {"young_modulus": 3e6}, {"fails": "cable"}, {"young_modulus": 4e6}, {"fails": "build"}]
    batched = sweep(path, designs, batch=8, workers=1, solver="direct")
    alone = sweep(path, [d for d in designs if "fails" not in d], batch=1, workers=1, solver="direct")
    status = {r.params.get("fails", "no"): (r.status, r.steps, r.error) for r in batched}
    assert status["build"][0] == "invalid" and status["build"][2] == "ValueError: this design cannot be built"
    assert status["load"][:2] == ("failed", 2) and "RuntimeError: the load's table ends here" in status["load"][2]
    assert status["cable"][:2] == ("failed", 1) and "KeyError" in status["cable"][2]
    assert status["nan"][:2] == ("failed", 2) and "must return 3 finite numbers" in status["nan"][2]
    good = [r for r in batched if "fails" not in r.params]
    assert [r.status for r in good] == ["completed"] * 4
    for a, b in zip(good, alone, strict=True):
        assert a.steps == 4 and np.abs(a.probes["tip"] - b.probes["tip"]).max() < 1e-12
    out = tmp_path / "out"
    code = main(["sweep", str(path), "--grid", "fails=['no', 'load', 'build']", "--batch", "3", "--workers", "2",
                 "--out", str(out)])
    assert code == 0
    with open(out / "results.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == ["completed", "failed", "invalid"]
    assert "1 of 3 designs completed" in capsys.readouterr().out


def read_rows(path) -> list[dict]:
    with open(path) as f:
        return list(csv.DictReader(f))


def test_a_stopped_sweep_resumes_where_it_stopped_and_keeps_its_table(beam, tmp_path, monkeypatch):
    """Six designs, two per batch, stopped (Ctrl-C) in the third batch: the table holds the
    four finished rows; the same command again runs the last two only, and its table equals an
    uninterrupted run's. Rerunning a finished sweep runs nothing and erases nothing (before, a
    rerun stopped after a batch left 2 rows of 8)."""
    import warpsoft.io.sweep as sweep_module

    designs = [{"young_modulus": e} for e in (1e6, 1.5e6, 2e6, 2.5e6, 3e6, 3.5e6)]
    whole = sweep(beam, designs, batch=2, workers=1, out=tmp_path / "whole", solver="direct")
    real, calls = sweep_module.run_designs, []

    def stopping(scene_file, chunk, *args):
        calls.append([r.params["young_modulus"] for r in chunk])
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(scene_file, chunk, *args)

    monkeypatch.setattr(sweep_module, "run_designs", stopping)
    out = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt):
        sweep(beam, designs, batch=2, workers=1, out=out, solver="direct")
    assert len(read_rows(out / "results.csv")) == 4 and not (out / ".lock").exists()
    calls.clear()
    resumed = sweep(beam, designs, batch=2, workers=1, out=out, solver="direct")
    assert calls == [[3e6, 3.5e6]]  # only the designs it had not finished
    assert read_rows(out / "results.csv") == [r | {"seconds": s["seconds"]} for r, s in
                                              zip(read_rows(tmp_path / "whole" / "results.csv"),
                                                  read_rows(out / "results.csv"), strict=True)]
    assert [r.metrics for r in resumed] == [r.metrics for r in whole]
    calls.clear()
    sweep(beam, designs, batch=2, workers=1, out=out, solver="direct")
    assert calls == [] and len(read_rows(out / "results.csv")) == 6


def test_a_folder_holds_one_sweep_unless_told_and_one_writer(beam, tmp_path):
    """Another sweep into a folder with results is refused (before, both exited 0 and one's rows
    vanished), unless it appends (its designs take the next indices) or overwrites; a folder a
    live process is writing is refused; a lock left by a process that is gone is taken over."""
    from warpsoft.io.store import folder_lock

    out = tmp_path / "out"
    sweep(beam, [{"young_modulus": 1e6}, {"young_modulus": 2e6}], workers=1, out=out, solver="direct")
    other = [{"young_modulus": 3e6}]
    with pytest.raises(ws.SceneError, match=r"holds the results of another sweep .* --append .* --overwrite"):
        sweep(beam, other, workers=1, out=out, solver="direct")
    sweep(beam, other, workers=1, out=out, solver="direct", append=True)
    rows = read_rows(out / "results.csv")
    assert [r["design"] for r in rows] == ["0", "1", "2"] and rows[2]["young_modulus"] == "3000000.0"
    sweep(beam, other, workers=1, out=out, solver="direct", overwrite=True)
    assert [r["young_modulus"] for r in read_rows(out / "results.csv")] == ["3000000.0"]
    with folder_lock(out), pytest.raises(ws.SceneError, match=r"is being written by process [0-9]+"):
        sweep(beam, other, workers=1, out=out, solver="direct")
    (out / ".lock").write_text("999999999")  # a writer that is gone
    sweep(beam, other, workers=1, out=out, solver="direct")
    assert not (out / ".lock").exists()


def test_a_mesh_cache_that_cannot_write_turns_itself_off(tmp_path, monkeypatch):
    """The cache only saves time: a full disk under it (np.savez raising ENOSPC) is a warning,
    the cache is off for the rest of the run, and the sweep completes (before, it died)."""
    import errno

    import warpsoft.scene.shapes as shapes

    path = tmp_path / "ball.py"
    path.write_text('''
import warpsoft as ws


def build(radius=0.01):
    scene = ws.Scene("ball", static=True, steps=1)
    body = scene.add_body("ball", ws.mesh_shape(ws.Ball((0.0, 0.0, 0.0), radius), radius / 2),
                          ws.Material(1e5, 0.3, 1000.0), element="corotational")
    scene.fix(body, ws.InHalfSpace((0.0, 0.0, -0.5 * radius), (0.0, 0.0, -1.0)))
    scene.add_probe("top", (0.0, 0.0, radius))
    return scene
''')

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(shapes.np, "savez", full)
    with pytest.warns(UserWarning, match=r"mesh cache: cannot write .*No space left on device.*the cache is off"):
        results = sweep(path, [{"radius": 0.01}, {"radius": 0.012}], workers=1, out=tmp_path / "out")
    assert [r.status for r in results] == ["completed", "completed"]
    assert not list((tmp_path / "out" / "mesh_cache").glob("*.npz"))


def test_a_batch_shows_its_first_factorization(capsys):
    """With factors for a preconditioner, a batch's first step says how many blocks it factorizes
    (the same beam at 1 and 3 MPa share one: 3 blocks for 4 designs) and its bar ends at all of them."""
    from warpsoft.io.sweep import _factor_bar

    from .test_blocks import four_designs

    sim = ws.Simulator(ws.finalize(four_designs()), device="cpu", solver="pcg", preconditioner="factors")
    seen = []
    _factor_bar(sim)
    shown = sim.solver.precond.progress
    sim.solver.precond.progress = lambda done, total: (seen.append((done, total)), shown(done, total))
    sim.step()
    assert seen == [(1, 3), (2, 3), (3, 3)]
    assert "factorizing the preconditioner's 3 blocks" in capsys.readouterr().out
