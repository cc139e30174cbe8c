"""The accuracy study's quick mode (``tools/accuracy.py --quick``): its tables, plots and summary
are written, its errors say what the physics says (10-node tetrahedra within 5 % of Timoshenko
where linear ones lock; the trapezoid ahead of implicit Euler; Figure 8's force drive further
from the reference than its displacement drive), and its Richardson extrapolation is a reference
worth its name: closer to the analytic beam than the finest mesh, its error estimate no smaller
than the finest mesh's true error."""

import csv
import sys
from pathlib import Path

import numpy as np
import pytest

from warpsoft.io.runner import load_scene_module

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import accuracy  # noqa: E402


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("accuracy")
    assert accuracy.main(["--quick", "--out", str(out)]) == 0
    with open(out / "accuracy.csv") as f:
        rows = list(csv.DictReader(f))
    return out, rows


def pick(rows, **match):
    return [r for r in rows if all(r[k] == str(v) for k, v in match.items())]


@pytest.mark.slow
def test_quick_writes_the_table_plots_and_summary(quick):
    out, rows = quick
    for name in ("accuracy.png", "figure8.png", "summary.md"):
        assert (out / name).stat().st_size > 1000
    assert {r["study"] for r in rows} == {"cantilever", "cantilever_nested", "figure8_warpsoft", "swing"}
    text = (out / "summary.md").read_text()
    assert "the cheapest setting within 5 % is quadratic" in text


@pytest.mark.slow
def test_quadratic_elements_are_within_5_percent_of_timoshenko_where_linear_ones_lock(quick):
    _, rows = quick
    quad = pick(rows, study="cantilever", element="quadratic", solver="direct")
    lin = pick(rows, study="cantilever", element="corotational", solver="direct")
    assert all(abs(float(r["signed_error"])) < 0.05 for r in quad)
    errors = [float(r["signed_error"]) for r in sorted(lin, key=lambda r: int(r["dofs"]))]
    assert errors[0] < errors[1] < -0.2  # too stiff, less so on the finer mesh
    for r in pick(rows, study="cantilever", solver="pcg"):  # CG to 1e-6 is the direct solve
        d = pick(rows, study="cantilever", element=r["element"], mesh=r["mesh"], solver="direct")[0]
        assert float(r["error"]) == pytest.approx(float(d["error"]), abs=1e-5)


def test_the_richardson_reference_beats_the_finest_mesh_and_bounds_its_error():
    """The nested cantilever (linear tetrahedra, split twice): the extrapolated tip deflection is
    closer to Timoshenko than the finest mesh, and the error it states for the finest mesh is at
    least that mesh's true error."""
    study = next(s for s in accuracy.studies(quick=True) if s.name == "cantilever_nested")
    rows = accuracy.run_study(study, "cpu", ("",))
    cantilever = load_scene_module(ROOT / "scenes" / "validation" / "cantilever.py")
    exact = -cantilever.timoshenko_tip_deflection(young_modulus=1e6, poisson_ratio=0.3, tip_force=0.001)
    finest = max(rows, key=lambda r: r["dofs"])
    extrapolated = finest["reference_value"][2]
    true_error = abs(finest["value"][2] / exact - 1.0)
    assert true_error > 0.05  # the finest is not converged: the reference must add something
    assert abs(extrapolated / exact - 1.0) < 0.5 * true_error
    assert finest["reference_error"] >= true_error
    assert 0.5 < finest["order"] < 2.5


@pytest.mark.slow
def test_figure8_force_drive_misses_more_and_reproduces_the_motion_on_the_finest_mesh(quick):
    _, rows = quick
    disp = sorted(pick(rows, study="figure8_warpsoft", drive="displacement", element="corotational"),
                  key=lambda r: int(r["dofs"]))
    force = sorted(pick(rows, study="figure8_warpsoft", drive="force"), key=lambda r: int(r["dofs"]))
    assert float(force[0]["error"]) > 2 * float(disp[0]["error"]) > 0.02
    # on the finest mesh, its own tensions give its own motion back
    assert float(force[-1]["error"]) == pytest.approx(0.0, abs=1e-3)


