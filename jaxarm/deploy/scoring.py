"""The tasks' scoring in numpy, from true or estimated states: the sorter's outcomes, target and shaped reward
(`jaxarm.envs.panda_sort.reward`), and the peg's distance, table contact and reward (`jaxarm.envs.peg_insert.env`).
The same formulas (tests/deploy/test_scoring.py holds them to the env's on hand-placed states). Imports numpy
alone.
"""

import dataclasses

import numpy as np

IN_PLAY = 0
IN_CORRECT_BIN = 1
IN_WRONG_BIN = 2
ON_FLOOR = 3
"""Outcome of a sorter object slot (the env's `jaxarm.envs.panda_sort.reward` reads these too)."""
FLOOR_Z = -0.05
"""An object whose centre is this far below the table top has fallen off."""
GRAVITY = 9.81
"""m/s², downwards: MuJoCo's default, which the sorter's scenes keep (the toss term's ballistic paths)."""
HELD_DISTANCE = 0.01
"""An object counts as held when its centre is within its size plus this of the tool centre ..."""
HELD_MIN_SQUEEZE = 0.002
"""... and the fingers are commanded at least this much (metres) closer than they are: they press on something
(open fingers straddling a large object do not hold it) ..."""
HELD_MIN_WIDTH = 1.0
"""... but are open more than this many sizes (fully closed fingers hold nothing; a cylinder is gripped at
1.4 sizes, a small sphere squeezed to about 1.5)."""
SHAPING_TERMS = ("reach", "grasp", "lift", "carry", "toss")
"""The sorter's shaping potentials, in the order the env's `shaping_potential` stacks them."""


@dataclasses.dataclass(frozen=True)
class Bins:
    """The sorter's bins (`jaxarm.envs.panda_sort.layout.Layout`'s numbers).

    Attributes:
      centres: [3, 2] (x, y) of the cube, cylinder and sphere bins.
      half: half-size of a bin's inside (square).
      wall_height: an object whose centre is inside a bin and below this height is in it.
    """

    centres: np.ndarray
    half: float
    wall_height: float


def bin_membership(position: np.ndarray, bins: Bins) -> np.ndarray:
    """[N, 3] object positions -> [N, 3] bool: centre inside bin k's walls and below its rim."""
    inside = np.all(np.abs(position[:, None, :2] - bins.centres[None]) < bins.half, axis=-1)
    return inside & (position[:, None, 2] < bins.wall_height)


def next_outcome(outcome: np.ndarray, shape: np.ndarray, position: np.ndarray, bins: Bins) -> np.ndarray:
    """Scores in-play objects [N] at their [N, 3] positions; out-of-play outcomes never change."""
    in_bin = bin_membership(position, bins)
    in_own_bin = in_bin[np.arange(len(shape)), shape]
    scored = np.select(
        [in_own_bin, np.any(in_bin, axis=1), position[:, 2] < FLOOR_Z],
        [IN_CORRECT_BIN, IN_WRONG_BIN, ON_FLOOR],
        IN_PLAY,
    )
    return np.where(outcome == IN_PLAY, scored, outcome)


def next_target(outcome: np.ndarray, target: int, position: np.ndarray, tcp: np.ndarray) -> int:
    """The target slot: kept while in play, else the in-play object nearest the tool centre `tcp` [3] (slot 0
    when none is in play); `target` -1 picks afresh."""
    in_play = outcome == IN_PLAY
    if target >= 0 and in_play[target]:
        return target
    distance = np.linalg.norm(position - tcp, axis=-1)
    return int(np.argmin(np.where(in_play, distance, np.inf)))


def carry_targets(bins: Bins, shape: np.ndarray, carry_height: float) -> np.ndarray:
    """[N] shapes -> [N, 3] the point `carry_height` above the centre of each object's own bin."""
    own_bin = bins.centres[shape]
    return np.concatenate([own_bin, np.full((len(shape), 1), carry_height)], -1)


@dataclasses.dataclass(frozen=True)
class SortReward:
    """The sorter's reward params (`PandaSortParams` fields of the same names) and `target_first`."""

    step_reward: float
    floor_reward: float
    wrong_bin_reward: float
    correct_bin_reward: float
    reach_weight: float
    grasp_weight: float
    lift_weight: float
    carry_weight: float
    toss_weight: float
    reach_scale: float
    lift_height: float
    carry_scale: float
    carry_height: float
    toss_scale: float
    toss_flight: float
    target_first: bool


@dataclasses.dataclass(frozen=True)
class SortState:
    """What the sorter's scoring reads of the world (N objects).

    Attributes:
      position: [N, 3] object centres.
      shape: [N] int shapes; size: [N] sizes (m).
      outcome: [N] outcomes; exit_xy: [N, 2] where each out-of-play object left play.
      velocity: [N, 3] object centres' velocities (world frame).
      target: the target slot.
      tcp: [3] the tool centre.
      finger_q: [2] the fingers' openings; finger_ctrl: [2] their targets.
    """

    position: np.ndarray
    shape: np.ndarray
    size: np.ndarray
    outcome: np.ndarray
    exit_xy: np.ndarray
    velocity: np.ndarray
    target: int
    tcp: np.ndarray
    finger_q: np.ndarray
    finger_ctrl: np.ndarray


