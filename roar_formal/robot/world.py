"""The deterministic physical world of the reference robot (pymunk, top-down, no gravity).

A :class:`World` is built from a :class:`~roar_formal.robot.scenario.Scenario`,
a seed and the fault points turned on. Everything that varies draws from
random streams derived from that one seed and time is counted in ticks, so
the same seed, faults and commands give a bit-identical run: what a
verification run needs to reproduce a counterexample.

A world pickles as its recipe (scenario, seed, faults) plus the commands it
was given at each tick; unpickling rebuilds it and replays them. pymunk's
own pickle of a space drops solver state (the contact bias velocities of
the bodies and the joints' accumulated impulses), so a space restored from
it drifts from the original within a few ticks of any contact; replaying
is exact. Change a world only through its methods (not by moving pymunk
bodies by hand), or the replay cannot know about it.

The floor is not a pymunk body: wheel-floor traction, wheel slip and the
floor's drag on loose objects are applied as impulses each tick before
``space.step``; walls, doors, objects and joints are pymunk's.
"""

from __future__ import annotations

import math
import pickle
import random
from typing import Iterable, Optional

import pymunk

try:  # pymunk's own binding of Chipmunk: lidar rays through it cost a quarter of the public call
    from pymunk._chipmunk_cffi import ffi as _ffi, lib as _lib
    _RAW_RAYS = hasattr(_lib, "cpSpaceSegmentQueryFirst")
except ImportError:  # pragma: no cover - another pymunk layout: the public call does the same
    _RAW_RAYS = False

from ..errors import RoarError
from .scenario import DoorChange, Fault, Scenario, Shape, did_you_mean

G = 9.81                     # m/s^2: the floor load of the wheels and objects
WHEEL_INERTIA = 0.005        # kg m^2: wheel plus the motor rotor seen through the gearbox
TRACTION_ITERATIONS = 4      # Gauss-Seidel passes over the motors and wheel contacts per tick
CONTACT_SLOP = 0.001         # m of overlap pymunk tolerates (its default, 0.1, suits pixels, not metres)
GRIP_CLOSE_TIME = 0.3        # s for the jaws to close or open
GRIP_TEAR_DISTANCE = 0.05    # m an object may move from where it was gripped before the grip is lost
PTU_GAIN = 15.0              # 1/s: rate command per unit of angle error, below the rate limit
PTU_MASS = 1.0
PTU_MOMENT = 0.005           # kg m^2 of the pan head
PTU_POST_RADIUS = 0.05
STUCK_TIME = 0.5             # s of commanded motion without movement that counts as stuck
SNAPSHOT_FORMAT = 1

ROBOT_TYPE = 1               # collision type of the chassis
ROBOT_GROUP = 1              # shapes in this group ignore each other, and the lidar ignores them
CAT_STATIC, CAT_DOOR, CAT_OBJECT, CAT_ROBOT = 1, 2, 4, 8
SOLID_MASK = CAT_STATIC | CAT_DOOR


def _wrap(angle: float) -> float:
    """An angle in (-pi, pi]."""
    a = math.fmod(angle + math.pi, 2 * math.pi)
    if a <= 0:
        a += 2 * math.pi
    return a - math.pi


class _Contacts:
    """Shapes the chassis touches now, and contacts begun so far (filled by the collision callbacks)."""

    def __init__(self) -> None:
        self.touching = 0
        self.begun = 0


def _chassis_contact_begins(arbiter: pymunk.Arbiter, space: pymunk.Space, contacts: _Contacts) -> None:
    contacts.touching += 1
    contacts.begun += 1


def _chassis_contact_ends(arbiter: pymunk.Arbiter, space: pymunk.Space, contacts: _Contacts) -> None:
    contacts.touching = max(0, contacts.touching - 1)


def _box_vertices(w: float, h: float) -> list[tuple[float, float]]:
    return [(-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2)]


