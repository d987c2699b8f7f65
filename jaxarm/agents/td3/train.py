"""TD3 (and DDPG, the same learner with one critic, no smoothing, no delay) compiled end to end.

One `update`: step all `num_envs` envs `rollout_length` times (uniform random actions before
`learning_starts`, then the actor plus Gaussian noise), add the transitions to the on-device replay
buffer, then run `grad_steps_per_update` gradient steps in blocks of `policy_delay` critic steps followed
by one actor step and one Polyak step of both target networks. Camera observations are stored as uint8 frames
and read through conv encoders (networks.py), with DrQ's random shift on training batches when
`random_shift_pad` > 0. With `n_step` > 1 each stored transition carries the discounted rewards of up to n
steps of its rollout (losses.n_step_returns). With `critic_atoms` the critics learn distributions of the return
(C51, losses.distributional_critic_target) and the actor their means. With `normalize_observations` the networks
read observations standardised by running statistics of every collected step (the replay keeps them raw).
Hyper-parameters arrive as `HParams` data, so `jax.vmap(make_train(trainer))(keys, hparams)` trains seeds ×
hyper-parameters at once; what the run fixes when it is built (config, networks, envs) is one `TD3Setup` record,
the first argument of every phase.
"""

import dataclasses
import functools
from collections.abc import Callable, Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct

from jaxarm.agents.common import normalizer as observation_normalizer
from jaxarm.agents.common import replay
from jaxarm.agents.common.augment import shift_observation
from jaxarm.agents.common.config import HParams
from jaxarm.agents.common.encoders import numpy_encoder
from jaxarm.agents.common.networks import numpy_mlp_policy
from jaxarm.agents.common.trainer import EpisodeSummary, Trainer, remaining_fraction, summarise_episodes
from jaxarm.agents.td3.config import TD3Config
from jaxarm.agents.td3.losses import (
    actor_loss,
    critic_loss,
    critic_target,
    distributional_critic_loss,
    distributional_critic_target,
    n_step_returns,
    polyak_update,
    smoothed_target_action,
)
from jaxarm.agents.td3.networks import Params, TD3Networks, make_networks
from jaxarm.envs import AutoReset, EnvSpec, EnvState, Observation, VmapEnv, compiler_options, deferred_step_checks
from jaxarm.envs.observation import IMAGE
from jaxarm.export.numpy_policy import NumpyPolicy


@struct.dataclass
class Experience:
    """One stored transition (leaves gain a leading [N] axis in batches).

    Attributes:
      obs: observation the action was taken in ([O], or a camera observation's parts; frames as uint8).
      action: [A] action in the actor's [-1, 1] units.
      reward: [] reward of the step, or with `n_step` > 1 the discounted sum of the rewards from it on.
      next_obs: observation the (last summed) step reached, before any auto-reset (`EnvState.final_obs`).
      terminated: [] bool, the task ended there (no bootstrap); a time-limit truncation is not termination.
      discount: [] the bootstrap's discount: γ, or γ^m for a reward summed over m steps.
    """

    obs: Observation
    action: jax.Array
    reward: jax.Array
    next_obs: Observation
    terminated: jax.Array
    discount: jax.Array


def n_step_experience(experience: Experience, done: jax.Array, gamma: jax.Array, n: int) -> Experience:
    """A rollout's one-step transitions [T, B] -> n-step ones (`n_step_returns`): each keeps its observation and
    action and takes the discounted rewards, the next observation and the termination of up to n steps."""
    returns, last, discount = n_step_returns(experience.reward, done, gamma, n)

    def at_last(leaf):
        return jnp.take_along_axis(leaf, last.reshape(*last.shape, *[1] * (leaf.ndim - 2)), 0)

    return dataclasses.replace(
        experience,
        reward=returns,
        next_obs=jax.tree.map(at_last, experience.next_obs),
        terminated=at_last(experience.terminated),
        discount=discount,
    )


@dataclasses.dataclass(frozen=True)
class TD3Setup:
    """What a TD3 run fixes when its trainer is built, and every update reads.

    Attributes:
      config: the run's sizes and choices.
      networks: the actor and critics (`make_networks`).
      batch_env: the [num_envs] auto-resetting envs.
      env_params: the envs' params (arrays, constants of the compiled update).
      shift_pad: the training images' random shift in pixels (`config.random_shift_pad` for a camera's
        observations, 0 for flat ones).
    """

    config: TD3Config
    networks: TD3Networks
    batch_env: VmapEnv
    env_params: Any
    shift_pad: int


