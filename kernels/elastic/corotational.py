"""Corotational linear tetrahedra: rotations, forces, stiffness products, energy.

Conventions (all kernels, float64):
- ``tets[e]`` holds the four node ids ``(i0, i1, i2, i3)`` of element ``e`` with positive
  rest volume ``(X1-X0) . ((X2-X0) x (X3-X0)) / 6 > 0``.
- ``dm_inv[e]`` is ``Dm^-1`` with ``Dm = [X1-X0, X2-X0, X3-X0]`` (m^-1). Row ``k`` of it is the
  gradient of the shape function of node ``k+1``; node 0's gradient is minus their sum.
- ``F = Ds Dm^-1`` (``Ds`` from current positions); ``R`` is the rotation of its polar
  decomposition, reflection-free also for inverted elements.
- Linear strain in the rotated frame ``eps = sym(R^T F) - I``; stress
  ``sigma = 2 mu eps + lam tr(eps) I`` (Pa). Internal force on node ``a``:
  ``f_a = -V R sigma g_a`` (N). The stiffness ``K = R K0 R^T`` (rotation not differentiated).
"""

import warp as wp

from .. import OPTIONS
from ..linear.cg import column_done
from ..worlds import still
from .geometry import edge_matrix, listed, polar_rotation, shape_gradient

wp.set_module_options(OPTIONS)


@wp.func
def hooke(eps: wp.mat33d, mu: wp.float64, lam: wp.float64) -> wp.mat33d:
    """Linear isotropic stress (Pa) of a symmetric strain."""
    tr = eps[0, 0] + eps[1, 1] + eps[2, 2]
    return wp.float64(2.0) * mu * eps + lam * tr * wp.identity(n=3, dtype=wp.float64)