class World:
    """A scenario in pymunk, stepped in fixed ticks of ``scenario.dt``."""

    def __init__(self, scenario: Scenario, seed: Optional[int] = None, faults: Iterable[str] = ()):
        self.scenario = scenario
        self.seed = scenario.seed if seed is None else seed
        self.faults = frozenset([faults] if isinstance(faults, str) else faults)
        self._log: list[tuple[int, str, str, tuple]] = []  # (tick, device, method, arguments): the commands given
        self.armed: list[tuple[str, float]] = []   # fault points armed during the run (arm), with the time
        for name in sorted(self.faults, key=str):
            if not isinstance(name, str) or name not in scenario.faults:
                known = ", ".join(scenario.faults) or "none"
                raise RoarError(f"scenario '{scenario.name}' has no fault point '{name}'"
                                f"{did_you_mean(str(name), scenario.faults)}; fault points: {known}")
        active = [f for f in scenario.faults.values() if f.name in self.faults]
        self.dt = scenario.dt
        self.steps = 0
        self.rng = random.Random(self.seed)
        # one stream per consumer, so that scanning more or less often leaves the odometry noise unchanged
        odometry_rng = random.Random(self.rng.getrandbits(64))
        lidar_rng = random.Random(self.rng.getrandbits(64))

        space = pymunk.Space()
        space.gravity = (0.0, 0.0)
        space.collision_slop = CONTACT_SLOP
        self.space = space
        self._contacts = _Contacts()
        space.on_collision(ROBOT_TYPE, None, begin=_chassis_contact_begins, separate=_chassis_contact_ends,
                           data=self._contacts)

        self.patches = [(p.area, p.mu) for p in scenario.patches]
        self.patches += [(f.area, f.mu) for f in active if f.kind == "friction"]
        self._build_statics()
        self._doors = {d.name: _Door(space, d) for d in scenario.doors}
        self._door_schedules = {d.name: d.schedule for d in scenario.doors}
        replaced_by: dict[str, str] = {}
        for f in active:
            if f.kind == "door":
                if f.door in replaced_by:
                    raise RoarError(f"faults '{replaced_by[f.door]}' and '{f.name}' both replace the schedule "
                                    f"of door '{f.door}'; turn on one of them")
                replaced_by[f.door] = f.name
                self._door_schedules[f.door] = f.schedule
        self.objects: dict[str, pymunk.Body] = {}
        self._object_specs = {}
        for o in scenario.objects:
            self.objects[o.name] = self._add_object(o)
            self._object_specs[o.name] = o

        self.base = Base(self, odometry_rng, next((f for f in active if f.kind == "odometry_bias"), None))
        self.lidar = Lidar(self, lidar_rng, [(f.start, f.until) for f in active if f.kind == "lidar_dropout"])
        cable = next((f for f in active if f.kind == "ptu_cable"), None)
        self.ptu = Ptu(self, cable) if scenario.ptu else None
        weak = next((f for f in active if f.kind == "grip_force"), None)
        self.gripper = Gripper(self, weak) if scenario.robot.gripper else None
        self._update_doors()

    # ------------------------------------------------------------ building

    def _build_statics(self) -> None:
        static = self.space.static_body
        shapes: list[pymunk.Shape] = []
        for w in self.scenario.walls:
            shapes.append(pymunk.Segment(static, w.start, w.end, w.thickness / 2))
        for o in self.scenario.obstacles:
            shapes.append(self._static_shape(static, o))
        if self.scenario.ptu:
            shapes.append(pymunk.Circle(static, PTU_POST_RADIUS, self.scenario.ptu.position))
        for s in shapes:
            s.friction = 0.5
            s.elasticity = 0.0
            s.filter = pymunk.ShapeFilter(categories=CAT_STATIC)
        self.space.add(*shapes)

    @staticmethod
    def _static_shape(static: pymunk.Body, o: Shape) -> pymunk.Shape:
        if o.kind == "circle":
            return pymunk.Circle(static, o.r, (o.x, o.y))
        t = pymunk.Transform.translation(o.x, o.y).rotated(o.angle)
        return pymunk.Poly(static, _box_vertices(o.w, o.h), transform=t)

    def _add_object(self, o) -> pymunk.Body:
        s = o.shape
        if s.kind == "circle":
            body = pymunk.Body(o.mass, pymunk.moment_for_circle(o.mass, 0, s.r))
            shape: pymunk.Shape = pymunk.Circle(body, s.r)
        else:
            body = pymunk.Body(o.mass, pymunk.moment_for_box(o.mass, (s.w, s.h)))
            shape = pymunk.Poly(body, _box_vertices(s.w, s.h))
        body.position = (s.x, s.y)
        body.angle = s.angle
        shape.friction = o.friction
        shape.elasticity = 0.0
        shape.filter = pymunk.ShapeFilter(categories=CAT_OBJECT)
        self.space.add(body, shape)
        return body

    # ------------------------------------------------------------ time

    @property
    def time(self) -> float:
        """Simulated seconds (ticks times dt, so it never drifts)."""
        return self.steps * self.dt

    def _record(self, device: str, method: str, args: tuple) -> None:
        """Note a command, so that unpickling can replay it at the same tick."""
        self._log.append((self.steps, device, method, args))

    def step(self) -> None:
        """One tick: device models, physics, then odometry, doors and bookkeeping."""
        self.base._drive()
        if self.ptu:
            self.ptu._control()
        self._drag_objects()
        self.space.step(self.dt)
        self.steps += 1
        self._update_doors()  # now, so that a door is in its scheduled state at every time one can observe
        self.base._after_step()
        if self.gripper:
            self.gripper._after_step()

    def run_for(self, seconds: float) -> None:
        """Step for ``seconds`` of simulated time (rounded to whole ticks)."""
        for _ in range(max(0, round(seconds / self.dt))):
            self.step()

    def _update_doors(self) -> None:
        """Put each door in the state its schedule says; a door does not close on the robot or an object."""
        now = self.time + 1e-9
        for name, door in self._doors.items():
            want_open = door.spec.open
            for change in self._door_schedules[name]:
                if change.time > now:
                    break
                want_open = change.open
            if want_open != door.open and (want_open or not door.blocked()):
                door.set_open(want_open)

    def _drag_objects(self) -> None:
        """Floor friction on the loose objects not held by the gripper (Coulomb: it stops, never reverses)."""
        held = self.gripper.holding if self.gripper else None
        dt = self.dt
        for name, body in self.objects.items():
            if name == held:
                continue
            spec = self._object_specs[name]
            vx, vy = body.velocity
            w = body.angular_velocity
            if vx == 0.0 and vy == 0.0 and w == 0.0:
                continue
            dv = spec.friction * G * dt
            speed = math.hypot(vx, vy)
            if speed <= dv:
                body.velocity = (0.0, 0.0)
            else:
                k = 1.0 - dv / speed
                body.velocity = (vx * k, vy * k)
            s = spec.shape
            r = s.r if s.kind == "circle" else math.sqrt(s.w * s.h / math.pi)
            dw = (2.0 / 3.0) * spec.friction * spec.mass * G * r * dt / body.moment
            body.angular_velocity = 0.0 if abs(w) <= dw else w - math.copysign(dw, w)

    # ------------------------------------------------------------ faults armed during a run

    def arm(self, name: str) -> None:
        """Turn fault point ``name`` on now, its own timeline starting now (robot-backed
        exploration arms fault points at primitive calls). A door fault's schedule and a
        lidar dropout's window are shifted by the current time; a friction patch, a cable,
        a weak grip and an odometry bias hold from now on. Recorded, so replays arm it at
        the same tick."""
        f = self.scenario.faults.get(name)
        if f is None:
            known = ", ".join(self.scenario.faults) or "none"
            raise RoarError(f"scenario '{self.scenario.name}' has no fault point '{name}'"
                            f"{did_you_mean(str(name), self.scenario.faults)}; fault points: {known}")
        if name in self.faults or name in self.armed:
            raise RoarError(f"fault point '{name}' is already on")
        if f.kind == "door":
            other = next((g for g in list(self.faults) + [a for a, _t in self.armed]
                          if self.scenario.faults[g].kind == "door" and self.scenario.faults[g].door == f.door), None)
            if other is not None:
                raise RoarError(f"faults '{other}' and '{name}' both replace the schedule of door '{f.door}'; "
                                "turn on one of them")
        self._record("world", "arm", (name,))
        now = self.time
        self.armed.append((name, now))
        if f.kind == "door":
            self._door_schedules[f.door] = tuple(DoorChange(c.time + now, c.open) for c in f.schedule)
            self._update_doors()
        elif f.kind == "lidar_dropout":
            self.lidar.dropouts.append((f.start + now, f.until + now))
        elif f.kind == "friction":
            self.patches.append((f.area, f.mu))
        elif f.kind == "ptu_cable":
            self.ptu.add_cable(f.max_deg)
        elif f.kind == "grip_force":
            self.gripper.force = f.force
        elif f.kind == "odometry_bias":
            self.base.left_scale = f.scale

    def scheduled_ticks(self) -> tuple:
        """Ticks from now to each future scheduled change (doors, lidar dropouts): what makes
        two worlds that look alike now behave differently later."""
        now = self.time + 1e-9
        out = []
        for name, sched in sorted(self._door_schedules.items()):
            out.extend((name, round((c.time - self.time) / self.dt)) for c in sched if c.time > now)
        for start, until in self.lidar.dropouts:
            out.extend(("lidar", round((t - self.time) / self.dt)) for t in (start, until) if t > now)
        return tuple(out)

    # ------------------------------------------------------------ queries

    def door_open(self, name: str) -> bool:
        if name not in self._doors:
            raise RoarError(f"scenario '{self.scenario.name}' has no door '{name}'"
                            f"{did_you_mean(name, self._doors)}")
        return self._doors[name].open

    def place_object(self, name: str, x: float, y: float, angle: float = 0.0) -> None:
        """Put a loose object at rest at (x, y), ``angle`` radians (for setting up a run)."""
        if name not in self.objects:
            raise RoarError(f"scenario '{self.scenario.name}' has no object '{name}'"
                            f"{did_you_mean(name, self.objects)}")
        if self.gripper and self.gripper.holding == name:
            self.gripper._release()
        self._record("world", "place_object", (name, x, y, angle))
        body = self.objects[name]
        body.position, body.angle = (x, y), angle
        body.velocity, body.angular_velocity = (0.0, 0.0), 0.0
        self.space.reindex_shapes_for_body(body)

    def occupied(self, x: float, y: float) -> bool:
        """Is the point inside a static shape (wall, obstacle, ptu post) or a closed door?"""
        return bool(self.space.point_query((x, y), 0.0, pymunk.ShapeFilter(mask=SOLID_MASK)))

    def patch_mu(self, x: float, y: float) -> float:
        """Wheel-floor friction at a point: the last patch containing it, else the robot's floor_mu."""
        mu = self.scenario.robot.floor_mu
        for (x0, y0, x1, y1), patch_mu in self.patches:
            if x0 <= x <= x1 and y0 <= y <= y1:
                mu = patch_mu
        return mu

    def geometry(self) -> dict:
        """Plain data for drawing and for ground-truth maps (active fault patches included)."""
        sc = self.scenario
        boxes = [(o.x, o.y, o.w, o.h, o.angle) for o in sc.obstacles if o.kind == "box"]
        circles = [(o.x, o.y, o.r) for o in sc.obstacles if o.kind == "circle"]
        objects = []
        for name, body in self.objects.items():
            s = self._object_specs[name].shape
            objects.append({"name": name, "kind": s.kind, "x": body.position.x, "y": body.position.y,
                            "angle": body.angle, "w": s.w, "h": s.h, "r": s.r})
        x, y, theta = self.base.pose
        ptu = None
        if self.ptu:
            px, py = sc.ptu.position
            ptu = {"x": px, "y": py, "angle_rad": self.ptu.body.angle, "radius": PTU_POST_RADIUS}
        return {
            "bounds": sc.bounds,
            "walls": [(w.start, w.end, w.thickness) for w in sc.walls],
            "boxes": boxes,
            "circles": circles,
            "doors": [{"name": d.spec.name, "from": d.spec.start, "to": d.spec.end, "thickness": d.spec.thickness,
                       "open": d.open} for d in self._doors.values()],
            "patches": [(*area, mu) for area, mu in self.patches],
            "objects": objects,
            "robot": {"x": x, "y": y, "theta": theta, "radius": sc.robot.bounding_radius,
                      "size": sc.robot.size},
            "ptu": ptu,
        }

    # ------------------------------------------------------------ snapshots

    def snapshot(self) -> bytes:
        """The whole world as bytes; :meth:`restore` continues it bit for bit."""
        return pickle.dumps(self, protocol=pickle.HIGHEST_PROTOCOL)

    @staticmethod
    def restore(data: bytes) -> "World":
        """A world from :meth:`snapshot` bytes (rebuilt and replayed: the cost grows with its age)."""
        try:
            world = pickle.loads(data)
        except RoarError:
            raise
        except Exception as exc:  # a corrupt or foreign snapshot is bad input, not a bug
            raise RoarError(f"cannot restore a world snapshot: {exc}") from None
        if not isinstance(world, World):
            raise RoarError(f"not a world snapshot (it holds a {type(world).__name__})")
        return world

    def clone(self) -> "World":
        return World.restore(self.snapshot())

    def __getstate__(self) -> dict:
        return {"format": SNAPSHOT_FORMAT, "scenario": self.scenario, "seed": self.seed,
                "faults": sorted(self.faults), "steps": self.steps, "log": list(self._log),
                "lidar_rng": self.lidar.rng.getstate()}

    def __setstate__(self, state: dict) -> None:
        if not isinstance(state, dict) or state.get("format") != SNAPSHOT_FORMAT:
            raise RoarError("cannot restore a world snapshot: it was written by another version")
        self.__init__(state["scenario"], state["seed"], state["faults"])
        devices = {"world": self, "base": self.base, "ptu": self.ptu, "gripper": self.gripper}
        for tick, device, method, args in state["log"]:
            while self.steps < tick:
                self.step()
            getattr(devices[device], method)(*args)
        while self.steps < state["steps"]:
            self.step()
        self.lidar.rng.setstate(state["lidar_rng"])  # scans are not replayed: they change nothing else


