"""The CLI, its JSON report and the USD animation."""

import json

import pytest

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
