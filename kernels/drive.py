"""Nodes carried by kinematic frames (``warpsoft/drive.py``)."""

import warp as wp

from . import OPTIONS

wp.set_module_options(OPTIONS)


@wp.kernel
def prescribe(ids: wp.array(dtype=wp.int32), target: wp.array(dtype=wp.vec3d), axes: wp.array(dtype=wp.vec3d),
              q: wp.array(dtype=wp.vec3d), dx: wp.array2d(dtype=wp.vec3d)):
    """Driven node ``k`` (global id ``ids[k]``) moves over the step by ``dx = target - q`` (m)
    along its driven ``axes[k]`` (1 = driven; the others keep ``dx``'s value)."""
    k = wp.tid()
    i = ids[k]
    a = axes[k]
    d = wp.cw_mul(a, target[k] - q[i])
    old = dx[0, i]
    dx[0, i] = d + wp.cw_mul(wp.vec3d(wp.float64(1.0), wp.float64(1.0), wp.float64(1.0)) - a, old)


@wp.kernel
def lift_rhs(mask: wp.array(dtype=wp.vec3d), a_dx: wp.array2d(dtype=wp.vec3d), rhs: wp.array2d(dtype=wp.vec3d)):
    """``rhs[0] -= P A dx``: the free nodes' share of the prescribed motion moves to the
    right-hand side."""
    i = wp.tid()
    rhs[0, i] = rhs[0, i] - wp.cw_mul(mask[i], a_dx[0, i])