class _Door:
    """A door: a kinematic segment whose shape is in the space only while the door is closed."""

    def __init__(self, space: pymunk.Space, spec):
        self.spec = spec
        self.space = space
        self.body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.shape = pymunk.Segment(self.body, spec.start, spec.end, spec.thickness / 2)
        self.shape.friction = 0.5
        self.shape.filter = pymunk.ShapeFilter(categories=CAT_DOOR)
        space.add(self.body)
        self.open = True

    def blocked(self) -> bool:
        """Is a robot or an object in the doorway (so that closing now would crush it)?"""
        return any(q.shape.body.body_type == pymunk.Body.DYNAMIC for q in self.space.shape_query(self.shape))

    def set_open(self, want_open: bool) -> None:
        if want_open == self.open:
            return
        if want_open:
            self.space.remove(self.shape)
        else:
            self.space.add(self.shape)
        self.open = want_open


class _Device:
    """A part of a world; pickling one pickles its world and picks the part out again."""

    world: World
    attribute = ""

    def __reduce__(self):
        return (getattr, (self.world, self.attribute))


class Base(_Device):
    """The differential-drive base: two motor-driven wheels coupled to the chassis by floor friction.

    Each wheel is a spinning state driven by a torque-limited speed
    controller. Its rim meets the floor at a contact point beside the
    chassis centre: the slip between rim speed and the chassis' ground
    speed there gives a traction impulse clamped to mu*N (and an equal
    reaction on the wheel), and the sideways speed there is removed by a
    friction impulse with the same clamp. Wheels that cannot grip spin
    (odometry over-reads); a chassis held by a wall stalls.
    """

    attribute = "base"

    def __init__(self, world: World, rng: random.Random, bias: Optional[Fault]):
        self.world = world
        self.spec = spec = world.scenario.robot
        self.rng = rng
        self.left_scale = bias.scale if bias else 1.0
        if spec.size:
            length, width = spec.size
            moment = pymunk.moment_for_box(spec.mass, (length, width))
        else:
            moment = pymunk.moment_for_circle(spec.mass, 0, spec.radius)
        self.body = body = pymunk.Body(spec.mass, moment)
        x, y, theta = spec.start
        body.position = (x, y)
        body.angle = theta
        if spec.size:
            self.shape: pymunk.Shape = pymunk.Poly(body, _box_vertices(*spec.size))
        else:
            self.shape = pymunk.Circle(body, spec.radius)
        self.shape.friction = 0.3
        self.shape.elasticity = 0.0
        self.shape.collision_type = ROBOT_TYPE
        self.shape.filter = pymunk.ShapeFilter(group=ROBOT_GROUP, categories=CAT_ROBOT)
        world.space.add(body, self.shape)
        self.target = [0.0, 0.0]   # wheel speed commands, rad/s
        self.omega = [0.0, 0.0]    # actual wheel speeds, rad/s
        self._odometry = (x, y, _wrap(theta))
        self._stalled_ticks = 0
        self.normal_force = spec.mass * G / 2

    def set_wheel_speeds(self, left: float, right: float) -> None:
        """Target wheel speeds (rad/s), clamped to max_wheel_speed."""
        top = self.spec.max_wheel_speed
        target = [max(-top, min(top, float(left))), max(-top, min(top, float(right)))]
        if target != self.target:
            self.world._record("base", "set_wheel_speeds", (left, right))
            self.target = target

    def stop(self) -> None:
        self.set_wheel_speeds(0.0, 0.0)

    @property
    def pose(self) -> tuple[float, float, float]:
        """True (x, y, theta), theta in (-pi, pi]."""
        p = self.body.position
        return (p.x, p.y, _wrap(self.body.angle))

    @property
    def velocity(self) -> tuple[float, float]:
        """(forward speed m/s, turn rate rad/s)."""
        vx, vy = self.body.velocity
        theta = self.body.angle
        return (vx * math.cos(theta) + vy * math.sin(theta), self.body.angular_velocity)

    @property
    def wheel_speeds(self) -> tuple[float, float]:
        return (self.omega[0], self.omega[1])

    @property
    def odometry(self) -> tuple[float, float, float]:
        """Pose dead-reckoned from the wheel encoders, theta in (-pi, pi]."""
        return self._odometry

    def reset_odometry(self, pose: Optional[tuple[float, float, float]] = None) -> None:
        """Set the dead-reckoned pose: to ``pose`` (x, y, theta rad), or to the true pose when None."""
        self.world._record("base", "reset_odometry", (pose,))
        x, y, theta = self.pose if pose is None else pose
        self._odometry = (float(x), float(y), _wrap(float(theta)))

    def teleport(self, x: float, y: float, theta: Optional[float] = None) -> None:
        """Put the chassis at rest at (x, y), heading ``theta`` rad (kept when None); odometry is not told."""
        self.world._record("base", "teleport", (x, y, theta))
        body = self.body
        body.position = (x, y)
        if theta is not None:
            body.angle = theta
        body.velocity, body.angular_velocity = (0.0, 0.0), 0.0
        self.world.space.reindex_shapes_for_body(body)

    @property
    def bumped(self) -> bool:
        """Is the chassis touching a static shape, a door or an object now?"""
        return self.world._contacts.touching > 0

    @property
    def bump_count(self) -> int:
        return self.world._contacts.begun

    @property
    def stuck(self) -> bool:
        """Have the wheels been commanded to move for STUCK_TIME while the chassis hardly moved?"""
        return self._stalled_ticks * self.world.dt >= STUCK_TIME

    def _drive(self) -> None:
        """Motor and traction impulses of one tick, applied to the chassis as a force and a torque."""
        spec, body, dt = self.spec, self.body, self.world.dt
        r, half = spec.wheel_radius, spec.wheel_base / 2
        inv_mass, inv_moment = 1.0 / body.mass, 1.0 / body.moment
        omega, target = self.omega, self.target
        motor_limit = spec.max_torque * dt  # angular impulse a motor can give in one tick

        theta = body.angle
        c, s = math.cos(theta), math.sin(theta)
        vx, vy = body.velocity
        x, y = body.position
        forward0, sideways0, turn0 = vx * c + vy * s, -vx * s + vy * c, body.angular_velocity
        forward, sideways, turn = forward0, sideways0, turn0
        offsets = (half, -half)  # left wheel on the left (+y in the body frame)
        limits = [self.world.patch_mu(x - d * s, y + d * c) * self.normal_force * dt for d in offsets]
        along_mass = 1.0 / (r * r / WHEEL_INERTIA + inv_mass + half * half * inv_moment)
        along = [0.0, 0.0]   # traction impulse so far this tick, per wheel
        motor = [0.0, 0.0]   # motor angular impulse so far this tick, per wheel
        for _ in range(TRACTION_ITERATIONS):
            # both wheels from the same chassis state, so neither leads and equal commands drive exactly straight
            pushes = [0.0, 0.0]
            for i in (0, 1):
                # the motor: a speed controller whose torque is limited
                total = max(-motor_limit, min(motor_limit, motor[i] + (target[i] - omega[i]) * WHEEL_INERTIA))
                omega[i] += (total - motor[i]) / WHEEL_INERTIA
                motor[i] = total
                # traction along the wheel, against the slip between rim and floor, at most mu*N
                slip = omega[i] * r - (forward - turn * offsets[i])
                total = max(-limits[i], min(limits[i], along[i] + slip * along_mass))
                pushes[i], along[i] = total - along[i], total
                omega[i] -= pushes[i] * r / WHEEL_INERTIA
            forward += (pushes[0] + pushes[1]) * inv_mass
            turn -= (offsets[0] * pushes[0] + offsets[1] * pushes[1]) * inv_moment
        # sideways friction at both wheels (on the axle, so it does not turn the chassis), at most mu*N each
        sideways_limit = limits[0] + limits[1]
        sideways += max(-sideways_limit, min(sideways_limit, -sideways * body.mass)) * inv_mass
        # as a force, not a new velocity: pymunk integrates positions before it solves contacts, so a velocity
        # set here would carry the chassis into a wall before the contact could stop it
        forward -= forward0
        sideways -= sideways0
        body.force = (body.mass / dt * (forward * c - sideways * s), body.mass / dt * (forward * s + sideways * c))
        body.torque = body.moment / dt * (turn - turn0)

    def _after_step(self) -> None:
        """Integrate the encoders into the odometry; track stalling."""
        spec, dt, rng = self.spec, self.world.dt, self.rng
        noise = spec.odometry_noise
        left = self.omega[0] * spec.wheel_radius * dt * (1.0 + rng.gauss(0.0, noise)) * self.left_scale
        right = self.omega[1] * spec.wheel_radius * dt * (1.0 + rng.gauss(0.0, noise))
        x, y, theta = self._odometry
        ds, dtheta = (left + right) / 2, (right - left) / spec.wheel_base
        heading = theta + dtheta / 2
        self._odometry = (x + ds * math.cos(heading), y + ds * math.sin(heading), _wrap(theta + dtheta))

        commanded = spec.wheel_radius * (abs(self.target[0]) + abs(self.target[1])) / 2
        v, w = self.velocity
        moving = abs(v) + abs(w) * spec.wheel_base / 2
        if commanded > 0.05 and moving < 0.1 * commanded:
            self._stalled_ticks += 1
        else:
            self._stalled_ticks = 0


