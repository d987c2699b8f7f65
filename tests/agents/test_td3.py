"""TD3 / DDPG: replay buffer, losses on hand-worked numbers, truncation handling, probe envs, a CPU solve."""

import dataclasses
import json

import jax
import jax.extend
import jax.numpy as jnp
import numpy as np
import pytest

from experiments.configs import td3 as td3_presets
from jaxarm.agents import registry
from jaxarm.agents.common import checkpoint, replay
from jaxarm.agents.common.augment import random_shift
from jaxarm.agents.common.trainer import make_train
from jaxarm.agents.td3 import TD3Config, make_trainer
from jaxarm.agents.td3.losses import (
    actor_loss,
    categorical_projection,
    critic_loss,
    critic_target,
    distributional_critic_loss,
    distributional_critic_target,
    n_step_returns,
    polyak_update,
    smoothed_target_action,
)
from jaxarm.agents.td3.networks import make_networks
from jaxarm.agents.td3.train import Experience, annealed_step_sizes, n_step_experience
from tests.agents.probe_envs import HOST_CHECKS, ConstantRewardEnv, HostCheckedEnv, ImageTargetEnv, TargetActionEnv

SMALL = dict(
    hidden_sizes=(32, 32),
    batch_size=64,
    buffer_size=4_096,
    updates_per_chunk=10,
    checkpoint_every_updates=10,
    eval_episodes=10,
)


def train(config, env=None, env_params=None, seed=0):
    trainer = make_trainer(config, env, env_params)
    state, metrics = jax.jit(make_train(trainer))(jax.random.PRNGKey(seed), config.hparams())
    return trainer, state, metrics


# Replay buffer


def test_replay_add_sample_and_wrap_around():
    buffer = replay.init({"x": jnp.zeros((), jnp.int32), "y": jnp.zeros((2,))}, capacity=5)
    buffer = replay.add(buffer, {"x": jnp.arange(3), "y": jnp.zeros((3, 2))})
    assert int(buffer.position) == 3 and int(buffer.size) == 3
    drawn = replay.sample(buffer, jax.random.PRNGKey(0), 200)
    assert drawn["y"].shape == (200, 2)
    assert set(np.asarray(drawn["x"]).tolist()) == {0, 1, 2}

    buffer = replay.add(buffer, {"x": jnp.arange(3, 7), "y": jnp.zeros((4, 2))})
    np.testing.assert_array_equal(buffer.items["x"], [5, 6, 2, 3, 4])
    assert int(buffer.position) == 2 and int(buffer.size) == 5
    drawn = replay.sample(buffer, jax.random.PRNGKey(1), 500)
    assert set(np.asarray(drawn["x"]).tolist()) == {2, 3, 4, 5, 6}

    with pytest.raises(ValueError, match="capacity"):
        replay.add(buffer, {"x": jnp.arange(6), "y": jnp.zeros((6, 2))})


# Losses on hand-worked numbers


def test_critic_target_takes_min_and_cuts_bootstrap_only_on_termination():
    next_q = jnp.array([[1.0, 2.0, 4.0], [3.0, 0.5, 4.0]])  # [C=2, B=3]
    reward = jnp.array([0.5, 1.0, 1.0])
    terminated = jnp.array([False, True, False])  # the third is e.g. a truncation: it bootstraps
    target = critic_target(next_q, reward, terminated, discount=jnp.float32(0.9), reward_scale=jnp.float32(2.0))
    # 2·0.5 + 0.9·min(1, 3); 2·1 (terminated); 2·1 + 0.9·4
    np.testing.assert_allclose(target, [1.9, 2.0, 5.6], rtol=1e-6)


def test_categorical_projection_shares_each_mass_between_the_two_nearest_atoms():
    atoms = jnp.array([0.0, 1.0, 2.0])
    values = jnp.array([[0.5, 1.0, 1.75], [-3.0, 2.7, 1.25]])  # the second row's ends lie beyond the span
    probs = jnp.array([[0.2, 0.3, 0.5], [0.5, 0.25, 0.25]])
    # Row 1: 0.5 splits 0.1 / 0.1 onto atoms 0, 1; 1.0 lands on atom 1; 1.75 gives 0.125 to atom 1, 0.375 to 2.
    # Row 2: -3 clips to atom 0, 2.7 to atom 2; 1.25 gives 0.1875 to atom 1 and 0.0625 to atom 2.
    expected = [[0.1, 0.525, 0.375], [0.5, 0.1875, 0.3125]]
    np.testing.assert_allclose(categorical_projection(values, probs, atoms), expected, atol=1e-6)


