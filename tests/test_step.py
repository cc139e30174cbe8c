"""The step's device flow as graphs replay it (one graph, or two around the host QP) equals the
stage-by-stage step. On the CPU device the graph flow runs uncaptured: the same calls in the
same order; tools/gpu_check.py compares the captured step with the uncaptured one on CUDA."""

import numpy as np
import pytest

import warpsoft as ws


def run(scenes, capture, steps=4):
    sim = ws.Simulator(ws.finalize(scenes), solver="pcg", preconditioner="dense", tolerance=1e-10)
    sim.capture = capture
    history = [sim.step() for _ in range(steps)]
    return sim, history


@pytest.mark.parametrize("modes", [("direct",), ("inverse",), ("inverse", "direct")])
def test_graph_flow_equals_stage_by_stage(scene_module, modes):
    diamond = scene_module("scenes/diamond.py")

    def scenes():
        return [diamond.build(mesh_size=0.025, mode=mode, circle_period=0.2,
                              cable_displacements=(0.003, 0.0, 0.001, 0.0), ramp_time=0.04) for mode in modes]

    staged, h_staged = run(scenes(), capture=False)
    graphed, h_graphed = run(scenes(), capture=True)
    expected = {"device_before_qp", "resolve", "device_after_qp"} if "inverse" in modes else {"device_step"}
    graphs = {"device_step", "newton_step", "line_search", "device_before_qp", "newton_before_qp",
              "device_after_qp", "resolve"}  # (a step that iterates adds its iterations' graphs)
    assert expected <= set(h_graphed[-1].stages) <= graphs  # step 1 refactorizes: it runs stage by stage
    assert set(h_graphed[0].stages) == set(h_staged[0].stages)
    assert np.abs(graphed.state.positions() - staged.state.positions()).max() == 0.0
    for a, b in zip(h_graphed, h_staged, strict=True):
        assert a.cg_iterations == b.cg_iterations
        for wa, wb in zip(a.worlds, b.worlds, strict=True):
            assert wa.actuator_lambda == wb.actuator_lambda and wa.qp_status == wb.qp_status
            assert wa.resolve_iterations == wb.resolve_iterations


def test_readback_returns_each_array_as_it_is_on_the_device():
    """The step's one-transfer read: arrays of any element type and shape come back intact, each
    at its own (aligned) place in the buffer, and a second gather sees the arrays' new values."""
    import warp as wp

    from warpsoft.readback import Readback

    rng = np.random.default_rng(2)
    arrays = {"flag": wp.array([3], dtype=wp.int32), "points": wp.array(rng.standard_normal((5, 3)), dtype=wp.vec3d),
              "scal": wp.array(rng.standard_normal((2, 3, 9)), dtype=wp.float64),
              "rot": wp.array(rng.standard_normal((2, 3, 3)), dtype=wp.mat33d)}
    rb = Readback(arrays, "cpu")
    rb.gather()
    got = rb.read()
    for name, a in arrays.items():
        assert got[name].dtype == a.numpy().dtype and np.array_equal(got[name], a.numpy()), name
    arrays["flag"].fill_(7)
    arrays["points"].zero_()
    rb.gather()
    got = rb.read()
    assert got["flag"][0] == 7 and not got["points"].any() and np.array_equal(got["scal"], arrays["scal"].numpy())
