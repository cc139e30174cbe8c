"""The Scene: what a user writes. Mutable, CPU-side, validated with clear errors.

A scene lists bodies (mesh + material), fixed regions, external loads, probe points,
gravity, damping and the time discretization. Only what it declares is simulated.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from .cable import Cable
from .cavity import Cavity
from .effector import Effector
from .material import Material
from .mesh import TetMesh
from .obstacles import Obstacle, ObstacleEntry, SelfContact, pose_of
from .regions import Region, as_region
from .rigid import Attachment, RigidBody, make_rigid
from .surface import area_shares

Vec3 = tuple[float, float, float]
ELEMENTS = ("corotational", "quadratic", "neohookean")  # the element models a body may choose (warpsoft/elastic)


def _finite(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SceneError(f"{what} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise SceneError(f"{what} must be finite, got {value!r}")
    return float(value)


def _vec3(value, what: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SceneError(f"{what} must be 3 numbers, got {value!r}") from None
    if a.shape != (3,):
        raise SceneError(f"{what} must be 3 numbers, got {value!r}")
    if not np.all(np.isfinite(a)):
        raise SceneError(f"{what} must be finite, got {a.tolist()}")
    return a


@dataclass
class Body:
    """A deformable body of the scene (do not build directly: use :meth:`Scene.add_body`)."""

    name: str
    mesh: TetMesh
    material: Material
    total_mass: float | None = None
    overrides: list[tuple[Region, Material]] = field(default_factory=list)
    element: str = "corotational"

    def set_material(self, region: Region, material: Material) -> Body:
        """Give the elements whose centroid lies in ``region`` another material."""
        if not isinstance(material, Material):
            raise SceneError(f"body '{self.name}': set_material expects a Material, got {material!r}")
        region = as_region(region, f"body '{self.name}': set_material's region")
        if not np.any(region(self._centroids())):
            raise SceneError(f"body '{self.name}': set_material region {region!r} contains no element centroid")
        self.overrides.append((region, material))
        return self

    def _centroids(self) -> np.ndarray:
        """Each tetrahedron's centroid ``(m, 3)`` (m); in a quadratic mesh, its element's."""
        if self.mesh.quadratic is not None:
            return np.repeat(self.mesh.nodes[self.mesh.quadratic[:, :4]].mean(axis=1), 8, axis=0)
        return self.mesh.nodes[self.mesh.tets].mean(axis=1)

    def element_materials(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per tetrahedron of the mesh ``(mu, lambda, density)`` in Pa, Pa, kg/m^3, each shape
        ``(m,)``. In a quadratic mesh, the eight of an element share its material, chosen by the
        element's centroid."""
        mats = [self.material] + [mat for _, mat in self.overrides]
        which = np.zeros(self.mesh.num_elements, dtype=np.int64)  # each element's material, in mats
        if self.overrides:
            centroids = self._centroids()
            for k, (region, _) in enumerate(self.overrides, 1):  # a later override wins
                which[np.asarray(region(centroids), dtype=bool)] = k
        table = np.array([(*mt.lame, mt.density) for mt in mats])  # (materials, 3)
        mu, lam, rho = table[which].T
        return mu.copy(), lam.copy(), rho.copy()


@dataclass
class Fixture:
    """Nodes of ``body`` in ``region`` held along ``axes``: at their rest position, or carried by
    ``motion`` (a kinematic frame: ``t -> translation`` or ``t -> (rotation, translation)``, the
    rigid motion of the rest positions at time ``t``)."""

    body: Body
    region: Region
    axes: str = "xyz"
    motion: Callable[[float], object] | None = None


@dataclass
class Load:
    """A total external force (N) spread over the body's surface triangles in ``region`` in
    proportion to area; ``total`` is a 3-vector or a function ``t -> 3-vector`` of time (s)."""

    name: str
    body: Body
    region: Region
    total: np.ndarray | Callable[[float], Vec3]


@dataclass
class Probe:
    """A named material point (m, rest configuration) whose position is recorded."""

    name: str
    point: np.ndarray


INTEGRATORS = ("implicit_euler", "trapezoidal")