def test_distributional_target_shifts_the_least_critic_and_cuts_bootstrap_only_on_termination():
    atoms = jnp.linspace(-2.0, 2.0, 5)  # spacing 1
    low = jnp.log(jnp.array([0.0, 0.0, 0.5, 0.5, 0.0]) + 1e-30)  # mean 0.5
    high = jnp.log(jnp.array([0.0, 0.0, 0.0, 0.0, 1.0]) + 1e-30)  # mean 2
    # Critic 0 is the least at transition 0, critic 1 at transition 1.
    next_logits = jnp.stack([jnp.stack([low, high]), jnp.stack([high, low])])  # [C=2, B=2, N=5]
    target = distributional_critic_target(
        next_logits,
        reward=jnp.array([1.0, 10.0]),
        terminated=jnp.array([False, True]),
        discount=jnp.array([0.5, 0.5]),
        reward_scale=jnp.float32(0.1),
        atoms=atoms,
    )
    # Transition 0: 0.1 + 0.5·{0, 1} = {0.1, 0.6}, half each: atom 0 gets 0.45 + 0.2, atom 1 0.05 + 0.3.
    # Transition 1 terminated: all its mass at 0.1·10 = 1.
    np.testing.assert_allclose(target, [[0, 0, 0.65, 0.35, 0], [0, 0, 0, 1, 0]], atol=1e-6)
    # The cross-entropy of two uniform critics over 5 atoms is log 5 each, whatever the target.
    np.testing.assert_allclose(distributional_critic_loss(jnp.zeros((2, 2, 5)), target), 2 * np.log(5), rtol=1e-6)


def test_config_rejects_one_atom_and_an_empty_span():
    with pytest.raises(ValueError, match="critic_atoms must be 0"):
        TD3Config(critic_atoms=1).validate()
    with pytest.raises(ValueError, match="value_min"):
        TD3Config(critic_atoms=11, value_min=1.0, value_max=1.0).validate()


def test_n_step_returns_stop_at_an_episode_end_and_at_the_rollout_end():
    reward = jnp.array([[1.0], [2.0], [3.0], [4.0]])
    done = jnp.array([[False], [True], [False], [False]])
    returns, last, discount = n_step_returns(reward, done, jnp.float32(0.5), 3)
    # t=0: 1 + 0.5·2 (step 1 ends the episode); t=1: 2; t=2: 3 + 0.5·4 (the rollout ends); t=3: 4.
    np.testing.assert_allclose(returns[:, 0], [2.0, 2.0, 5.0, 4.0])
    np.testing.assert_array_equal(last[:, 0], [1, 1, 3, 3])
    np.testing.assert_allclose(discount[:, 0], [0.25, 0.5, 0.25, 0.5])
    one_step = n_step_returns(reward, done, jnp.float32(0.5), 1)
    np.testing.assert_array_equal(one_step[0], reward)
    np.testing.assert_array_equal(one_step[1][:, 0], [0, 1, 2, 3])
    np.testing.assert_array_equal(one_step[2], jnp.full((4, 1), 0.5))


def test_n_step_experience_bootstraps_from_the_last_summed_step():
    steps, envs = 3, 2
    experience = Experience(
        obs=jnp.arange(steps * envs, dtype=jnp.float32).reshape(steps, envs, 1),
        action=jnp.zeros((steps, envs, 1)),
        reward=jnp.ones((steps, envs)),
        next_obs=10.0 + jnp.arange(steps * envs, dtype=jnp.float32).reshape(steps, envs, 1),
        terminated=jnp.array([[False, True], [False, False], [True, False]]),
        discount=jnp.full((steps, envs), 0.9),
    )
    out = n_step_experience(experience, experience.terminated, jnp.float32(0.9), 2)
    np.testing.assert_array_equal(out.obs, experience.obs)
    # Env 0: steps 0-1, 1-2 (terminates at 2), 2. Env 1: step 0 (terminates), 1-2, 2.
    np.testing.assert_array_equal(out.next_obs[:, :, 0], [[12.0, 11.0], [14.0, 15.0], [14.0, 15.0]])
    np.testing.assert_array_equal(out.terminated, [[False, True], [True, False], [True, False]])
    np.testing.assert_allclose(out.reward, [[1.9, 1.0], [1.9, 1.9], [1.0, 1.0]])
    np.testing.assert_allclose(out.discount, [[0.81, 0.9], [0.81, 0.81], [0.9, 0.9]], rtol=1e-6)


