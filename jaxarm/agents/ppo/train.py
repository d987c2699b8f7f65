"""PPO compiled end to end: rollout over vmapped envs, GAE, epochs × minibatches, all inside `lax.scan`.

One `update` collects `rollout_length` steps from every env with the stochastic policy, updates the
observation normaliser, computes GAE (bootstrapping from the pre-reset observation on truncation, not on
termination), and runs `num_epochs` × `num_minibatches` clipped-surrogate steps. The policy and value
functions are `PPONetworks` (networks.py); the tanh-squashed Gaussian and running statistics are brax's. The
three phases run under the named scopes `collect`, `advantages` and `sgd`, which profiles show in every op's
name (`python -m experiments.bench profile` sums time by them). What the run fixes when it is built (config,
networks, envs, teacher) is one `PPOSetup` record, the first argument of every phase.

With `asymmetric`, the env observes its privileged state beside the policy's input in the same step; rollouts,
GAE and the value loss carry it for the critic (bootstrapping from the final observation's privileged part),
while the policy, `act` and exports read only the rest. With a `teacher` (`jaxarm.agents.common.teachers`), each
sample is labelled with the teacher's action and the policy regresses onto it.
"""

import dataclasses
import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct

from jaxarm.agents.common import normalizer as observation_normalizer
from jaxarm.agents.common.config import HParams
from jaxarm.agents.common.encoders import numpy_encoder
from jaxarm.agents.common.networks import numpy_mlp_policy
from jaxarm.agents.common.permutation import random_permutation
from jaxarm.agents.common.teachers import Teacher
from jaxarm.agents.common.trainer import EpisodeSummary, Trainer, remaining_fraction, summarise_episodes
from jaxarm.agents.ppo import losses
from jaxarm.agents.ppo.config import PPOConfig
from jaxarm.agents.ppo.networks import NetworkParams, PPONetworks, make_networks
from jaxarm.envs import AutoReset, EnvSpec, EnvState, Observation, VmapEnv, compiler_options, deferred_step_checks
from jaxarm.envs.observation import IMAGE, PRIVILEGED
from jaxarm.export.numpy_policy import NumpyPolicy

SGD_STEPS_UNROLLED = 4
"""Minibatch steps per iteration of an epoch's loop. An iteration of a loop on the GPU waits for the previous one,
so its small kernels start one after the other with gaps between them; four steps per iteration cut the SGD phase
of a sorter update from 18.2 to 16.7 ms at 4,096 envs × 16 steps, 16 minibatches, and from 38.5 to 32.0 ms at
8,192 × 16, 32 minibatches (NVIDIA H100; `bench learner` times it). Every step unrolled gained nothing more and
compiled 3-6x longer."""


class PPOState(struct.PyTreeNode):
    """The whole learner state, checkpointed as one pytree.

    Attributes:
      params: network parameters.
      opt_state: Adam state over `params`.
      normalizer: brax running mean/std of observations (of a camera observation, its proprio part).
      env_state: [num_envs] batched env state; None in a state for acting (`Trainer.init_for_acting`).
      key: PRNG key (raw uint32[2]).
      updates: [] int32, updates done so far (env steps: `updates × env_steps_per_update`, counted on the host,
        where they may pass int32).
      critic_normalizer: running mean/std of the privileged observation the asymmetric critic reads; None (no
        leaves) otherwise.
    """

    params: NetworkParams
    opt_state: optax.OptState
    normalizer: observation_normalizer.Normalizer
    env_state: EnvState
    key: jax.Array
    updates: jax.Array
    critic_normalizer: observation_normalizer.Normalizer | None = None


@struct.dataclass
class PPOMetrics:
    """Scalars logged per update."""

    episodes: EpisodeSummary
    loss: losses.LossTerms
    learning_rate: jax.Array
    grad_norm: jax.Array


@struct.dataclass
class Samples:
    """Training samples, [T, B, ...] per field as the rollout holds them; `teacher_action` [T, B, A] only when
    distilling."""

    obs: Observation
    raw_action: jax.Array
    log_prob: jax.Array
    advantage: jax.Array
    target: jax.Array
    teacher_action: jax.Array | None = None


