"""Builds the MuJoCo model of peg insertion and resolves the ids the env needs, once, outside jit.

The peg is a capsule fixed in the robot's hand (the fingers close on it for show; they collide with
nothing), its tip `PEG_LENGTH` below the tool centre whatever the robot. The block is a static body of five
boxes: a floor and four walls around a square hole. Its position is `mjx.Model.body_pos` and the walls' placement
`geom_pos`/`geom_size`, both replaced per env inside the step (`hole_walls` gives the walls for a clearance), so
the hole moves and resizes under vmap.

Contacts come only from explicit <pair>s: the peg against the table top and against each box of the block.
"""

import dataclasses
import functools
from pathlib import Path

import jax.numpy as jnp
import mujoco
import numpy as np

from jaxarm import robots
from jaxarm.envs.panda.dynamics import NOMINAL
from jaxarm.envs.panda.robot import RobotIds, resolve_robot_ids, scene_spec
from jaxarm.robots import RobotDescription

ASSETS = Path(__file__).parent / "assets"
PEG_RADIUS = 0.01
PEG_LENGTH = 0.08
"""The peg's tip is this far below the tool centre (the fingers hold its upper end)."""
PEG_ABOVE_TCP = 0.035
"""How far the peg reaches above the tool centre, into the hand."""
HOLE_DEPTH = 0.04
HOLE_FLOOR = 0.01
"""Thickness of the block's floor: the hole bottom is this high above the table."""
WALL_THICKNESS = 0.02
HOLE_NOMINAL = (0.5, 0.0)
"""(x, y) of the hole's centre before the per-episode shift."""
WALL_NAMES = ("wall_px", "wall_nx", "wall_py", "wall_ny")
BLOCK_GEOMS = ("hole_floor",) + WALL_NAMES
PEG_FRICTION = (0.5, 0.5, 0.005, 0.0001, 0.0001)


@dataclasses.dataclass(frozen=True)
class PegIds:
    """Indices into the compiled model (numpy ints / arrays, static under jit).

    Attributes:
      robot: the robot's ids.
      peg_geom: geom id of the peg.
      peg_tip: site id of the peg's tip.
      table_geom: geom id of the table top.
      block_body: body id of the block with the hole.
      wall_geoms: [4] geom ids of the walls, in WALL_NAMES order.
      block_geoms: [5] geom ids of the block's boxes, in BLOCK_GEOMS order.
      block_pairs: [5] ids of the peg-vs-block pairs.
    """

    robot: RobotIds
    peg_geom: int
    peg_tip: int
    table_geom: int
    block_body: int
    wall_geoms: np.ndarray
    block_geoms: np.ndarray
    block_pairs: np.ndarray


def hole_walls(clearance) -> tuple:
    """Clearance (metres, [] numpy or jax) -> wall centres [4, 3] and half-sizes [4, 3] in the block frame.

    The hole is a square of half-width PEG_RADIUS + clearance; walls ±x span the hole's y extent plus both
    y walls' thickness, walls ±y span the hole's x extent.
    """
    half_width = PEG_RADIUS + clearance
    t, h = WALL_THICKNESS / 2, HOLE_DEPTH / 2
    z = HOLE_FLOOR + h
    offset = half_width + t
    ones = jnp.ones_like(jnp.asarray(half_width))
    centres = jnp.stack(
        [
            jnp.stack([offset, 0.0 * ones, z * ones]),
            jnp.stack([-offset, 0.0 * ones, z * ones]),
            jnp.stack([0.0 * ones, offset, z * ones]),
            jnp.stack([0.0 * ones, -offset, z * ones]),
        ]
    )
    long_wall = jnp.stack([t * ones, half_width + 2 * t, h * ones])
    short_wall = jnp.stack([half_width, t * ones, h * ones])
    return centres, jnp.stack([long_wall, long_wall, short_wall, short_wall])