class Lidar(_Device):
    """A planar scanner at the chassis centre; rays ignore the robot and what it holds."""

    attribute = "lidar"

    def __init__(self, world: World, rng: random.Random, dropouts: list[tuple[float, float]]):
        self.world = world
        self.rng = rng
        self.spec = spec = world.scenario.robot.lidar
        self.period = spec.period
        self.range = spec.range
        self.dropouts = dropouts
        fov = math.radians(spec.fov_deg)
        n = spec.rays
        if spec.fov_deg >= 360.0:
            self.angles = [-math.pi + 2 * math.pi * i / n for i in range(n)]
        elif n == 1:
            self.angles = [0.0]
        else:
            self.angles = [-fov / 2 + fov * i / (n - 1) for i in range(n)]
        self.filter = pymunk.ShapeFilter(group=ROBOT_GROUP)

    @property
    def dropped_out(self) -> bool:
        now = self.world.time + 1e-9
        return any(start <= now < until for start, until in self.dropouts)

    def scan(self) -> list[tuple[float, Optional[float]]]:
        """(angle from the heading in rad, range in m or None beyond range); [] during a dropout."""
        if self.dropped_out:
            return []
        body, rng = self.world.base.body, self.rng
        x, y = body.position
        theta = body.angle
        reach, noise = self.range, self.spec.noise
        readings: list[tuple[float, Optional[float]]] = []
        for a, alpha in zip(self.angles, self._cast(x, y, theta)):
            if alpha is None:
                readings.append((a, None))
            else:
                readings.append((a, min(reach, max(0.0, alpha * reach + rng.gauss(0.0, noise)))))
        return readings

    def _cast(self, x: float, y: float, theta: float) -> list[Optional[float]]:
        """The fraction of the range at which each ray first hits something (None: nothing)."""
        space, reach, filt = self.world.space, self.range, self.filter
        ends = [(x + reach * math.cos(theta + a), y + reach * math.sin(theta + a)) for a in self.angles]
        if _RAW_RAYS:
            # the same Chipmunk query pymunk's segment_query_first makes, without its per-ray Python objects
            # (a quarter of the cost)
            info = _ffi.new("cpSegmentQueryInfo *")
            first = _lib.cpSpaceSegmentQueryFirst
            handle = space._space
            null = _ffi.NULL
            return [info.alpha if first(handle, (x, y), end, 0.0, filt, info) != null else None for end in ends]
        hits = [space.segment_query_first((x, y), end, 0.0, filt) for end in ends]
        return [None if hit is None else hit.alpha for hit in hits]


