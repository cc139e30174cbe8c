"""Corotational quadratic (10-node) tetrahedra: rotations, forces, stiffness products, energy.

Conventions (all kernels, float64):
- ``elems[e]`` holds ten node ids: the corners ``(i0, i1, i2, i3)`` (positive rest volume),
  then the edges' midpoints in the order 01, 02, 03, 12, 13, 23 (straight edges at rest).
- ``dm_inv[e]`` and ``volume[e]`` are those of the corner tetrahedron (as in
  :mod:`corotational`); ``g_i`` the gradient of the barycentric coordinate ``L_i``.
- Shape gradients at a point of barycentric coordinates ``L``: corner ``i``,
  ``(4 L_i - 1) g_i``; edge ``(i, j)``, ``4 (L_i g_j + L_j g_i)``.
- Integrals by the four-point rule (weights ``V/4``, exact for ``B^T C B``, of degree 2).
- One rotation per element: ``R``, the polar rotation of the element's mean deformation gradient
  ``F = sum over edges x_ij (g_i + g_j)`` (the corners' mean gradients vanish), held fixed over
  the step as in :mod:`corotational`. At a quadrature point the strain is
  ``eps = sym(R^T F_q) - I``, the stress ``sigma = 2 mu eps + lam tr(eps) I`` (Pa), and node
  ``a`` gets ``f_a = -sum_q (V/4) R sigma_q grad N_a(q)`` (N): ``f = -R K0 (R^T x - X)``.
"""

import warp as wp

from .. import OPTIONS
from ..linear.cg import column_done
from ..worlds import still
from .corotational import hooke, stiffness_block
from .geometry import listed, polar_rotation, shape_gradient

# loops stay loops: unrolled, the nested loops over ten nodes and four points took minutes to compile
wp.set_module_options(OPTIONS | {"max_unroll": 0})

vec10i = wp.types.vector(length=10, dtype=wp.int32)

QUAD_A = wp.constant(wp.float64(0.5854101966249685))  # the four-point rule's barycentric coordinates
QUAD_B = wp.constant(wp.float64(0.1381966011250105))


@wp.func
def corner_gradients(Di: wp.mat33d):
    """The four corner gradients ``g_0 .. g_3`` (m^-1) from ``Dm^-1``."""
    return shape_gradient(Di, 0), shape_gradient(Di, 1), shape_gradient(Di, 2), shape_gradient(Di, 3)


@wp.func
def pick(g0: wp.vec3d, g1: wp.vec3d, g2: wp.vec3d, g3: wp.vec3d, i: int) -> wp.vec3d:
    """``g_i`` of the four corner gradients."""
    if i == 1:
        return g1
    if i == 2:
        return g2
    if i == 3:
        return g3
    return g0


@wp.func
def edge_ends(k: int) -> wp.vec2i:
    """The corners of edge ``k`` (nodes 4 + k): 01, 02, 03, 12, 13, 23."""
    if k == 0:
        return wp.vec2i(0, 1)
    if k == 1:
        return wp.vec2i(0, 2)
    if k == 2:
        return wp.vec2i(0, 3)
    if k == 3:
        return wp.vec2i(1, 2)
    if k == 4:
        return wp.vec2i(1, 3)
    return wp.vec2i(2, 3)


@wp.func
def bary(q: int, i: int) -> wp.float64:
    """Barycentric coordinate ``L_i`` of quadrature point ``q``."""
    if q == i:
        return QUAD_A
    return QUAD_B


@wp.func
def quad_gradient(g0: wp.vec3d, g1: wp.vec3d, g2: wp.vec3d, g3: wp.vec3d, a: int, q: int) -> wp.vec3d:
    """Gradient (m^-1) of node ``a``'s quadratic shape function at quadrature point ``q``."""
    if a < 4:
        return (wp.float64(4.0) * bary(q, a) - wp.float64(1.0)) * pick(g0, g1, g2, g3, a)
    ij = edge_ends(a - 4)
    gi = pick(g0, g1, g2, g3, ij[0])
    gj = pick(g0, g1, g2, g3, ij[1])
    return wp.float64(4.0) * (bary(q, ij[0]) * gj + bary(q, ij[1]) * gi)


@wp.func
def mean_gradient(x: wp.array(dtype=wp.vec3d), t: vec10i, g0: wp.vec3d, g1: wp.vec3d, g2: wp.vec3d,
                  g3: wp.vec3d) -> wp.mat33d:
    """The element's mean deformation gradient ``sum over edges x_ij (g_i + g_j)``."""
    F = wp.mat33d()
    for k in range(6):
        ij = edge_ends(k)
        F += wp.outer(x[t[4 + k]], pick(g0, g1, g2, g3, ij[0]) + pick(g0, g1, g2, g3, ij[1]))
    return F


@wp.func
def point_gradient(x: wp.array(dtype=wp.vec3d), t: vec10i, g0: wp.vec3d, g1: wp.vec3d, g2: wp.vec3d, g3: wp.vec3d,
                   q: int) -> wp.mat33d:
    """``F_q = sum_a x_a grad N_a(q)`` at quadrature point ``q``."""
    F = wp.mat33d()
    for a in range(10):
        F += wp.outer(x[t[a]], quad_gradient(g0, g1, g2, g3, a, q))
    return F