@pytest.mark.slow
def test_the_trapezoid_follows_the_falling_beam_closer_and_both_converge(quick):
    _, rows = quick
    err = {(r["integrator"], float(r["dt"])): float(r["error"]) for r in pick(rows, study="swing")}
    for dt in (0.008, 0.002):
        assert err[("trapezoidal", dt)] < 0.5 * err[("implicit_euler", dt)]
    assert err[("implicit_euler", 0.002)] < 0.5 * err[("implicit_euler", 0.008)]  # first order: 4x less dt
    assert err[("trapezoidal", 0.002)] < 0.25 * err[("trapezoidal", 0.008)]
    assert np.isfinite(list(err.values())).all()


@pytest.mark.slow
def test_figure8_cables_pull_points_whose_stiffness_falls_with_the_mesh(quick):
    """A cable fastened at one point loads the body by a point force, whose displacement has no
    finite limit in 3D elasticity: the finer the mesh around the point, the less tension the same
    shortening takes. Split once, the Diamond's driven cables need at least 10 % less; 10-node
    elements on the coarse mesh, as many DOFs, resolve the point as well."""
    _, rows = quick
    disp = {(r["element"], int(r["mesh"])): np.array(r["value"].split(), float)
            for r in pick(rows, study="figure8_warpsoft", drive="displacement")}
    coarse, fine, quad = disp[("corotational", 0)], disp[("corotational", 1)], disp[("quadratic", 0)]
    assert (fine[3:6] < 0.9 * coarse[3:6]).all()
    assert (quad[3:6] < 0.9 * coarse[3:6]).all()
    q = pick(rows, study="figure8_warpsoft", element="quadratic")[0]
    assert q["dofs"] == pick(rows, study="figure8_warpsoft", drive="displacement", element="corotational", mesh=1)[0][
        "dofs"]


def test_cuda_default_solver_rows_join_the_cpu_direct_ones():
    cpu = {"study": "cantilever", "element": "quadratic", "poisson_ratio": 0.45, "drive": "", "mesh": 0.005,
           "solver": "direct", "tolerance": "", "dt": "", "integrator": ""}
    assert accuracy.key(cpu) == accuracy.key(cpu | {"solver": "auto"})
    assert accuracy.key(cpu) != accuracy.key(cpu | {"solver": "pcg", "tolerance": 1e-6})


def test_two_meshes_extrapolate_at_the_assumed_order_of_the_sweeps_element():
    """Where only two nested meshes fit (the PneuNet's 10-node sweep), the reference is their
    Richardson extrapolation at the study's assumed order: exact for a quantity that converges at
    that order, with the finest mesh's error stated, and the linear meshes scored against it."""
    study = next(s for s in accuracy.studies(False) if s.name == "pneunet")
    assert study.sweep == "quadratic" and study.order == 1.0 and study.meshes == [0, 1]
    exact = np.array([0.001, -0.002, -0.0107])
    rows = [{"dofs": 10 ** k, "element": e, "solver": "direct", "value": exact * (1 + c * 0.5 ** k)}
            for e, c in (("quadratic", 0.1), ("corotational", 0.7)) for k in (0, 1)]
    value, kind, estimate, order, element = accuracy.reference(study, {}, [r for r in rows if r["element"] ==
                                                                             "quadratic"])
    assert kind == "assumed order" and element == "quadratic" and order == 1.0
    assert np.allclose(value, exact, rtol=1e-12)
    assert estimate == pytest.approx(0.05)  # the finest quadratic mesh is 5 % off
    accuracy.score(rows, (value, kind, estimate, order, element), 3)
    assert [round(r["signed_error"], 6) for r in rows] == [0.1, 0.05, 0.7, 0.35]
