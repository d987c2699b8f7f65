"""TD3's run config: static sizes and choices, and the dynamic hyper-parameters `train` takes as data.

DDPG is this config with one critic, no target smoothing and no policy delay (see `ddpg_arm2d` in
experiments/configs/td3.py).
"""

import dataclasses

from jaxarm.agents.common.config import RunConfig, dynamic
from jaxarm.agents.common.encoders import check_encoder


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
      hidden_sizes: hidden layer widths of the actor and of each critic.
      activation: hidden-layer activation (a flax.linen function name).
      encoder: conv stack each network reads camera observations through (`jaxarm.agents.common.encoders`:
        "nature", "impala", "patches"); unused for flat observations.
      encoder_features: width of the encoder's dense output layer.
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
    """

    num_envs: int = 16
    total_env_steps: int = 200_000
    updates_per_chunk: int = 500
    checkpoint_every_updates: int = 2_500

    actor_learning_rate: float = dynamic(1e-3)
    critic_learning_rate: float = dynamic(1e-3)
    gamma: float = dynamic(0.99)
    tau: float = dynamic(0.005)
    exploration_noise: float = dynamic(0.1)
    target_noise: float = dynamic(0.2)
    target_noise_clip: float = dynamic(0.5)
    reward_scale: float = dynamic(1.0)

    hidden_sizes: tuple[int, ...] = (256, 256)
    activation: str = "relu"
    encoder: str = "nature"
    encoder_features: int = 256
    random_shift_pad: int = 0
    num_critics: int = 2
    policy_delay: int = 2
    target_smoothing: bool = True
    batch_size: int = 256
    buffer_size: int = 1_000_000
    learning_starts: int = 5_000
    rollout_length: int = 1
    grad_steps_per_update: int = 4

    @property
    def env_steps_per_update(self) -> int:
        return self.num_envs * self.rollout_length

    @property
    def num_updates(self) -> int:
        return self.whole_chunks(self.env_steps_per_update)

    def validate(self) -> None:
        """RunConfig's checks, positive sizes, whole policy-delay blocks, and room for one update's steps."""
        super().validate()
        check_encoder(self.encoder)
        if self.random_shift_pad < 0:
            raise ValueError(f"random_shift_pad must be >= 0, got {self.random_shift_pad}")
        for field in (
            "num_critics",
            "policy_delay",
            "batch_size",
            "buffer_size",
            "rollout_length",
            "grad_steps_per_update",
        ):
            if getattr(self, field) <= 0:
                raise ValueError(f"{field} must be positive, got {getattr(self, field)}")
        if self.grad_steps_per_update % self.policy_delay:
            raise ValueError(
                f"grad_steps_per_update ({self.grad_steps_per_update}) must be a multiple of "
                f"policy_delay ({self.policy_delay})"
            )
        if self.env_steps_per_update > self.buffer_size:
            raise ValueError(
                f"buffer_size ({self.buffer_size}) must hold one update's {self.env_steps_per_update} env steps"
            )