class Scene:
    """A soft-robot scene.

    Args:
        name: scene label (report, USD).
        gravity: acceleration (m/s^2), 3 numbers; zero means no gravity pass.
        dt: time step (s). In a quasi-static scene it only advances time for loads that
            depend on time.
        static: quasi-static (no mass, no damping) instead of implicit dynamics.
        steps: default number of steps for ``warpsoft run``.
        integrator: how a dynamic step integrates, one of :data:`INTEGRATORS`:
            ``"implicit_euler"`` (forces and velocities at the step's end: unconditionally
            stable, and it dissipates the energy of motions the step does not resolve) or
            ``"trapezoidal"`` (Newmark's average acceleration: the mean of the forces and of the
            velocities at both ends; second order, it keeps the energy of an undamped body, and
            it keeps unresolved high frequencies ringing too). Ignored by quasi-static scenes.
    """

    def __init__(self, name: str = "scene", gravity: Vec3 = (0.0, 0.0, 0.0), dt: float = 0.01,
                 static: bool = False, steps: int = 100, integrator: str = "implicit_euler"):
        self.name = str(name)
        self.gravity = _vec3(gravity, f"scene '{name}': gravity")
        self.dt = _finite(dt, f"scene '{name}': dt")
        if self.dt <= 0:
            raise SceneError(f"scene '{name}': dt must be > 0 s, got {dt!r}")
        self.static = bool(static)
        if int(steps) < 1:
            raise SceneError(f"scene '{name}': steps must be >= 1, got {steps!r}")
        self.steps = int(steps)
        if integrator not in INTEGRATORS:
            raise SceneError(f"scene '{name}': integrator must be one of {', '.join(INTEGRATORS)}, got {integrator!r}")
        self.integrator = integrator
        self.bodies: list[Body] = []
        self.fixtures: list[Fixture] = []
        self.loads: list[Load] = []
        self.probes: list[Probe] = []
        self.cables: list[Cable] = []
        self.cavities: list[Cavity] = []
        self.effectors: list[Effector] = []
        self.obstacles: list[ObstacleEntry] = []
        self.rigid_bodies: list[RigidBody] = []
        self.attachments: list[Attachment] = []
        self.self_contacts: list[SelfContact] = []
        self.contact_capacity = 64  # contact rows per world (set_contacts)
        self.rayleigh_mass = 0.0
        self.rayleigh_stiffness = 0.0
        self.inverse = False
        self.inverse_epsilon = 1e-4
        self.params: dict = {}

    # ---- components -------------------------------------------------------------------
    def add_body(self, name: str, mesh: TetMesh, material: Material, total_mass: float | None = None,
                 element: str = "quadratic") -> Body:
        """Add a deformable body. ``total_mass`` (kg), if given, sets a uniform density
        ``total_mass / volume`` in place of the material's. ``element``: "quadratic" (the default:
        10-node tetrahedra on the same mesh, a node added at each edge's midpoint; they do not lock
        in bending or near incompressibility, see ``warpsoft/elastic/quadratic.py``),
        "corotational" (linear tetrahedra: 5-6x fewer DOFs, but too stiff where a body bends, the
        more so as nu nears 0.5: a cantilever at nu 0.45 by 16-20 %) or "neohookean" (linear
        tetrahedra of stable Neo-Hookean material: the same at small strain, hyperelastic at large
        strain and robust to inversion, see ``warpsoft/elastic/neohookean.py``)."""
        if any(b.name == name for b in self.bodies):
            raise SceneError(f"scene '{self.name}': a body named '{name}' exists already")
        if not isinstance(mesh, TetMesh):
            raise SceneError(f"body '{name}': mesh must be a TetMesh, got {type(mesh).__name__}")
        if not isinstance(material, Material):
            raise SceneError(f"body '{name}': material must be a Material, got {material!r}")
        if element not in ELEMENTS:
            raise SceneError(f"body '{name}': element must be one of {', '.join(map(repr, ELEMENTS))}, got {element!r}")
        if element == "quadratic":
            mesh = mesh.quadratic_refined()
        elif mesh.quadratic is not None:
            raise SceneError(f"body '{name}': its mesh has quadratic elements; give element='quadratic'")
        if total_mass is not None:
            total_mass = _finite(total_mass, f"body '{name}': total_mass")
            if total_mass <= 0:
                raise SceneError(f"body '{name}': total_mass must be > 0 kg, got {total_mass!r}")
            material = Material(material.young_modulus, material.poisson_ratio, total_mass / mesh.volume)
        body = Body(name, mesh, material, total_mass, element=element)
        self.bodies.append(body)
        return body

    def fix(self, body: Body, region: Region, axes: str = "xyz",
            motion: Callable[[float], object] | None = None) -> Fixture:
        """Hold the nodes of ``body`` in ``region`` along ``axes`` (any of "x", "y", "z").

        ``motion``: a kinematic frame that carries them (a moving base, a gripper's palm): a
        schedule ``t -> translation`` (m) or ``t -> (rotation, translation)`` applied to their
        rest positions at time ``t`` (s) (e.g. ``ws.waypoints``); each step moves them, along
        ``axes``, to where the frame is at the step's end."""
        self._own(body, "fix")
        region = as_region(region, f"body '{body.name}': fixed region")
        if not axes or any(a not in "xyz" for a in axes) or len(set(axes)) != len(axes):
            raise SceneError(f"body '{body.name}': fix axes must be a subset of 'xyz', got {axes!r}")
        if not np.any(region(body.mesh.nodes)):
            raise SceneError(f"body '{body.name}': fixed region {region!r} selects no node")
        if motion is not None:
            if not callable(motion):
                raise SceneError(f"body '{body.name}': fixed region motion must be a function of the time t (s), "
                                 f"got {motion!r}")
            pose_of(motion, 0.0, f"body '{body.name}': fixed region motion")  # checked now, not at the first step
        f = Fixture(body, region, axes, motion)
        self.fixtures.append(f)
        return f

    def add_force(self, body: Body, region: Region, total, name: str | None = None) -> Load:
        """Spread a total force (N) over the surface of ``body`` inside ``region``."""
        self._own(body, "add_force")
        name = name or f"load{len(self.loads)}"
        region = as_region(region, f"load '{name}': region")
        if not callable(total):
            total = _vec3(total, f"load '{name}': total force")
        load = Load(name, body, region, total)
        load_weights(load)  # validates the region now, not at the first step
        self.loads.append(load)
        return load

    def add_probe(self, name: str, point: Vec3) -> Probe:
        """Record the position of the material point at ``point`` (m, rest configuration)."""
        if any(p.name == name for p in self.probes):
            raise SceneError(f"scene '{self.name}': a probe named '{name}' exists already")
        probe = Probe(str(name), _vec3(point, f"probe '{name}': point"))
        self.probes.append(probe)
        return probe

    def add_cable(self, name: str, body: Body, points, pull_point, mode: str = "displacement",
                  value: float | Callable[[float], float] = 0.0, min_force: float = 0.0, max_force: float = math.inf,
                  min_displacement: float = -math.inf, max_displacement: float = math.inf,
                  max_step: float = math.inf, pull_motion: Callable[[float], object] | None = None,
                  anchor_radius: float = 0.0) -> Cable:
        """A cable pulled from the fixed ``pull_point`` (m) through ``points`` ``(k, 3)`` (m) of ``body``.

        ``mode="displacement"``: ``value`` is the shortening (m); ``mode="force"``: the tension
        (N). Bounds: tension in [min_force >= 0, max_force] N, shortening in
        [min_displacement, max_displacement] m, at most ``max_step`` m of change per step.
        ``pull_motion``: the pull point rides a kinematic frame (its motor on a moving base or
        palm): ``t -> translation`` or ``t -> (rotation, translation)``, as ``fix(..., motion=)``.
        ``anchor_radius`` (m): the cable is fastened over the material within this radius of its
        last point (a knot, a washer): the pull is spread over it and the fastening's motion is
        that material's mean motion, which converges as the mesh is refined. 0 (SOFA's point
        fastening): the last point alone, whose motion under a given tension grows with every
        refinement (a point load in a solid).
        """
        self._own(body, "add_cable")
        self._new_row_name(name)
        if pull_motion is not None:
            if not callable(pull_motion):
                raise SceneError(f"cable '{name}': pull_motion must be a function of the time t (s), got "
                                 f"{pull_motion!r}")
            pose_of(pull_motion, 0.0, f"cable '{name}': pull_motion")
        cable = Cable(name, mode, value, min_force, max_force, min_displacement, max_displacement, max_step,
                      body=body, points=points, pull_point=pull_point, pull_motion=pull_motion,
                      anchor_radius=anchor_radius)
        self.cables.append(cable)
        return cable

    def add_cavity(self, name: str, body: Body, region: Region | None = None, triangles=None,
                   mode: str = "pressure", value: float | Callable[[float], float] = 0.0, min_pressure: float = 0.0,
                   max_pressure: float = math.inf, min_volume_growth: float = -math.inf,
                   max_volume_growth: float = math.inf, max_step: float = math.inf,
                   symmetry_planes: list | None = None) -> Cavity:
        """A pneumatic cavity: the closed void of ``body`` whose boundary lies in ``region``.

        ``mode="pressure"``: ``value`` is the pressure (Pa); ``mode="volume"``: the volume
        growth (m^3). ``min_pressure < 0`` allows vacuum. In a model cut by symmetry planes
        (``ws.OnPlane`` list) the cavity surface may be open along them.
        """
        self._own(body, "add_cavity")
        self._new_row_name(name)
        modes = {"pressure": "force", "volume": "displacement"}
        if mode not in modes:
            raise SceneError(f"cavity '{name}': mode must be 'pressure' or 'volume', got {mode!r}")
        if (region is None) == (triangles is None):
            raise SceneError(f"cavity '{name}': give either a region or triangles")
        if region is not None:
            region = as_region(region, f"cavity '{name}': region")
        cavity = Cavity(name, modes[mode], value, min_pressure, max_pressure, min_volume_growth, max_volume_growth,
                        max_step, body=body, region=region, triangles=triangles, symmetry_planes=symmetry_planes)
        cavity.surface()  # validates now: closed and oriented
        self.cavities.append(cavity)
        return cavity

    def add_effector(self, name: str, point: Vec3, target=None, axes: str = "xyz", weight: float = 1.0) -> Effector:
        """A point (m, rest configuration) to place: ``target`` is a 3-vector, a function of time
        ``t -> 3-vector`` or None (its rest position); ``axes`` selects the controlled axes."""
        self._new_row_name(name)
        eff = Effector(name, point, target, axes, weight)
        self.effectors.append(eff)
        return eff

    def use_inverse_model(self, epsilon: float = 1e-4) -> None:
        """Resolve the actuators by the inverse model: each step, the actuation (within its
        bounds) that brings the effectors closest to their targets. ``epsilon`` weighs the
        actuation energy relative to the task (see ``warpsoft.inverse``); the actuators' own
        input values are not used."""
        epsilon = _finite(epsilon, f"scene '{self.name}': inverse epsilon")
        if epsilon < 0:
            raise SceneError(f"scene '{self.name}': inverse epsilon must be >= 0, got {epsilon}")
        self.inverse, self.inverse_epsilon = True, epsilon

    @property
    def actuators(self) -> list:
        """Cables then cavities: the order of the actuator rows."""
        return [*self.cables, *self.cavities]

    def _new_row_name(self, name: str) -> None:
        if any(r.name == name for r in [*self.cables, *self.cavities, *self.effectors]):
            raise SceneError(f"scene '{self.name}': an actuator or effector named '{name}' exists already")

    def set_damping(self, rayleigh_mass: float = 0.0, rayleigh_stiffness: float = 0.0) -> None:
        """Rayleigh damping ``D = rayleigh_mass M + rayleigh_stiffness K`` (1/s and s)."""
        a = _finite(rayleigh_mass, f"scene '{self.name}': rayleigh_mass")
        b = _finite(rayleigh_stiffness, f"scene '{self.name}': rayleigh_stiffness")
        if a < 0 or b < 0:
            raise SceneError(f"scene '{self.name}': Rayleigh coefficients must be >= 0, got ({a}, {b})")
        self.rayleigh_mass, self.rayleigh_stiffness = a, b

    def add_obstacle(self, name: str, shape: Obstacle, mu: float = 0.0, contact_distance: float | None = None,
                     motion: Callable[[float], object] | None = None) -> ObstacleEntry:
        """A rigid obstacle (``ws.obstacles.Floor``, ``Ball``, ``Box``, ``Capsule``, ``Cylinder``, ``Mesh``)
        that every body's surface nodes touch, with Coulomb friction ``mu`` (0: frictionless): a
        node closer than ``contact_distance`` (m; default a quarter of the body's mean surface
        edge) becomes a contact that keeps it out (and, with friction, holds it within the cone).

        ``motion``: a kinematic schedule ``t -> translation`` (m) or ``t -> (rotation, translation)``
        that carries the solid as declared to where it is at time ``t`` (s) (e.g. ``ws.waypoints``);
        friction then holds a node still relative to the moving surface."""
        if not isinstance(shape, Obstacle):
            raise SceneError(f"obstacle '{name}': expected one of ws.obstacles (Floor, Ball, Box, Capsule, "
                             f"Cylinder, Mesh), got {type(shape).__name__}")
        if any(o.name == name for o in self.obstacles + self.rigid_bodies):
            raise SceneError(f"scene '{self.name}': two obstacles are named '{name}' (obstacles and rigid "
                             "bodies share one set of names)")
        if contact_distance is not None:
            contact_distance = _finite(contact_distance, f"obstacle '{name}': contact_distance")
            if contact_distance <= 0:
                raise SceneError(f"obstacle '{name}': contact_distance must be > 0 m, got {contact_distance!r}")
        mu = _finite(mu, f"obstacle '{name}': friction coefficient mu")
        if mu < 0:
            raise SceneError(f"obstacle '{name}': friction coefficient mu must be >= 0, got {mu!r}")
        if motion is not None:
            if not callable(motion):
                raise SceneError(f"obstacle '{name}': motion must be a function of the time t (s), got {motion!r}")
            pose_of(motion, 0.0, f"obstacle '{name}': motion")  # checked now, not at the first step
        entry = ObstacleEntry(str(name), shape, mu, contact_distance, motion)
        self.obstacles.append(entry)
        return entry

    def add_rigid(self, name: str, shape: Obstacle, density: float | None = None, mass: float | None = None,
                  inertia=None, velocity: Vec3 = (0.0, 0.0, 0.0), angular_velocity: Vec3 = (0.0, 0.0, 0.0),
                  mu: float = 0.0, contact_distance: float | None = None, points=None) -> RigidBody:
        """A rigid body (6 DOF): the solid ``shape`` (``ws.obstacles.Ball``, ``Box``, ``Capsule``,
        ``Cylinder`` or a closed ``Mesh``) where it is at ``t = 0``, with a ``density`` (kg/m^3)
        or a ``mass`` (kg); ``inertia`` (kg m^2 about its centre of mass: 3 numbers or 3x3)
        overrides the solid's. It moves with the same implicit step under gravity and contacts:
        the bodies' surface nodes touch its solid, with Coulomb friction ``mu``; its ``points``
        ``(k, 3)`` (m, default: a box's corners, edge middles and face centres,
        points spread over other solids) touch the
        obstacles and the other rigid bodies. ``contact_distance`` (m) as for obstacles."""
        if any(r.name == name for r in self.rigid_bodies) or any(o.name == name for o in self.obstacles):
            raise SceneError(f"scene '{self.name}': a rigid body or obstacle named '{name}' exists already")
        body = make_rigid(name, shape, density, mass, inertia, velocity, angular_velocity, mu, contact_distance,
                          points)
        self.rigid_bodies.append(body)
        return body

    def attach(self, body: Body, region: Region, rigid: RigidBody, name: str | None = None) -> Attachment:
        """Hold the nodes of ``body`` in ``region`` by the rigid body ``rigid``: each keeps, in the
        rigid body's frame, the place it has at ``t = 0`` (a payload glued to an arm, a soft
        finger on a free hand). Each node is three bilateral constraint rows whose forces (N)
        act on the node and, opposite, on the rigid body: the two move as one there, and their
        contacts with each other are left out."""
        self._own(body, "attach")
        name = str(name or f"attachment{len(self.attachments)}")
        if not any(r is rigid for r in self.rigid_bodies):
            raise SceneError(f"attachment '{name}': rigid must be a rigid body of this scene (Scene.add_rigid), "
                             f"got {rigid!r:.60}")
        if any(a.name == name for a in self.attachments):
            raise SceneError(f"scene '{self.name}': an attachment named '{name}' exists already")
        region = as_region(region, f"attachment '{name}': region")
        nodes = np.flatnonzero(region(body.mesh.nodes))
        if not len(nodes):
            raise SceneError(f"attachment '{name}': region {region!r} selects no node of body '{body.name}'")
        for other in self.attachments:
            both = np.intersect1d(nodes, other.nodes) if other.body is body else []
            if len(both):
                raise SceneError(f"attachment '{name}': node {int(both[0])} of body '{body.name}' is held by "
                                 f"attachment '{other.name}' already; a node is held by one rigid body")
        a = Attachment(name, body, rigid, region, nodes)
        self.attachments.append(a)
        return a

    def add_self_contact(self, body: Body, mu: float = 0.0, contact_distance: float | None = None) -> SelfContact:
        """Let ``body`` touch itself: a surface node closer than ``contact_distance`` (m; default
        a quarter of the body's mean surface edge) to a surface triangle of the same body becomes
        a contact between the two (a normal row on four nodes, and two friction rows with
        Coulomb coefficient ``mu``): a bending actuator whose chambers meet, a tentacle that
        curls onto itself. Surfaces closer than twice that distance in the rest shape (a
        corner's two faces, a thin wall's two sides) are neighbours, never in contact."""
        self._own(body, "add_self_contact")
        name = f"{body.name} (self)"
        if any(s.body is body for s in self.self_contacts):
            raise SceneError(f"scene '{self.name}': body '{body.name}' already touches itself (add_self_contact "
                             "twice)")
        if contact_distance is not None:
            contact_distance = _finite(contact_distance, f"self-contact of '{body.name}': contact_distance")
            if contact_distance <= 0:
                raise SceneError(f"self-contact of '{body.name}': contact_distance must be > 0 m, got "
                                 f"{contact_distance!r}")
        mu = _finite(mu, f"self-contact of '{body.name}': friction coefficient mu")
        if mu < 0:
            raise SceneError(f"self-contact of '{body.name}': friction coefficient mu must be >= 0, got {mu!r}")
        entry = SelfContact(name, body, mu, contact_distance)
        self.self_contacts.append(entry)
        return entry

    @property
    def touches(self) -> bool:
        """Whether the scene has contacts to resolve: obstacles, rigid bodies or a self-contact."""
        return bool(self.obstacles or self.rigid_bodies or self.self_contacts)

    def set_contacts(self, capacity: int) -> None:
        """At most ``capacity`` contacts at once in this scene (default 64); more are reported
        as an overflow (the nearest are not chosen: raise the capacity)."""
        if isinstance(capacity, bool) or not isinstance(capacity, (int, np.integer)) or capacity < 1:
            raise SceneError(f"scene '{self.name}': contact capacity must be an integer >= 1, got {capacity!r}")
        self.contact_capacity = int(capacity)

    # ---- checks -----------------------------------------------------------------------
    def _own(self, body: Body, what: str) -> None:
        if not any(b is body for b in self.bodies):
            raise SceneError(f"scene '{self.name}': {what} got a body that is not in this scene ({body!r:.60})")

    def validate(self) -> None:
        """Check the scene as a whole (called when a simulator is built)."""
        if not self.bodies:
            raise SceneError(f"scene '{self.name}': it has no body")
        for body in self.bodies:
            if self.static:
                axes = "".join(f.axes for f in self.fixtures if f.body is body)
                missing = [a for a in "xyz" if a not in axes]
                if missing:
                    raise SceneError(
                        f"scene '{self.name}': quasi-static body '{body.name}' is free along {''.join(missing)} "
                        "(no fixed region holds that axis): its stiffness is singular"
                    )
            elif body.material.density <= 0 and not body.overrides:
                raise SceneError(f"scene '{self.name}': dynamic body '{body.name}' has density 0 (no mass)")
        if self.static and self.rigid_bodies:
            raise SceneError(f"scene '{self.name}': rigid body '{self.rigid_bodies[0].name}' needs a dynamic scene "
                             "(a quasi-static step has no inertia to hold a free solid): set static=False")
        if self.rigid_bodies and not self.static and self.integrator != "implicit_euler":
            raise SceneError(f"scene '{self.name}': rigid body '{self.rigid_bodies[0].name}' is integrated by "
                             f"implicit Euler only; integrator {self.integrator!r} takes soft bodies alone")
        for a in self.attachments:
            held = [f for f in self.fixtures if f.body is a.body and np.any(f.region(a.body.mesh.nodes[a.nodes]))]
            if held:
                raise SceneError(f"attachment '{a.name}': nodes of body '{a.body.name}' are also fixed (region "
                                 f"{held[0].region!r}); a node is held by a fixed region or a rigid body, not both")
        self._check_clear()
        if self.inverse:
            if not self.actuators:
                raise SceneError(f"scene '{self.name}': the inverse model needs at least one actuator")
            if not any(e.target is not None for e in self.effectors):
                raise SceneError(f"scene '{self.name}': the inverse model needs an effector with a target")

    def _check_clear(self) -> None:
        """No body of a dynamic scene starts inside an obstacle (at its pose at ``t = 0``) or a rigid
        body (but for the nodes glued to it): the contact would throw it out in the first step. A
        quasi-static scene may start so: the first step then presses the obstacle in, an imposed
        indentation (``scenes/validation/hertz.py``), with no inertia to throw anything."""
        if self.static:
            return
        solids = []
        for entry in self.obstacles:
            shape = entry.shape
            if entry.motion is not None:
                shape = shape.moved(*pose_of(entry.motion, 0.0, f"obstacle '{entry.name}': motion"))
            solids.append((f"obstacle '{entry.name}'", shape, None))
        for rigid in self.rigid_bodies:
            solids.append((f"rigid body '{rigid.name}'", rigid.shape, rigid))
        for body in self.bodies:
            if not solids:
                break
            ids = np.unique(body.mesh.surface())
            x, edge = body.mesh.nodes[ids], body.mesh.mean_surface_edge()
            for what, shape, rigid in solids:
                glued = np.zeros(len(ids), dtype=bool)
                for a in self.attachments:
                    if a.rigid is rigid and a.body is body:
                        glued |= np.isin(ids, a.nodes)
                d = signed_distance(shape, x[~glued])
                if len(d) and -d.min() > START_OVERLAP * edge:
                    k = int(np.argmin(d))
                    raise SceneError(
                        f"scene '{self.name}': body '{body.name}' starts {-d[k]:.3g} m inside {what} (its node at "
                        f"{np.round(x[~glued][k], 6).tolist()} m): the contact would throw it out at the first "
                        "step; move them apart (a Mesh obstacle's normals must point out of its solid, an open "
                        "one's towards the bodies)")