@dataclasses.dataclass(frozen=True)
class PPOSetup:
    """What a PPO run fixes when its trainer is built, and every update reads.

    Attributes:
      config: the run's sizes and choices.
      networks: the policy and value functions (`make_networks`).
      batch_env: the [num_envs] auto-resetting envs.
      env_params: the envs' params (arrays, constants of the compiled update).
      teacher: obs [B, ...] -> [B, A] the actions the policy is distilled onto; None without a teacher.
      sgd_unroll: minibatch steps per iteration of an epoch's loop (`SGD_STEPS_UNROLLED`).
    """

    config: PPOConfig
    networks: PPONetworks
    batch_env: VmapEnv
    env_params: Any
    teacher: Teacher | None = None
    sgd_unroll: int = SGD_STEPS_UNROLLED


@struct.dataclass
class SGDInputs:
    """What one update's SGD phase reads and never changes.

    Attributes:
      samples: the rollout's training samples, [T, B, ...] per field.
      normalizer: the observation statistics, updated with the rollout's observations.
      critic_normalizer: the asymmetric critic's (`PPOState.critic_normalizer`), updated likewise; None otherwise.
      hparams: the run's dynamic hyper-parameters.
      learning_rate: [] the update's step size (`learning_rate_at`).
      policy_weight: [] 1, or 0 while the critic warms up (`PPOConfig.critic_warm_up_updates`).
      imitation_weight: [] the distillation loss's weight at this update (`imitation_weight_at`).
    """

    samples: Samples
    normalizer: observation_normalizer.Normalizer
    critic_normalizer: observation_normalizer.Normalizer | None
    hparams: HParams
    learning_rate: jax.Array
    policy_weight: jax.Array
    imitation_weight: jax.Array


@struct.dataclass
class Rollout:
    """One rollout, [T, B, ...] per field. Observations are raw (not normalised; camera frames stay uint8)."""

    obs: Observation
    raw_action: jax.Array
    log_prob: jax.Array
    reward: jax.Array
    terminated: jax.Array
    done: jax.Array
    final_obs: Observation


def make_optimizer(hparams: HParams, learning_rate) -> optax.GradientTransformation:
    """Built inside the compiled update from dynamic values; its state does not depend on them."""
    return optax.chain(optax.clip_by_global_norm(hparams.max_grad_norm), optax.adam(learning_rate, eps=1e-5))


def minibatch_loss(
    setup: PPOSetup, params: NetworkParams, inputs: SGDInputs, batch: Samples, key: jax.Array
) -> tuple[jax.Array, losses.LossTerms]:
    """PPO's loss on one minibatch `batch` ([N, ...] per field) of `inputs.samples` (clipped surrogate, value
    error, entropy bonus; the first and last weighted by `inputs.policy_weight`) and its terms. With teacher actions
    in `batch`, the distillation loss is added, to the value loss alone where `config.imitation_only`."""
    config, networks, hparams = setup.config, setup.networks, inputs.hparams
    action_dist = networks.action_dist
    dist_params = networks.policy_params(params, inputs.normalizer, batch.obs)
    log_prob = action_dist.log_prob(dist_params, batch.raw_action)
    advantages = batch.advantage
    if config.normalize_advantages:
        advantages = losses.normalize(advantages)
    policy_loss, approx_kl, clip_fraction = losses.clipped_policy_loss(
        log_prob, batch.log_prob, advantages, hparams.clip_epsilon
    )
    values = networks.value(params, inputs.normalizer, batch.obs, inputs.critic_normalizer)
    value_loss = losses.value_loss(values, batch.target)
    entropy = jnp.mean(action_dist.entropy(dist_params, key))
    # A weight of exactly 1 leaves every product as it was: runs without a warm-up are unchanged, bit for bit.
    weight = inputs.policy_weight
    total = weight * policy_loss + hparams.value_coef * value_loss - weight * hparams.entropy_coef * entropy
    imitation = jnp.zeros(())
    if batch.teacher_action is not None:
        imitation = losses.imitation_loss(action_dist.mode(dist_params), batch.teacher_action)
        reinforced = hparams.value_coef * value_loss if config.imitation_only else total
        total = reinforced + inputs.imitation_weight * imitation
    return total, losses.LossTerms(policy_loss, value_loss, entropy, approx_kl, clip_fraction, imitation)


