"""Model: the device arrays of one or more worlds, built once by :func:`finalize`.

A world is one scene: a robot or a design variant. Worlds may differ in everything (mesh,
material, fixtures, actuators, effectors, loads); they share the time step, whether the step is
quasi-static, and the Rayleigh damping, because they advance together. Arrays are concatenated
over worlds; ``world_node_start`` and ``world_elem_start`` (length worlds + 1) say where each
world's nodes and elements sit, ``node_world`` and ``elem_world`` give the world of each.
Element node ids are global, so element kernels need no world bookkeeping.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels.elastic import geometry
from warpsoft.kernels.elastic.quadratic import vec10i

from .errors import SceneError, call_user
from .launch import launch
from .mapping import locate
from .processes import in_threads
from .scene import Scene, load_weights
from .state import State


@dataclass
class BodyInfo:
    """Where a body's nodes and elements sit in the model's arrays."""

    name: str
    world: int
    node_start: int
    node_count: int
    elem_start: int
    elem_count: int
    surface: np.ndarray  # (k, 3) global node ids, outward triangles
    element: str = "corotational"  # its element model (warpsoft/elastic)
    quadratic: np.ndarray | None = None  # (k, 10) its 10-node elements, body-local node ids (quadratic only)


@dataclass
class ElementGroup:
    """The elements of one element model over every world (``kind``, a key of
    :data:`warpsoft.elastic.ELEMENT_MODELS`). Device arrays, ``(count,)``: ``elems`` (vec4i or
    vec10i, global node ids), ``dm_inv`` (mat33d, 1/m) and ``volume`` (float64, m^3) of the corner
    tetrahedron, ``mu`` and ``lam`` (float64, Pa), ``world`` (int32). ``elems_np``: ``elems`` on
    the host, ``(count, k)``; ``start``: where the group's rotations begin in the array of all."""

    kind: str
    elems: wp.array
    elems_np: np.ndarray
    dm_inv: wp.array
    volume: wp.array
    mu: wp.array
    lam: wp.array
    world: wp.array
    start: int
    count: int


def finalize(scenes: Scene | Sequence[Scene], device: str | None = None) -> Model:
    """Build the device-side :class:`Model` of one scene, or of several (one world each)."""
    return Model(scenes, device)