class Ptu(_Device):
    """A pan unit on a fixed post: pivot, torque-limited motor, joint limits (and a cable when faulty)."""

    attribute = "ptu"

    def __init__(self, world: World, cable: Optional[Fault]):
        self.world = world
        self.spec = spec = world.scenario.ptu
        space, static = world.space, world.space.static_body
        self.body = pymunk.Body(PTU_MASS, PTU_MOMENT)
        self.body.position = spec.position
        self.body.angle = math.radians(max(spec.min_deg, min(spec.max_deg, 0.0)))
        pivot = pymunk.PivotJoint(static, self.body, spec.position)
        self.motor = pymunk.SimpleMotor(static, self.body, 0.0)
        self.motor.max_force = spec.max_torque
        limits = pymunk.RotaryLimitJoint(static, self.body, math.radians(spec.min_deg), math.radians(spec.max_deg))
        space.add(self.body, pivot, self.motor, limits)
        self.cable_deg = None
        if cable:
            self.add_cable(cable.max_deg)
        self.target_deg = math.degrees(self.body.angle)

    def add_cable(self, max_deg: float) -> None:
        """A cable that stops the pan ``max_deg`` either side of zero (a fault)."""
        self.cable_deg = max_deg
        space, static = self.world.space, self.world.space.static_body
        space.add(pymunk.RotaryLimitJoint(static, self.body, -math.radians(max_deg), math.radians(max_deg)))

    def command(self, angle_deg: float) -> None:
        """Turn toward ``angle_deg``, clamped to the unit's own limits (it does not know about a cable)."""
        target = max(self.spec.min_deg, min(self.spec.max_deg, float(angle_deg)))
        if target != self.target_deg:
            self.world._record("ptu", "command", (angle_deg,))
            self.target_deg = target

    @property
    def angle_deg(self) -> float:
        return math.degrees(self.body.angle)

    @property
    def rate_deg(self) -> float:
        return math.degrees(self.body.angular_velocity)

    def at_target(self, tol_deg: float = 1.0) -> bool:
        return abs(self.target_deg - self.angle_deg) <= tol_deg

    def _control(self) -> None:
        """Rate command: proportional to the error, limited to max_rate_deg."""
        top = math.radians(self.spec.max_rate_deg)
        error = math.radians(self.target_deg) - self.body.angle
        # SimpleMotor drives the second body at -rate relative to the first
        self.motor.rate = -max(-top, min(top, PTU_GAIN * error))