def shuffled_minibatches(config: PPOConfig, samples: Samples, key: jax.Array) -> Samples:
    """`samples` ([T, B, ...] per field) in a random order, as [num_minibatches, minibatch_size, ...].

    The B envs form `shuffle_groups` (G) groups of contiguous envs, each shuffled alone, and every minibatch takes
    minibatch_size / G samples from each group. A run splits its envs over devices in contiguous blocks, so where
    G is a multiple of the device count each device draws its share of every minibatch from its own samples, and
    the gradient steps run data-parallel; one shuffle over all samples (G = 1) gathers the whole batch onto every
    device each epoch. The grouping follows env indices, not devices: a config computes the same run on any count.
    """
    groups = config.shuffle_groups
    per_group = config.env_steps_per_update // groups
    # One group keeps the single shuffle's draws (the key itself, not a split of it).
    keys = jax.random.split(key, groups) if groups > 1 else key[None]
    orders = jax.vmap(lambda group_key: random_permutation(group_key, per_group))(keys)

    def shuffle(x: jax.Array) -> jax.Array:
        rollout_length, num_envs, *rest = x.shape
        by_group = x.reshape((rollout_length, groups, num_envs // groups, *rest)).swapaxes(0, 1)
        shuffled = jax.vmap(lambda group, order: group[order])(by_group.reshape((groups, per_group, *rest)), orders)
        split = shuffled.reshape((groups, config.num_minibatches, config.minibatch_size // groups, *rest))
        return split.swapaxes(0, 1).reshape((config.num_minibatches, config.minibatch_size, *rest))

    return jax.tree.map(shuffle, samples)


def sgd_epochs(setup: PPOSetup, params: NetworkParams, opt_state: optax.OptState, inputs: SGDInputs, key: jax.Array):
    """`num_epochs` passes of `num_minibatches` clipped-surrogate steps over freshly shuffled `inputs.samples`
    (`shuffled_minibatches`), `setup.sgd_unroll` steps per iteration of each epoch's loop.

    Returns ((params, opt_state), (loss terms, grad norms)), the last two [num_epochs, num_minibatches].
    """
    config = setup.config
    optimizer = make_optimizer(inputs.hparams, inputs.learning_rate)

    def sgd_step(carry, minibatch_and_key):
        params, opt_state = carry
        minibatch, key = minibatch_and_key
        grads, terms = jax.grad(minibatch_loss, argnums=1, has_aux=True)(setup, params, inputs, minibatch, key)
        updates, opt_state = optimizer.update(grads, opt_state, params)
        return (optax.apply_updates(params, updates), opt_state), (terms, optax.global_norm(grads))

    def epoch(carry, key):
        permute_key, step_key = jax.random.split(key)
        minibatches = shuffled_minibatches(config, inputs.samples, permute_key)
        return jax.lax.scan(
            sgd_step, carry, (minibatches, jax.random.split(step_key, config.num_minibatches)), unroll=setup.sgd_unroll
        )

    return jax.lax.scan(epoch, (params, opt_state), jax.random.split(key, config.num_epochs))


def init_state(setup: PPOSetup, key: jax.Array, hparams: HParams) -> PPOState:
    """A fresh learner: initialised networks and Adam state, empty normalisers, [num_envs] reset envs."""
    env_key = jax.random.split(key, 4)[2]
    acting = init_acting_state(setup.networks, setup.batch_env.spec, key, hparams)
    return acting.replace(env_state=setup.batch_env.reset(env_key, setup.env_params))


def init_acting_state(networks: PPONetworks, spec: EnvSpec, key: jax.Array, hparams: HParams) -> PPOState:
    """`init_state` without its envs (env_state None), from the same `key`."""
    policy_key, value_key, _, run_key = jax.random.split(key, 4)
    params = networks.init(policy_key, value_key, spec)
    return PPOState(
        params=params,
        opt_state=make_optimizer(hparams, hparams.learning_rate).init(params),
        normalizer=observation_normalizer.init(spec),
        env_state=None,  # type: ignore[arg-type]  # None only in a state for acting, which never trains
        key=run_key,
        updates=jnp.zeros((), jnp.int32),
        critic_normalizer=networks.init_critic_normalizer(spec),
    )


def collect(setup: PPOSetup, state: PPOState, key: jax.Array) -> tuple[EnvState, Rollout, EpisodeSummary]:
    """Steps the envs `rollout_length` times with the stochastic policy.

    Returns (env state [B], the rollout [T, B, ...], a summary of the episodes that finished).
    """
    networks, batch_env = setup.networks, setup.batch_env
    action_dist = networks.action_dist

    def env_step(env_state, step_key):
        dist_params = networks.policy_params(state.params, state.normalizer, env_state.obs)
        raw_action = action_dist.sample_no_postprocessing(dist_params, step_key)
        log_prob = action_dist.log_prob(dist_params, raw_action)
        next_state = batch_env.step(env_state, action_dist.postprocess(raw_action), setup.env_params)
        step = Rollout(
            obs=env_state.obs,
            raw_action=raw_action,
            log_prob=log_prob,
            reward=next_state.reward,
            terminated=next_state.terminated.astype(jnp.float32),
            done=next_state.done.astype(jnp.float32),
            final_obs=next_state.final_obs,
        )
        return next_state, (step, next_state)

    with deferred_step_checks():  # one check of the whole rollout, below, instead of one per step
        env_state, (rollout, states) = jax.lax.scan(
            env_step, state.env_state, jax.random.split(key, setup.config.rollout_length)
        )
    return batch_env.checked(env_state), rollout, summarise_episodes(states)


def advantage_samples(setup: PPOSetup, state: PPOState, rollout: Rollout, hparams: HParams):
    """(normaliser and critic normaliser updated with the rollout's observations, [T, B] training samples with
    GAE targets, labelled with the teacher's actions where there is one)."""
    config, networks, teacher = setup.config, setup.networks, setup.teacher
    normalizer = observation_normalizer.update(state.normalizer, config.normalize_observations, rollout.obs)
    critic_normalizer = state.critic_normalizer
    if config.asymmetric:
        critic_normalizer = observation_normalizer.update(
            critic_normalizer, config.normalize_observations, rollout.obs[PRIVILEGED]
        )
    values = networks.value(state.params, normalizer, rollout.obs, critic_normalizer)
    next_values = networks.value(state.params, normalizer, rollout.final_obs, critic_normalizer)
    advantages, targets = losses.gae(
        rollout.reward * hparams.reward_scale,
        values,
        next_values,
        rollout.terminated,
        rollout.done,
        hparams.gamma,
        hparams.gae_lambda,
    )
    teacher_action = None if teacher is None else jax.vmap(teacher)(rollout.obs)
    samples = Samples(rollout.obs, rollout.raw_action, rollout.log_prob, advantages, targets, teacher_action)
    return normalizer, critic_normalizer, samples


def learning_rate_at(config: PPOConfig, hparams: HParams, updates: jax.Array) -> jax.Array:
    """The step size after `updates` updates: annealed linearly to 0 over the run, or constant."""
    return hparams.learning_rate * (
        remaining_fraction(updates, config.num_updates) if config.anneal_learning_rate else 1.0
    )


def imitation_weight_at(config: PPOConfig, hparams: HParams, updates: jax.Array) -> jax.Array:
    """[] the distillation loss's weight after `updates` updates: `imitation_coef`, falling linearly to 0 over
    `imitation_decay_updates` (kickstarting), or constant where that is 0."""
    if not config.imitation_decay_updates:
        return hparams.imitation_coef
    return hparams.imitation_coef * jnp.maximum(remaining_fraction(updates, config.imitation_decay_updates), 0.0)


def optimizer_state_after_warm_up(config: PPOConfig, state: PPOState, hparams: HParams) -> optax.OptState:
    """`state.opt_state`, or a fresh one at the update that ends the critic's warm-up (`critic_warm_up_updates`):
    Adam's step count runs on through the warm-up while the policy's moments stay zero, and its bias correction
    would then make the policy's first steps 2-3x the learning rate, not a new run's."""
    if not config.critic_warm_up_updates:
        return state.opt_state
    fresh = make_optimizer(hparams, hparams.learning_rate).init(state.params)
    restart = state.updates == config.critic_warm_up_updates
    return jax.tree.map(lambda new, old: jnp.where(restart, new, old), fresh, state.opt_state)


def update(setup: PPOSetup, state: PPOState, hparams: HParams) -> tuple[PPOState, PPOMetrics]:
    """One update (the module docstring): collect, advantages, then the SGD epochs, each under its named scope."""
    collect_key, shuffle_key, next_key = jax.random.split(state.key, 3)
    with jax.named_scope("collect"):
        env_state, rollout, episodes = collect(setup, state, collect_key)
    with jax.named_scope("advantages"):
        normalizer, critic_normalizer, samples = advantage_samples(setup, state, rollout, hparams)
    learning_rate = learning_rate_at(setup.config, hparams, state.updates)
    policy_weight = (state.updates >= setup.config.critic_warm_up_updates).astype(jnp.float32)
    imitation_weight = imitation_weight_at(setup.config, hparams, state.updates)
    inputs = SGDInputs(samples, normalizer, critic_normalizer, hparams, learning_rate, policy_weight, imitation_weight)
    with jax.named_scope("sgd"):
        opt_state = optimizer_state_after_warm_up(setup.config, state, hparams)
        (params, opt_state), (terms, grad_norms) = sgd_epochs(setup, state.params, opt_state, inputs, shuffle_key)
    new_state = PPOState(
        params=params,
        opt_state=opt_state,
        normalizer=normalizer,
        env_state=env_state,
        key=next_key,
        updates=state.updates + 1,
        critic_normalizer=critic_normalizer,
    )
    metrics = PPOMetrics(
        episodes=episodes,
        loss=jax.tree.map(jnp.mean, terms),
        learning_rate=learning_rate,
        grad_norm=jnp.mean(grad_norms),
    )
    return new_state, metrics


def numpy_policy(config: PPOConfig, spec: EnvSpec, state: PPOState) -> NumpyPolicy:
    """The deterministic policy as arrays: the policy MLP (its first A outputs are the Gaussian's mean), the
    normaliser, and for a camera the policy's encoder."""
    encoder = None
    if not spec.flat_observation:
        encoder = numpy_encoder(config.encoder, state.params.policy["params"]["encoder"], spec.observation[IMAGE].shape)
    return numpy_mlp_policy(
        state.params.policy,
        spec,
        state.normalizer,
        config.normalize_observations,
        config.activation,
        offset=np.zeros(spec.action_size),
        scale=np.ones(spec.action_size),
        encoder=encoder,
    )


def make_trainer(config: PPOConfig, env=None, env_params=None, teacher: Teacher | None = None) -> Trainer:
    """PPO for `config` (see the module docstring). `env`, `env_params` replace the config's env (probes);
    `teacher` is the policy of `config.teacher`'s run (`jaxarm.runner.learners.make_trainer` loads it; a scripted
    one in tests)."""
    config.validate()
    if config.teacher and teacher is None:
        raise ValueError(
            f"teacher={config.teacher}: build this trainer with jaxarm.runner.learners.make_trainer, which loads the "
            "teacher's run"
        )
    if env is None:
        env, env_params = config.make_env()
    if config.asymmetric and PRIVILEGED not in (env.spec.observation_parts or {}):
        raise ValueError(
            f"asymmetric=true needs an env that observes its privileged state: {config.env} with a pixel obs_mode "
            "and env_kwargs.privileged=true"
        )
    networks = make_networks(config, env.spec.action_size, camera=not env.spec.flat_observation)

    def act(state: PPOState, obs):
        """Deterministic action: tanh of the Gaussian's mean, of the policy's input alone (an observation's
        privileged part, given or not, is never read)."""
        return networks.deterministic_action(state.params, state.normalizer, obs)

    setup = PPOSetup(config, networks, VmapEnv(AutoReset(env), config.num_envs), env_params, teacher)
    return Trainer(
        init=functools.partial(init_state, setup),
        init_for_acting=functools.partial(init_acting_state, networks, env.spec),
        update=functools.partial(update, setup),
        act=act,
        num_updates=config.num_updates,
        env_steps_per_update=config.env_steps_per_update,
        compiler_options=compiler_options(env),
        numpy_policy=functools.partial(numpy_policy, config, env.spec),
    )
