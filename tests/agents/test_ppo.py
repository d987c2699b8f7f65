"""PPO: whole-run compilation, vmap over seeds × hyper-parameters, probe envs, and a small solve on arm2d."""

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from jaxarm.agents.common.evaluate import evaluate
from jaxarm.agents.common.teachers import teacher_input
from jaxarm.agents.common.trainer import make_chunk_runner, make_train
from jaxarm.agents.ppo import PPOConfig, make_networks, make_trainer
from jaxarm.agents.ppo.train import Samples, imitation_weight_at, shuffled_minibatches
from jaxarm.agents.ppo.warm_start import warm_start
from jaxarm.envs.observation import PRIVILEGED, actor_observation
from tests.agents.probe_envs import HOST_CHECKS, ConstantRewardEnv, HostCheckedEnv, ImageTargetEnv, TargetActionEnv

TINY = PPOConfig(
    num_envs=8,
    rollout_length=4,
    num_minibatches=2,
    num_epochs=2,
    total_env_steps=32 * 4,
    updates_per_chunk=2,
    policy_hidden_sizes=(16,),
    value_hidden_sizes=(16,),
)


def test_whole_run_equals_the_chunked_run():
    trainer = make_trainer(TINY)
    hparams = TINY.hparams()
    whole_state, whole_metrics = jax.jit(make_train(trainer))(jax.random.PRNGKey(0), hparams)
    state = jax.jit(trainer.init)(jax.random.PRNGKey(0), hparams)
    chunk = make_chunk_runner(trainer, TINY.updates_per_chunk)
    for _ in range(trainer.num_updates // TINY.updates_per_chunk):
        state, _ = chunk(state, hparams)
    assert int(whole_state.updates) == trainer.num_updates == 4
    for whole, chunked in zip(jax.tree.leaves(whole_state.params), jax.tree.leaves(state.params), strict=True):
        np.testing.assert_allclose(whole, chunked, rtol=1e-5, atol=1e-6)


def test_a_warm_start_keeps_the_trained_means_with_the_trained_spread_or_a_fresh_one():
    source = TINY  # trained with initial_log_std 0
    plain = dataclasses.replace(TINY, initial_log_std=-0.6)
    config = dataclasses.replace(plain, warm_start_spread=True)  # as a run with init_from has it
    fresh = jax.jit(make_trainer(plain).init)(jax.random.PRNGKey(0), plain.hparams())
    # A "trained" policy whose spread differs from state to state: every weight drawn at random.
    leaves, tree = jax.tree.flatten(fresh.params)
    keys = jax.random.split(jax.random.PRNGKey(1), len(leaves))
    drawn = [jax.random.normal(key, leaf.shape) for key, leaf in zip(keys, leaves, strict=True)]
    trained = fresh.replace(params=jax.tree.unflatten(tree, drawn))
    size = fresh.normalizer.mean.shape[0]
    action_size = plain.make_env()[0].spec.action_size
    obs = jax.random.normal(jax.random.PRNGKey(2), (64, size))
    trained_params = make_networks(source, action_size).policy_params(trained.params, trained.normalizer, obs)
    trained_loc, trained_scale = jnp.split(trained_params, 2, -1)
    assert float(jnp.std(trained_scale)) > 0.1, "the trained spread was uniform: the test shows nothing"
    networks = make_networks(plain, action_size)

    def started_with(config):
        started = warm_start(config, source, fresh, trained, np.arange(size), np.zeros(size, np.float32))
        assert tree_equal(started.params.value, trained.params.value)
        return jnp.split(networks.policy_params(started.params, started.normalizer, obs), 2, -1)

    loc, scale = started_with(config)
    np.testing.assert_allclose(loc, trained_loc, rtol=1e-6)
    np.testing.assert_allclose(jax.nn.softplus(scale), np.exp(-0.6), rtol=1e-5)
    # Without: the trained spread, though the new run's initial_log_std differs from the source's.
    loc, scale = started_with(plain)
    np.testing.assert_allclose(loc, trained_loc, rtol=1e-6)
    np.testing.assert_allclose(jax.nn.softplus(scale), jax.nn.softplus(trained_scale), rtol=1e-5)
    same = warm_start(source, source, fresh, trained, np.arange(size), np.zeros(size, np.float32))
    assert tree_equal(same.params.policy, trained.params.policy)


def test_a_critic_warm_up_trains_the_value_alone_then_starts_the_policy_as_a_new_run_would():
    config = dataclasses.replace(TINY, critic_warm_up_updates=2)
    trainer, hparams = make_trainer(config), config.hparams()
    one_update = make_chunk_runner(trainer, 1)  # donates the state it is given: compare copies
    start = jax.device_get(jax.jit(trainer.init)(jax.random.PRNGKey(0), hparams))
    warmed = jax.device_get(one_update(one_update(start, hparams)[0], hparams)[0])
    assert tree_equal(warmed.params.policy, start.params.policy)
    assert not tree_equal(warmed.params.value, start.params.value)
    # The first policy step is a new run's: Adam starts afresh, its step count that of a run's first update.
    after, _ = one_update(warmed, hparams)
    assert not tree_equal(after.params.policy, warmed.params.policy)
    plain = make_trainer(TINY)
    new_run, _ = make_chunk_runner(plain, 1)(jax.jit(plain.init)(jax.random.PRNGKey(0), hparams), hparams)
    assert optax.tree_utils.tree_get(after.opt_state, "count") == optax.tree_utils.tree_get(new_run.opt_state, "count")


def tree_equal(a, b) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True))


