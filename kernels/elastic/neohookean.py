"""Stable Neo-Hookean linear tetrahedra: forces, projected tangent products, energy.

Conventions as in :mod:`corotational` (``tets``, ``dm_inv``, ``F = Ds Dm^-1``, shape gradients
``g_a``, float64). The energy density (J/m^3) is the stable Neo-Hookean one (Smith, de Goes and
Kim 2018, without its log term), with the Lame parameters ``mu`` and ``lam`` of linear
elasticity at small strain:

    Psi(F) = mu/2 (|F|^2 - 3) - mu (J - 1) + (lam + mu)/2 (J - 1)^2,    J = det F.

It is zero at rest, finite for inverted elements (no ``log J``), and its stress is

    P = mu F + c cof F,    c = (lam + mu)(J - 1) - mu,    cof F = dJ/dF = J F^-T

(first Piola-Kirchhoff, Pa); at small strain ``P = 2 mu eps + lam tr(eps) I``. The force on
node ``a`` is ``f_a = -V P g_a`` (N).

Tangent. ``d2Psi/dF2 = mu I + (lam + mu) cof F (x) cof F + c d2J/dF2``. In the frame of the
rotation-variant SVD ``F = U diag(s) V^T`` (``U``, ``V`` rotations, ``s_2 < 0`` for an inverted
element) a direction ``D = U^T dF V`` splits into
- its diagonal (the scaling modes), on which the Hessian is the 3x3 matrix
  ``mu I + (lam + mu) g g^T + c A``, ``g = (s1 s2, s0 s2, s0 s1)``, ``A_ij = s_k`` off the
  diagonal (``k`` the third index), zero on it;
- for each pair ``i < j`` (``k`` the third index), its twist ``(D_ij - D_ji)/2``, eigenvalue
  ``mu + c s_k``, and its flip ``(D_ij + D_ji)/2``, eigenvalue ``mu - c s_k``.
Every negative eigenvalue is clamped to zero (the projected Newton of Teran et al. 2005): the
tangent stays positive semi-definite for the step's solvers, also under compression and for
inverted elements, and equals the exact Hessian wherever that is already positive. At rest the
twists (rotations) have eigenvalue zero and the rest is Hooke's law. The scaling block is
diagonalized (``eig3``) only where it is not positive definite; most elements' is, and is kept
whole.
"""

import warp as wp

from .. import OPTIONS
from ..linear.cg import column_done
from ..worlds import still
from .geometry import edge_matrix, listed, shape_gradient

wp.set_module_options(OPTIONS)


@wp.struct
class Tangent:
    """An element's projected tangent: ``dP = U T(U^T dF V) V^T`` (see the module doc)."""

    U: wp.mat33d  # left singular vectors (a rotation)
    V: wp.mat33d  # right singular vectors (a rotation)
    scaling: wp.mat33d  # the scaling modes' projected 3x3 block (Pa)
    twist: wp.vec3d  # pair k's twist eigenvalue (Pa), clamped at zero
    flip: wp.vec3d  # pair k's flip eigenvalue (Pa), clamped at zero


@wp.func
def cofactor(F: wp.mat33d) -> wp.mat33d:
    """``cof F = dJ/dF`` (columns ``f1 x f2, f2 x f0, f0 x f1`` of the columns ``f`` of ``F``)."""
    f0 = wp.vec3d(F[0, 0], F[1, 0], F[2, 0])
    f1 = wp.vec3d(F[0, 1], F[1, 1], F[2, 1])
    f2 = wp.vec3d(F[0, 2], F[1, 2], F[2, 2])
    c0 = wp.cross(f1, f2)
    c1 = wp.cross(f2, f0)
    c2 = wp.cross(f0, f1)
    return wp.mat33d(c0[0], c1[0], c2[0], c0[1], c1[1], c2[1], c0[2], c1[2], c2[2])


@wp.func
def volume_coefficient(J: wp.float64, mu: wp.float64, lam: wp.float64) -> wp.float64:
    """``c = dPsi/dJ = (lam + mu)(J - 1) - mu`` (Pa)."""
    return (lam + mu) * (J - wp.float64(1.0)) - mu


@wp.func
def stress(F: wp.mat33d, mu: wp.float64, lam: wp.float64) -> wp.mat33d:
    """First Piola-Kirchhoff stress ``P = mu F + c cof F`` (Pa)."""
    return mu * F + volume_coefficient(wp.determinant(F), mu, lam) * cofactor(F)


@wp.func
def energy_density(F: wp.mat33d, mu: wp.float64, lam: wp.float64) -> wp.float64:
    """``Psi(F)`` (J/m^3), zero at rest."""
    Jm1 = wp.determinant(F) - wp.float64(1.0)
    return (wp.float64(0.5) * mu * (wp.ddot(F, F) - wp.float64(3.0)) - mu * Jm1
            + wp.float64(0.5) * (lam + mu) * Jm1 * Jm1)