class Gripper(_Device):
    """Jaws in front of the chassis: a closing grip holds an object between them with a limited force."""

    attribute = "gripper"

    def __init__(self, world: World, weak: Optional[Fault]):
        self.world = world
        self.spec = spec = world.scenario.robot.gripper
        self.force = weak.force if weak else spec.grip_force
        self.closed = False
        self.holding: Optional[str] = None
        self.drops = 0
        self._moving_ticks = 0
        self._closing = False
        self._joints: list[pymunk.Constraint] = []
        self._anchor = (0.0, 0.0)  # where the held object sits, in chassis coordinates

    @property
    def busy(self) -> bool:
        """Are the jaws still moving?"""
        return self._moving_ticks > 0

    def close(self) -> None:
        """Start closing; whether something is held is decided when the jaws are shut."""
        if self.closed or (self.busy and self._closing):
            return
        self.world._record("gripper", "close", ())
        self._closing = True
        self._moving_ticks = self._ticks()

    def open(self) -> None:
        """Release anything held and open the jaws."""
        if self.holding is None and not self.closed and not (self.busy and self._closing):
            return
        self.world._record("gripper", "open", ())
        self._release()
        self.closed = False
        self._closing = False
        self._moving_ticks = self._ticks()

    def _ticks(self) -> int:
        return max(1, math.ceil(GRIP_CLOSE_TIME / self.world.dt - 1e-9))

    def jaw_region(self) -> list[tuple[float, float]]:
        """The jaw box in world coordinates (for drawing and tests)."""
        chassis = self.world.base.body
        return [tuple(chassis.local_to_world(p)) for p in self._jaw_vertices()]

    def _jaw_vertices(self) -> list[tuple[float, float]]:
        front = self.world.scenario.robot.half_length
        half = self.spec.width / 2
        return [(front, -half), (front + self.spec.reach, -half), (front + self.spec.reach, half), (front, half)]

    def _after_step(self) -> None:
        if self._moving_ticks > 0:
            self._moving_ticks -= 1
            if self._moving_ticks == 0 and self._closing:
                self.closed = True
                self._grip()
        if self.holding is not None:
            body = self.world.objects[self.holding]
            ax, ay = self.world.base.body.local_to_world(self._anchor)
            px, py = body.position
            if math.hypot(px - ax, py - ay) > GRIP_TEAR_DISTANCE:
                self._release()
                self.drops += 1

    def _grip(self) -> None:
        world = self.world
        chassis = world.base.body
        jaws = pymunk.Poly(chassis, self._jaw_vertices())
        jaws.filter = pymunk.ShapeFilter(group=ROBOT_GROUP, mask=CAT_OBJECT)
        names = {id(body): name for name, body in world.objects.items()}
        centre = chassis.local_to_world((world.scenario.robot.half_length + self.spec.reach / 2, 0.0))
        inside = sorted((world.objects[names[id(q.shape.body)]].position.get_distance(centre), names[id(q.shape.body)])
                        for q in world.space.shape_query(jaws) if id(q.shape.body) in names)
        if not inside:
            return
        name = inside[0][1]  # the object nearest the middle of the jaws
        body = world.objects[name]
        self._anchor = tuple(chassis.world_to_local(body.position))
        hold = pymunk.PivotJoint(chassis, body, self._anchor, (0.0, 0.0))
        hold.max_force = self.force
        twist = pymunk.GearJoint(chassis, body, body.angle - chassis.angle, 1.0)
        twist.max_force = self.force * self.spec.width / 2
        self._joints = [hold, twist]
        world.space.add(*self._joints)
        for shape in body.shapes:
            shape.filter = pymunk.ShapeFilter(group=ROBOT_GROUP, categories=CAT_OBJECT)
        self.holding = name

    def _release(self) -> None:
        if self.holding is None:
            return
        body = self.world.objects[self.holding]
        self.world.space.remove(*self._joints)
        self._joints = []
        for shape in body.shapes:
            shape.filter = pymunk.ShapeFilter(categories=CAT_OBJECT)
        self.holding = None
