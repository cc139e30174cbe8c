"""The lazy contact set (the Gauss-Seidel on the host's CPU): only the contacts that bear are
resolved, the others checked against the correction (W from the factor) or their row of W (W from
solved columns); it must step exactly as resolving every contact does."""

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.resolve import contact_set

from .test_rigid import drop_scene

G = 9.81


def hertz(scene_module):
    return scene_module("scenes/validation/hertz.py").build(), 1


def cube_on_slab(scene_module):
    """A 25 mm rigid cube dropped 0.5 mm on a soft slab, friction 0.5 (the rigid bodies' share of W)."""
    return drop_scene(drop=0.0005, soft_floor=True), 30


def sliding_block(scene_module):
    """A soft block on the floor with gravity tilted by 17 degrees and mu = 0.5: it sticks."""
    scene = ws.Scene("block", gravity=(0.3 * G, 0.0, -G), dt=0.005)
    scene.add_body("block", ws.box_grid((-0.01, -0.01, 0.0005), (0.01, 0.01, 0.0105), (5, 5, 3)),
                   ws.Material(1e5, 0.3, 1000.0), element="corotational")
    scene.set_damping(1.0, 0.0)
    scene.add_obstacle("floor", ws.obstacles.Floor(), mu=0.5, contact_distance=0.002)
    scene.set_contacts(64)
    return scene, 30


def contact_forces(sim) -> np.ndarray:
    """The force the contacts of world 0 put on each node (N, ``(nodes, 3)``): unique where the
    positions are, unlike its split between dependent contacts (a rigid point over a slab's
    triangle and the triangle's nodes against the solid's face)."""
    return sim.rows.forces(sim.gauss_seidel.lam.numpy())


@pytest.mark.parametrize("solver", ["direct", "pcg"])
@pytest.mark.parametrize("case", [hertz, cube_on_slab, sliding_block])
def test_the_lazy_contact_set_steps_as_resolving_every_contact(scene_module, case, solver):
    """Same trajectory (nodes and rigid poses) with and without the lazy set, with a Gauss-Seidel
    tolerance tight enough that each converges; the set is smaller than the contacts in use at
    some step and needs more than one round at some step (else the test would prove nothing),
    and every contact left out ends with an open gap (Signorini holds for it: no force, gap >= 0).
    ``direct``: W from the factor, between the set's rows only; ``pcg``: W from solved columns
    (what the CUDA path reads), tight enough that both runs' solves agree to round-off."""
    def make(lazy):
        scene, steps = case(scene_module)
        # (a factorization at every step: a kept one leaves a residual near factor_reuse, where a
        # contact whose force is 1e-9 of the largest bears on one side and not on the other)
        reuse = {"factor_reuse": 0.0} if solver == "direct" else {}
        sim = ws.Simulator(scene, device="cpu", solver=solver, tolerance=1e-6 if solver == "direct" else 1e-11,
                           lazy_contacts=lazy, **reuse)
        sim.gauss_seidel.tolerance, sim.gauss_seidel.max_iterations = 1e-13, 20000
        return sim, steps

    (lazy, steps), (full, _) = make(True), make(False)
    assert lazy.contact_set is not None and full.contact_set is None
    smaller = rounds = 0
    for _ in range(steps):
        a, b = lazy.step(), full.step()
        assert not any("Gauss-Seidel stopped" in m for m in a.warnings + b.warnings)
        assert np.abs(lazy.state.positions() - full.state.positions()).max() < 1e-12
        for name, (r, p) in lazy.rigid_poses().items():
            r_full, p_full = full.rigid_poses()[name]
            assert np.abs(p - p_full).max() < 1e-12 and np.abs(r - r_full).max() < 1e-10
        on_nodes = contact_forces(full)
        assert np.abs(contact_forces(lazy) - on_nodes).max() <= 1e-8 * max(np.abs(on_nodes).max(), 1e-12)
        assert abs(a.contact_force - b.contact_force) <= 1e-9 * max(b.contact_force, 1e-12)
        rows = lazy.rows
        in_use = int(rows.world_force_rows.numpy()[0])
        smaller += lazy.contact_set.size < in_use
        rounds = max(rounds, lazy.contact_set.rounds)
        gaps = rows.delta.numpy()[rows.contact_rows(0)][: in_use - int(rows.world_actuators[0]):
                                                          rows.rows_per_contact(0)]
        assert gaps.min() > -1e-9 * 0.01  # the contacts left out included: no node went through
    assert smaller and rounds >= 2


def test_the_lazy_set_is_only_where_the_host_sweeps_direct_worlds(scene_module):
    """On the CPU device, whatever the solver; not in an inverse-model world (its QPCC reads W
    whole); not when asked not to."""
    scene, _ = sliding_block(scene_module)
    assert ws.Simulator(scene, device="cpu", solver="pcg").contact_set is not None
    assert ws.Simulator(scene, device="cpu", lazy_contacts=False).contact_set is None
    trunk = scene_module("scenes/trunk.py").build(obstacles=True)
    assert ws.Simulator(trunk, device="cpu").contact_set is None
    assert contact_set.MAX_ROUNDS >= 2