@wp.func
def flip_last_column(M: wp.mat33d) -> wp.mat33d:
    return wp.mat33d(M[0, 0], M[0, 1], -M[0, 2], M[1, 0], M[1, 1], -M[1, 2], M[2, 0], M[2, 1], -M[2, 2])


@wp.func
def positive_definite(H: wp.mat33d) -> bool:
    """Whether a symmetric 3x3 matrix is positive definite: its leading minors are all positive."""
    m2 = H[0, 0] * H[1, 1] - H[0, 1] * H[1, 0]
    return H[0, 0] > wp.float64(0.0) and m2 > wp.float64(0.0) and wp.determinant(H) > wp.float64(0.0)


@wp.func
def tangent_at(F: wp.mat33d, mu: wp.float64, lam: wp.float64) -> Tangent:
    """The projected tangent of ``Psi`` at ``F`` (module doc)."""
    U = wp.mat33d()
    s = wp.vec3d()
    V = wp.mat33d()
    wp.svd3(F, U, s, V)
    # rotation-variant: U and V rotations, the sign of det F on the smallest singular value
    if wp.determinant(U) < wp.float64(0.0):
        U = flip_last_column(U)
        s = wp.vec3d(s[0], s[1], -s[2])
    if wp.determinant(V) < wp.float64(0.0):
        V = flip_last_column(V)
        s = wp.vec3d(s[0], s[1], -s[2])
    c = volume_coefficient(s[0] * s[1] * s[2], mu, lam)
    g = wp.vec3d(s[1] * s[2], s[0] * s[2], s[0] * s[1])
    A = wp.mat33d(wp.float64(0.0), s[2], s[1], s[2], wp.float64(0.0), s[0], s[1], s[0], wp.float64(0.0))
    H = mu * wp.identity(n=3, dtype=wp.float64) + (lam + mu) * wp.outer(g, g) + c * A
    zero = wp.float64(0.0)
    T = Tangent()
    T.U = U
    T.V = V
    T.scaling = H
    if not positive_definite(H):
        Q = wp.mat33d()
        d = wp.vec3d()
        wp.eig3(H, Q, d)
        T.scaling = Q * wp.diag(wp.vec3d(wp.max(d[0], zero), wp.max(d[1], zero), wp.max(d[2], zero))) * wp.transpose(Q)
    T.twist = wp.vec3d(wp.max(mu + c * s[0], zero), wp.max(mu + c * s[1], zero), wp.max(mu + c * s[2], zero))
    T.flip = wp.vec3d(wp.max(mu - c * s[0], zero), wp.max(mu - c * s[1], zero), wp.max(mu - c * s[2], zero))
    return T


@wp.func
def tangent_product(T: Tangent, dF: wp.mat33d) -> wp.mat33d:
    """``dP`` (Pa) of a change ``dF`` of the deformation gradient, by the projected tangent."""
    D = wp.transpose(T.U) * dF * T.V
    p = T.scaling * wp.vec3d(D[0, 0], D[1, 1], D[2, 2])
    out = wp.diag(p)
    for k in range(3):
        i = (k + 1) % 3
        j = (k + 2) % 3
        twist = wp.float64(0.5) * (D[i, j] - D[j, i])
        flip = wp.float64(0.5) * (D[i, j] + D[j, i])
        out[i, j] = T.twist[k] * twist + T.flip[k] * flip
        out[j, i] = T.flip[k] * flip - T.twist[k] * twist
    return T.U * out * wp.transpose(T.V)


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
    tangent: wp.array(dtype=Tangent),
    force: wp.array(dtype=wp.vec3d),
):
    """Linearize: each element's projected tangent and rotation ``U V^T`` (for the warped
    preconditioner), and its internal forces (N) scattered; an element of a world that stays
    (``kernels/worlds.py``) keeps all three."""
    e = wp.tid()
    if still(moving, world[e]):
        return
    t = tets[e]
    Di = dm_inv[e]
    F = edge_matrix(q[t[0]], q[t[1]], q[t[2]], q[t[3]]) * Di
    T = tangent_at(F, mu[e], lam[e])
    tangent[e] = T
    rot[e] = T.U * wp.transpose(T.V)
    P = volume[e] * stress(F, mu[e], lam[e])
    for a in range(4):
        wp.atomic_sub(force, t[a], P * shape_gradient(Di, a))


@wp.func
def add_element_product(x: wp.array2d(dtype=wp.vec3d), c: wp.int32, t: wp.vec4i, T: Tangent, g0: wp.vec3d,
                        g1: wp.vec3d, g2: wp.vec3d, g3: wp.vec3d, s: wp.float64, y: wp.array2d(dtype=wp.vec3d)):
    """``y[c] += s K_e x[c]`` (``s = scale V``): the gradient of column ``c`` over the element,
    its stress by the tangent, the forces scattered."""
    dF = (wp.outer(x[c, t[0]], g0) + wp.outer(x[c, t[1]], g1) + wp.outer(x[c, t[2]], g2)
          + wp.outer(x[c, t[3]], g3))
    P = s * tangent_product(T, dF)
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
    tangent: wp.array(dtype=Tangent),
    scale: wp.float64,
    world: wp.array(dtype=wp.int32),
    done: wp.array3d(dtype=wp.float64),
    y: wp.array2d(dtype=wp.vec3d),
):
    """``y[c] += scale K x[c]``, one thread per column ``c`` and element ``e`` (launched over
    ``(k, elements)``); a converged column of the element's world is skipped."""
    c, e = wp.tid()
    if column_done(done, c, world[e]):
        return
    Di = dm_inv[e]
    add_element_product(x, c, tets[e], tangent[e], shape_gradient(Di, 0), shape_gradient(Di, 1),
                        shape_gradient(Di, 2), shape_gradient(Di, 3), scale * volume[e], y)


