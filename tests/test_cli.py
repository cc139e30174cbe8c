"""The CLI, its JSON report and the USD animation."""

import json

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.io.cli import main

from .conftest import ROOT

CANTILEVER = str(ROOT / "scenes/validation/cantilever.py")


def test_run_writes_report_and_usd(tmp_path, capsys):
    from pxr import Usd, UsdGeom

    usd, rep = tmp_path / "beam.usda", tmp_path / "beam.json"
    code = main(["run", CANTILEVER, "--steps", "4", "--device", "cpu", "--usd", str(usd), "--report", str(rep),
                 "--param", "static=False", "--param", "gravity=9.81", "--param", "mesh_size=0.005",
                 "--param", "dt=0.02", "--quiet"])
    assert code == 0
    d = json.loads(rep.read_text())
    for key in ("scene", "params", "device", "dofs", "nodes", "elements", "points", "cg", "timings", "warnings"):
        assert key in d
    assert d["params"] == {"static": False, "gravity": 9.81, "mesh_size": 0.005, "dt": 0.02}
    assert d["device"] == "cpu" and d["dofs"] == 3 * d["nodes"] and d["steps"] == 4
    assert len(d["points"]["tip"]) == 4 and d["points"]["tip"][-1][2] < 0  # sags
    assert len(d["cg"]["iterations"]) == 4 and all(r <= 1e-6 for r in d["cg"]["residuals"])
    assert {"median", "p90"} <= set(d["timings"]["step"])
    assert set(d["timings"]["stages"]) == {"linearize", "free_solve", "correct"}  # no loads stage: none declared

    stage = Usd.Stage.Open(str(usd))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == pytest.approx(50.0)
    points = UsdGeom.Mesh(stage.GetPrimAtPath("/World/beam")).GetPointsAttr()
    assert points.GetTimeSamples() == [0.0, 1.0, 2.0, 3.0, 4.0]  # the initial state, then one per step
    tip = UsdGeom.Xformable(stage.GetPrimAtPath("/World/probes/tip")).GetOrderedXformOps()[0]
    assert len(tip.GetTimeSamples()) == 5
    assert tip.Get(4.0)[2] == pytest.approx(d["points"]["tip"][-1][2])


def test_usdc_binary_output(tmp_path):
    from pxr import Usd

    out = tmp_path / "beam.usdc"
    assert main(["run", CANTILEVER, "--param", "mesh_size=0.005", "--param", "tip_force=0.01",
                 "--usd", str(out), "--quiet"]) == 0
    assert out.read_bytes()[:8] == b"PXR-USDC"
    assert Usd.Stage.Open(str(out)).GetPrimAtPath("/World/beam")