@wp.kernel
def element_forces(
    q: wp.array(dtype=wp.vec3d),
    tets: wp.array(dtype=wp.vec4i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    world: wp.array(dtype=wp.int32),
    moving: wp.array(dtype=wp.int32),
    rot: wp.array(dtype=wp.mat33d),
    force: wp.array(dtype=wp.vec3d),
):
    """Linearize: store each element's rotation and scatter its internal forces (N); an element of
    a world that stays (``kernels/worlds.py``) keeps both."""
    e = wp.tid()
    if still(moving, world[e]):
        return
    t = tets[e]
    Di = dm_inv[e]
    F = edge_matrix(q[t[0]], q[t[1]], q[t[2]], q[t[3]]) * Di
    R = polar_rotation(F)
    rot[e] = R
    eps_full = wp.transpose(R) * F
    eps = wp.float64(0.5) * (eps_full + wp.transpose(eps_full)) - wp.identity(n=3, dtype=wp.float64)
    P = volume[e] * (R * hooke(eps, mu[e], lam[e]))
    for a in range(4):
        wp.atomic_sub(force, t[a], P * shape_gradient(Di, a))


@wp.func
def add_element_product(x: wp.array2d(dtype=wp.vec3d), c: wp.int32, t: wp.vec4i, R: wp.mat33d, g0: wp.vec3d,
                        g1: wp.vec3d, g2: wp.vec3d, g3: wp.vec3d, s: wp.float64, mu: wp.float64, lam: wp.float64,
                        y: wp.array2d(dtype=wp.vec3d)):
    """``y[c] += s K0_e`` applied to column ``c`` of ``x`` in the element's rotated frame
    (``s = scale V``; ``g`` the shape gradients): strain of ``R^T x``, Hooke, forces rotated back."""
    Rt = wp.transpose(R)
    G = (wp.outer(Rt * x[c, t[0]], g0) + wp.outer(Rt * x[c, t[1]], g1) + wp.outer(Rt * x[c, t[2]], g2)
         + wp.outer(Rt * x[c, t[3]], g3))
    eps = wp.float64(0.5) * (G + wp.transpose(G))
    P = s * (R * hooke(eps, mu, lam))
    wp.atomic_add(y, c, t[0], P * g0)
    wp.atomic_add(y, c, t[1], P * g1)
    wp.atomic_add(y, c, t[2], P * g2)
    wp.atomic_add(y, c, t[3], P * g3)


@wp.kernel
def stiffness_product(
    x: wp.array2d(dtype=wp.vec3d),
    tets: wp.array(dtype=wp.vec4i),
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
    """``y[c] += scale * K x[c]``, one thread per column ``c`` and element ``e``, with
    ``K_e = R (V B^T C B) R^T`` (launched over ``(k, elements)``); a converged column of the
    element's world (``world[e]``, :func:`column_done`) is skipped."""
    c, e = wp.tid()
    if column_done(done, c, world[e]):
        return
    Di = dm_inv[e]
    add_element_product(x, c, tets[e], rot[e], shape_gradient(Di, 0), shape_gradient(Di, 1), shape_gradient(Di, 2),
                        shape_gradient(Di, 3), scale * volume[e], mu[e], lam[e], y)


@wp.kernel
def stiffness_product_columns(
    x: wp.array2d(dtype=wp.vec3d),
    tets: wp.array(dtype=wp.vec4i),
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
    """:func:`stiffness_product` with one thread per element for all the columns of ``x``
    (launched over the elements): the element's data are read, and its gradients formed, once."""
    e = wp.tid()
    w = world[e]
    t = tets[e]
    Di = dm_inv[e]
    R = rot[e]
    g0 = shape_gradient(Di, 0)
    g1 = shape_gradient(Di, 1)
    g2 = shape_gradient(Di, 2)
    g3 = shape_gradient(Di, 3)
    s = scale * volume[e]
    mu_e = mu[e]
    lam_e = lam[e]
    for c in range(x.shape[0]):
        if not column_done(done, c, w):
            add_element_product(x, c, t, R, g0, g1, g2, g3, s, mu_e, lam_e, y)


@wp.func
def stiffness_block(ga: wp.vec3d, gb: wp.vec3d, mu: wp.float64, lam: wp.float64) -> wp.mat33d:
    """Unrotated 3x3 block ``K0_ab / V`` coupling nodes ``a`` and ``b`` (Pa m^-2). Rotated,
    ``R K0(ga, gb) R^T = K0(R ga, R gb)`` (``R I R^T = I``, ``R (u v^T) R^T = (R u)(R v)^T``):
    the kernels below rotate the four gradients once, not each block."""
    return mu * wp.dot(ga, gb) * wp.identity(n=3, dtype=wp.float64) + mu * wp.outer(gb, ga) + lam * wp.outer(
        ga, gb
    )


@wp.kernel
def stiffness_diagonal(
    tets: wp.array(dtype=wp.vec4i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    diag: wp.array(dtype=wp.mat33d),
):
    """Accumulate the 3x3 diagonal blocks of ``K`` (N/m) per node."""
    e = wp.tid()
    t = tets[e]
    Di = dm_inv[e]
    R = rot[e]
    for a in range(4):
        g = R * shape_gradient(Di, a)
        wp.atomic_add(diag, t[a], volume[e] * stiffness_block(g, g, mu[e], lam[e]))


@wp.kernel
def rotated_gradients(
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    world: wp.array(dtype=wp.int32),
    moving: wp.array(dtype=wp.int32),
    grads: wp.array(dtype=wp.vec3d),
    moduli: wp.array(dtype=wp.vec2d),
):
    """Each element's four rotated shape gradients ``grads[4 e + a] = R g_a`` (1/m) and
    ``moduli[e] = (V mu, V lam)`` (N m): what :func:`stiffness_slots_from` reads of it (kept for
    the worlds that stay)."""
    e = wp.tid()
    if still(moving, world[e]):
        return
    Di = dm_inv[e]
    R = rot[e]
    for a in range(4):
        grads[4 * e + a] = R * shape_gradient(Di, a)
    moduli[e] = wp.vec2d(volume[e] * mu[e], volume[e] * lam[e])


@wp.kernel
def stiffness_slots_from(
    grads: wp.array(dtype=wp.vec3d),
    moduli: wp.array(dtype=wp.vec2d),
    slot_start: wp.array(dtype=wp.int32),
    contributions: wp.array(dtype=wp.int32),
    world: wp.array(dtype=wp.int32),
    moving: wp.array(dtype=wp.int32),
    values: wp.array(dtype=wp.mat33d),
):
    """The blocks of :func:`stiffness_blocks` summed where they land, a thread per slot, none
    stored: ``values[s] = sum V K0(R g_a, R g_b)`` (N/m) over the element blocks ``16 e + 4 a + b``
    listed for slot ``s`` (``contributions[slot_start[s]:slot_start[s + 1]]``), from
    :func:`rotated_gradients` (``K0`` is linear in ``mu`` and ``lam``). A contribution reads two
    gradients and two moduli (64 bytes); reading its element's ``D^-1``, rotation and material
    (168 bytes) and rotating the gradients there took 3.93 ms for 1024 Diamonds on the H200,
    against 1.89 ms now and 0.72 for the gradients. A slot of a world that stays (its first
    element's) keeps its value; a padding slot has no element and stays zero."""
    s = wp.tid()
    j0, j1 = slot_start[s], slot_start[s + 1]
    if j0 == j1 or still(moving, world[contributions[j0] // 16]):
        return
    acc = wp.mat33d()
    for j in range(j0, j1):
        k = contributions[j]
        e = k // 16
        c = moduli[e]
        acc += stiffness_block(grads[4 * e + (k // 4) % 4], grads[4 * e + k % 4], c[0], c[1])
    values[s] = acc


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
    """All sixteen rotated 3x3 blocks of each element's stiffness, for sparse assembly
    (direct solver only): ``blocks[16 e + 4 a + b] = V R K0_ab R^T = V K0(R g_a, R g_b)`` (N/m);
    ``K_ba = K_ab^T``. With ``elements`` (not empty), thread ``i`` takes element ``elements[i]``
    and writes its blocks at ``16 i``."""
    i = wp.tid()
    e = listed(elements, i)
    Di = dm_inv[e]
    R = rot[e]
    V = volume[e]
    for a in range(4):
        ga = R * shape_gradient(Di, a)
        for b in range(a, 4):
            Kab = V * stiffness_block(ga, R * shape_gradient(Di, b), mu[e], lam[e])
            blocks[16 * i + 4 * a + b] = Kab
            if b != a:
                blocks[16 * i + 4 * b + a] = wp.transpose(Kab)


@wp.kernel
def elastic_energy(
    q: wp.array(dtype=wp.vec3d),
    tets: wp.array(dtype=wp.vec4i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    mu: wp.array(dtype=wp.float64),
    lam: wp.array(dtype=wp.float64),
    energy: wp.array(dtype=wp.float64),
):
    """Corotational strain energy (J) summed into ``energy[0]``."""
    e = wp.tid()
    t = tets[e]
    F = edge_matrix(q[t[0]], q[t[1]], q[t[2]], q[t[3]]) * dm_inv[e]
    R = polar_rotation(F)
    RF = wp.transpose(R) * F
    eps = wp.float64(0.5) * (RF + wp.transpose(RF)) - wp.identity(n=3, dtype=wp.float64)
    sig = hooke(eps, mu[e], lam[e])
    w = wp.float64(0.0)
    for i in range(3):
        for j in range(3):
            w += eps[i, j] * sig[i, j]
    wp.atomic_add(energy, 0, wp.float64(0.5) * volume[e] * w)
