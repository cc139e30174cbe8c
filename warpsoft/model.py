"""Model (device arrays built once from a Scene) and State (positions, velocities)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels import fem

from .errors import SceneError
from .mapping import locate
from .scene import Scene, load_weights


@dataclass
class State:
    """Per-step state: positions ``q`` and velocities ``v``, each ``(n,)`` of vec3d (m, m/s)."""

    q: wp.array
    v: wp.array

    def positions(self) -> np.ndarray:
        """A copy of the positions as a ``(n, 3)`` NumPy array (m)."""
        return self.q.numpy().copy()


@dataclass
class BodyInfo:
    """Where a body's nodes and elements sit in the model's arrays."""

    name: str
    node_start: int
    node_count: int
    elem_start: int
    elem_count: int
    surface: np.ndarray  # (k, 3) global node ids, outward triangles


class Model:
    """Everything fixed over a run, on one device.

    Arrays (device): ``rest`` (n vec3d, m), ``tets`` (m vec4i), ``dm_inv`` (m mat33d, 1/m),
    ``volume`` (m float64, m^3), ``mu``/``lam`` (m float64, Pa), ``mass`` (n float64, kg; only
    in dynamic scenes or under gravity, else None), ``mask`` (n vec3d, 1 = free, 0 = fixed), ``f_const`` (n vec3d, N:
    gravity and constant loads; None when there are none), probe ``probe_nodes`` /
    ``probe_weights``.
    """

    def __init__(self, scene: Scene, device: str | None = None):
        scene.validate()
        self.scene = scene
        self.device = wp.get_device(device)
        nodes, tets, mu, lam, rho, self.bodies = [], [], [], [], [], []
        n0 = e0 = 0
        for body in scene.bodies:
            m = body.mesh
            nodes.append(m.nodes)
            tets.append(m.tets + n0)
            bm, bl, br = body.element_materials()
            mu.append(bm)
            lam.append(bl)
            rho.append(br)
            self.bodies.append(BodyInfo(body.name, n0, m.num_nodes, e0, m.num_elements, m.surface() + n0))
            n0 += m.num_nodes
            e0 += m.num_elements
        self.rest_np = np.concatenate(nodes)
        self.tets_np = np.concatenate(tets).astype(np.int32)
        self.num_nodes, self.num_elements = len(self.rest_np), len(self.tets_np)
        self.static = scene.static
        self.dt = scene.dt

        d = self.device
        self.rest = wp.array(self.rest_np, dtype=wp.vec3d, device=d)
        self.tets = wp.array(self.tets_np, dtype=wp.vec4i, device=d)
        self.mu = wp.array(np.concatenate(mu), dtype=wp.float64, device=d)
        self.lam = wp.array(np.concatenate(lam), dtype=wp.float64, device=d)
        self.dm_inv = wp.zeros(self.num_elements, dtype=wp.mat33d, device=d)
        self.volume = wp.zeros(self.num_elements, dtype=wp.float64, device=d)
        wp.launch(fem.tet_rest_shape, self.num_elements, inputs=[self.rest, self.tets],
                  outputs=[self.dm_inv, self.volume], device=d)

        # mass exists whenever something needs it: inertia (dynamic) or gravity
        self.has_gravity = bool(np.any(scene.gravity != 0.0))
        self.mass = None
        if not self.static or self.has_gravity:
            density = wp.array(np.concatenate(rho), dtype=wp.float64, device=d)
            self.mass = wp.zeros(self.num_nodes, dtype=wp.float64, device=d)
            wp.launch(fem.lumped_mass, self.num_elements, inputs=[self.tets, self.volume, density],
                      outputs=[self.mass], device=d)
            self.mass_np = self.mass.numpy()
            if not self.static and np.any(self.mass_np <= 0):
                i = int(np.argmin(self.mass_np))
                raise SceneError(f"scene '{scene.name}': node {i} has no mass ({self.mass_np[i]} kg) in a "
                                 "dynamic scene; give every element a density > 0")

        mask = np.ones((self.num_nodes, 3))
        for fx in scene.fixtures:
            info = self.body_info(fx.body.name)
            sel = np.flatnonzero(fx.region(fx.body.mesh.nodes)) + info.node_start
            for a in fx.axes:
                mask[sel, "xyz".index(a)] = 0.0
        self.mask_np = mask
        self.mask = wp.array(mask, dtype=wp.vec3d, device=d)
        self.num_fixed_dofs = int((mask == 0).sum())

        self.load_weights = []  # (load, global node ids, weights) of every load
        for load in scene.loads:
            info = self.body_info(load.body.name)
            w = load_weights(load)
            ids = np.flatnonzero(w)
            self.load_weights.append((load, ids + info.node_start, w[ids]))
        self.time_dependent_loads = [lw for lw in self.load_weights if callable(lw[0].total)]
        f_const = np.zeros((self.num_nodes, 3))
        if self.has_gravity:
            f_const += self.mass_np[:, None] * scene.gravity[None, :]
        for load, ids, w in self.load_weights:
            if not callable(load.total):
                f_const[ids] += w[:, None] * load.total[None, :]
        has_const = self.has_gravity or len(self.load_weights) > len(self.time_dependent_loads)
        self.f_const_np = f_const
        self.f_const = wp.array(f_const, dtype=wp.vec3d, device=d) if has_const else None

        self.probe_names = [p.name for p in scene.probes]
        self.probe_nodes = self.probe_weights = None
        if scene.probes:
            ids, w = locate(self.rest_np, self.tets_np, np.array([p.point for p in scene.probes]), self.probe_names)
            self.probe_nodes = wp.array(ids, dtype=wp.vec4i, device=d)
            self.probe_weights = wp.array(w, dtype=wp.vec4d, device=d)

    @property
    def num_dofs(self) -> int:
        """Number of degrees of freedom, fixed ones included (3 per node)."""
        return 3 * self.num_nodes

    def body_info(self, name: str) -> BodyInfo:
        for b in self.bodies:
            if b.name == name:
                return b
        raise SceneError(f"model: no body named '{name}'")

    def state(self) -> State:
        """A new state at rest (positions = rest positions, zero velocity)."""
        return State(wp.clone(self.rest), wp.zeros(self.num_nodes, dtype=wp.vec3d, device=self.device))

    def external_forces(self, t: float) -> np.ndarray | None:
        """Time-dependent part of the external forces at time ``t`` (s), ``(n, 3)`` N, or None."""
        if not self.time_dependent_loads:
            return None
        f = np.zeros((self.num_nodes, 3))
        for load, ids, w in self.time_dependent_loads:
            total = np.asarray(load.total(t), dtype=float)
            if total.shape != (3,) or not np.all(np.isfinite(total)):
                raise SceneError(f"load '{load.name}': total({t:g}) must return 3 finite numbers, got {total!r}")
            f[ids] += w[:, None] * total[None, :]
        return f