def test_unknown_parameter_and_missing_file_are_clear_errors(tmp_path, capsys):
    assert main(["run", CANTILEVER, "--param", "lenght=0.2", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "unknown parameter(s) lenght" in err and "length" in err
    assert main(["run", str(tmp_path / "nope.py"), "--quiet"]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["run", CANTILEVER, "--param", "young_modulus=-1", "--quiet"]) == 2
    assert "young_modulus must be > 0 Pa, got -1" in capsys.readouterr().err


def test_param_values_are_python_or_json_literals():
    from warpsoft.io.runner import parse_params

    p = parse_params(["target=[0,0,0.1]", "mode=inverse", "flag=true", "n=3", "d={'a': 1}"])
    assert p == {"target": [0, 0, 0.1], "mode": "inverse", "flag": True, "n": 3, "d": {"a": 1}}


def test_report_and_usd_carry_actuators_and_effectors(tmp_path):
    from pxr import Usd, UsdGeom

    usd, rep = tmp_path / "finger.usda", tmp_path / "finger.json"
    assert main(["run", str(ROOT / "scenes/finger.py"), "--steps", "3", "--usd", str(usd), "--report", str(rep),
                 "--param", "mesh_size=0.006", "--quiet"]) == 0
    d = json.loads(rep.read_text())
    assert set(d["stages_run"]) == {"linearize", "free_solve", "compliance", "resolve", "correct"}
    cable = d["actuators"]["cable"]
    assert cable["kind"] == "cable" and cable["mode"] == "displacement"
    assert len(cable["delta"]) == len(cable["lambda"]) == 3 and min(cable["lambda"]) >= 0
    assert len(d["W"]) == 3 and len(d["W"][0]) == 1 and d["W"][0][0][0] > 0
    assert all(i >= 1 for i in d["resolve_iterations"]) and all(r < 1e-9 for r in d["resolve_residuals"])
    assert len(d["effectors"]["fingertip"]) == 3 and "targets" not in d  # the fingertip has no target
    stage = Usd.Stage.Open(str(usd))
    curve = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/cables/cable"))
    assert curve.GetPointsAttr().GetTimeSamples() == [0.0, 1.0, 2.0, 3.0]
    assert len(curve.GetPointsAttr().Get(3.0)) == 11  # the pull point and ten path points
    assert stage.GetPrimAtPath("/World/effectors/fingertip").IsValid()
    for group in ("cables", "effectors", "probes"):  # typed group prims
        assert stage.GetPrimAtPath(f"/World/{group}").GetTypeName() == "Scope", group


def test_usd_draws_the_cavity_walls_moving_with_the_body(tmp_path):
    """The pneunet's cavity: its walls as a mesh (the body's nodes on them), time-sampled, and
    grown under pressure."""
    from pxr import Usd, UsdGeom

    usd = tmp_path / "pneunet.usda"
    assert main(["run", str(ROOT / "scenes/pneunet.py"), "--steps", "3", "--usd", str(usd),
                 "--param", "mesh_size=0.006", "--param", "ramp_time=0.04", "--quiet"]) == 0
    stage = Usd.Stage.Open(str(usd))
    assert stage.GetPrimAtPath("/World/cavities").GetTypeName() == "Scope"
    meshes = [p for p in stage.GetPrimAtPath("/World/cavities").GetChildren() if p.GetTypeName() == "Mesh"]
    assert len(meshes) == 1
    points = UsdGeom.Mesh(meshes[0]).GetPointsAttr()
    assert points.GetTimeSamples() == [0.0, 1.0, 2.0, 3.0]
    p0, p3 = np.array(points.Get(0.0)), np.array(points.Get(3.0))
    assert len(p0) > 10 and np.abs(p3 - p0).max() > 1e-5  # the walls moved


def test_obstacles_are_drawn_and_contacts_reported(tmp_path):
    """The column on its floor from the CLI: the report gives the contacts and their total normal
    force per step; the USD holds the floor as a square through its top plane, and with
    --usd-contacts the contact points and their forces."""
    from pxr import Usd, UsdGeom

    usd, rep = tmp_path / "column.usda", tmp_path / "column.json"
    assert main(["run", str(ROOT / "scenes/validation/column.py"), "--steps", "12", "--usd", str(usd),
                 "--usd-contacts", "--report", str(rep), "--quiet"]) == 0
    d = json.loads(rep.read_text())
    assert d["contacts"]["obstacles"] == ["floor"] and min(d["contacts"]["count"]) > 10
    assert d["contacts"]["normal_force"][-1] == pytest.approx(0.05, rel=1e-4)  # the quarter column's load
    stage = Usd.Stage.Open(str(usd))
    assert stage.GetPrimAtPath("/World/obstacles").GetTypeName() == "Scope"
    floor = UsdGeom.Mesh(stage.GetPrimAtPath("/World/obstacles/floor"))
    corners = np.array(floor.GetPointsAttr().Get())
    assert corners.shape == (4, 3) and np.abs(corners[:, 2]).max() < 1e-9 and np.ptp(corners[:, 0]) > 0.1
    # --usd-contacts: each frame's contact points on the floor, their forces adding up to the load
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/contacts/points"))
    at = np.array(points.GetPointsAttr().Get(12))
    force = np.array(UsdGeom.PrimvarsAPI(points).GetPrimvar("force").Get(12))
    assert at.shape == force.shape and len(at) >= d["contacts"]["count"][-1] and np.abs(at[:, 2]).max() < 1e-6
    assert force.sum(axis=0) == pytest.approx([0.0, 0.0, 0.05], abs=1e-5)
    segments = np.array(UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/contacts/forces")).GetPointsAttr().Get(12))
    assert len(segments) == 2 * len(at) and np.all(segments[1::2, 2] >= segments[0::2, 2])  # drawn upwards


def test_usd_places_turned_and_long_obstacles(tmp_path):
    """A turned box and a slanted cylinder: the prims' world transforms put a local point where
    the obstacle's own geometry says it is."""
    from pxr import Gf, Usd, UsdGeom

    from warpsoft.io.usd import UsdWriter

    scene = ws.Scene("s", dt=0.01)
    scene.add_body("b", ws.box_grid((0, 0, 0.1), (0.01, 0.01, 0.11), (1, 1, 1)), ws.Material(1e5, 0.3, 1000.0),
                   element="corotational")
    c, s_ = np.cos(0.5), np.sin(0.5)
    box = ws.obstacles.Box((0.1, 0.2, 0.0), (0.2, 0.1, 0.05), ((c, -s_, 0.0), (s_, c, 0.0), (0.0, 0.0, 1.0)))
    cyl = ws.obstacles.Cylinder((0.0, 0.0, 0.0), (0.1, 0.1, 0.05), 0.02)
    scene.add_obstacle("box", box)
    scene.add_obstacle("cyl", cyl)
    writer = UsdWriter(tmp_path / "o.usda", ws.finalize(scene))
    writer.save()
    stage = Usd.Stage.Open(str(tmp_path / "o.usda"))
    to_world = UsdGeom.Xformable(stage.GetPrimAtPath("/World/obstacles/box")).ComputeLocalToWorldTransform(0)
    corner = np.array(to_world.Transform(Gf.Vec3d(0.5, 0.5, 0.5)))  # a corner of the unit cube
    assert abs(box.distance(corner[None])[0]) < 1e-6 and np.linalg.norm(corner - box.center) > 0.1
    to_world = UsdGeom.Xformable(stage.GetPrimAtPath("/World/obstacles/cyl")).ComputeLocalToWorldTransform(0)
    end = np.array(to_world.Transform(Gf.Vec3d(0.0, 0.0, 0.5 * np.linalg.norm(np.subtract(cyl.b, cyl.a)))))
    assert np.allclose(end, cyl.b, atol=1e-6)  # (USD stores the scale in float32)


# ---- outputs checked first, how a run ended, user code, interruption (issue: never lose a result) ----
BEAM_WITH_FAILING_LOAD = '''
import warpsoft as ws


def build(fail_at=0.045):
    """A beam under a load whose function fails at ``fail_at`` s (the scene's own bug)."""
    scene = ws.Scene("beam", dt=0.01)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.05, 0.01, 0.01), (5, 1, 1)), ws.Material(1e5, 0.3))
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))

    def load(t):
        if t > fail_at:
            raise ZeroDivisionError("my bad")
        return (0.0, 0.0, -0.01 * t)

    scene.add_force(body, ws.OnPlane((0.05, 0, 0), (1, 0, 0)), load)
    scene.add_probe("tip", (0.05, 0.005, 0.005))
    return scene
'''


def test_outputs_and_device_are_checked_before_anything_runs(tmp_path, capsys):
    blocker = tmp_path / "file.txt"
    blocker.write_text("a file, not a folder")
    assert main(["run", CANTILEVER, "--report", str(blocker / "r.json"), "--quiet"]) == 2
    assert "cannot be written" in capsys.readouterr().err
    assert main(["run", CANTILEVER, "--report", str(tmp_path), "--quiet"]) == 2
    assert "is a folder, not a file" in capsys.readouterr().err
    assert main(["run", CANTILEVER, "--usd", str(tmp_path / "beam.obj"), "--quiet"]) == 2
    assert "extension must be one of .usda, .usdc, .usd" in capsys.readouterr().err
    assert main(["run", CANTILEVER, "--device", "gpu", "--quiet"]) == 2
    assert "unknown device 'gpu'" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.json"))


def test_version_and_scene_parameters(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.startswith("warpsoft ")
    assert main(["params", CANTILEVER]) == 0
    out = capsys.readouterr().out
    assert "length = 0.1" in out and "mesh_size = None" in out


def test_report_says_how_the_run_ended_and_with_what(tmp_path):
    rep = tmp_path / "r.json"
    assert main(["run", CANTILEVER, "--steps", "2", "--param", "mesh_size=0.005", "--report", str(rep),
                 "--quiet"]) == 0
    d = json.loads(rep.read_text())
    assert d["status"] == "completed" and d["error"] is None
    assert {"warpsoft", "warp", "numpy", "python"} <= set(d["versions"])
    assert d["params"] == {"mesh_size": 0.005}
    assert d["params_used"]["mesh_size"] == 0.005 and d["params_used"]["length"] == 0.1  # defaults included
    assert d["options"] == {"solver": "auto", "tolerance": 1e-6, "steps": 2, "newton_iterations": 10,
                            "newton_tolerance": 0.1}
    assert d["inverted_elements"] == [0, 0]
    assert d["newton"]["iterations"] == [1, 1] and max(d["newton"]["residuals"]) <= 0.1


def test_newton_options_reach_the_step(tmp_path):
    """The finger at dt = 0.5 s iterates by default; with --newton-iterations 1 it cannot, and
    the report says its residual was not met."""
    rep = tmp_path / "r.json"
    args = ["run", str(ROOT / "scenes/finger.py"), "--steps", "3", "--param", "dt=0.5", "--param", "mesh_size=0.006",
            "--report", str(rep), "--quiet"]
    assert main(args) == 0
    assert max(json.loads(rep.read_text())["newton"]["iterations"]) > 1
    assert main([*args, "--newton-iterations", "1"]) == 0
    d = json.loads(rep.read_text())
    assert d["newton"]["iterations"] == [1, 1, 1] and max(d["newton"]["residuals"]) > 0.1
    assert any("did not converge" in w for w in d["warnings"])


def test_an_error_in_the_scenes_own_code_is_named_and_the_finished_steps_kept(tmp_path, capsys):
    scene = tmp_path / "beam.py"
    scene.write_text(BEAM_WITH_FAILING_LOAD)
    rep, usd = tmp_path / "r.json", tmp_path / "r.usda"
    assert main(["run", str(scene), "--steps", "10", "--report", str(rep), "--usd", str(usd), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "load 'load0': its force function raised ZeroDivisionError: my bad (at t = 0.05 s)" in err
    assert "scene's code" in err and "solver" not in err
    d = json.loads(rep.read_text())
    assert d["status"] == "failed" and "UserCodeError" in d["error"] and d["steps"] == 4
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(usd))  # (kept: its prims live as long as it does)
    assert UsdGeom.Mesh(stage.GetPrimAtPath("/World/beam")).GetPointsAttr().GetTimeSamples() == [0, 1, 2, 3, 4]


def test_sigterm_ends_the_run_cleanly_with_every_finished_step(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    scene = tmp_path / "beam.py"
    scene.write_text(BEAM_WITH_FAILING_LOAD)
    rep, usd = tmp_path / "r.json", tmp_path / "r.usda"
    proc = subprocess.Popen([sys.executable, "-m", "warpsoft.io.cli", "run", str(scene), "--param", "fail_at=1e9",
                             "--steps", "1000000", "--report", str(rep), "--usd", str(usd), "--flush-every", "1",
                             "--quiet"], stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 120
        while time.time() < deadline:  # wait until a few steps are on disk
            if rep.exists() and json.loads(rep.read_text())["steps"] >= 3:
                break
            time.sleep(0.2)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130 and "stopped by SIGTERM" in err
    d = json.loads(rep.read_text())
    assert d["status"] == "interrupted" and d["steps"] >= 3 and len(d["points"]["tip"]) == d["steps"]
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(usd))
    samples = UsdGeom.Mesh(stage.GetPrimAtPath("/World/beam")).GetPointsAttr().GetTimeSamples()
    assert len(samples) == d["steps"] + 1


def test_no_cuda_driver_warning_on_a_machine_without_one():
    """Warp's C runtime warns on stderr at every start when no NVIDIA driver is found; warpsoft
    starts it with that warning muted (on this kind of machine only)."""
    import ctypes.util
    import subprocess
    import sys

    if ctypes.util.find_library("cuda") is not None:
        pytest.skip("this machine has an NVIDIA driver")
    out = subprocess.run([sys.executable, "-c", "import warpsoft, warp; print(warp.get_device('cpu'))"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "cpu"
    assert "CUDA driver" not in out.stderr


def test_plot_draws_the_figures_of_a_report(tmp_path, capsys):
    """`warpsoft plot`: effectors against targets, actuators, timings, as PNG files; a report
    without actuators gets the figures it has data for; a file that is not a report is a clear
    error."""
    rep = tmp_path / "diamond.json"
    assert main(["run", str(ROOT / "scenes/diamond.py"), "--steps", "3", "--param", "mode='inverse'",
                 "--param", "mesh_size=0.02", "--report", str(rep), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["plot", str(rep), "--out", str(tmp_path / "fig")]) == 0
    paths = capsys.readouterr().out.split()
    assert [p.rsplit("-", 1)[-1] for p in paths] == ["effectors.png", "actuators.png", "timings.png"]
    for p in paths:
        assert open(p, "rb").read(8) == b"\x89PNG\r\n\x1a\n"
    beam = tmp_path / "beam.json"
    assert main(["run", CANTILEVER, "--steps", "2", "--param", "mesh_size=0.005", "--report", str(beam),
                 "--quiet"]) == 0
    capsys.readouterr()
    assert main(["plot", str(beam)]) == 0
    assert [p.rsplit("-", 1)[-1] for p in capsys.readouterr().out.split()] == ["effectors.png", "timings.png"]
    (tmp_path / "other.json").write_text("{}")
    assert main(["plot", str(tmp_path / "other.json")]) == 2
    assert "is not a warpsoft run report" in capsys.readouterr().err


def test_a_run_says_what_it_does_before_the_first_step(capsys):
    """Meshing and the first step (kernel compilation) can take long: the CLI says so first."""
    assert main(["run", CANTILEVER, "--steps", "1", "--param", "mesh_size=0.005"]) == 0
    err = capsys.readouterr().err
    assert "building" in err and "scene 'cantilever' built in" in err and "compiles the kernels" in err


def test_a_full_disk_keeps_the_last_whole_usd_and_the_report_says_why(tmp_path, monkeypatch, capsys):
    """The USD's third write meets a full disk: the run stops as failed, the report (still
    writable) says so with the reason, the USD on disk is the last whole one and opens, and no
    temporary file is left (before: a traceback, the report left 'running', a USD cut at 32 KiB)."""
    import errno
    import os
    import types

    from pxr import Usd

    import warpsoft.io.atomic as atomic

    writes = []

    def replace(src, dst):  # the USD's renames: the third meets a full disk (the report's go through)
        if str(dst).endswith(".usda"):
            writes.append(src)
            if len(writes) > 2:
                raise OSError(errno.ENOSPC, "No space left on device")
        os.replace(src, dst)

    monkeypatch.setattr(atomic, "os", types.SimpleNamespace(replace=replace))
    usd, rep = tmp_path / "beam.usda", tmp_path / "beam.json"
    code = main(["run", CANTILEVER, "--steps", "6", "--device", "cpu", "--usd", str(usd), "--report", str(rep),
                 "--param", "mesh_size=0.005", "--flush-every", "2", "--quiet"])
    assert code == 2 and "No space left on device" in capsys.readouterr().err
    d = json.loads(rep.read_text())
    assert d["status"] == "failed" and "USD: cannot write" in d["error"] and "No space left" in d["error"]
    assert d["steps"] >= 2
    stage = Usd.Stage.Open(str(usd))
    assert stage.GetPrimAtPath("/World/beam")
    assert not [p.name for p in tmp_path.iterdir() if "tmp" in p.name]


def test_a_new_usd_writer_removes_what_a_killed_one_left(tmp_path):
    """A run killed while saving leaves its own temporary (``.beam.tmp.usda``) or the one USD's
    atomic writer was filling (``.beam.tmp.XXXXXX``, as seen on a kill inside ``Export``, with
    usd-core 26.11); the next writer of that USD removes both, and nothing else."""
    from warpsoft.io.usd import UsdWriter

    scene = ws.Scene("beam", static=True, steps=1)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (4, 1, 1)), ws.Material(1e5, 0.3),
                          element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    stale = [".beam.tmp.usda", ".beam.tmp.Cq6MuW"]
    kept = [".beam.tmp.notes.txt", "beam.Cq6MuW", ".other.tmp.Cq6MuW", ".beam.tmp.Cq6MuW7", "beam.usda"]
    for name in stale + kept:
        (tmp_path / name).write_text("x")
    UsdWriter(tmp_path / "beam.usda", ws.Model(scene, "cpu"))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(kept)