def test_config_rejects_n_step_beyond_the_rollout():
    with pytest.raises(ValueError, match="n_step"):
        TD3Config(n_step=3, rollout_length=2).validate()


def test_critic_actor_losses_and_smoothing_and_polyak():
    q = jnp.array([[1.0, 2.0], [0.0, 2.0]])  # [C=2, B=2]
    target = jnp.array([1.0, 1.0])
    # critic 0: mean(0², 1²) = 0.5; critic 1: mean(1², 1²) = 1
    np.testing.assert_allclose(critic_loss(q, target), 1.5)
    np.testing.assert_allclose(critic_loss(q[:1], target), 0.5)  # DDPG: one critic, plain MSE
    np.testing.assert_allclose(actor_loss(jnp.array([1.0, 3.0])), -2.0)

    smoothed = smoothed_target_action(jnp.array([[0.9, -0.2]]), jnp.array([[0.8, -0.1]]), jnp.float32(0.5))
    np.testing.assert_allclose(smoothed, [[1.0, -0.3]], rtol=1e-6)  # noise clipped to 0.5, action to 1

    blended = polyak_update({"w": jnp.array([0.0, 10.0])}, {"w": jnp.array([1.0, 0.0])}, jnp.float32(0.1))
    np.testing.assert_allclose(blended["w"], [0.1, 9.0], rtol=1e-6)


# What gets stored


def test_replay_stores_pre_reset_next_obs_and_truncation_is_not_termination():
    config = TD3Config(
        env_params=(("max_episode_steps", 3),),
        num_envs=2,
        rollout_length=3,
        learning_starts=10**6,
        total_env_steps=6,
        **{**SMALL, "buffer_size": 16},
    )
    trainer = make_trainer(config)
    state, metrics = jax.jit(trainer.update)(trainer.init(jax.random.PRNGKey(0), config.hparams()), config.hparams())
    stored = jax.tree.map(lambda leaf: leaf[:6].reshape(3, 2, *leaf.shape[1:]), state.replay.items)  # [T, B]
    assert int(state.replay.size) == 6
    assert not np.any(stored.terminated)
    np.testing.assert_array_equal(stored.next_obs[:2], stored.obs[1:])
    # The last step hit the time limit: the stored next obs is the one it reached, not the reset obs.
    np.testing.assert_array_equal(stored.next_obs[2], state.env_state.final_obs)
    assert not np.allclose(stored.next_obs[2], state.env_state.obs)
    assert np.all(state.env_state.truncated)
    assert float(metrics.episodes.episodes) == 2


def test_a_rollout_checks_the_envs_host_faults_once_per_update_and_raises_on_one():
    config = TD3Config(num_envs=2, rollout_length=3, learning_starts=6, total_env_steps=18, **SMALL)
    env = HostCheckedEnv()
    HOST_CHECKS.clear()
    trainer, _, _ = train(config, env, env.default_params())
    assert {"checked": trainer.num_updates} == HOST_CHECKS  # and none by the steps themselves
    with pytest.raises(Exception, match="probe fault in 2 envs"):
        jax.block_until_ready(train(config, env, env.default_params().replace(fault_at=jnp.array(2, jnp.int32)))[1])


def test_the_warm_up_reads_updates_past_int32_env_steps():
    # 2^30 updates of 6 env steps each are 6.4e9 env steps, past int32: still past learning_starts, so it learns.
    config = TD3Config(
        num_envs=2, rollout_length=3, learning_starts=12, total_env_steps=6, **{**SMALL, "buffer_size": 16}
    )
    trainer = make_trainer(config)
    fresh = trainer.init(jax.random.PRNGKey(0), config.hparams())
    update = jax.jit(trainer.update)
    _, warming = update(fresh, config.hparams())
    _, learning = update(fresh.replace(updates=jnp.int32(2**30)), config.hparams())
    assert float(warming.critic_loss) == 0.0
    assert float(learning.critic_loss) > 0.0


# DDPG is a configuration of the same learner


def test_ddpg_preset_is_one_critic_no_smoothing_no_delay():
    config = td3_presets.ddpg_arm2d()
    assert (config.num_critics, config.policy_delay, config.target_smoothing) == (1, 1, False)
    assert registry.name_of(config) == "td3" and config.hidden_sizes == (100,) and config.batch_size == 32
    state = make_trainer(config).init(jax.random.PRNGKey(0), config.hparams())
    assert all(leaf.shape[0] == 1 for leaf in jax.tree.leaves(state.critic_params))


