"""The CPU device's replayed launches do what ``wp.launch`` does, whatever changed between calls."""

import numpy as np
import warp as wp

from warpsoft import launch as launches
from warpsoft.launch import launch


@wp.struct
class Pair:
    a: wp.array(dtype=wp.float64)
    b: wp.array(dtype=wp.float64)


@wp.kernel
def axpy_pair(pair: Pair, s: wp.float64, k: int, out: wp.array(dtype=wp.float64)):
    i = wp.tid()
    out[i] = s * pair.a[i] + pair.b[i] + wp.float64(k)


def test_a_replayed_launch_follows_its_arguments():
    """Scalars, arrays, a struct's reassigned field, a view, an empty launch: each call gives
    what the arguments of that call say, replayed or recorded anew."""
    cpu = "cpu"
    a = wp.array(np.arange(4.0), dtype=wp.float64, device=cpu)
    b = wp.array(np.ones(4), dtype=wp.float64, device=cpu)
    other = wp.array(10.0 * np.ones(4), dtype=wp.float64, device=cpu)
    out = wp.zeros(4, dtype=wp.float64, device=cpu)
    pair = Pair()
    pair.a, pair.b = a, b

    def run(s, k, dim=4, target=out):
        target.zero_()
        launch(axpy_pair, dim, inputs=[pair, wp.float64(s), k], outputs=[target], device=cpu)
        return target.numpy().copy()

    assert np.array_equal(run(2.0, 1), 2.0 * np.arange(4.0) + 2.0)
    assert np.array_equal(run(2.0, 1), 2.0 * np.arange(4.0) + 2.0)  # replayed
    assert len(launches._recorded[axpy_pair]) == 1
    assert np.array_equal(run(3.0, 1), 3.0 * np.arange(4.0) + 2.0)  # a scalar changed
    assert np.array_equal(run(2.0, 5), 2.0 * np.arange(4.0) + 6.0)
    pair.b = other  # the same struct object, a field reassigned
    assert np.array_equal(run(2.0, 1), 2.0 * np.arange(4.0) + 11.0)
    elsewhere = wp.zeros(4, dtype=wp.float64, device=cpu)  # another output of the same shape
    out.zero_()
    assert np.array_equal(run(2.0, 1, target=elsewhere), 2.0 * np.arange(4.0) + 11.0)
    assert not out.numpy().any()
    half = out[2:]  # a view: another address and shape
    assert np.array_equal(run(1.0, 0, dim=2, target=half), np.arange(2.0) + 10.0)
    assert np.array_equal(run(1.0, 0, dim=0), np.zeros(4))  # no thread: nothing runs
    assert len(launches._recorded[axpy_pair]) == launches.SLOTS
