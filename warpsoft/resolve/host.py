"""The multipliers resolved on the host, between a step's two graphs (:func:`resolve_on_host`):
the direct-model worlds' Gauss-Seidel when it runs there, and the inverse-model worlds' QPs
(piqp through qpsolvers; a QPCC by pivoting where contacts were detected), each world from the
one read of ``W``, ``delta_free``, ``delta`` and ``lambda``."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from warpsoft.kernels.resolve import gauss_seidel as gs_kernels

from .gauss_seidel import RowInputs
from .inverse import solve_inverse
from .qpcc import ContactQP, solve_inverse_contacts
from .qpcc_friction import FrictionQP, solve_inverse_friction

if TYPE_CHECKING:
    from ..simulator import Simulator
    from ..stats import StepStats


def resolve_on_host(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Between the two graphs, from one read (``host``): the direct-model worlds' Gauss-Seidel
    when it runs on the host, then the inverse-model worlds' QPs; the multipliers go back in one
    copy."""
    if sim.host_gauss_seidel and sim.contact_set is not None:  # (no inverse world then)
        sim.contact_set.resolve_columns(host)
    elif sim.host_gauss_seidel:
        sim.gauss_seidel.solve_host(host)
    if any(s.inverse for s in sim.model.scenes) and sim.device_inverse is None:
        resolve_inverse(sim, stats, host)
    else:
        sim.gauss_seidel.lam.assign(host["lam"])


def resolve_inverse(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Inverse-model worlds: a QP each on the host (a QPCC where contacts were detected), from
    ``W``, ``delta_free``, ``delta`` and ``lambda`` read in one transfer (``host``); the
    multipliers go back in one copy."""
    rows, gs, scenes = sim.rows, sim.gauss_seidel, sim.model.scenes
    W, dfree, delta, lam = host["W"], host["delta_free"], host["delta"], host["lam"]
    for w, scene in enumerate(scenes):
        if not (scene.inverse and rows.world_actuators[w]):
            continue
        a, e = rows.actuator_rows(w), rows.effector_rows(w)
        na = a.stop - a.start
        inputs = row_inputs(gs.host, sim.values, delta, a)
        b = np.arange(rows.bilateral_rows(w).start, rows.bilateral_rows(w).stop)  # attachments, always held
        touching = int(host["force_rows"][w]) - na - len(b)  # the contacts detected this step
        if touching > 0 or len(b):  # a QPCC: the attachments' and contacts' forces with the actuation
            c = np.arange(rows.contact_rows(w).start, rows.contact_rows(w).start + touching)
            ids = np.concatenate([np.arange(a.start, a.stop), b, c, np.arange(e.start, e.stop)])
            nf = na + len(b) + touching
            local = (np.arange(na), na + np.arange(len(b)), na + len(b) + np.arange(touching),
                     nf + np.arange(e.stop - e.start))
            if rows.rows_per_contact(w) > 1:  # with friction: the direct model's contact states
                qp = FrictionQP(W[ids, :nf], dfree[ids], *local, inputs, sim.effector_weights[w],
                                host["friction"][c[1::3]], scene.inverse_epsilon)

                def physics(lam_a, w=w, a=a, b=b, c=c):
                    lam_w = gs.contacts_at(host, w, a, lam_a)
                    return lam_w[b], lam_w[c]

                res = solve_inverse_friction(qp, lam[a], physics)
            else:
                qp = ContactQP(W[ids, :nf], dfree[ids], local[0], local[2], local[3], inputs,
                               sim.effector_weights[w], scene.inverse_epsilon, b=local[1])
                res = solve_inverse_contacts(qp, lam[a])
            lam[a], lam[c] = res.lam_a, res.lam_c
            if res.lam_b is not None:
                lam[b] = res.lam_b
            stats.worlds[w].qp_pivots = res.pivots
        else:
            res = solve_inverse(W[a, :na], W[e, :na], dfree[a], dfree[e], inputs, sim.effector_weights[w], lam[a],
                                scene.inverse_epsilon)
            lam[a] = res.lam
        stats.worlds[w].qp_status, stats.worlds[w].qp_seconds = res.status, res.seconds
        if res.warning:
            stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: inverse model: {res.warning}")
    gs.lam.assign(lam)


def row_inputs(host: np.ndarray, values: np.ndarray, delta: np.ndarray, a: slice) -> RowInputs:
    """The inputs of actuator rows ``a`` for the host solvers, displacement bounds narrowed to the
    change allowed this step (as the device Gauss-Seidel does)."""
    k = gs_kernels
    lo_step, hi_step = delta[a] - host[k.MAX_STEP, a], delta[a] + host[k.MAX_STEP, a]
    return RowInputs(force_mode=host[k.FORCE_MODE, a] != 0, value=values[a], lo=host[k.LO, a], hi=host[k.HI, a],
                     dmin=np.clip(host[k.DMIN, a], lo_step, hi_step), dmax=np.clip(host[k.DMAX, a], lo_step, hi_step))