def test_annealed_step_sizes_fall_linearly_to_zero_over_the_run_and_stay_without_annealing():
    config = TD3Config(total_env_steps=400, num_envs=4, rollout_length=1, actor_learning_rate=1e-3)  # 100 updates
    hparams = config.hparams()
    annealed = dataclasses.replace(config, anneal_learning_rate=True)
    for updates, remaining in [(0, 1.0), (25, 0.75), (100, 0.0)]:
        step_sizes = annealed_step_sizes(annealed, hparams, jnp.int32(updates))
        np.testing.assert_allclose(step_sizes.actor_learning_rate, 1e-3 * remaining, rtol=1e-6)
        np.testing.assert_allclose(step_sizes.critic_learning_rate, config.critic_learning_rate * remaining, rtol=1e-6)
        assert annealed_step_sizes(config, hparams, jnp.int32(updates)) is hparams


def test_config_rejects_a_delay_that_does_not_divide_the_gradient_steps():
    with pytest.raises(ValueError, match="multiple of policy_delay"):
        TD3Config(policy_delay=2, grad_steps_per_update=3).validate()


# Probe envs with known answers

DDPG = dict(num_critics=1, policy_delay=1, target_smoothing=False)


THREE_STEP = dict(n_step=3, rollout_length=4, grad_steps_per_update=8)
"""3-step returns; four times the gradient steps per update, as an update collects four times the steps."""
C51 = dict(critic_atoms=21, value_min=-1.0, value_max=3.0)
"""Distributional critics, atoms 0.2 apart over returns of −1 … 3."""


@pytest.mark.parametrize(
    "terminate, expected_q, learner",
    [
        (False, 2.0, {}),
        (True, 1.0, DDPG),
        (False, 2.0, THREE_STEP),
        (True, 1.0, {**DDPG, **THREE_STEP}),
        (False, 2.0, C51),
        (True, 1.0, C51),
    ],
    ids=[
        "td3-truncation-bootstraps",
        "ddpg-termination-cuts",
        "td3-3-step-returns-across-truncations",
        "ddpg-3-step-returns-cut-at-termination",
        "td3-c51-truncation-bootstraps",
        "td3-c51-termination-cuts",
    ],
)
def test_critic_learns_constant_reward_value(terminate, expected_q, learner):
    """γ = 0.5, reward 1: Q = 1 / (1 − γ) = 2 when time limits truncate (bootstrap), 1 when terminating; the
    same with 3-step returns (episodes of 5 steps: returns cut at each episode's end and the rollout's)."""
    env = ConstantRewardEnv()
    env_params = env.default_params().replace(terminate=jnp.array(terminate))
    base = dict(gamma=0.5, num_envs=4, learning_starts=64, total_env_steps=4_000, grad_steps_per_update=2, tau=0.05)
    config = TD3Config(**{**base, **SMALL, **learner})
    trainer, state, metrics = train(config, env, env_params)
    obs = jnp.ones((3, 1))
    actions = jnp.array([[-1.0], [0.0], [1.0]])
    networks = make_networks(config, action_size=1)
    q = networks.q_values(networks.q(state.critic_params, obs, actions))
    assert q.shape == (config.num_critics, 3)
    np.testing.assert_allclose(q, expected_q, atol=0.1)
    # The actor trained in every update after learning_starts, with or without a policy delay.
    assert np.all(np.asarray(metrics.actor_loss[-10:]) != 0)


@pytest.mark.parametrize("critics", [{}, dict(critic_atoms=51, value_min=-2.0, value_max=0.0)], ids=["td3", "td3-c51"])
def test_actor_learns_observation_dependent_target_action(critics):
    # Rewards −Σ(a − target)² of two dims in ±0.5 lie in −2 … 0: the distributional critics' span.
    env = TargetActionEnv(action_size=2)
    config = TD3Config(
        num_envs=8, learning_starts=256, total_env_steps=8_000, grad_steps_per_update=4, **SMALL, **critics
    )
    trainer, state, _ = train(config, env, env.default_params())
    targets = jax.random.uniform(jax.random.PRNGKey(5), (64, 2), minval=-0.5, maxval=0.5)
    np.testing.assert_allclose(trainer.act(state, targets), targets, atol=0.1)