@wp.func
def rotated_strain(R: wp.mat33d, F: wp.mat33d) -> wp.mat33d:
    """``sym(R^T F) - I``."""
    RF = wp.transpose(R) * F
    return wp.float64(0.5) * (RF + wp.transpose(RF)) - wp.identity(n=3, dtype=wp.float64)


@wp.func
def node_force(P0: wp.mat33d, P1: wp.mat33d, P2: wp.mat33d, P3: wp.mat33d, g0: wp.vec3d, g1: wp.vec3d, g2: wp.vec3d,
               g3: wp.vec3d, a: int) -> wp.vec3d:
    """``sum_q P_q grad N_a(q)``: node ``a``'s share of the four points' stresses ``P_q`` (weighted,
    rotated back)."""
    return (P0 * quad_gradient(g0, g1, g2, g3, a, 0) + P1 * quad_gradient(g0, g1, g2, g3, a, 1)
            + P2 * quad_gradient(g0, g1, g2, g3, a, 2) + P3 * quad_gradient(g0, g1, g2, g3, a, 3))


@wp.kernel
def element_forces(
    q: wp.array(dtype=wp.vec3d),
    elems: wp.array(dtype=vec10i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    world: wp.array(dtype=wp.int32),
    moving: wp.array(dtype=wp.int32),
    rot: wp.array(dtype=wp.mat33d),
    force: wp.array(dtype=wp.vec3d),
):
    """Linearize: store each element's rotation and scatter its internal forces (N); an element
    of a world that stays (``kernels/worlds.py``) keeps both."""
    e = wp.tid()
    if still(moving, world[e]):
        return
    t = elems[e]
    Di = dm_inv[e]
    g0, g1, g2, g3 = corner_gradients(Di)
    R = polar_rotation(mean_gradient(q, t, g0, g1, g2, g3))
    rot[e] = R
    w = wp.float64(0.25) * volume[e]
    P0 = w * (R * hooke(rotated_strain(R, point_gradient(q, t, g0, g1, g2, g3, 0)), mu[e], lam[e]))
    P1 = w * (R * hooke(rotated_strain(R, point_gradient(q, t, g0, g1, g2, g3, 1)), mu[e], lam[e]))
    P2 = w * (R * hooke(rotated_strain(R, point_gradient(q, t, g0, g1, g2, g3, 2)), mu[e], lam[e]))
    P3 = w * (R * hooke(rotated_strain(R, point_gradient(q, t, g0, g1, g2, g3, 3)), mu[e], lam[e]))
    for a in range(10):
        f = node_force(P0, P1, P2, P3, g0, g1, g2, g3, a)
        wp.atomic_sub(force, t[a], f)


@wp.func
def column_strain(x: wp.array2d(dtype=wp.vec3d), c: int, t: vec10i, Rt: wp.mat33d, g0: wp.vec3d, g1: wp.vec3d,
                  g2: wp.vec3d, g3: wp.vec3d, q: int) -> wp.mat33d:
    """Small strain at quadrature point ``q`` of ``R^T x[c]`` (``Rt = R^T``)."""
    G = wp.mat33d()
    for a in range(10):
        G += wp.outer(Rt * x[c, t[a]], quad_gradient(g0, g1, g2, g3, a, q))
    return wp.float64(0.5) * (G + wp.transpose(G))


@wp.func
def add_element_product(x: wp.array2d(dtype=wp.vec3d), c: int, t: vec10i, R: wp.mat33d, g0: wp.vec3d, g1: wp.vec3d,
                        g2: wp.vec3d, g3: wp.vec3d, s: wp.float64, mu: wp.float64, lam: wp.float64,
                        y: wp.array2d(dtype=wp.vec3d)):
    """``y[c] += s K0_e``-product of column ``c`` in the element's rotated frame (``s = scale V/4``)."""
    Rt = wp.transpose(R)
    P0 = s * (R * hooke(column_strain(x, c, t, Rt, g0, g1, g2, g3, 0), mu, lam))
    P1 = s * (R * hooke(column_strain(x, c, t, Rt, g0, g1, g2, g3, 1), mu, lam))
    P2 = s * (R * hooke(column_strain(x, c, t, Rt, g0, g1, g2, g3, 2), mu, lam))
    P3 = s * (R * hooke(column_strain(x, c, t, Rt, g0, g1, g2, g3, 3), mu, lam))
    for a in range(10):
        f = node_force(P0, P1, P2, P3, g0, g1, g2, g3, a)
        wp.atomic_add(y, c, t[a], f)


@wp.kernel
def stiffness_product(
    x: wp.array2d(dtype=wp.vec3d),
    elems: wp.array(dtype=vec10i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    scale: wp.float64,
    world: wp.array(dtype=wp.int32),
    done: wp.array3d(dtype=wp.float64),
    y: wp.array2d(dtype=wp.vec3d),
):
    """``y[c] += scale K x[c]``, one thread per column and element (launched over ``(k, elements)``);
    a converged column of the element's world is skipped."""
    c, e = wp.tid()
    if column_done(done, c, world[e]):
        return
    Di = dm_inv[e]
    add_element_product(x, c, elems[e], rot[e], shape_gradient(Di, 0), shape_gradient(Di, 1), shape_gradient(Di, 2),
                        shape_gradient(Di, 3), wp.float64(0.25) * scale * volume[e], mu[e], lam[e], y)


@wp.kernel
def stiffness_product_columns(
    x: wp.array2d(dtype=wp.vec3d),
    elems: wp.array(dtype=vec10i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    scale: wp.float64,
    world: wp.array(dtype=wp.int32),
    done: wp.array3d(dtype=wp.float64),
    y: wp.array2d(dtype=wp.vec3d),
):
    """:func:`stiffness_product` with one thread per element for all the columns of ``x``."""
    e = wp.tid()
    w = world[e]
    Di = dm_inv[e]
    g0, g1, g2, g3 = corner_gradients(Di)
    s = wp.float64(0.25) * scale * volume[e]
    for c in range(x.shape[0]):
        if not column_done(done, c, w):
            add_element_product(x, c, elems[e], rot[e], g0, g1, g2, g3, s, mu[e], lam[e], y)


@wp.func
def rotated_gradient(R: wp.mat33d, g0: wp.vec3d, g1: wp.vec3d, g2: wp.vec3d, g3: wp.vec3d, a: int,
                     q: int) -> wp.vec3d:
    return R * quad_gradient(g0, g1, g2, g3, a, q)


@wp.kernel
def stiffness_diagonal(
    elems: wp.array(dtype=vec10i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    diag: wp.array(dtype=wp.mat33d),
):
    """Accumulate the 3x3 diagonal blocks of ``K`` (N/m) per node."""
    e = wp.tid()
    t = elems[e]
    Di = dm_inv[e]
    g0, g1, g2, g3 = corner_gradients(Di)
    R = rot[e]
    w = wp.float64(0.25) * volume[e]
    for a in range(10):
        block = wp.mat33d()
        for q in range(4):
            g = rotated_gradient(R, g0, g1, g2, g3, a, q)
            block += stiffness_block(g, g, mu[e], lam[e])
        wp.atomic_add(diag, t[a], w * block)


@wp.kernel
def stiffness_blocks(
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    elements: wp.array(dtype=wp.int32),
    blocks: wp.array(dtype=wp.mat33d),
):
    """All hundred rotated 3x3 blocks of each element's stiffness, for sparse assembly:
    ``blocks[100 e + 10 a + b] = sum_q (V/4) K0(R grad N_a(q), R grad N_b(q))`` (N/m). With
    ``elements`` (not empty), thread ``i`` takes element ``elements[i]`` and writes at ``100 i``."""
    i = wp.tid()
    e = listed(elements, i)
    Di = dm_inv[e]
    g0, g1, g2, g3 = corner_gradients(Di)
    R = rot[e]
    w = wp.float64(0.25) * volume[e]
    for a in range(10):
        for b in range(a, 10):
            Kab = wp.mat33d()
            for q in range(4):
                Kab += stiffness_block(rotated_gradient(R, g0, g1, g2, g3, a, q),
                                       rotated_gradient(R, g0, g1, g2, g3, b, q), mu[e], lam[e])
            blocks[100 * i + 10 * a + b] = w * Kab
            if b != a:
                blocks[100 * i + 10 * b + a] = w * wp.transpose(Kab)


@wp.kernel
def elastic_energy(
    q: wp.array(dtype=wp.vec3d),
    elems: wp.array(dtype=vec10i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    energy: wp.array(dtype=wp.float64),
):
    """Corotational strain energy (J) summed into ``energy[0]``."""
    e = wp.tid()
    t = elems[e]
    Di = dm_inv[e]
    g0, g1, g2, g3 = corner_gradients(Di)
    R = polar_rotation(mean_gradient(q, t, g0, g1, g2, g3))
    w = wp.float64(0.0)
    for p in range(4):
        eps = rotated_strain(R, point_gradient(q, t, g0, g1, g2, g3, p))
        w += wp.ddot(eps, hooke(eps, mu[e], lam[e]))
    wp.atomic_add(energy, 0, wp.float64(0.125) * volume[e] * w)


@wp.kernel
def accumulate_node_rotations(
    elems: wp.array(dtype=vec10i),
    volume: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    world: wp.array(dtype=wp.int32),
    moving: wp.array(dtype=wp.int32),
    node_sum: wp.array(dtype=wp.mat33d),
):
    """``node_sum[i] += V_e R_e`` over the elements ``e`` around node ``i`` (not for the worlds
    that stay)."""
    e = wp.tid()
    if still(moving, world[e]):
        return
    t = elems[e]
    w = volume[e] * rot[e]
    for a in range(10):
        wp.atomic_add(node_sum, t[a], w)