def _add_peg(spec: mujoco.MjSpec, robot: RobotDescription) -> None:
    hand = spec.body(robot.hand_body)
    peg = hand.add_body(name="peg")
    # The tool centre's height along the hand's z axis, where the hand points (both robots' tcp sites).
    tcp_in_hand = spec.site(robot.tcp_site).pos[2]
    top, tip = tcp_in_hand - PEG_ABOVE_TCP, tcp_in_hand + PEG_LENGTH
    peg.add_geom(
        name="peg",
        type=mujoco.mjtGeom.mjGEOM_CAPSULE,
        size=[PEG_RADIUS, 0, 0],
        fromto=[0, 0, top, 0, 0, tip - PEG_RADIUS],
        mass=0.05,
        contype=0,
        conaffinity=0,
        rgba=[0.85, 0.6, 0.15, 1],
    )
    peg.add_site(name="peg_tip", pos=[0, 0, tip], size=[0.004, 0, 0], rgba=[1, 0, 0, 1])


def _add_block(spec: mujoco.MjSpec, clearance: float) -> None:
    block = spec.worldbody.add_body(name="block", pos=[*HOLE_NOMINAL, 0.0])
    outer = PEG_RADIUS + clearance + WALL_THICKNESS
    common = dict(type=mujoco.mjtGeom.mjGEOM_BOX, contype=0, conaffinity=0, rgba=[0.45, 0.5, 0.6, 1])
    block.add_geom(name="hole_floor", pos=[0, 0, HOLE_FLOOR / 2], size=[outer, outer, HOLE_FLOOR / 2], **common)
    centres, halves = (np.asarray(array) for array in hole_walls(np.float32(clearance)))
    for name, centre, half in zip(WALL_NAMES, centres, halves, strict=True):
        block.add_geom(name=name, pos=centre, size=half, **common)


def build_spec(
    clearance: float, dynamics: str = NOMINAL, robot: str = "panda", robot_xml: Path | None = None
) -> mujoco.MjSpec:
    """The scene as an MjSpec: table and camera from assets/scene.xml with `robot` (by name, `jaxarm.robots`) and its
    `dynamics` (`dynamics.DYNAMICS`), then the peg and the block. The robot's model is its description's
    `model_xml`, or `robot_xml`, another with the names of its description (`robot.scene_spec`)."""
    description = robots.robot(robot)
    spec = scene_spec(ASSETS / "scene.xml", description, dynamics, robot_xml)
    _add_peg(spec, description)
    _add_block(spec, clearance)
    spec.add_pair(geomname1="table", geomname2="peg", condim=3, friction=PEG_FRICTION)
    for name in BLOCK_GEOMS:
        spec.add_pair(geomname1=name, geomname2="peg", condim=3, friction=PEG_FRICTION)
    return spec


@functools.cache
def build_model(
    clearance: float = 0.001, dynamics: str = NOMINAL, robot: str = "panda", robot_xml: Path | None = None
) -> mujoco.MjModel:
    """Compiled model with the walls at `clearance` (the env replaces them per env from its params), `robot` with
    its `dynamics`, from `robot_xml` where given (`build_spec`; cached: every argument is hashable)."""
    return build_spec(clearance, dynamics, robot, robot_xml).compile()


def resolve_ids(model: mujoco.MjModel, robot: str = "panda") -> PegIds:
    """Looks up every id the env uses, by name, with `robot`'s by its description's names."""
    block_geoms = {model.geom(name).id for name in BLOCK_GEOMS}
    return PegIds(
        robot=resolve_robot_ids(model, robots.robot(robot)),
        peg_geom=model.geom("peg").id,
        peg_tip=model.site("peg_tip").id,
        table_geom=model.geom("table").id,
        block_body=model.body("block").id,
        wall_geoms=np.array([model.geom(name).id for name in WALL_NAMES]),
        block_geoms=np.array([model.geom(name).id for name in BLOCK_GEOMS]),
        block_pairs=np.array(
            [k for k in range(model.npair) if {int(model.pair_geom1[k]), int(model.pair_geom2[k])} & block_geoms],
            dtype=np.int64,
        ),
    )