def test_a_rollout_checks_the_envs_host_faults_once_per_update_and_raises_on_one():
    env = HostCheckedEnv()
    clean = make_trainer(TINY, env, env.default_params())
    HOST_CHECKS.clear()
    jax.block_until_ready(jax.jit(make_train(clean))(jax.random.PRNGKey(0), TINY.hparams()))
    assert {"checked": clean.num_updates} == HOST_CHECKS  # and none by the steps themselves
    faulty = make_trainer(TINY, env, env.default_params().replace(fault_at=jnp.array(2, jnp.int32)))
    with pytest.raises(Exception, match="probe fault in 8 envs"):
        jax.block_until_ready(jax.jit(make_train(faulty))(jax.random.PRNGKey(0), TINY.hparams()))


@pytest.mark.slow
def test_vmap_over_seeds_and_hyper_parameters():
    trainer = make_trainer(TINY)
    seeds, rates = jnp.meshgrid(jnp.arange(2), jnp.array([1e-4, 1e-2]), indexing="ij")
    hparams = jax.tree.map(lambda leaf: jnp.broadcast_to(leaf, (4,)), TINY.hparams())
    hparams = hparams.replace(learning_rate=rates.ravel())
    keys = jax.vmap(jax.random.PRNGKey)(seeds.ravel())
    states, metrics = jax.jit(jax.vmap(make_train(trainer)))(keys, hparams)
    assert metrics.loss.policy_loss.shape == (4, trainer.num_updates)
    assert np.all(np.isfinite(metrics.loss.value_loss))
    np.testing.assert_allclose(metrics.learning_rate[:, 0], rates.ravel())
    first_layer = states.params.policy["params"]["Dense_0"]["kernel"]
    assert not np.allclose(first_layer[0], first_layer[1])  # learning rates differ
    assert not np.allclose(first_layer[0], first_layer[2])  # seeds differ


def test_sizes_that_do_not_split_into_minibatches_are_rejected():
    with pytest.raises(ValueError, match="num_minibatches"):
        make_trainer(dataclasses.replace(TINY, num_minibatches=3))