def test_mixed_exploration_noise_spreads_the_noise_over_the_envs():
    # The actor barely moves (a tiny learning rate) and sees one observation: it keeps one action, and each
    # stored action less that action is env e's noise, of std 0.2 · (e + 1) / 4.
    env = ConstantRewardEnv()
    config = TD3Config(
        num_envs=4,
        learning_starts=0,
        total_env_steps=8_000,
        exploration_noise=0.2,
        mixed_exploration_noise=True,
        actor_learning_rate=1e-12,
        **{**SMALL, "buffer_size": 8_000},
    )
    trainer, state, _ = train(config, env, env.default_params())
    policy = trainer.act(state, jnp.ones((1, 1)))[0, 0]
    noise = (np.asarray(state.replay.items.action)[:, 0] - float(policy)).reshape(-1, config.num_envs)
    np.testing.assert_allclose(noise.std(axis=0), [0.05, 0.1, 0.15, 0.2], rtol=0.1)


def test_normalised_observations_learn_a_target_shown_far_off_scale():
    # The target in ±0.5 is shown as 1000 + 100 · target; standardised, the networks see inputs of unit scale.
    env = TargetActionEnv(action_size=2, obs_offset=1000.0, obs_scale=100.0)
    config = TD3Config(
        num_envs=8,
        learning_starts=256,
        total_env_steps=16_000,
        grad_steps_per_update=4,
        normalize_observations=True,
        **SMALL,
    )
    trainer, state, _ = train(config, env, env.default_params())
    # Uniform in ±0.5 shown scaled: mean 1000 and std 100 / sqrt(12) per dim.
    np.testing.assert_allclose(state.normalizer.mean, [1000.0, 1000.0], atol=2.0)
    np.testing.assert_allclose(state.normalizer.std, [100 / np.sqrt(12)] * 2, rtol=0.05)
    targets = jax.random.uniform(jax.random.PRNGKey(5), (64, 2), minval=-0.5, maxval=0.5)
    np.testing.assert_allclose(trainer.act(state, 1000.0 + 100.0 * targets), targets, atol=0.1)


# Whole runs


@pytest.mark.slow
def test_vmap_over_seeds_and_learning_rates():
    config = TD3Config(num_envs=4, learning_starts=32, total_env_steps=160, grad_steps_per_update=2, **SMALL)
    trainer = make_trainer(config)
    hparams = jax.tree.map(lambda leaf: jnp.stack([leaf] * 4), config.hparams())
    hparams = hparams.replace(
        actor_learning_rate=jnp.array([1e-3, 1e-3, 1e-4, 1e-4]),
        critic_learning_rate=jnp.array([1e-3, 1e-3, 1e-4, 1e-4]),
    )
    keys = jnp.stack([jax.random.PRNGKey(seed) for seed in (0, 1, 0, 1)])
    state, metrics = jax.jit(jax.vmap(make_train(trainer)))(keys, hparams)
    assert metrics.critic_loss.shape == (4, trainer.num_updates)
    assert np.all(np.isfinite(metrics.critic_loss))
    assert np.all(np.asarray(state.updates) * trainer.env_steps_per_update == 160)
    actor_kernels = np.asarray(jax.tree.leaves(state.actor_params)[0])
    assert not np.allclose(actor_kernels[0], actor_kernels[1])  # seeds differ
    assert not np.allclose(actor_kernels[0], actor_kernels[2])  # learning rates differ


def test_learner_state_checkpoints_whole(tmp_path):
    config = TD3Config(num_envs=2, **SMALL)
    trainer = make_trainer(config)
    state = trainer.init(jax.random.PRNGKey(0), config.hparams())
    checkpoint.save(tmp_path, 4, state)
    restored = checkpoint.restore(tmp_path, trainer.init(jax.random.PRNGKey(1), config.hparams()))
    for saved, loaded in zip(jax.tree.leaves(state), jax.tree.leaves(restored), strict=True):
        np.testing.assert_array_equal(saved, loaded)


