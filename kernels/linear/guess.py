"""Kernels of the solves' extrapolated warm starts (``warpsoft.linear.guess``)."""

import warp as wp

from .. import OPTIONS

wp.set_module_options(OPTIONS)


@wp.kernel
def extrapolate(held: wp.array(dtype=wp.int32), world: wp.array(dtype=wp.int32), steps: wp.array(dtype=wp.int32),
                moved: wp.array(dtype=wp.int32), x: wp.array2d(dtype=wp.vec3d), last: wp.array2d(dtype=wp.vec3d),
                before: wp.array2d(dtype=wp.vec3d)):
    """Column ``c`` of node ``i``: ``x`` becomes the start of this step's solve and the history
    moves on by one. ``steps`` counts the starts made since the history began: ``x`` is the last
    step's solution from the second on, ``last`` the one before from the third, ``before`` from
    the fourth. The start is the polynomial through the solutions known, taken one step on:
    ``x`` (one), ``2 x - last`` (two), ``3 x - 3 last + before`` (three). A column past the
    world's ``held`` force rows (a contact's, whose row changes every step; every column where
    ``held`` is -1) and every column after a state ``moved`` from outside keep ``x``."""
    c, i = wp.tid()
    xi = x[c, i]
    known = steps[0] - 1  # solutions known besides x
    if moved[0] != 0 or c > held[world[i]]:
        known = 0
    guess = xi
    if known == 1:
        guess = wp.float64(2.0) * xi - last[c, i]
    elif known >= 2:
        guess = wp.float64(3.0) * (xi - last[c, i]) + before[c, i]
    before[c, i] = last[c, i]
    last[c, i] = xi
    x[c, i] = guess


@wp.kernel
def count_steps(moved: wp.array(dtype=wp.int32), steps: wp.array(dtype=wp.int32)):
    """The starts made since the history began (at most 3); after a state moved from outside,
    the history begins again with this start's ``x``, a solution from before the move."""
    if moved[0] != 0:
        steps[0] = 1
    else:
        steps[0] = wp.min(steps[0] + 1, 3)
