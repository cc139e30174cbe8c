"""Energies of the state (the step's own kernels are in ``newton.py``)."""

import warp as wp

from . import OPTIONS

wp.set_module_options(OPTIONS)


@wp.kernel
def kinetic_energy(v: wp.array(dtype=wp.vec3d), mass: wp.array(dtype=wp.float64),
                   energy: wp.array(dtype=wp.float64)):
    """``energy[0] += 1/2 m v.v`` (J)."""
    i = wp.tid()
    wp.atomic_add(energy, 0, wp.float64(0.5) * mass[i] * wp.dot(v[i], v[i]))
