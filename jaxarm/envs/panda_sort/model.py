"""Builds the MuJoCo model of the sorting scene and resolves the ids the env needs, once, outside jit.

Object slots. MJX shapes are static, yet every slot must hold a cube, a cylinder or a sphere. Each slot is
one free body with three collision geoms (`box`, `box45`, `sphere`) whose sizes the env sets per episode
(mjx.Model.geom_size is read at run time, so it can differ per env under vmap). The drawn shape gets its
full size; the others shrink to a quarter, deep inside it, where they can never touch anything.
One body per slot (rather than three bodies with two parked) keeps nv at 6 per slot and the contact set
at three geoms per slot.

Cylinders. MJX 3.17 has no cylinder-box collision, and its cylinder-capsule/sphere collisions are SDF
searches (slow). A cylinder object therefore collides as an octagonal prism: `box` and `box45` (the same
box turned 45 degrees about z) with their corners on the cylinder's circle; their convex hull is a
regular octagon with 92-100 % of the radius, the flat bottom stands on the table and the fingers grip its
faces when one of the octagon's faces is turned towards them (a flat pad on a corner ridge slips). A
contype-0 `cylinder` geom is added for drawing only.

Contacts come only from the explicit <pair>s made here: finger pads and hand vs objects; objects vs tables,
bin walls (frictionless, see BIN_WALL_CONDIM), blocker and each other. There is no floor contact: an object
is taken out of play as soon as it drops below the table top, long before it could reach the floor.
"""

import dataclasses
import functools
from pathlib import Path

import mujoco
import numpy as np

from jaxarm import robots
from jaxarm.envs.panda.dynamics import NOMINAL
from jaxarm.envs.panda.robot import RobotIds, resolve_robot_ids, scene_spec
from jaxarm.envs.panda_sort.layout import Layout

ASSETS = Path(__file__).parent / "assets"
OBJECT_GEOMS = ("box", "box45", "sphere")
"""Collision geoms of one object slot, in geom-id order."""
MAX_OBJECT_SIZE = 0.05
"""Largest half-size/radius the XML is built with (geom_rbound for MJX's broad phase is recomputed anyway)."""
FINGER_FRICTION = (2.5, 2.5, 0.005, 0.0001, 0.0001)
FINGER_SOLIMP = (0.97, 0.995, 0.001, 0.5, 2.0)
"""Gripper contacts are hard (impedance 0.99..0.999, default 0.9..0.95): squeezed by the fingers, a light
sphere is penetrated by about a millimetre, not by a third of its radius."""
FIRM_GRIP_TIMESTEP = 0.004
FIRM_GRIP_SOLREF = (0.008, 1.0)
"""The tosser's physics timestep and finger-contact solref (time constant, damping ratio), for a grip that rides
a throw (scripted_throw.py). At the scenes' 0.01 s MuJoCo keeps a contact's time constant at 0.02 s or more (twice
the timestep): the pads sink 1.4-6 mm into a held object, which creeps and pivots out of the fingers during the
wind-up; neither condim-4 torsional friction, a 70 N finger force, 20 solver iterations nor an elliptic cone kept
it (MJX-JAX, CPU, 8 held starts, 2026-11-25). The largest distance of each object from the tool centre through the
swing: 1.9-2.3 cm at 0.004 s and 0.008 s (10 physics steps per env step instead of 4), 0.8-1.2 cm at 0.002 s and
0.004 s (20), 2.7-7.2 cm at 0.005 s and 0.01 s."""
OBJECT_FRICTION = (0.8, 0.8, 0.005, 0.0001, 0.0001)
BIN_WALL_CONDIM = 1
"""Bin walls are frictionless: one constraint row per contact instead of four. Half of all contacts are
object-wall ones (six thin walls, every object geom), and with friction they made bare `mjx.step` of the
three-object scene 4.6x slower on an H100 (6.1e4 vs 2.8e5 physics steps/s at 4,096 envs, 2026-11-23).
Walls only stop objects; scoring never depends on them."""