class TD3State(struct.PyTreeNode):
    """The whole learner state (checkpointed as one pytree).

    Attributes:
      actor_params: online actor.
      critic_params: online critics, every leaf [num_critics, ...].
      target_actor_params: Polyak-averaged actor for the critic target.
      target_critic_params: Polyak-averaged critics, [num_critics, ...].
      actor_opt_state: Adam state of the actor.
      critic_opt_state: Adam state of the critics.
      normalizer: running mean and std of the collected observations (updated only with
        `normalize_observations`).
      replay: the replay buffer of `Experience`; None in a state for acting (`Trainer.init_for_acting`).
      env_state: the [num_envs] auto-resetting envs; None in a state for acting.
      key: PRNG key (raw uint32).
      updates: [] int32, updates done so far (env steps: `updates × env_steps_per_update`, counted on the host,
        where they may pass int32).
    """

    actor_params: Mapping[str, Any]
    critic_params: Mapping[str, Any]
    target_actor_params: Mapping[str, Any]
    target_critic_params: Mapping[str, Any]
    actor_opt_state: optax.OptState
    critic_opt_state: optax.OptState
    normalizer: observation_normalizer.Normalizer
    replay: replay.ReplayState
    env_state: EnvState
    key: jax.Array
    updates: jax.Array


@struct.dataclass
class TD3Metrics:
    """Per-update metrics, [] each: finished episodes, and the update's mean losses and Q.

    The losses and Q are 0 before `learning_starts` (no gradient steps yet).
    """

    episodes: EpisodeSummary
    critic_loss: jax.Array
    actor_loss: jax.Array
    q_mean: jax.Array


def to_env_action(spec: EnvSpec, action: jax.Array) -> jax.Array:
    """Actions [..., A] in the actor's [-1, 1] units -> the env's [action_low, action_high]."""
    return spec.action_low + (action + 1.0) * (0.5 * (spec.action_high - spec.action_low))


def standardized(config: TD3Config, normalizer: observation_normalizer.Normalizer, obs: Observation) -> Observation:
    """Observations [B, ...] as the networks read them: standardised where the config normalises them."""
    return observation_normalizer.normalize(normalizer, config.normalize_observations, obs)


def augmented(key: jax.Array, stream: int, obs: Observation, shift_pad: int) -> Observation:
    """Observations [B, ...] randomly shifted by up to `shift_pad` pixels (0: as they are), with a key folded from
    `key` (whose own draws, and so the numbers of runs without augmentation, stay as they are)."""
    if not shift_pad:
        return obs
    return shift_observation(jax.random.fold_in(key, stream), obs, shift_pad)


def exploration_scales(config: TD3Config) -> jax.Array:
    """[B, 1] each env's share of `exploration_noise` (see `TD3Config.mixed_exploration_noise`)."""
    if config.mixed_exploration_noise:
        return (jnp.arange(1, config.num_envs + 1) / config.num_envs)[:, None]
    return jnp.ones((config.num_envs, 1))