class Model:
    """Everything fixed over a run, on one device, for every world.

    Arrays (device): ``rest`` (n vec3d, m), ``tets`` (m vec4i, global node ids), ``dm_inv``
    (m mat33d, 1/m), ``volume`` (m float64, m^3), ``mu``/``lam`` (m float64, Pa), ``mass`` (n
    float64, kg; only when some world is dynamic or under gravity, else None), ``mask`` (n vec3d,
    1 = free, 0 = fixed), ``f_const`` (n vec3d, N: gravity and constant loads; None when there are
    none), ``node_world`` (n int32), ``elem_world`` (m int32), probe ``probe_nodes`` /
    ``probe_weights``. Host: ``world_node_start``, ``world_elem_start`` (worlds + 1), the same
    arrays with an ``_np`` suffix; ``driven``, the fixed regions a motion carries
    (``warpsoft/drive.py``); ``rigid`` the rigid bodies ``(world, RigidBody)`` in model order.
    Rigid bodies (device, ``(bodies,)``, only when some world has them): ``rigid_world``,
    ``rigid_inv_mass`` (1/kg), ``rigid_inertia`` (mat33d, kg m^2, the body's frame),
    ``rigid_gravity`` (m/s^2). A body of 10-node elements puts in ``tets`` the eight tetrahedra
    that split each element (for mappings, masses, surfaces and contacts); the elastic forces
    come from ``element_groups`` (:class:`ElementGroup`, one per element model in use).
    """

    def __init__(self, scenes: Scene | Sequence[Scene], device: str | None = None):
        self.scenes = [scenes] if isinstance(scenes, Scene) else list(scenes)
        if not self.scenes or not all(isinstance(s, Scene) for s in self.scenes):
            raise SceneError(f"finalize: expected a Scene or a non-empty list of Scenes, got {scenes!r:.80}")
        for s in self.scenes:
            s.validate()
        first = self.scenes[0]
        for w, s in enumerate(self.scenes[1:], 1):
            for attr in ("dt", "static", "integrator", "rayleigh_mass", "rayleigh_stiffness"):
                if getattr(s, attr) != getattr(first, attr):
                    raise SceneError(f"finalize: world {w} (scene '{s.name}') has {attr} = {getattr(s, attr)!r}, "
                                     f"world 0 (scene '{first.name}') {getattr(first, attr)!r}: worlds step "
                                     "together and must share it")
        self.num_worlds = len(self.scenes)
        self.device = wp.get_device(device)
        self.static, self.dt, self.integrator = first.static, first.dt, first.integrator
        self.rayleigh_mass, self.rayleigh_stiffness = first.rayleigh_mass, first.rayleigh_stiffness

        nodes, tets, mu, lam, rho, self.bodies = [], [], [], [], [], []
        node_starts, elem_starts = [0], [0]
        meshes = {id(b.mesh): b.mesh for scene in self.scenes for b in scene.bodies}
        in_threads(lambda mesh: mesh.surface(), list(meshes.values()))  # (found once, kept by each mesh)
        n0 = e0 = 0
        for w, scene in enumerate(self.scenes):
            for body in scene.bodies:
                m = body.mesh
                nodes.append(m.nodes)
                tets.append(m.tets + n0)
                bm, bl, br = body.element_materials()
                mu.append(bm)
                lam.append(bl)
                rho.append(br)
                self.bodies.append(BodyInfo(body.name, w, n0, m.num_nodes, e0, m.num_elements, m.surface() + n0,
                                            body.element, m.quadratic))
                n0 += m.num_nodes
                e0 += m.num_elements
            node_starts.append(n0)
            elem_starts.append(e0)
        self._body_at = {(b.name, b.world): b for b in self.bodies}  # (name, world) -> its BodyInfo
        self.world_node_start = np.array(node_starts, dtype=np.int32)
        self.world_elem_start = np.array(elem_starts, dtype=np.int32)
        self.rest_np = np.concatenate(nodes)
        self.tets_np = np.concatenate(tets).astype(np.int32)
        self.num_nodes, self.num_elements = len(self.rest_np), len(self.tets_np)
        self.node_world_np = np.repeat(np.arange(self.num_worlds, dtype=np.int32), np.diff(self.world_node_start))
        self.elem_world_np = np.repeat(np.arange(self.num_worlds, dtype=np.int32), np.diff(self.world_elem_start))

        d = self.device
        self.rest = wp.array(self.rest_np, dtype=wp.vec3d, device=d)
        self.tets = wp.array(self.tets_np, dtype=wp.vec4i, device=d)
        self.node_world = wp.array(self.node_world_np, dtype=wp.int32, device=d)
        self.elem_world = wp.array(self.elem_world_np, dtype=wp.int32, device=d)
        self.mu = wp.array(np.concatenate(mu), dtype=wp.float64, device=d)
        self.lam = wp.array(np.concatenate(lam), dtype=wp.float64, device=d)
        mu_np, lam_np = np.concatenate(mu), np.concatenate(lam)
        self.poisson_np = lam_np / (2.0 * (lam_np + mu_np))  # per element, from the Lame parameters
        self.dm_inv = wp.zeros(self.num_elements, dtype=wp.mat33d, device=d)
        self.volume = wp.zeros(self.num_elements, dtype=wp.float64, device=d)
        launch(geometry.tet_rest_shape, self.num_elements, inputs=[self.rest, self.tets],
               outputs=[self.dm_inv, self.volume], device=d)
        self.element_groups = self._element_groups()

        # gravity per node: each world its own
        g = np.array([s.gravity for s in self.scenes])[self.node_world_np]  # (n, 3) m/s^2
        self.has_gravity = bool(np.any(g != 0.0))
        self.mass = None
        if not self.static or self.has_gravity:  # mass exists whenever something needs it
            density = wp.array(np.concatenate(rho), dtype=wp.float64, device=d)
            self.mass = wp.zeros(self.num_nodes, dtype=wp.float64, device=d)
            launch(geometry.lumped_mass, self.num_elements, inputs=[self.tets, self.volume, density],
                   outputs=[self.mass], device=d)
            self.mass_np = self.mass.numpy()
            if not self.static and np.any(self.mass_np <= 0):
                i = int(np.argmin(self.mass_np))
                w = int(self.node_world_np[i])
                raise SceneError(f"scene '{self.scenes[w].name}': node {i - node_starts[w]} has no mass "
                                 f"({self.mass_np[i]} kg) in a dynamic scene; give every element a density > 0")

        mask = np.ones((self.num_nodes, 3))
        self.load_weights = []  # (load, global node ids, weights) of every load
        self.driven = []  # fixed regions carried by a motion: (label, motion, global node ids, (k, 3) 1 = driven axis)
        driver = np.full(self.num_nodes, -1)
        for w, scene in enumerate(self.scenes):
            for fx in scene.fixtures:
                info = self.body_info(fx.body.name, w)
                sel = np.flatnonzero(fx.region(fx.body.mesh.nodes)) + info.node_start
                for a in fx.axes:
                    mask[sel, "xyz".index(a)] = 0.0
                if fx.motion is not None:
                    label = f"scene '{scene.name}': body '{fx.body.name}': fixed region {fx.region!r}"
                    twice = sel[driver[sel] >= 0]
                    if len(twice):
                        raise SceneError(f"{label}: node {int(twice[0]) - info.node_start} is also carried by "
                                         f"{self.driven[driver[twice[0]]][0]}; a node follows one motion")
                    driver[sel] = len(self.driven)
                    axes = np.array([[float(a in fx.axes) for a in "xyz"]] * len(sel)).reshape(-1, 3)
                    self.driven.append((label, fx.motion, sel, axes))
            for load in scene.loads:
                wts = load_weights(load)
                ids = np.flatnonzero(wts)
                self.load_weights.append((load, ids + self.body_info(load.body.name, w).node_start, wts[ids]))
        self.mask_np = mask
        if self.static:
            for b in self.bodies:
                check_held(self.scenes[b.world].name, b, self.rest_np, mask)
        self.mask = wp.array(mask, dtype=wp.vec3d, device=d)
        self.num_fixed_dofs = int((mask == 0).sum())

        self.time_dependent_loads = [lw for lw in self.load_weights if callable(lw[0].total)]
        f_const = np.zeros((self.num_nodes, 3))
        if self.has_gravity:
            f_const += self.mass_np[:, None] * g
        for load, ids, wts in self.load_weights:
            if not callable(load.total):
                f_const[ids] += wts[:, None] * load.total[None, :]
        has_const = self.has_gravity or len(self.load_weights) > len(self.time_dependent_loads)
        self.f_const_np = f_const
        self.f_const = wp.array(f_const, dtype=wp.vec3d, device=d) if has_const else None

        # rigid bodies, world by world: mass properties and the state at t = 0
        self.rigid = [(w, rb) for w, scene in enumerate(self.scenes) for rb in scene.rigid_bodies]
        self.num_rigid = len(self.rigid)
        if self.rigid:
            f64 = lambda v, dtype: wp.array(np.array(v, dtype=float), dtype=dtype, device=d)  # noqa: E731
            self.rigid_world_np = np.array([w for w, _ in self.rigid], dtype=np.int32)
            self.rigid_world = wp.array(self.rigid_world_np, dtype=wp.int32, device=d)
            self.rigid_inv_mass = f64([1.0 / rb.mass for _, rb in self.rigid], wp.float64)
            self.rigid_inertia = f64([rb.inertia for _, rb in self.rigid], wp.mat33d)  # its own frame
            self.rigid_gravity = f64([self.scenes[w].gravity for w, _ in self.rigid], wp.vec3d)

        # probes: located in their own world's elements
        self.probe_names, self.probe_world, ids, wts = [], [], [], []
        probed = [w for w, scene in enumerate(self.scenes) if scene.probes]

        def probes(w: int) -> tuple[np.ndarray, np.ndarray]:
            lo, hi = self.world_elem_start[w], self.world_elem_start[w + 1]
            points = np.array([p.point for p in self.scenes[w].probes])
            return locate(self.rest_np, self.tets_np[lo:hi], points, [p.name for p in self.scenes[w].probes])

        for w, (i_, w_) in zip(probed, in_threads(probes, probed), strict=True):
            names = [p.name for p in self.scenes[w].probes]
            self.probe_names += names
            self.probe_world += [w] * len(names)
            ids.append(i_)
            wts.append(w_)
        self.probe_nodes = self.probe_weights = None
        if ids:
            self.probe_nodes = wp.array(np.concatenate(ids), dtype=wp.vec4i, device=d)
            self.probe_weights = wp.array(np.concatenate(wts), dtype=wp.vec4d, device=d)

    def _element_groups(self) -> list[ElementGroup]:
        """The elastic elements by element model: the tetrahedra of the corotational bodies (the
        model's own arrays when every body is), then those of the Neo-Hookean ones, then the
        10-node elements of the quadratic ones (each over the eight tetrahedra that split it)."""
        d = self.device
        if all(b.element == "corotational" for b in self.bodies):
            return [ElementGroup("corotational", self.tets, self.tets_np, self.dm_inv, self.volume, self.mu, self.lam,
                                 self.elem_world, 0, self.num_elements)]
        groups, start = [], 0
        mu_np, lam_np, volume_np, dm_inv_np = (a.numpy() for a in (self.mu, self.lam, self.volume, self.dm_inv))
        for kind in ("corotational", "neohookean"):  # linear tetrahedra: the model's, by index
            bodies = [b for b in self.bodies if b.element == kind]
            if not bodies:
                continue
            idx = np.concatenate([np.arange(b.elem_start, b.elem_start + b.elem_count) for b in bodies])
            volume, mu, lam = (wp.array(a[idx], dtype=wp.float64, device=d) for a in (volume_np, mu_np, lam_np))
            groups.append(ElementGroup(kind, wp.array(self.tets_np[idx], dtype=wp.vec4i, device=d),
                                       self.tets_np[idx], wp.array(dm_inv_np[idx], dtype=wp.mat33d, device=d),
                                       volume, mu, lam, wp.array(self.elem_world_np[idx], dtype=wp.int32, device=d),
                                       start, len(idx)))
            start += len(idx)
        quadratic = [b for b in self.bodies if b.element == "quadratic"]
        if not quadratic:
            return groups
        elems, first = [], []
        for b in quadratic:
            elems.append(b.quadratic.astype(np.int32) + b.node_start)
            first.append(b.elem_start + 8 * np.arange(len(b.quadratic)))  # each element's first tetrahedron
        elems_np, first = np.concatenate(elems), np.concatenate(first)
        corners = wp.array(elems_np[:, :4], dtype=wp.vec4i, device=d)
        dm_inv = wp.zeros(len(elems_np), dtype=wp.mat33d, device=d)
        volume = wp.zeros(len(elems_np), dtype=wp.float64, device=d)
        launch(geometry.tet_rest_shape, len(elems_np), inputs=[self.rest, corners], outputs=[dm_inv, volume], device=d)
        groups.append(ElementGroup("quadratic", wp.array(elems_np, dtype=vec10i, device=d), elems_np, dm_inv, volume,
                                   wp.array(mu_np[first], dtype=wp.float64, device=d),
                                   wp.array(lam_np[first], dtype=wp.float64, device=d),
                                   wp.array(self.elem_world_np[first], dtype=wp.int32, device=d), start, len(elems_np)))
        return groups

    @property
    def scene(self) -> Scene:
        """The scene of a one-world model (a model of several worlds has ``scenes``)."""
        if self.num_worlds != 1:
            raise SceneError(f"model: it has {self.num_worlds} worlds; use model.scenes[world]")
        return self.scenes[0]

    @property
    def num_dofs(self) -> int:
        """Number of degrees of freedom, fixed ones included (3 per node)."""
        return 3 * self.num_nodes

    def world_nodes(self, world: int) -> slice:
        """The nodes of ``world`` in the concatenated arrays."""
        return slice(int(self.world_node_start[world]), int(self.world_node_start[world + 1]))

    def body_info(self, name: str, world: int = 0) -> BodyInfo:
        if (name, world) in self._body_at:
            return self._body_at[name, world]
        raise SceneError(f"model: no body named '{name}' in world {world}")

    def state(self) -> State:
        """A new state at rest (positions = rest positions, zero velocity)."""
        d = self.device
        state = State(wp.clone(self.rest), wp.zeros(self.num_nodes, dtype=wp.vec3d, device=d))
        if self.rigid:
            bodies = [rb for _, rb in self.rigid]
            state.body_p = wp.array(np.array([rb.center for rb in bodies]), dtype=wp.vec3d, device=d)
            state.body_r = wp.array(np.tile([0.0, 0.0, 0.0, 1.0], (len(bodies), 1)), dtype=wp.quatd, device=d)
            state.body_v = wp.array(np.array([rb.velocity for rb in bodies]), dtype=wp.vec3d, device=d)
            state.body_w = wp.array(np.array([rb.angular_velocity for rb in bodies]), dtype=wp.vec3d, device=d)
        return state

    def external_forces(self, t: float) -> np.ndarray | None:
        """Time-dependent part of the external forces at time ``t`` (s), ``(n, 3)`` N, or None."""
        if not self.time_dependent_loads:
            return None
        f = np.zeros((self.num_nodes, 3))
        for load, ids, w in self.time_dependent_loads:
            total = np.asarray(call_user(load.total, t, f"load '{load.name}': its force function"), dtype=float)
            if total.shape != (3,) or not np.all(np.isfinite(total)):
                raise SceneError(f"load '{load.name}': total({t:g}) must return 3 finite numbers, got {total!r}")
            f[ids] += w[:, None] * total[None, :]
        return f


