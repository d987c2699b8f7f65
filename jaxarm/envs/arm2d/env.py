"""The planar N-link reaching arm ("arm2d"), the classic 2-link tutorial arm generalised.

Defaults reproduce the tutorial: a 400x400 world, the base at (200, 200), two links of 100, joint angles
θ ← (θ + clip(a, −1, 1)·0.1) mod 2π, a goal square of side 40, reward −‖goal − finger‖/400 plus 1 while the
finger is strictly inside the goal square, terminated once the goal has been held for more than 50
consecutive steps, truncated at 200 steps. Observation for N links (4N + 1 values): every link end's
position / (world/2), then every (goal − link end) / world, then on_goal. For N = 2 that is the tutorial's
[elbow/200, finger/200, (goal−elbow)/400, (goal−finger)/400, on_goal].

`obs_mode` "pixels" observes a top-down grayscale image of links and goal instead (`camera.py`,
{"image": uint8 [R, R, 1]}); "pixels+proprio" adds the link ends' positions / (world/2) ({"proprio": [2N]}),
so that the goal is seen only in the image. With `privileged`, a pixel mode's observation also holds the state
observation ({"privileged": [4N + 1]}, for a learner's critic: `jaxarm.envs.observation`).
"""

import jax
import jax.numpy as jnp
from flax import struct

from jaxarm.envs.arm2d.arm import (
    Arm2dParams,
    Arm2dSim,
    goal_reachable,
    link_end_positions,
    sample_goal,
)
from jaxarm.envs.arm2d.camera import grayscale_image
from jaxarm.envs.arm2d.render import draw_frame
from jaxarm.envs.base import Env, EnvSpec, Observation, Transition
from jaxarm.envs.observation import check_obs_mode, observation_parts, pixel_observation


@struct.dataclass
class Arm2dInfo:
    """Per-step diagnostics: distance [] (normalised by world size), on_goal [] bool, goal_reachable [] bool."""

    distance: jax.Array
    on_goal: jax.Array
    goal_reachable: jax.Array


class Arm2d(Env[Arm2dParams, Arm2dSim]):
    """N-link planar reaching arm. Constructor args are static: `num_links` fixes the shapes, `obs_mode`
    ("state", "pixels", "pixels+proprio") what is observed, `resolution` the camera image's side in pixels,
    `privileged` whether a pixel mode's observation also holds the state observation."""

    def __init__(self, num_links: int = 2, obs_mode: str = "state", resolution: int = 64, privileged: bool = False):
        if num_links < 1:
            raise ValueError(f"num_links must be >= 1, got {num_links}")
        check_obs_mode(obs_mode, resolution, privileged)
        self.num_links = num_links
        self.obs_mode = obs_mode
        self.resolution = resolution
        self.privileged = privileged
        action_shape = (num_links,)
        state_size = 4 * num_links + 1
        if obs_mode == "state":
            self.spec = EnvSpec(observation_shape=(state_size,), action_shape=action_shape)
        else:
            parts = observation_parts(
                obs_mode, (resolution, resolution, 1), 2 * num_links, state_size if privileged else None
            )
            self.spec = EnvSpec(observation_parts=parts, action_shape=action_shape)

    def default_params(self) -> Arm2dParams:
        return Arm2dParams(link_lengths=jnp.full((self.num_links,), 200.0 / self.num_links, jnp.float32))

    def render(self, state, params: Arm2dParams):
        return draw_frame(state.sim, params)

    @property
    def draws_images(self) -> bool:
        return self.obs_mode != "state"

    def images(self, sim: Arm2dSim, params: Arm2dParams) -> jax.Array:
        return grayscale_image(sim, params, self.resolution)

    def _observe(self, sim: Arm2dSim, params: Arm2dParams) -> Observation:
        ends = link_end_positions(sim.angles, params)
        proprio = (ends / (params.world_size / 2)).ravel()
        on_goal = (sim.hold_count > 0).astype(jnp.float32)[None]
        state = jnp.concatenate([proprio, ((sim.goal - ends) / params.world_size).ravel(), on_goal])
        if self.obs_mode == "state":
            return state
        return pixel_observation(self.obs_mode, self.blank_image(), proprio, state if self.privileged else None)

    def _info(self, sim: Arm2dSim, params: Arm2dParams, on_goal: jax.Array) -> Arm2dInfo:
        finger = link_end_positions(sim.angles, params)[-1]
        return Arm2dInfo(
            distance=jnp.linalg.norm(sim.goal - finger) / params.world_size,
            on_goal=on_goal,
            goal_reachable=goal_reachable(sim.goal, params),
        )

    def _reset(self, key, params):
        # One draw for everything: each threefry call costs more than the arm's maths (see BENCHMARKS.md).
        uniforms = jax.random.uniform(key, (self.num_links + 4,))
        sim = Arm2dSim(
            angles=uniforms[: self.num_links] * 2 * jnp.pi,
            goal=sample_goal(uniforms[self.num_links :], params),
            hold_count=jnp.zeros((), jnp.int32),
        )
        return sim, self._observe(sim, params), self._info(sim, params, jnp.zeros((), jnp.bool_))

    def _transition(self, sim, action, params):
        angles = jnp.mod(sim.angles + action * params.action_scale, 2 * jnp.pi)
        finger = link_end_positions(angles, params)[-1]
        on_goal = jnp.all(jnp.abs(finger - sim.goal) < params.goal_size / 2)
        hold_count = jnp.where(on_goal, sim.hold_count + 1, 0)
        sim = Arm2dSim(angles=angles, goal=sim.goal, hold_count=hold_count)
        info = self._info(sim, params, on_goal)
        terminated = hold_count > params.hold_steps
        return Transition(
            sim=sim,
            obs=self._observe(sim, params),
            reward=(
                -params.distance_weight * info.distance
                + params.goal_bonus * on_goal
                + params.success_bonus * terminated
            ),
            terminated=terminated,
            success=terminated,
            info=info,
        )