@wp.kernel
def stiffness_product_columns(
    x: wp.array2d(dtype=wp.vec3d),
    tets: wp.array(dtype=wp.vec4i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    tangent: wp.array(dtype=Tangent),
    scale: wp.float64,
    world: wp.array(dtype=wp.int32),
    done: wp.array3d(dtype=wp.float64),
    y: wp.array2d(dtype=wp.vec3d),
):
    """:func:`stiffness_product` with one thread per element for all the columns of ``x``."""
    e = wp.tid()
    w = world[e]
    t = tets[e]
    Di = dm_inv[e]
    T = tangent[e]
    g0 = shape_gradient(Di, 0)
    g1 = shape_gradient(Di, 1)
    g2 = shape_gradient(Di, 2)
    g3 = shape_gradient(Di, 3)
    s = scale * volume[e]
    for c in range(x.shape[0]):
        if not column_done(done, c, w):
            add_element_product(x, c, t, T, g0, g1, g2, g3, s, y)


@wp.func
def node_block(P0: wp.mat33d, P1: wp.mat33d, P2: wp.mat33d, ga: wp.vec3d) -> wp.mat33d:
    """The 3x3 block coupling nodes ``a`` and ``b``: column ``d`` is ``P_d ga``, the force on node
    ``a`` (gradient ``ga``) of a unit motion of node ``b`` along axis ``d`` whose stress change
    is ``P_d`` (``K_ab / V`` in Pa m^-2; ``K_ab`` in N/m with ``P_d`` times the volume)."""
    k0 = P0 * ga
    k1 = P1 * ga
    k2 = P2 * ga
    return wp.mat33d(k0[0], k1[0], k2[0], k0[1], k1[1], k2[1], k0[2], k1[2], k2[2])


@wp.func
def unit_motion_stress(T: Tangent, gb: wp.vec3d, d: int) -> wp.mat33d:
    """``dP`` (Pa per m) of a unit motion along axis ``d`` of a node with shape gradient ``gb``."""
    e = wp.vec3d()
    e[d] = wp.float64(1.0)
    return tangent_product(T, wp.outer(e, gb))


@wp.kernel
def stiffness_diagonal(
    tets: wp.array(dtype=wp.vec4i),
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    tangent: wp.array(dtype=Tangent),
    diag: wp.array(dtype=wp.mat33d),
):
    """Accumulate the 3x3 diagonal blocks of ``K`` (N/m) per node."""
    e = wp.tid()
    t = tets[e]
    Di = dm_inv[e]
    T = tangent[e]
    for a in range(4):
        g = shape_gradient(Di, a)
        Kaa = node_block(unit_motion_stress(T, g, 0), unit_motion_stress(T, g, 1), unit_motion_stress(T, g, 2), g)
        wp.atomic_add(diag, t[a], volume[e] * Kaa)


@wp.kernel
def stiffness_blocks(
    dm_inv: wp.array(dtype=wp.mat33d),
    volume: wp.array(dtype=wp.float64),
    tangent: wp.array(dtype=Tangent),
    elements: wp.array(dtype=wp.int32),
    blocks: wp.array(dtype=wp.mat33d),
):
    """All sixteen 3x3 blocks of each element's tangent stiffness, for sparse assembly:
    ``blocks[16 e + 4 a + b] = K_ab`` (N/m). Each node's three unit motions give the stress
    changes that make the blocks of its column (12 tangent products an element). With
    ``elements`` (not empty), thread ``i`` takes element ``elements[i]`` and writes at ``16 i``."""
    i = wp.tid()
    e = listed(elements, i)
    Di = dm_inv[e]
    T = tangent[e]
    V = volume[e]
    for b in range(4):
        gb = shape_gradient(Di, b)
        P0 = V * unit_motion_stress(T, gb, 0)
        P1 = V * unit_motion_stress(T, gb, 1)
        P2 = V * unit_motion_stress(T, gb, 2)
        for a in range(4):
            blocks[16 * i + 4 * a + b] = node_block(P0, P1, P2, shape_gradient(Di, a))


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
    """Stable Neo-Hookean strain energy (J) summed into ``energy[0]``."""
    e = wp.tid()
    t = tets[e]
    F = edge_matrix(q[t[0]], q[t[1]], q[t[2]], q[t[3]]) * dm_inv[e]
    wp.atomic_add(energy, 0, volume[e] * energy_density(F, mu[e], lam[e]))