def check_held(scene: str, body: BodyInfo, rest: np.ndarray, mask: np.ndarray) -> None:
    """A quasi-static body must be held against all six rigid-body motions (K alone is singular
    otherwise: v1 returned tips at 5.8e8 m). The fixed DOFs' rows of the rigid-motion basis
    (three translations, three rotations about the body's centre) must have rank 6."""
    ids = np.arange(body.node_start, body.node_start + body.node_count)
    r = rest[ids] - rest[ids].mean(axis=0)
    r = r / max(float(np.abs(r).max()), 1e-300)  # rotations and translations on one scale
    node, axis = np.nonzero(mask[ids] == 0.0)
    if len(node):
        basis = np.zeros((len(node), 6))
        basis[np.arange(len(node)), axis] = 1.0  # translations
        x, y, z = r[node].T
        rot = np.stack([np.stack([0 * x, -z, y], 1), np.stack([z, 0 * x, -x], 1), np.stack([-y, x, 0 * x], 1)], 2)
        basis[:, 3:] = rot[np.arange(len(node)), axis]  # (e_k x r) along the fixed axis
        rank = int(np.linalg.matrix_rank(basis, tol=1e-8))
    else:
        rank = 0
    if rank < 6:
        held = len(np.unique(node))
        raise SceneError(f"scene '{scene}' is quasi-static and body '{body.name}' is held at {held} node(s): "
                         f"{6 - rank} rigid-body motion(s) stay free, so its stiffness is singular; fix at least "
                         "three nodes that are not on one line (e.g. a ws.OnPlane region), or make the scene dynamic")