# a body may start this far inside an obstacle (times its mean surface spacing): round-off of a
# body placed on a surface, no more
START_OVERLAP = 1e-3


def signed_distance(shape: Obstacle, points: np.ndarray) -> np.ndarray:
    """``shape.distance(points)`` (m, negative inside), a Mesh's by chunks of points (its brute
    force holds a point-triangle table)."""
    step = max(1, 2_000_000 // max(1, len(getattr(shape, "triangles", ())) or 1))
    return np.concatenate([shape.distance(points[i:i + step]) for i in range(0, len(points), step)] or [np.zeros(0)])


def load_weights(load: Load) -> np.ndarray:
    """Per-node share (sums to 1) of ``load`` over its body's surface inside its region: the
    integral of each node's shape function over it (:func:`warpsoft.scene.surface.area_shares`;
    a quadratic body's 6-node faces count whole, so their corners take none of a flat face's load)."""
    mesh = load.body.mesh
    tris = mesh.surface()
    inside = load.region(mesh.nodes)
    tris = tris[np.all(inside[tris], axis=1)]
    if len(tris) == 0:
        raise SceneError(f"load '{load.name}': region {load.region!r} contains no surface triangle of body "
                         f"'{load.body.name}'")
    w = area_shares(mesh, tris, f"load '{load.name}'")
    return w / w.sum()