@pytest.mark.slow
def test_ddpg_arm2d_places_95_percent_on_each_of_seeds_0_to_4_each_run_as_a_user_runs_it(tmp_path):
    """`python -m experiments.run --config ddpg_arm2d seed=S` for S in 0-4, each a separate run (the seeds
    protocol), must place >= 95% of 1,000 fresh episodes: float-level differences between two programs (another
    CPU, seeds vmapped together) decided where the tutorial's settings ended (ddpg_arm2d_tutorial)."""
    from experiments import seeds

    out = tmp_path / "study"
    assert seeds.main(["--config", "ddpg_arm2d", "--seeds", "0-4", "--goal", "0.95", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["met"], seeds.markdown(summary)


def image_probe_config(shared_encoder: bool) -> TD3Config:
    return TD3Config(
        num_envs=8,
        learning_starts=256,
        total_env_steps=2_000,
        grad_steps_per_update=4,
        encoder="patches",
        encoder_features=16,
        shared_encoder=shared_encoder,
        random_shift_pad=2,
        **SMALL,
    )


@pytest.mark.parametrize("shared_encoder", [False, True])
def test_actor_and_critics_learn_from_images_with_random_shifts(shared_encoder):
    # The target (−0.5 or +0.5) shows only as a dark or bright image, which a shift leaves as it is.
    env = ImageTargetEnv()
    trainer, state, _ = train(image_probe_config(shared_encoder), env, env.default_params())
    assert state.replay.items.obs["image"].dtype == jnp.uint8
    images = {"image": jnp.stack([env.image(jnp.array(False)), env.image(jnp.array(True))])}
    np.testing.assert_allclose(trainer.act(state, images)[:, 0], [-0.5, 0.5], atol=0.1)
    assert ("encoder" in state.actor_params["params"]) != shared_encoder
    assert ("encoder" in state.critic_params) == shared_encoder


def test_the_shared_encoder_learns_from_the_critics_alone():
    env = ImageTargetEnv()
    networks = make_networks(image_probe_config(shared_encoder=True), 1, camera=True)
    obs = {"image": jnp.stack([env.image(jnp.array(False)), env.image(jnp.array(True))])}
    actor_params, critic_params = networks.init(
        jax.random.PRNGKey(0), jax.random.PRNGKey(1), 2, env.spec.zero_observation(), jnp.zeros(1)
    )

    def encoder_gradient(objective):
        gradient = jax.grad(objective)(critic_params)["encoder"]
        return max(float(jnp.abs(leaf).max()) for leaf in jax.tree.leaves(gradient))

    assert encoder_gradient(lambda params: networks.action(actor_params, networks.encode(params, obs)).sum()) == 0
    assert encoder_gradient(lambda params: networks.q(params, networks.encode(params, obs), jnp.ones((2, 1))).sum()) > 0


def qr_operand_shapes(jaxpr: jax.extend.core.Jaxpr) -> list[tuple[int, ...]]:
    """The operand shape of every QR factorisation in `jaxpr` and the jaxprs inside it (scans, loops, conds, pjit)."""
    shapes = [equation.invars[0].aval.shape for equation in jaxpr.eqns if equation.primitive.name == "qr"]
    for inner in jax.extend.core.subjaxprs(jaxpr):
        shapes += qr_operand_shapes(inner)
    return shapes


@pytest.mark.parametrize("shared_encoder", [False, True, None])
def test_the_critics_orthogonal_initialisations_are_never_batched(shared_encoder):
    # Batched, two QR factorisations deadlocked jaxlib 0.10.2's CPU runtime in its thread pool: td3_peg_pixels'
    # init hung within 300 repeats on the 2-core CPU with its shared encoder's heads vmapped (2026-11-29).
    config = image_probe_config(bool(shared_encoder)) if shared_encoder is not None else TD3Config(**SMALL)
    env = ImageTargetEnv() if shared_encoder is not None else TargetActionEnv()
    networks = make_networks(config, 1, camera=shared_encoder is not None)
    init = jax.make_jaxpr(lambda key: networks.init(key, key, 2, env.spec.zero_observation(), jnp.zeros(1)))
    shapes = qr_operand_shapes(init(jax.random.PRNGKey(0)).jaxpr)
    assert shapes and all(len(shape) == 2 for shape in shapes), shapes


def test_random_shift_moves_each_image_by_at_most_the_pad():
    images = jnp.zeros((64, 8, 8, 1), jnp.uint8).at[:, 4, 4, 0].set(255)
    shifted = random_shift(jax.random.PRNGKey(0), images, 2)
    assert shifted.shape == images.shape and shifted.dtype == jnp.uint8
    rows, columns = np.nonzero(np.asarray(shifted[..., 0]))[1:]
    assert len(rows) == 64  # one lit pixel each, none lost at the border
    assert set(rows) == set(range(2, 7)) and set(columns) == set(range(2, 7))