@dataclasses.dataclass(frozen=True)
class ModelIds:
    """Indices into the compiled model, resolved once (numpy ints / arrays, static under jit).

    Attributes:
      robot: the Panda's ids.
      object_qpos: [N] qpos address of each object's free joint (7 values: pos, quat).
      object_qvel: [N] dof address of each object's free joint (6 values: linear, angular velocity).
      object_body: [N] body ids of the objects.
      object_geom: [N, 3] geom ids of each slot's box, box45 and sphere.
      object_visual: [N] geom id of each slot's drawing-only cylinder.
      finger_pair: [P] ids of the finger/hand-object pairs (their friction is FINGER_FRICTION).
      object_pair: [Q] ids of the other pairs (their friction is OBJECT_FRICTION).
    """

    robot: RobotIds
    object_qpos: np.ndarray
    object_qvel: np.ndarray
    object_body: np.ndarray
    object_geom: np.ndarray
    object_visual: np.ndarray
    finger_pair: np.ndarray
    object_pair: np.ndarray


def _add_box(body, name: str, box, rgba) -> None:
    body.add_geom(
        name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=box.center, size=box.half, rgba=rgba, contype=0, conaffinity=0
    )


def _add_object(worldbody, slot: int) -> None:
    body = worldbody.add_body(name=f"object{slot}", pos=[2.0 + slot, 2.0, 0.1])
    body.add_freejoint(name=f"object{slot}")
    # Mass and inertia are set per episode from shape, size and density; these are placeholders.
    body.explicitinertial = True
    body.mass, body.inertia = 0.1, [1e-4, 1e-4, 1e-4]
    body.ipos, body.iquat = [0, 0, 0], [1, 0, 0, 0]  # centre of mass at the body frame (left unset: at the spawn point)
    s = MAX_OBJECT_SIZE
    common = dict(contype=0, conaffinity=0, rgba=[0.8, 0.3, 0.3, 1])
    body.add_geom(name=f"object{slot}_box", type=mujoco.mjtGeom.mjGEOM_BOX, size=[s, s, s], **common)
    body.add_geom(
        name=f"object{slot}_box45",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[s, s, s],
        quat=[np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)],
        **common,
    )
    body.add_geom(name=f"object{slot}_sphere", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[s, 0, 0], **common)
    # Drawing only (`render.dress_objects` shows it for a cylinder, at its size): transparent here, so that the
    # cameras (`camera.Scene`, which casts visible geoms) see each object's own collision shape, not a cylinder
    # of the largest size over every object.
    body.add_geom(
        name=f"object{slot}_cylinder",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[s, s, 0],
        **{**common, "rgba": [0.8, 0.3, 0.3, 0]},
    )


def _add_static(world: mujoco.MjsBody, layout: Layout) -> list[str]:
    """Adds `layout`'s tables, bin walls and blocker to `world`; returns their geoms' names, in that order."""
    static = [f"table{k}" for k in range(len(layout.tables))]
    for name, box in zip(static, layout.tables, strict=True):
        _add_box(world, name, box, [0.55, 0.45, 0.35, 1])
    for k, wall in enumerate(layout.bin_walls):
        _add_box(world, f"bin_wall{k}", wall, [0.3, 0.3, 0.35, 1])
        static.append(f"bin_wall{k}")
    if layout.blocker is not None:
        _add_box(world, "blocker", layout.blocker, [0.7, 0.2, 0.2, 1])
        static.append("blocker")
    return static


