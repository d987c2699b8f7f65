"""TD3's run config: static sizes and choices, and the dynamic hyper-parameters `train` takes as data.

DDPG is this config with one critic, no target smoothing and no policy delay (see `ddpg_arm2d` in
experiments/configs/td3.py).
"""

import dataclasses

from jaxarm import ranges
from jaxarm.agents.common.config import RunConfig, dynamic, inherit, static
from jaxarm.agents.common.encoders import ENCODER
from jaxarm.agents.common.networks import ACTIVATION
from jaxarm.ranges import (
    AT_ONCE,
    COUNT,
    DISCOUNT,
    LAYER_WIDTH,
    LEARNING_RATE,
    NON_NEGATIVE,
    PASSES,
    POSITIVE,
    REPLAY_SIZE,
    Range,
)


@dataclasses.dataclass(frozen=True)
class TD3Config(RunConfig):
    """TD3 / DDPG settings. Actions are in the actor's [-1, 1] units (mapped to the env's bounds on stepping).

    Fields declared `dynamic` reach `train` as data (`hparams()`), so sweeps vmap over them.

    Attributes:
      actor_learning_rate: Adam step size of the actor.
      critic_learning_rate: Adam step size of the critics.
      gamma: discount factor.
      tau: Polyak rate of the target networks (target ← (1 − tau)·target + tau·online).
      exploration_noise: std of the Gaussian noise added to the actor's action while collecting.
      target_noise: std of the target-policy smoothing noise (used only if `target_smoothing`).
      target_noise_clip: the smoothing noise is clipped to ±this.
      reward_scale: rewards are multiplied by this in the critic target.
      anneal_learning_rate: decay both step sizes linearly to 0 over the run, so that the policy settles where
        training ends instead of swinging between evaluations (DDPG's deterministic policy does: ddpg_arm2d).
      normalize_observations: the networks read observations standardised by a running mean and std (brax's;
        of a camera observation, its proprio part), updated with every collected step; replay keeps them raw.
      hidden_sizes: hidden layer widths of the actor and of each critic.
      activation: hidden-layer activation, one of `jaxarm.agents.common.networks.ACTIVATIONS`.
      encoder: conv stack each network reads camera observations through, one of
        `jaxarm.agents.common.encoders.ENCODERS`; unused for flat observations.
      encoder_features: width of the encoder's dense output layer.
      shared_encoder: one encoder for every network, trained by the critics' loss alone, whose features the
        actor reads without a gradient (DrQ's layout); else one per network.
      random_shift_pad: DrQ's augmentation: the critics' and the actor's training images shifted by up to
        ±this many pixels (0: off; DrQ used 4 at 84×84).
      num_critics: critics trained on the same target; the target takes their minimum (2: TD3, 1: DDPG).
      policy_delay: critic steps per actor and target-network step (2: TD3, 1: DDPG).
      target_smoothing: add clipped noise to the target action (TD3); False for DDPG.
      batch_size: transitions per gradient step.
      buffer_size: replay capacity in transitions.
      learning_starts: env steps of uniform random actions before gradient steps begin.
      rollout_length: steps of all `num_envs` envs collected per update.
      grad_steps_per_update: gradient (critic) steps per update; a multiple of `policy_delay`.
      n_step: rewards summed per stored transition before the target bootstraps (n-step returns, within each
        update's rollout of `rollout_length` steps, never across an episode's end); 1 for one-step TD3.
      critic_atoms: 0: each critic outputs Q. N ≥ 2: each outputs a categorical distribution of the (scaled)
        return over N atoms evenly spaced on [`value_min`, `value_max`] (C51), trained by cross-entropy against
        the target critics' distribution shifted by the reward, discounted and projected back onto the atoms;
        of the target critics, the one whose mean is least gives each transition's target (clipped double Q),
        and the actor ascends the first critic's mean.
      value_min, value_max: the atoms' span, in units of scaled return (`reward_scale` · return): returns
        beyond it count as its ends.
      mixed_exploration_noise: env e of B explores with noise std `exploration_noise` · (e + 1) / B instead of
        `exploration_noise` in every env: a spread from nearly greedy to the widest.
    """

    num_envs: int = inherit(RunConfig, "num_envs", 16)
    total_env_steps: int = inherit(RunConfig, "total_env_steps", 200_000)
    updates_per_chunk: int = inherit(RunConfig, "updates_per_chunk", 500)
    checkpoint_every_updates: int = inherit(RunConfig, "checkpoint_every_updates", 2_500)

    actor_learning_rate: float = dynamic(1e-3, LEARNING_RATE)
    critic_learning_rate: float = dynamic(1e-3, LEARNING_RATE)
    gamma: float = dynamic(0.99, DISCOUNT)
    tau: float = dynamic(0.005, Range(gt=0, le=1))
    exploration_noise: float = dynamic(0.1, NON_NEGATIVE)
    target_noise: float = dynamic(0.2, NON_NEGATIVE)
    target_noise_clip: float = dynamic(0.5, NON_NEGATIVE)
    reward_scale: float = dynamic(1.0, POSITIVE)

    anneal_learning_rate: bool = False
    normalize_observations: bool = False
    hidden_sizes: tuple[int, ...] = static((256, 256), LAYER_WIDTH)
    activation: str = static("relu", ACTIVATION)
    encoder: str = static("nature", ENCODER)
    encoder_features: int = static(256, LAYER_WIDTH)
    shared_encoder: bool = False
    random_shift_pad: int = static(0, Range(ge=0, le=1 << 8))  # pixels, as wide as a 256-pixel image
    num_critics: int = static(2, Range(ge=1, le=1 << 8))  # each a network: 1e8 asked XLA for 26 TB
    policy_delay: int = static(2, COUNT)
    target_smoothing: bool = True
    batch_size: int = static(256, AT_ONCE)
    buffer_size: int = static(1_000_000, REPLAY_SIZE)
    learning_starts: int = static(5_000, NON_NEGATIVE)
    rollout_length: int = static(1, COUNT)
    grad_steps_per_update: int = static(4, PASSES)
    n_step: int = static(1, COUNT)
    critic_atoms: int = static(0, Range(ge=0, le=LAYER_WIDTH.le))  # an output layer's width
    value_min: float = static(-10.0)
    value_max: float = static(10.0)
    mixed_exploration_noise: bool = False

    @property
    def env_steps_per_update(self) -> int:
        return self.num_envs * self.rollout_length

    def validate(self) -> None:
        """RunConfig's checks, whole policy-delay blocks drawn at once, a distribution's atoms, and room for one
        update's steps."""
        super().validate()
        if self.grad_steps_per_update % self.policy_delay:
            raise ValueError(
                f"grad_steps_per_update ({self.grad_steps_per_update}) must be a multiple of "
                f"policy_delay ({self.policy_delay})"
            )
        if self.n_step > self.rollout_length:
            raise ValueError(
                f"n_step ({self.n_step}) must not exceed rollout_length ({self.rollout_length}): returns are summed "
                "within one update's rollout"
            )
        drawn = self.policy_delay * self.batch_size  # one draw from the buffer feeds a whole delay block
        if not AT_ONCE.admits(drawn):
            raise ValueError(
                f"policy_delay x batch_size = {drawn:,} samples drawn at once; it must be {AT_ONCE.describe()}"
            )
        if self.critic_atoms == 1:
            raise ValueError("critic_atoms must be 0 (a critic outputs Q) or at least 2 (a distribution over atoms)")
        if self.critic_atoms and not self.value_min < self.value_max:
            raise ValueError(f"value_min ({self.value_min}) must be below value_max ({self.value_max})")
        if self.env_steps_per_update > self.buffer_size:
            raise ValueError(
                f"buffer_size ({self.buffer_size}) must hold one update's {self.env_steps_per_update} env steps"
            )
        if self.learning_starts + self.env_steps_per_update > ranges.INT32.max:
            raise ValueError(
                f"learning_starts ({self.learning_starts:,}) plus one update's env steps must fit in int32, the "
                "warm-up's step counter"
            )
