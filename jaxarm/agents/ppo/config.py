"""PPO's frozen config: static sizes and choices, and the dynamic hyper-parameters `train` takes as data."""

import dataclasses

from jaxarm.agents.common.config import RunConfig, dynamic
from jaxarm.agents.common.encoders import check_encoder


@dataclasses.dataclass(frozen=True)
class PPOConfig(RunConfig):
    """PPO run config. Fields declared `dynamic` reach `train` as data (`hparams()`), so sweeps vmap over them.

    Attributes (beyond RunConfig's):
      rollout_length: env steps per env between updates (T).
      num_minibatches: minibatches per epoch; T·num_envs must divide by it.
      num_epochs: passes over each rollout.
      policy_hidden_sizes: hidden layer sizes of the policy MLP.
      value_hidden_sizes: hidden layer sizes of the value MLP.
      activation: flax.linen activation name for hidden layers.
      encoder: conv stack in front of the MLPs for camera observations (`jaxarm.agents.common.encoders`:
        "nature", "impala", "patches"); unused for flat observations.
      encoder_features: width of the encoder's dense output layer.
      shared_encoder: one encoder (the policy's) feeds both heads, trained by both losses; else one each.
      normalize_observations: keep running mean/std of observations in the learner state (of a camera
        observation, its proprio part only).
      normalize_advantages: standardise advantages per minibatch.
      anneal_learning_rate: decay the learning rate linearly to 0 over the run.
      initial_log_std: initial policy standard deviation's log (pre-tanh).
      learning_rate: Adam step size (linearly annealed to 0 when `anneal_learning_rate`).
      gamma: discount.
      gae_lambda: GAE's λ.
      clip_epsilon: PPO's ratio clip.
      entropy_coef: weight of the entropy bonus.
      value_coef: weight of the value loss.
      max_grad_norm: global gradient-norm clip.
      reward_scale: rewards are multiplied by this before GAE.
    """

    rollout_length: int = 16
    num_minibatches: int = 8
    num_epochs: int = 4
    policy_hidden_sizes: tuple[int, ...] = (64, 64)
    value_hidden_sizes: tuple[int, ...] = (64, 64)
    activation: str = "tanh"
    encoder: str = "nature"
    encoder_features: int = 256
    shared_encoder: bool = False
    normalize_observations: bool = True
    normalize_advantages: bool = True
    anneal_learning_rate: bool = True
    initial_log_std: float = 0.0
    learning_rate: float = dynamic(3e-4)
    gamma: float = dynamic(0.99)
    gae_lambda: float = dynamic(0.95)
    clip_epsilon: float = dynamic(0.2)
    entropy_coef: float = dynamic(0.01)
    value_coef: float = dynamic(0.5)
    max_grad_norm: float = dynamic(0.5)
    reward_scale: float = dynamic(1.0)

    @property
    def env_steps_per_update(self) -> int:
        return self.rollout_length * self.num_envs

    @property
    def num_updates(self) -> int:
        return self.whole_chunks(self.env_steps_per_update)

    @property
    def minibatch_size(self) -> int:
        return self.env_steps_per_update // self.num_minibatches

    def validate(self) -> None:
        """RunConfig's checks, and that each rollout splits into whole minibatches."""
        super().validate()
        check_encoder(self.encoder)
        if self.env_steps_per_update % self.num_minibatches:
            raise ValueError(
                f"rollout_length*num_envs={self.env_steps_per_update} must divide by "
                f"num_minibatches={self.num_minibatches}"
            )
