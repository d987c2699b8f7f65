"""PPO's frozen config: static sizes and choices, and the dynamic hyper-parameters `train` takes as data."""

import dataclasses

from jaxarm.agents.common.config import RunConfig, dynamic, static
from jaxarm.agents.common.encoders import ENCODER
from jaxarm.agents.common.networks import ACTIVATION
from jaxarm.agents.common.teachers import WARM_START_TEACHER, teacher_preset_name
from jaxarm.ranges import (
    COUNT,
    DISCOUNT,
    LAYER_WIDTH,
    LEARNING_RATE,
    NON_NEGATIVE,
    PASSES,
    POSITIVE,
    UNIT_INTERVAL,
    Range,
)


@dataclasses.dataclass(frozen=True)
class PPOConfig(RunConfig):
    """PPO run config. Fields declared `dynamic` reach `train` as data (`hparams()`), so sweeps vmap over them.

    Attributes (beyond RunConfig's):
      rollout_length: env steps per env between updates (T).
      num_minibatches: minibatches per epoch; T·num_envs must divide by it.
      num_epochs: passes over each rollout.
      shuffle_groups: groups of contiguous envs whose samples are shuffled apart, each minibatch taking an equal
        share of every group (`train.shuffled_minibatches`). It defines the run whatever the device count; a
        multiple of the device count keeps every device's minibatch share on that device (data-parallel SGD).
        1 shuffles all samples together.
      policy_hidden_sizes: hidden layer sizes of the policy MLP.
      value_hidden_sizes: hidden layer sizes of the value MLP.
      activation: hidden-layer activation, one of `jaxarm.agents.common.networks.ACTIVATIONS`.
      encoder: conv stack in front of the MLPs for camera observations, one of
        `jaxarm.agents.common.encoders.ENCODERS`; unused for flat observations.
      encoder_features: width of the encoder's dense output layer.
      shared_encoder: one encoder (the policy's) feeds both heads, trained by both losses; else one each.
      teacher: run directory of a finished run (any learner) whose deterministic policy the policy is distilled
        from, DAgger-style: the student drives the rollouts and each observation is labelled with the teacher's
        action, read from the observation's privileged part where it has one (a state teacher for a camera
        student: `env_kwargs.privileged=true`), else from the observation; "" for none. `preset:NAME` names a
        preset instead: the runner first trains it into the run directory's `teacher/` (a finished one is
        reused; a resumed run resumes the stage it stopped in), then the student from it. `init_from` names the
        run this one warm-starts from (`RunConfig.init_from`; with `imitation_only=false` and
        `imitation_decay_updates`, kickstarting).
      teacher_overrides: with `teacher=preset:NAME`, `key=value` overrides of that preset (e.g. to shrink it on a
        CPU; on the command line comma-separated, so values without commas).
      imitation_coef: weight of the distillation loss (squared distance between the student's mean action and
        the teacher's); used with `teacher`.
      imitation_only: with `teacher`, the policy learns from the teacher alone (the distillation loss and the
        value loss, so the critic is ready for PPO afterwards); off, PPO's loss is added.
      imitation_decay_updates: with `teacher` and `imitation_only=false`, the distillation loss's weight falls
        linearly from `imitation_coef` to 0 over this many updates, then PPO's loss trains alone (kickstarting:
        a teacher's behaviour kept while PPO learns a task that asks more of it); 0 keeps the weight constant.
      asymmetric: asymmetric actor-critic: the value MLP reads the env's privileged state observation
        (obs["privileged"] of an env built with `env_kwargs.privileged=true`, with its own running normaliser),
        while the policy reads only the rest (images and proprio), all a robot has; off, both read the policy's
        input. Only the critic, used in training alone, sees the privileged part: `act` and exports never do.
      critic_warm_up_updates: updates at the run's start that train the value function alone (the policy's loss
        and entropy bonus weighted 0; with `shared_encoder` the encoder learns from the value loss): after a warm
        start from another task (`init_from`), the critic learns this task's values before its advantages move the
        policy. 0 for none.
      warm_start_spread: with a warm start (`init_from`), the policy keeps the trained means but takes a fresh
        policy's standard deviation, exp(`initial_log_std`), at every observation: a trained policy's spread is
        narrow where it was sure of itself in its own task, which may be where the new task asks it to explore.
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

    rollout_length: int = static(16, COUNT)
    num_minibatches: int = static(8, COUNT)
    num_epochs: int = static(4, PASSES)
    shuffle_groups: int = static(1, COUNT)
    policy_hidden_sizes: tuple[int, ...] = static((64, 64), LAYER_WIDTH)
    value_hidden_sizes: tuple[int, ...] = static((64, 64), LAYER_WIDTH)
    activation: str = static("tanh", ACTIVATION)
    encoder: str = static("nature", ENCODER)
    encoder_features: int = static(256, LAYER_WIDTH)
    shared_encoder: bool = False
    asymmetric: bool = False
    teacher: str = ""
    teacher_overrides: tuple[str, ...] = ()
    imitation_only: bool = True
    imitation_decay_updates: int = static(0, NON_NEGATIVE)
    critic_warm_up_updates: int = static(0, NON_NEGATIVE)
    warm_start_spread: bool = False
    normalize_observations: bool = True
    normalize_advantages: bool = True
    anneal_learning_rate: bool = True
    initial_log_std: float = static(0.0)
    learning_rate: float = dynamic(3e-4, LEARNING_RATE)
    gamma: float = dynamic(0.99, DISCOUNT)
    gae_lambda: float = dynamic(0.95, UNIT_INTERVAL)
    clip_epsilon: float = dynamic(0.2, Range(gt=0, le=1))
    entropy_coef: float = dynamic(0.01, NON_NEGATIVE)
    value_coef: float = dynamic(0.5, POSITIVE)
    max_grad_norm: float = dynamic(0.5, POSITIVE)
    reward_scale: float = dynamic(1.0, POSITIVE)
    imitation_coef: float = dynamic(1.0, NON_NEGATIVE)

    @property
    def env_steps_per_update(self) -> int:
        return self.rollout_length * self.num_envs

    @property
    def budget_shapes_updates(self) -> str:
        return "learning-rate schedule (anneal_learning_rate=true)" if self.anneal_learning_rate else ""

    @property
    def minibatch_size(self) -> int:
        return self.env_steps_per_update // self.num_minibatches

    def validate(self) -> None:
        """RunConfig's checks, that each rollout splits into whole minibatches and shuffle groups, that an
        asymmetric critic has no encoder to share, that a warm start's spread has a warm start, that the critic's
        warm-up ends before the run, and that a teacher named by preset names one (which one exists, the runner
        checks: presets are not the library's)."""
        super().validate()
        preset = teacher_preset_name(self.teacher)
        if preset == "":
            raise ValueError(f"teacher={self.teacher} names no preset: give teacher=preset:NAME or a run directory")
        if self.teacher_overrides and preset is None:
            raise ValueError("teacher_overrides apply to a teacher named by preset (teacher=preset:NAME) alone")
        if self.teacher == WARM_START_TEACHER and not self.init_from:
            raise ValueError(f"teacher={WARM_START_TEACHER} names the run this one warm-starts from: give init_from")
        if self.imitation_decay_updates and (not self.teacher or self.imitation_only):
            raise ValueError(
                f"imitation_decay_updates={self.imitation_decay_updates} decays the distillation loss beside PPO's: "
                "it needs teacher=... and imitation_only=false"
            )
        if self.asymmetric and self.shared_encoder:
            raise ValueError("asymmetric=true gives the critic the privileged state, not images: no encoder to share")
        if self.env_steps_per_update % self.num_minibatches:
            raise ValueError(
                f"rollout_length*num_envs={self.env_steps_per_update} must divide by "
                f"num_minibatches={self.num_minibatches}"
            )
        if self.num_envs % self.shuffle_groups or self.minibatch_size % self.shuffle_groups:
            raise ValueError(
                f"num_envs={self.num_envs} and the minibatch size {self.minibatch_size} must divide by "
                f"shuffle_groups={self.shuffle_groups}"
            )
        if self.warm_start_spread and not self.init_from:
            raise ValueError("warm_start_spread=true sets a warm-started policy's spread: give init_from")
        if self.critic_warm_up_updates and self.critic_warm_up_updates >= self.num_updates:
            raise ValueError(
                f"critic_warm_up_updates={self.critic_warm_up_updates} leaves the policy untrained: the run has "
                f"{self.num_updates:,} updates"
            )