def warm_up_steps(config: TD3Config, updates: jax.Array) -> jax.Array:
    """[] int32 env steps collected before update `updates`, as far as `learning_starts` reads them: counted up to
    the first update past the warm-up and constant after, so that the count never leaves int32."""
    warm_up_updates = -(-config.learning_starts // config.env_steps_per_update)
    return jnp.minimum(updates, warm_up_updates) * config.env_steps_per_update


def init_state(setup: TD3Setup, key: jax.Array) -> TD3State:
    """A fresh learner: networks and their targets initialised alike, an empty replay, [num_envs] reset envs."""
    config, batch_env = setup.config, setup.batch_env
    spec = batch_env.spec
    env_key = jax.random.split(key, 4)[2]
    obs = spec.zero_observation()
    zero = jnp.zeros((), jnp.float32)
    example = Experience(
        obs=obs,
        action=jnp.zeros((spec.action_size,), jnp.float32),
        reward=zero,
        next_obs=obs,
        terminated=jnp.zeros((), jnp.bool_),
        discount=zero,
    )
    return init_acting_state(config, setup.networks, spec, key).replace(
        replay=replay.init(example, config.buffer_size), env_state=batch_env.reset(env_key, setup.env_params)
    )


def init_acting_state(config: TD3Config, networks: TD3Networks, spec: EnvSpec, key: jax.Array) -> TD3State:
    """`init_state` without its replay and envs (both None), from the same `key`."""
    actor_key, critic_key, _, state_key = jax.random.split(key, 4)
    obs = spec.zero_observation()
    action = jnp.zeros((spec.action_size,), jnp.float32)
    actor_params, critic_params = networks.init(actor_key, critic_key, config.num_critics, obs, action)
    # optax.adam(lr) holds no state that depends on lr, so the update rebuilds it per step from the traced
    # hyper-parameter; the step size stays data and vmaps.
    optimizer_state_init = optax.adam(0.0).init
    return TD3State(
        actor_params=actor_params,
        critic_params=critic_params,
        target_actor_params=actor_params,
        target_critic_params=critic_params,
        actor_opt_state=optimizer_state_init(actor_params),
        critic_opt_state=optimizer_state_init(critic_params),
        normalizer=observation_normalizer.init(spec),
        # None only in a state for acting, which never trains: the fields keep the training state's types.
        replay=None,  # type: ignore[arg-type]
        env_state=None,  # type: ignore[arg-type]
        key=state_key,
        updates=jnp.zeros((), jnp.int32),
    )


def collect(
    setup: TD3Setup, state: TD3State, hparams: HParams, key: jax.Array
) -> tuple[EnvState, jax.Array, Experience, EnvState]:
    """Steps the envs `rollout_length` times: uniform random actions while fewer than `learning_starts` env steps
    are collected, then the actor's plus Gaussian noise.

    Returns (env state [B], env steps as `warm_up_steps` counts them, experience [T*B], states [T, B]).
    """
    config, networks, batch_env = setup.config, setup.networks, setup.batch_env
    spec = batch_env.spec
    scales = exploration_scales(config)

    def env_step(carry, step_key):
        env_state, env_steps = carry
        noise_key, random_key = jax.random.split(step_key)
        shape = (config.num_envs, spec.action_size)
        obs = standardized(config, state.normalizer, env_state.obs)
        policy = networks.action(state.actor_params, networks.encode(state.critic_params, obs))
        noise = scales * hparams.exploration_noise * jax.random.normal(noise_key, shape)
        noisy = jnp.clip(policy + noise, -1.0, 1.0)
        random = jax.random.uniform(random_key, shape, minval=-1.0, maxval=1.0)
        action = jnp.where(env_steps < config.learning_starts, random, noisy)
        next_state = batch_env.step(env_state, to_env_action(spec, action), setup.env_params)
        experience = Experience(
            obs=env_state.obs,
            action=action,
            reward=next_state.reward,
            next_obs=next_state.final_obs,
            terminated=next_state.terminated,
            discount=jnp.broadcast_to(hparams.gamma, next_state.reward.shape),
        )
        return (next_state, env_steps + config.num_envs), (experience, next_state)

    step_keys = jax.random.split(key, config.rollout_length)
    with deferred_step_checks():  # one check of the whole rollout, below, instead of one per step
        (env_state, env_steps), (experience, states) = jax.lax.scan(
            env_step, (state.env_state, warm_up_steps(config, state.updates)), step_keys
        )
    env_state = batch_env.checked(env_state)
    if config.n_step > 1:
        experience = n_step_experience(experience, states.done, hparams.gamma, config.n_step)
    flat = jax.tree.map(lambda leaf: leaf.reshape(-1, *leaf.shape[2:]), experience)
    return env_state, env_steps, flat, states


def critic_step(
    setup: TD3Setup,
    hparams: HParams,
    state: TD3State,
    critic: tuple[Params, optax.OptState],
    batch_and_key: tuple[Experience, jax.Array],
) -> tuple[tuple[Params, optax.OptState], tuple[jax.Array, jax.Array]]:
    """One gradient step of the critics (params, Adam state) on a batch of `Experience` [N] towards the targets of
    `state`'s target networks (smoothed target actions with `target_smoothing`; distributions with atoms).

    Returns ((critic params, Adam state), ([] loss, [] mean Q of the batch)).
    """
    config, networks, shift_pad = setup.config, setup.networks, setup.shift_pad
    critic_params, opt_state = critic
    batch, noise_key = batch_and_key
    batch = dataclasses.replace(
        batch,
        obs=standardized(config, state.normalizer, augmented(noise_key, 1, batch.obs, shift_pad)),
        next_obs=standardized(config, state.normalizer, augmented(noise_key, 2, batch.next_obs, shift_pad)),
    )
    next_encoded = networks.encode(state.target_critic_params, batch.next_obs)
    next_action = networks.action(state.target_actor_params, next_encoded)
    if config.target_smoothing:
        noise = hparams.target_noise * jax.random.normal(noise_key, next_action.shape)
        next_action = smoothed_target_action(next_action, noise, hparams.target_noise_clip)
    next_outputs = networks.q(state.target_critic_params, next_encoded, next_action)
    target_args = (batch.reward, batch.terminated, batch.discount, hparams.reward_scale)
    loss_of_outputs: Callable[[jax.Array, jax.Array], jax.Array]
    if networks.atoms is None:
        target = critic_target(next_outputs, *target_args)
        loss_of_outputs = critic_loss
    else:
        target = distributional_critic_target(next_outputs, *target_args, jnp.asarray(networks.atoms))
        loss_of_outputs = distributional_critic_loss

    def loss_fn(params):
        outputs = networks.q(params, networks.encode(params, batch.obs), batch.action)
        return loss_of_outputs(outputs, target), networks.q_values(outputs)

    (loss, q), grads = jax.value_and_grad(loss_fn, has_aux=True)(critic_params)
    updates, opt_state = optax.adam(hparams.critic_learning_rate).update(grads, opt_state, critic_params)
    return (optax.apply_updates(critic_params, updates), opt_state), (loss, jnp.mean(q))


def actor_step(
    networks: TD3Networks,
    actor: tuple[Params, optax.OptState],
    critic_params: Params,
    obs: Observation,
    hparams: HParams,
) -> tuple[tuple[Params, optax.OptState], jax.Array]:
    """One gradient step of the actor (params, Adam state) raising the first critic's Q of its actions in `obs`
    [N, ...] (as the networks read them). Returns ((actor params, Adam state), [] loss)."""
    params, opt_state = actor
    encoded = networks.encode(critic_params, obs)

    def loss_fn(actor_params):
        q = networks.q_values(networks.q(critic_params, encoded, networks.action(actor_params, encoded)))
        return actor_loss(q[0])

    loss, grads = jax.value_and_grad(loss_fn)(params)
    updates, opt_state = optax.adam(hparams.actor_learning_rate).update(grads, opt_state, params)
    return (optax.apply_updates(params, updates), opt_state), loss


def delayed_block(
    setup: TD3Setup, state: TD3State, key: jax.Array, hparams: HParams
) -> tuple[TD3State, tuple[jax.Array, jax.Array, jax.Array]]:
    """`policy_delay` critic steps on fresh replay batches, then one actor step and one Polyak step of both target
    networks. Returns (state, ([] mean critic loss, [] actor loss, [] mean Q))."""
    config = setup.config
    sample_key, noise_key = jax.random.split(key)
    batches = replay.sample(state.replay, sample_key, config.policy_delay * config.batch_size)
    batches = jax.tree.map(lambda leaf: leaf.reshape(config.policy_delay, config.batch_size, *leaf.shape[1:]), batches)
    (critic_params, critic_opt_state), (critic_losses, q_means) = jax.lax.scan(
        functools.partial(critic_step, setup, hparams, state),
        (state.critic_params, state.critic_opt_state),
        (batches, jax.random.split(noise_key, config.policy_delay)),
    )
    last_obs = jax.tree.map(lambda leaf: leaf[-1], batches.obs)
    (actor_params, actor_opt_state), loss = actor_step(
        setup.networks,
        (state.actor_params, state.actor_opt_state),
        critic_params,
        standardized(config, state.normalizer, augmented(key, 1, last_obs, setup.shift_pad)),
        hparams,
    )
    state = state.replace(
        actor_params=actor_params,
        critic_params=critic_params,
        actor_opt_state=actor_opt_state,
        critic_opt_state=critic_opt_state,
        target_actor_params=polyak_update(state.target_actor_params, actor_params, hparams.tau),
        target_critic_params=polyak_update(state.target_critic_params, critic_params, hparams.tau),
    )
    return state, (jnp.mean(critic_losses), loss, jnp.mean(q_means))


def learn(
    setup: TD3Setup, state: TD3State, key: jax.Array, hparams: HParams
) -> tuple[TD3State, tuple[jax.Array, jax.Array, jax.Array]]:
    """`grad_steps_per_update` gradient steps in `delayed_block`s. Returns (state, the blocks' mean losses and Q)."""
    blocks = setup.config.grad_steps_per_update // setup.config.policy_delay
    state, (critic_losses, actor_losses, q_means) = jax.lax.scan(
        lambda carry, block_key: delayed_block(setup, carry, block_key, hparams),
        state,
        jax.random.split(key, blocks),
    )
    return state, (jnp.mean(critic_losses), jnp.mean(actor_losses), jnp.mean(q_means))


def annealed_step_sizes(config: TD3Config, hparams: HParams, updates: jax.Array) -> HParams:
    """`hparams` with the actor's and the critics' step sizes after `updates` updates: annealed linearly to 0 over
    the run (`anneal_learning_rate`), or as they are."""
    if not config.anneal_learning_rate:
        return hparams
    remaining = remaining_fraction(updates, config.num_updates)
    return hparams.replace(
        actor_learning_rate=hparams.actor_learning_rate * remaining,
        critic_learning_rate=hparams.critic_learning_rate * remaining,
    )


def update(setup: TD3Setup, state: TD3State, hparams: HParams) -> tuple[TD3State, TD3Metrics]:
    """One update (the module docstring): collect, store, and learn once `learning_starts` env steps are in."""
    config = setup.config
    key, collect_key, learn_key = jax.random.split(state.key, 3)
    step_sizes = annealed_step_sizes(config, hparams, state.updates)
    env_state, env_steps, experience, states = collect(setup, state, hparams, collect_key)
    normalizer = observation_normalizer.update(state.normalizer, config.normalize_observations, experience.obs)
    state = state.replace(
        normalizer=normalizer,
        env_state=env_state,
        key=key,
        updates=state.updates + 1,
        replay=replay.add(state.replay, experience),
    )

    def skip_learning(state: TD3State, key: jax.Array, hparams: HParams):
        del key, hparams
        zero = jnp.zeros((), jnp.float32)
        return state, (zero, zero, zero)

    state, (critic_loss_value, actor_loss_value, q_mean) = jax.lax.cond(
        env_steps >= config.learning_starts,
        functools.partial(learn, setup),
        skip_learning,
        state,
        learn_key,
        step_sizes,
    )
    metrics = TD3Metrics(
        episodes=summarise_episodes(states),
        critic_loss=critic_loss_value,
        actor_loss=actor_loss_value,
        q_mean=q_mean,
    )
    return state, metrics


def numpy_policy(config: TD3Config, spec: EnvSpec, state: TD3State) -> NumpyPolicy:
    """The actor as arrays: its MLP, and the map of its tanh outputs onto the env's action bounds."""
    half_range = 0.5 * (spec.action_high - spec.action_low)
    encoder = None
    if not spec.flat_observation:
        # The shared encoder's params sit beside the critics' heads (`TD3Networks`), an own one in the actor's.
        if config.shared_encoder:
            params = state.critic_params["encoder"]["params"]
        else:
            params = state.actor_params["params"]["encoder"]
        encoder = numpy_encoder(config.encoder, params, spec.observation[IMAGE].shape)
    return numpy_mlp_policy(
        state.actor_params,
        spec,
        state.normalizer,
        config.normalize_observations,
        config.activation,
        offset=np.full(spec.action_size, spec.action_low + half_range),
        scale=np.full(spec.action_size, half_range),
        encoder=encoder,
    )


def make_trainer(config: TD3Config, env=None, env_params=None) -> Trainer:
    """Builds the TD3 / DDPG trainer for `config`. `env`, `env_params` replace the config's env (probe envs)."""
    config.validate()
    if env is None:
        env, env_params = config.make_env()
    spec = env.spec
    camera = not spec.flat_observation
    networks = make_networks(config, spec.action_size, camera)
    batch_env = VmapEnv(AutoReset(env), config.num_envs)
    setup = TD3Setup(config, networks, batch_env, env_params, shift_pad=config.random_shift_pad if camera else 0)

    def act(state: TD3State, obs: jax.Array) -> jax.Array:
        encoded = networks.encode(state.critic_params, standardized(config, state.normalizer, obs))
        return to_env_action(spec, networks.action(state.actor_params, encoded))

    return Trainer(
        init=lambda key, hparams: init_state(setup, key),
        init_for_acting=lambda key, hparams: init_acting_state(config, networks, spec, key),
        update=functools.partial(update, setup),
        act=act,
        num_updates=config.num_updates,
        env_steps_per_update=config.env_steps_per_update,
        compiler_options=compiler_options(env),
        numpy_policy=functools.partial(numpy_policy, config, spec),
    )
