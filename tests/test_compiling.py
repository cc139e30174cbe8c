"""Kernel compilation made visible: :class:`~warpsoft.io.compiling.ModuleLoads` reads the load
messages of the installed Warp, counts each module's load and names the compiled ones."""

import numpy as np
import warp as wp

from warpsoft.io.compiling import ModuleLoads


@wp.kernel
def scale(x: wp.array(dtype=wp.float64), s: wp.float64):
    i = wp.tid()
    x[i] = s * x[i]


def test_a_module_loaded_inside_is_counted_and_a_compiled_one_named():
    """This file's module, loaded by its first launch, is seen as compiled (an empty kernel cache,
    as on a fresh machine) or cached; a compiled one is said by name, with its device and time."""
    lines = []
    x = wp.array(np.ones(4), dtype=wp.float64, device="cpu")
    with ModuleLoads(say=lines.append) as loads:
        wp.launch(scale, dim=4, inputs=[x, wp.float64(2.0)], device="cpu")
    assert np.all(x.numpy() == 2.0)
    assert loads.count["compiled"] + loads.count["cached"] == 1
    assert len(lines) == len(loads.compiled) == loads.count["compiled"]
    if lines:
        assert "compiled kernel module tests.test_compiling" in lines[0] and "for cpu in" in lines[0]
    # Warp's message forms: with and without the module's hash, with the block size added at debug level
    with ModuleLoads(say=lines.append) as loads:
        for message in ("Module warpsoft.kernels.newton 3f2a1b7 load on device 'cuda:0' took 1523.40 ms (compiled)",
                        "Module warpsoft.kernels.rows.cable load on device 'cpu' (block_dim=256) "
                        "took 12.00 ms (cached)"):
            loads.info(message)
    assert loads.count == {"compiled": 1, "cached": 1} and loads.compiled == [("warpsoft.kernels.newton", 1.5234)]
    assert lines[-1].startswith("  compiled kernel module warpsoft.kernels.newton for cuda:0 in 1.5 s")