@pytest.mark.parametrize("groups", [1, 4])
def test_each_minibatch_draws_an_equal_share_of_every_env_group_once(groups):
    config = PPOConfig(num_envs=8, rollout_length=3, num_minibatches=2, shuffle_groups=groups)
    # Each sample is its own index: env e's step t is t * 8 + e.
    index = jnp.arange(3 * 8).reshape(3, 8)
    samples = Samples(obs=index, raw_action=index, log_prob=index, advantage=index, target=index)
    minibatches = np.asarray(shuffled_minibatches(config, samples, jax.random.PRNGKey(0)).obs)
    assert minibatches.shape == (2, 12)
    assert sorted(minibatches.ravel()) == list(range(24))
    group_of = (minibatches % 8) // (8 // groups)
    for minibatch in group_of:
        assert np.bincount(minibatch, minlength=groups).tolist() == [12 // groups] * groups


def test_shuffle_groups_that_do_not_split_the_envs_or_minibatches_are_rejected():
    with pytest.raises(ValueError, match="shuffle_groups=3"):
        PPOConfig(num_envs=8, rollout_length=3, num_minibatches=2, shuffle_groups=3).validate()


@pytest.mark.slow
def test_ppo_solves_the_fixed_goal_arm():
    config = PPOConfig(
        num_envs=256,
        rollout_length=16,
        num_minibatches=4,
        total_env_steps=600_000,
        updates_per_chunk=10,
        gamma=0.9,
        learning_rate=3e-3,
        env_params=(("success_bonus", 10.0),),
    )
    trainer = make_trainer(config)
    state, metrics = jax.jit(make_train(trainer))(jax.random.PRNGKey(0), config.hparams())
    env, env_params = config.make_env()
    result = evaluate(env, env_params, lambda obs: trainer.act(state, obs), jax.random.PRNGKey(1), 100)
    assert float(result.successes.mean()) >= 0.95


PROBE = PPOConfig(
    num_envs=64,
    rollout_length=8,
    num_minibatches=4,
    num_epochs=4,
    total_env_steps=64 * 8 * 60,
    updates_per_chunk=60,
    policy_hidden_sizes=(32,),
    value_hidden_sizes=(32,),
    gamma=0.9,
    learning_rate=3e-3,
    entropy_coef=0.0,
)


def probe_value(config, state, obs):
    """V(obs) of a trained PPO state, through the same normaliser and network the learner uses."""
    return make_networks(config, 1).value(state.params, state.normalizer, obs)


@pytest.mark.parametrize("terminate, expected", [(True, 1.0), (False, 1.0 / (1.0 - 0.9))])
def test_value_learns_termination_and_bootstraps_truncation(terminate, expected):
    env = ConstantRewardEnv()
    params = env.default_params().replace(terminate=jnp.array(terminate))
    trainer = make_trainer(PROBE, env, params)
    state, _ = jax.jit(make_train(trainer))(jax.random.PRNGKey(0), PROBE.hparams())
    value = float(probe_value(PROBE, state, jnp.ones((1, 1)))[0])
    assert abs(value - expected) < 0.1 * expected, value


def test_policy_learns_an_observation_dependent_action():
    env = TargetActionEnv()
    trainer = make_trainer(PROBE, env, env.default_params())
    state, _ = jax.jit(make_train(trainer))(jax.random.PRNGKey(0), PROBE.hparams())
    targets = jnp.linspace(-0.5, 0.5, 11)[:, None]
    np.testing.assert_allclose(trainer.act(state, targets), targets, atol=0.1)


@pytest.mark.parametrize(("imitation_only", "teacher_sign"), [(True, -1.0), (False, 1.0)])
def test_a_student_distilled_from_a_scripted_teacher_takes_its_actions(imitation_only, teacher_sign):
    # Alone, distillation teaches the teacher's actions even against the reward (−target where the reward's
    # optimum is +target); added to PPO's loss, with a teacher that agrees with the reward, both fall together.
    env = TargetActionEnv()
    config = dataclasses.replace(PROBE, teacher="scripted", imitation_only=imitation_only)
    trainer = make_trainer(config, env, env.default_params(), teacher=lambda obs: teacher_sign * obs)
    state, metrics = jax.jit(make_train(trainer))(jax.random.PRNGKey(0), config.hparams())
    targets = jnp.linspace(-0.5, 0.5, 11)[:, None]
    np.testing.assert_allclose(trainer.act(state, targets), teacher_sign * targets, atol=0.1)
    imitation = np.asarray(metrics.loss.imitation)
    assert imitation[-1] < 0.05 * imitation[0], (imitation[0], imitation[-1])


@pytest.mark.parametrize("decay_updates", [20, 0])
def test_a_kickstarting_teacher_leads_until_its_weight_has_decayed_then_the_reward_decides(decay_updates):
    # The teacher acts against the reward (−target), its loss weighted 20: kept for the whole run, the student
    # sides with it; falling to 0 over the first 20 of 60 updates, the student follows it, then the reward.
    env = TargetActionEnv()
    config = dataclasses.replace(
        PROBE, teacher="scripted", imitation_only=False, imitation_coef=20.0, imitation_decay_updates=decay_updates
    )
    trainer = make_trainer(config, env, env.default_params(), teacher=lambda obs: -obs)
    state, metrics = jax.jit(make_train(trainer))(jax.random.PRNGKey(0), config.hparams())
    targets = jnp.linspace(-0.5, 0.5, 11)[:, None]
    actions = np.asarray(trainer.act(state, targets))
    imitation = np.asarray(metrics.loss.imitation)
    if decay_updates:
        np.testing.assert_allclose(actions, targets, atol=0.1)
        assert imitation[4] < 0.05 * imitation[-1], (imitation[4], imitation[-1])
        weights = [float(imitation_weight_at(config, config.hparams(), jnp.array(u))) for u in (0, 10, 20, 40)]
        np.testing.assert_allclose(weights, [20.0, 10.0, 0.0, 0.0])
    else:
        assert np.all(actions[targets != 0] * np.asarray(targets)[targets != 0] < 0), actions.ravel()


def test_a_teacher_reads_the_privileged_state_of_a_camera_observation():
    obs = {"image": jnp.zeros((2, 8, 8, 1), jnp.uint8), "privileged": jnp.ones((2, 9))}
    np.testing.assert_array_equal(teacher_input(obs), obs["privileged"])
    np.testing.assert_array_equal(teacher_input(obs["privileged"]), obs["privileged"])


CAMERA_PROBE = dataclasses.replace(PROBE, encoder="patches", encoder_features=16)


@pytest.mark.parametrize("shared_encoder", [False, True])
def test_policy_and_value_learn_from_images(shared_encoder):
    # The target shows only as a dark or bright image: the optimal actions are −0.5 and +0.5, and the optimal
    # value 0 in both (one-step episodes); a policy blind to the image could do no better than action 0.
    env = ImageTargetEnv()
    config = dataclasses.replace(CAMERA_PROBE, shared_encoder=shared_encoder)
    trainer = make_trainer(config, env, env.default_params())
    state, _ = jax.jit(make_train(trainer))(jax.random.PRNGKey(0), config.hparams())
    images = {"image": jnp.stack([env.image(jnp.array(False)), env.image(jnp.array(True))])}
    np.testing.assert_allclose(trainer.act(state, images)[:, 0], [-0.5, 0.5], atol=0.1)
    values = make_networks(config, 1, camera=True).value(state.params, state.normalizer, images)
    np.testing.assert_allclose(values, [0.0, 0.0], atol=0.1)
    assert ("encoder" in state.params.value["params"]) != shared_encoder


def test_camera_frames_stay_uint8_in_the_rollout_and_the_normaliser_sees_only_proprio():
    config = dataclasses.replace(
        TINY, env="arm2d_pixels_proprio", env_kwargs=(("resolution", 16),), encoder="patches", encoder_features=8
    )
    trainer = make_trainer(config)
    state = jax.jit(trainer.init)(jax.random.PRNGKey(0), config.hparams())
    assert state.env_state.obs["image"].dtype == jnp.uint8
    state, metrics = jax.jit(trainer.update)(state, config.hparams())
    assert state.normalizer.mean.shape == (4,) and float(state.normalizer.std.min()) > 0
    assert np.isfinite(float(metrics.loss.value_loss))


ASYMMETRIC = dataclasses.replace(
    TINY,
    env="arm2d_pixels_proprio",
    env_kwargs=(("resolution", 16), ("privileged", True)),
    encoder="patches",
    encoder_features=8,
    asymmetric=True,
)


def test_an_asymmetric_critic_reads_the_privileged_state_and_the_policy_never_does():
    trainer = make_trainer(ASYMMETRIC)
    hparams = ASYMMETRIC.hparams()
    state = jax.jit(trainer.init)(jax.random.PRNGKey(0), hparams)
    state, metrics = jax.jit(trainer.update)(state, hparams)
    assert np.isfinite(float(metrics.loss.value_loss)) and np.isfinite(float(metrics.loss.policy_loss))
    # The critic: an MLP on the 9 state inputs with statistics of its own; the policy: image and 4 proprio inputs.
    value_kernels = [layer["kernel"].shape for layer in state.params.value["params"].values()]
    assert value_kernels[0] == (9, 16) and "encoder" not in state.params.value["params"]
    assert state.critic_normalizer.mean.shape == (9,) and float(state.critic_normalizer.std.min()) > 0
    assert state.normalizer.mean.shape == (4,)
    policy_shapes = {leaf.shape for leaf in jax.tree.leaves(state.params.policy)}
    assert not any(9 in shape for shape in policy_shapes), policy_shapes
    # `act` takes the actor's observation alone (the exported form lowers from its structure), and ignores a
    # privileged part given to it.
    obs = state.env_state.obs
    actor = actor_observation(obs)
    assert set(actor) == {"image", "proprio"}
    actor_structure = jax.tree.map(lambda part: jax.ShapeDtypeStruct(part.shape, part.dtype), actor)
    exported = jax.export.export(jax.jit(functools.partial(trainer.act, state)))(actor_structure)
    assert exported.in_tree.num_leaves == 2
    actions = trainer.act(state, actor)
    np.testing.assert_array_equal(trainer.act(state, {**obs, PRIVILEGED: obs[PRIVILEGED] + 100.0}), actions)


def test_an_asymmetric_critic_needs_an_env_that_observes_its_privileged_state():
    with pytest.raises(ValueError, match="env_kwargs.privileged=true"):
        make_trainer(dataclasses.replace(ASYMMETRIC, env_kwargs=(("resolution", 16),)))
    with pytest.raises(ValueError, match="no encoder to share"):
        dataclasses.replace(ASYMMETRIC, shared_encoder=True).validate()
    with pytest.raises(ValueError, match="privileged=True adds the state observation to a pixel obs_mode"):
        dataclasses.replace(ASYMMETRIC, env="arm2d", env_kwargs=(("privileged", True),)).validate()


@pytest.mark.slow
def test_ppo_solves_the_fixed_goal_arm_from_pixels():
    # The arm's pose is seen only in a 16x16 image (25 world units per pixel, links 20 units thick).
    config = PPOConfig(
        env="arm2d_pixels",
        env_kwargs=(("resolution", 16),),
        env_params=(("success_bonus", 10.0),),
        num_envs=256,
        rollout_length=16,
        num_minibatches=4,
        total_env_steps=600_000,
        updates_per_chunk=10,
        gamma=0.9,
        learning_rate=3e-3,
        encoder="patches",
        encoder_features=64,
        shared_encoder=True,
    )
    trainer = make_trainer(config)
    state, _ = jax.jit(make_train(trainer))(jax.random.PRNGKey(0), config.hparams())
    env, env_params = config.make_env()
    result = evaluate(env, env_params, lambda obs: trainer.act(state, obs), jax.random.PRNGKey(1), 100)
    assert float(result.successes.mean()) >= 0.9


def test_an_image_too_small_for_the_encoder_is_a_clear_error():
    config = dataclasses.replace(TINY, env="arm2d_pixels", env_kwargs=(("resolution", 16),), encoder="nature")
    trainer = make_trainer(config)
    with pytest.raises(ValueError, match="use a larger resolution or encoder=patches"):
        trainer.init(jax.random.PRNGKey(0), config.hparams())
