"""Nodes carried by kinematic frames (``warpsoft/drive.py``)."""

import warp as wp


@wp.func
def pick(on: wp.float64, a: wp.float64, b: wp.float64):
    """``a`` where ``on`` is set (1), else ``b``."""
    return wp.where(on > wp.float64(0.0), a, b)


@wp.kernel
def drive_nodes(ids: wp.array(dtype=wp.int32), target: wp.array(dtype=wp.vec3d), axes: wp.array(dtype=wp.vec3d),
                inv_h: wp.float64, q: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d)):
    """Driven node ``k`` (global id ``ids[k]``) moves to ``target[k]`` (m) along its driven
    ``axes[k]`` (1 = driven); its velocity there is the move over the step (``inv_h = 1/h``; 0
    quasi-static)."""
    k = wp.tid()
    i = ids[k]
    a, t, old, vel = axes[k], target[k], q[i], v[i]
    q[i] = wp.vec3d(pick(a[0], t[0], old[0]), pick(a[1], t[1], old[1]), pick(a[2], t[2], old[2]))
    d = (t - old) * inv_h
    v[i] = wp.vec3d(pick(a[0], d[0], vel[0]), pick(a[1], d[1], vel[1]), pick(a[2], d[2], vel[2]))