def _add_pairs(spec: mujoco.MjSpec, objects_count: int, static: list[str], firm_grip: bool) -> None:
    """The explicit contact pairs, in the order the env's pair ids rely on: the gripper's with every object geom
    (FIRM_GRIP_SOLREF with `firm_grip`), then each object geom's with the `static` geoms and later objects'."""

    def pair(name1: str, name2: str, friction, condim: int = 3, **kwargs) -> mujoco.MjsPair:
        return spec.add_pair(geomname1=name1, geomname2=name2, condim=condim, friction=friction, **kwargs)

    slot_geoms = [[f"object{slot}_{kind}" for kind in OBJECT_GEOMS] for slot in range(objects_count)]
    for geoms in slot_geoms:
        for geom in geoms:
            for gripper in ("left_pad", "right_pad", "hand"):
                finger = pair(gripper, geom, FINGER_FRICTION, solimp=FINGER_SOLIMP)
                if firm_grip:
                    finger.solref = FIRM_GRIP_SOLREF
    for slot, geoms in enumerate(slot_geoms):
        for geom in geoms:
            for other in static:
                pair(other, geom, OBJECT_FRICTION, condim=BIN_WALL_CONDIM if other.startswith("bin_wall") else 3)
            for later in slot_geoms[slot + 1 :]:
                for other in later:
                    pair(geom, other, OBJECT_FRICTION)


def build_spec(
    objects_count: int,
    layout: Layout,
    dynamics: str = NOMINAL,
    firm_grip: bool = False,
    robot: str = "panda",
    robot_xml: Path | None = None,
) -> mujoco.MjSpec:
    """The scene as an MjSpec: table from assets/scene.xml with `robot` (by name, `jaxarm.robots`) and its `dynamics`
    (`dynamics.DYNAMICS`), the rest from `layout`; `firm_grip` sets FIRM_GRIP_TIMESTEP and
    FIRM_GRIP_SOLREF. The robot's model is its description's `model_xml`, or `robot_xml`, another with the names of
    its description (`robot.scene_spec`)."""
    spec = scene_spec(ASSETS / "scene.xml", robots.robot(robot), dynamics, robot_xml)
    if firm_grip:
        spec.option.timestep = FIRM_GRIP_TIMESTEP
    static = _add_static(spec.worldbody, layout)
    if layout.front_view is not None:
        camera = spec.camera("front")
        camera.pos = layout.front_view.pos
        camera.alt.type = mujoco.mjtOrientation.mjORIENTATION_XYAXES
        camera.alt.xyaxes = layout.front_view.xyaxes
    for slot in range(objects_count):
        _add_object(spec.worldbody, slot)
    _add_pairs(spec, objects_count, static, firm_grip)
    return spec


@functools.cache
def build_model(
    objects_count: int,
    layout: Layout,
    dynamics: str = NOMINAL,
    firm_grip: bool = False,
    robot: str = "panda",
    robot_xml: Path | None = None,
) -> mujoco.MjModel:
    """Compiled model for `objects_count` object slots in `layout` with `robot` and its `dynamics`, with the firm
    grip of a thrower if `firm_grip` (FIRM_GRIP_TIMESTEP), from `robot_xml` where given (`build_spec`; cached:
    every argument is hashable)."""
    return build_spec(objects_count, layout, dynamics, firm_grip, robot, robot_xml).compile()


def resolve_ids(model: mujoco.MjModel, objects_count: int, robot: str = "panda") -> ModelIds:
    """Looks up every id the env uses, by name, with `robot`'s by its description's names."""
    joint = model.joint
    gripper_geoms = {model.geom(name).id for name in ("left_pad", "right_pad", "hand")}
    is_finger_pair = np.array([int(model.pair_geom1[k]) in gripper_geoms for k in range(model.npair)])
    return ModelIds(
        robot=resolve_robot_ids(model, robots.robot(robot)),
        object_qpos=np.array([joint(f"object{k}").qposadr[0] for k in range(objects_count)], dtype=np.int64),
        object_qvel=np.array([joint(f"object{k}").dofadr[0] for k in range(objects_count)], dtype=np.int64),
        object_body=np.array([model.body(f"object{k}").id for k in range(objects_count)], dtype=np.int64),
        object_geom=np.array(
            [[model.geom(f"object{k}_{kind}").id for kind in OBJECT_GEOMS] for k in range(objects_count)],
            dtype=np.int64,
        ).reshape(objects_count, len(OBJECT_GEOMS)),
        object_visual=np.array([model.geom(f"object{k}_cylinder").id for k in range(objects_count)], dtype=np.int64),
        finger_pair=np.flatnonzero(is_finger_pair),
        object_pair=np.flatnonzero(~is_finger_pair),
    )