def landing_xy(position: np.ndarray, velocity: np.ndarray, flight: float) -> np.ndarray:
    """[N, 2] where each object would drop below the floor line if let go now, `flight` of the way along its
    ballistic path from `position` [N, 3] with `velocity` [N, 3] (`reward.landing_xy`)."""
    rise = velocity[:, 2]
    fall_time = (rise + np.sqrt(np.maximum(rise**2 + 2 * GRAVITY * (position[:, 2] - FLOOR_Z), 0.0))) / GRAVITY
    return position[:, :2] + flight * np.maximum(fall_time, 0.0)[:, None] * velocity[:, :2]


def shaping_potential(state: SortState, bins: Bins, reward: SortReward) -> np.ndarray:
    """[5] weighted potentials (`SHAPING_TERMS`), each summed over objects: `reward.shaping_potential`."""
    in_play = state.outcome == IN_PLAY
    distance = np.linalg.norm(state.position - state.tcp, axis=-1)
    squeeze = np.mean(state.finger_q - state.finger_ctrl)
    held = (
        (distance < state.size + HELD_DISTANCE)
        & (squeeze > HELD_MIN_SQUEEZE)
        & (np.sum(state.finger_q) > HELD_MIN_WIDTH * state.size)
    )
    lift = held * np.clip((state.position[:, 2] - state.size) / reward.lift_height, 0.0, 1.0)
    carry_target = carry_targets(bins, state.shape, reward.carry_height)
    to_target = np.linalg.norm(state.position - carry_target, axis=-1)
    on_floor = state.outcome == ON_FLOOR
    in_flight = landing_xy(state.position, state.velocity, reward.toss_flight)
    toss_xy = np.where(on_floor[:, None], state.exit_xy, in_flight)
    toss = 1.0 - np.tanh(np.linalg.norm(toss_xy - carry_target[:, :2], axis=-1) / reward.toss_scale)
    stages = np.stack(
        [
            1.0 - np.tanh(distance / reward.reach_scale),
            held.astype(np.float64),
            lift,
            lift * (1.0 - np.tanh(to_target / reward.carry_scale)),
            toss,
        ]
    )
    in_own_bin = (state.outcome == IN_CORRECT_BIN).astype(np.float64)
    out_of_play = np.stack([in_own_bin + on_floor * toss if name == "toss" else in_own_bin for name in SHAPING_TERMS])
    slots = np.arange(len(state.outcome))
    shaped = in_play & (slots == state.target) if reward.target_first else in_play
    weights = np.array([getattr(reward, f"{name}_weight") for name in SHAPING_TERMS])
    return weights * np.sum(np.where(shaped, stages, out_of_play), axis=1)


def sort_reward(previous_outcome: np.ndarray, outcome: np.ndarray, shaping: float, reward: SortReward) -> float:
    """One step's reward: the time cost, each object scored this step, and the change of the potentials' sum."""
    newly = (previous_outcome == IN_PLAY) & (outcome != IN_PLAY)

    def count(value: int) -> int:
        return int(np.sum(newly & (outcome == value)))

    return (
        reward.step_reward
        + reward.floor_reward * count(ON_FLOOR)
        + reward.wrong_bin_reward * count(IN_WRONG_BIN)
        + reward.correct_bin_reward * count(IN_CORRECT_BIN)
        + shaping
    )


@dataclasses.dataclass(frozen=True)
class PegReward:
    """The peg's reward and ending params (`PegInsertParams` fields of the same names)."""

    progress_weight: float
    success_bonus: float
    insert_distance: float
    max_distance: float


def capsule_below_plane(
    capsule_pos: np.ndarray, capsule_rotation: np.ndarray, radius: float, half_length: float, plane_pos, plane_rotation
) -> bool:
    """Whether a capsule (centre [3], rotation [3, 3], along its z) penetrates a plane (point [3], rotation [3, 3],
    normal its z): `PegInsert.table_contact`."""
    axis = capsule_rotation[:, 2]
    ends = capsule_pos + np.array([[half_length], [-half_length]]) * axis
    heights = (ends - plane_pos) @ plane_rotation[:, 2] - radius
    return bool(np.any(heights < 0.0))


def peg_reward(previous_distance: float, distance: float, initial_distance: float, reward: PegReward) -> float:
    """One step's reward: progress towards the hole bottom over the first distance, plus the bonus while in."""
    progress = reward.progress_weight * (previous_distance - distance) / initial_distance
    return progress + reward.success_bonus * (distance < reward.insert_distance)
