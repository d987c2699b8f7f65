"""Run configs: the hyper-parameters a config declares dynamic, the presets' validity, and the ranges, types and
relations every config field and env param is checked against."""

import dataclasses
import json
import typing

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct
from mujoco import mjx

from experiments import configs
from jaxarm import envs, ranges
from jaxarm.agents.common.config import HParams, RunConfig, apply_overrides, parse_literal
from jaxarm.agents.ppo import PPOConfig
from jaxarm.agents.td3 import TD3Config
from jaxarm.envs.panda_sort.env import OBJECT_CARRY_TARGET, OBJECT_OBS_SIZE
from jaxarm.envs.panda_sort.params import PandaSortParams
from jaxarm.envs.peg_insert.params import PegInsertParams
from jaxarm.runner import rundir, teacher


@pytest.mark.parametrize(
    "config_class, dynamic, static", [(PPOConfig, "gamma", "num_epochs"), (TD3Config, "tau", "policy_delay")]
)
def test_hparams_hold_the_fields_declared_dynamic_and_no_others(config_class, dynamic, static):
    hparams = config_class().hparams()
    paths = [jax.tree_util.keystr(path) for path, _ in jax.tree_util.tree_flatten_with_path(hparams)[0]]
    assert paths == [f".{name}" for name in config_class.dynamic_fields()]
    assert dynamic in config_class.dynamic_fields() and static not in config_class.dynamic_fields()
    assert all(leaf.dtype == jnp.float32 and leaf.shape == () for leaf in jax.tree.leaves(hparams))
    changed = hparams.replace(**{dynamic: jnp.float32(0.5)})
    assert isinstance(changed, HParams) and float(getattr(changed, dynamic)) == 0.5
    with pytest.raises(TypeError, match=static):
        hparams.replace(**{static: jnp.float32(1.0)})
    with pytest.raises(AttributeError, match=static):
        getattr(hparams, static)


def test_every_preset_is_valid():
    for name in configs.names():
        configs.get(name)  # validates


def test_a_run_builds_its_mjx_scene_once(monkeypatch):
    # validate() runs at every step of a run's start (preset, overrides, trainer, run directory) and each builds the
    # env: the registry hands them one instance, so the scene goes onto the device once.
    put_model = mjx.put_model
    calls = []
    monkeypatch.setattr(mjx, "put_model", lambda *args, **kwargs: calls.append(args) or put_model(*args, **kwargs))
    config = apply_overrides(configs.get("ppo_sorter"), ["seed=3"])
    config.validate()
    assert config.make_env()[0] is config.make_eval_env()[0] is envs.make(config.env, **dict(config.env_kwargs))
    assert len(calls) <= 1  # none where an earlier test built the same env


def test_every_sorter_preset_trains_with_curricula_and_evaluates_the_plain_task():
    sorter_presets = [name for name in configs.names() if configs.get(name).env.startswith("panda_sort")]
    assert "ppo_sorter_toss" in sorter_presets
    for name in sorter_presets:
        config = configs.get(name)
        training = envs.override_params(PandaSortParams(), dict(config.env_params))
        evaluation = envs.override_params(training, dict(config.eval_env_params))
        assert float(training.held_start_prob) > 0, name
        for start in ("held_start_prob", "ready_start_prob", "presorted_prob"):
            assert float(getattr(evaluation, start)) == 0.0, (name, start)


def test_the_tosser_warm_starts_from_a_sorter_that_observes_and_acts_as_it_does():
    # ppo_sorter_toss trains its stage first and starts from it: each of the tosser's inputs has its source there,
    # and the vector to the object's bin reads the bins' displacement more (layout.py: bins 0.15 m to the left and
    # 0.97 m farther), so that the stage's networks read what they read over the sorter's bins.
    toss = configs.get("ppo_sorter_toss")
    stage = configs.get(teacher.warm_start_preset(toss))
    tosser, sorter = toss.make_env()[0], stage.make_env()[0]
    assert tosser.spec.action_shape == sorter.spec.action_shape
    identity = np.arange(tosser.spec.observation_size)
    assert tosser.observation_source_index(sorter).tolist() == identity.tolist()
    shift = tosser.observation_source_shift(sorter)
    to_bin = np.arange(OBJECT_OBS_SIZE)[OBJECT_CARRY_TARGET]
    np.testing.assert_allclose(shift[to_bin], [-0.15, 0.97, 0.0], atol=1e-6)
    np.testing.assert_array_equal(np.delete(shift, to_bin), 0.0)
    assert sorter.observation_source_index(sorter).tolist() == identity.tolist()
    np.testing.assert_array_equal(sorter.observation_source_shift(sorter), 0.0)
    randomized = configs.get("ppo_sorter_toss_dr").make_env()[0]
    np.testing.assert_array_equal(randomized.observation_source_shift(sorter), shift)


CONFIG_CLASSES = [PPOConfig, TD3Config]
ISSUE_VALUES = [
    # The values a new user tried, which trained (or crashed late) before they were refused.
    (PPOConfig, "gamma", 2.0),
    (PPOConfig, "learning_rate", -1.0),
    (PPOConfig, "gae_lambda", 5.0),
    (PPOConfig, "max_grad_norm", 0.0),
    (PPOConfig, "num_minibatches", 0),
    (PPOConfig, "rollout_length", 0),
    (PPOConfig, "activation", "foo"),
    (TD3Config, "gamma", 2.0),
    (TD3Config, "rollout_length", 0),
    (TD3Config, "activation", "foo"),
    # Sizes that ran out of memory (or overflowed) with a traceback.
    (PPOConfig, "num_envs", 10_000_000),
    (TD3Config, "eval_episodes", 100_000_000),
    (PPOConfig, "encoder_features", 100_000_000),
    (TD3Config, "encoder_features", 100_000_000),
    (PPOConfig, "num_epochs", 1_000_000_000),
    (PPOConfig, "updates_per_chunk", 1_000_000_000),
    (TD3Config, "num_critics", 100_000_000),
    (TD3Config, "batch_size", 1_000_000_000),
    (TD3Config, "buffer_size", 1_000_000_000),
    (TD3Config, "grad_steps_per_update", 1_000_000_000),
    (TD3Config, "critic_atoms", 1_000_000_000),
    (TD3Config, "random_shift_pad", 1_000_000_000),
]
BOUNDED_BY_A_RELATION = {
    "total_env_steps": "a host count (int64); num_updates must fit in int32",
    "rollout_length": "env_steps_per_update must fit in int32",
    "num_minibatches": "divides env_steps_per_update",
    "shuffle_groups": "divides num_envs",
    "policy_delay": "divides grad_steps_per_update",
    "n_step": "at most rollout_length",
    "learning_starts": "plus an update's env steps must fit in int32",
    "seed": "a PRNG seed: any int32 allocates nothing",
    "checkpoint_every_updates": "compared with the update count: allocates nothing",
    "eval_every_updates": "compared with the update count: allocates nothing",
    "critic_warm_up_updates": "below num_updates, which fits in int32",
    "imitation_decay_updates": "divides an update count in float32: allocates nothing",
    "retry_at_env_steps": "inside the run's env steps: allocates nothing",
    "retry_train_at_env_steps": "before retry_at_env_steps: allocates nothing",
}


def numeric_fields(config_class) -> list[str]:
    hints = typing.get_type_hints(config_class)
    return [field.name for field in dataclasses.fields(config_class) if hints[field.name] in (int, float)]


def float_fields(config_class) -> list[str]:
    hints = typing.get_type_hints(config_class)
    return [field.name for field in dataclasses.fields(config_class) if hints[field.name] is float]


@pytest.mark.parametrize("config_class", CONFIG_CLASSES)
def test_every_number_size_and_choice_declares_its_range(config_class):
    hints = typing.get_type_hints(config_class)
    for field in dataclasses.fields(config_class):
        if hints[field.name] in (int, float, tuple[int, ...]) or field.name == "activation":
            assert ranges.RANGE in field.metadata, f"{config_class.__name__}.{field.name} declares no range"


@pytest.mark.parametrize("config_class", CONFIG_CLASSES)
def test_every_count_has_an_upper_bound_or_a_relation_that_bounds_it(config_class):
    # Before: num_epochs=1e9 asked XLA for 136 GB, updates_per_chunk=1e9 grew past 24 GB, num_critics=1e8 26 TB.
    hints = typing.get_type_hints(config_class)
    unbounded = {
        field.name
        for field in dataclasses.fields(config_class)
        if hints[field.name] in (int, tuple[int, ...])
        and (allowed := ranges.declared_range(field)) is not None
        and allowed.le is None
        and allowed.lt is None
        and not allowed.choices
    }
    assert unbounded <= set(BOUNDED_BY_A_RELATION), unbounded - set(BOUNDED_BY_A_RELATION)


def test_replay_draws_of_a_whole_delay_block_are_bounded():
    with pytest.raises(
        ValueError, match=r"^policy_delay x batch_size = 2,097,152 samples drawn at once; it must be in \[1, 1048576\]$"
    ):
        TD3Config(policy_delay=4, grad_steps_per_update=4, batch_size=1 << 19).validate()


def test_a_default_declared_again_keeps_its_range():
    assert TD3Config().num_envs == 16 and RunConfig.__dataclass_fields__["num_envs"].default == 256
    assert TD3Config.__dataclass_fields__["num_envs"].metadata == RunConfig.__dataclass_fields__["num_envs"].metadata
    with pytest.raises(ValueError, match=r"^num_envs must be in \[1, 1048576\], got 0"):
        TD3Config(num_envs=0)


@pytest.mark.parametrize("config_class, field, value", ISSUE_VALUES)
def test_issue_values_are_refused_by_the_class_and_by_overrides(config_class, field, value):
    with pytest.raises(ValueError, match=f"^{field} must be"):
        config_class(**{field: value})
    with pytest.raises(ValueError, match=f"^{field} must be"):
        apply_overrides(config_class(), [f"{field}={value}"])


@pytest.mark.parametrize("config_class, field", [(cls, name) for cls in CONFIG_CLASSES for name in float_fields(cls)])
@pytest.mark.parametrize("text", ["nan", "inf", "-inf"])
def test_every_float_field_refuses_nan_and_inf(config_class, field, text):
    with pytest.raises(ValueError, match=f"^{field} must be finite"):
        config_class(**{field: float(text)})
    with pytest.raises(ValueError, match=f"^{field} must be finite"):
        apply_overrides(config_class(), [f"{field}={text}"])


@pytest.mark.parametrize("config_class", CONFIG_CLASSES)
def test_integers_beyond_int32_and_wrong_types_are_refused(config_class):
    for field in numeric_fields(config_class):
        if field in float_fields(config_class):
            with pytest.raises(ValueError, match=f"^{field} must be a number"):
                config_class(**{field: "0.5"})
            continue
        # A budget in env steps is counted on the host and may use int64; every other integer is int32.
        width, beyond = ("int64", 2**63) if field == "total_env_steps" else ("int32", 2**31)
        with pytest.raises(ValueError, match=f"^{field} must fit in {width}"):
            config_class(**{field: beyond})
        with pytest.raises(ValueError, match=f"^{field} must fit in {width}"):
            apply_overrides(config_class(), [f"{field}={float(beyond) * 10:.0e}"])
        with pytest.raises(ValueError, match=f"^{field} must be an integer"):
            config_class(**{field: 2.5})
    with pytest.raises(ValueError, match="normalize_observations must be true or false|target_smoothing must be"):
        config_class(**{"normalize_observations" if config_class is PPOConfig else "target_smoothing": 1})
    field = "policy_hidden_sizes" if config_class is PPOConfig else "hidden_sizes"
    with pytest.raises(ValueError, match=rf"^{field}\[1\] must be in \[1, 65536\], got 0"):
        config_class(**{field: (64, 0)})


ENV_PARAM_VALUES = [
    ("goal_size", "-40", "must be > 0"),
    ("success_bonus", "nan", "must be finite"),
    ("max_episode_steps", "0", "must be >= 1"),
    ("max_episode_steps", "1e10", "must fit in int32"),
    ("max_episode_steps", "2.5", "must be an integer"),
    ("goal_mode", "3", "must be one of 0, 1, 2"),
]


@pytest.mark.parametrize("name, text, message", ENV_PARAM_VALUES)
def test_issue_env_params_are_refused_by_override_params_and_overrides(name, text, message):
    params = envs.make("arm2d").default_params()
    with pytest.raises(ValueError, match=f"^env param {name} {message}"):
        envs.override_params(params, {name: parse_literal(text)})
    for group in ("env_params", "eval_env_params"):
        with pytest.raises(ValueError, match=f"^{group}.{name} {message}"):
            apply_overrides(PPOConfig(), [f"{group}.{name}={text}"])
        with pytest.raises(ValueError, match=f"^{group}.{name} {message}"):
            PPOConfig(**{group: ((name, parse_literal(text)),)}).validate()


def test_sorter_params_are_refused_by_their_ranges_and_order():
    params = PandaSortParams()
    with pytest.raises(ValueError, match="^env param object_size must be > 0, got -0.01"):
        envs.override_params(params, {"object_size": -0.01})
    with pytest.raises(ValueError, match="size_scale_low .2.0. must not exceed env param size_scale_high .1.5."):
        envs.override_params(params, {"size_scale_low": 2.0})
    with pytest.raises(ValueError, match="^env param held_start_prob must be in .0, 1.*"):
        envs.override_params(params, {"held_start_prob": 1.5})
    assert float(envs.override_params(params, {"object_size": 0.03}).object_size) == pytest.approx(0.03)
    with pytest.raises(ValueError, match="^env_params.object_size must be > 0, got -0.01"):
        PPOConfig(env="panda_sort", env_params=(("object_size", -0.01),)).validate()


def test_default_env_params_lie_in_their_declared_ranges():
    for params in (
        envs.make("arm2d").default_params(),
        PandaSortParams(),
        PegInsertParams(),
    ):
        ranges.check_params(params)
        hints = [field.metadata for field in dataclasses.fields(params)]
        assert all(ranges.RANGE in metadata for metadata in hints), type(params).__name__


@struct.dataclass
class RangedParams:
    shaped: jax.Array = ranges.ranged(allowed=ranges.POSITIVE)
    steps: jax.Array = ranges.ranged(3, ranges.COUNT)
    offset: jax.Array = ranges.ranged([1.0, -2.0])


def test_a_ranged_param_defaults_to_int32_for_integers_float32_otherwise_or_to_what_the_env_gives():
    params = RangedParams(shaped=jnp.ones(4))
    assert params.steps.dtype == jnp.int32 and int(params.steps) == 3
    assert params.offset.dtype == jnp.float32 and params.offset.tolist() == [1.0, -2.0]
    declared = [ranges.declared_range(field) for field in dataclasses.fields(params)]
    assert declared == [ranges.POSITIVE, ranges.COUNT, None]
    with pytest.raises(TypeError, match="shaped"):
        RangedParams()


def test_a_chunk_larger_than_the_budget_shrinks_to_the_budget():
    preset = configs.get("ppo_arm2d")  # 1.5M env steps of 16,384 per update: 92 updates, run as 5 chunks of 20
    assert (preset.chunk_updates, preset.num_updates) == (20, 100)
    big = apply_overrides(preset, ["updates_per_chunk=1000"])
    assert (big.chunk_updates, big.num_updates) == (92, 92)
    assert big.num_updates * big.env_steps_per_update - big.total_env_steps < big.env_steps_per_update


def test_a_budget_beyond_int32_env_steps_is_taken_and_one_beyond_int32_updates_is_refused():
    PPOConfig(num_envs=1024, rollout_length=16, updates_per_chunk=4096, total_env_steps=10_000_000_000).validate()
    with pytest.raises(ValueError, match="needs 2,147,483,650 updates, more than the learners' int32 update counter"):
        PPOConfig(num_envs=1, rollout_length=1, num_minibatches=1, total_env_steps=2**31).validate()


@pytest.mark.parametrize("changes", [{}, {"teacher": "scripted"}])
def test_a_decaying_distillation_without_a_teacher_beside_ppo_is_refused(changes):
    config = PPOConfig(num_envs=8, rollout_length=4, num_minibatches=2, total_env_steps=320, imitation_decay_updates=5)
    dataclasses.replace(config, teacher="scripted", imitation_only=False).validate()
    with pytest.raises(ValueError, match="^imitation_decay_updates=5 decays .* needs teacher=... and imitation_only"):
        dataclasses.replace(config, **changes).validate()


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"teacher": "init_from"}, "^teacher=init_from names the run this one warm-starts from: give init_from$"),
        ({"warm_start_spread": True}, "^warm_start_spread=true sets a warm-started policy's spread: give init_from$"),
    ],
)
def test_what_reads_a_warm_start_needs_one(changes, message):
    config = PPOConfig(num_envs=8, rollout_length=4, num_minibatches=2, total_env_steps=320, **changes)
    dataclasses.replace(config, init_from="runs/somewhere").validate()
    with pytest.raises(ValueError, match=message):
        config.validate()


def test_a_critic_warm_up_as_long_as_the_run_is_refused():
    config = PPOConfig(num_envs=8, rollout_length=4, num_minibatches=2, total_env_steps=320, updates_per_chunk=5)
    dataclasses.replace(config, critic_warm_up_updates=9).validate()
    with pytest.raises(
        ValueError, match="^critic_warm_up_updates=10 leaves the policy untrained: the run has 10 updates$"
    ):
        dataclasses.replace(config, critic_warm_up_updates=10).validate()


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"retry_below": 0.5, "retry_at_env_steps": 32}, r"^retry_below=0.5 needs tries=N of at least 2 \(the first"),
        (
            {"retry_below": 0.5, "retry_at_env_steps": 32, "tries": 2, "eval_every_updates": 0},
            "needs eval_every_updates=N: the evaluations it reads$",
        ),
        ({"retry_below": 0.5, "tries": 2}, "^retry_at_env_steps=0 must lie inside the run's 320 env steps, after its"),
        ({"retry_below": 0.5, "retry_at_env_steps": 320, "tries": 2}, "^retry_at_env_steps=320 must lie inside"),
        ({"retry_warm_start": True}, r"^retry_warm_start=true trains a warm start again .* needs a gate \(retry_below"),
        (
            {"retry_below": 0.5, "retry_at_env_steps": 32, "tries": 2, "retry_warm_start": True},
            r"a warm start named by preset \(init_from=preset:NAME, got ''\)$",
        ),
        ({"retry_train_below": 0.1}, r"^retry_train_below=0.1 is an earlier gate of retry_below's tries: it needs"),
        (
            {"retry_below": 0.5, "retry_at_env_steps": 64, "tries": 2, "retry_train_below": 0.1},
            r"^retry_train_at_env_steps=0 must lie after the run's start and before retry_at_env_steps=64 ",
        ),
        (
            {
                "retry_below": 0.5,
                "retry_at_env_steps": 64,
                "tries": 2,
                "retry_train_below": 0.1,
                "retry_train_at_env_steps": 64,
            },
            "^retry_train_at_env_steps=64 must lie after",
        ),
    ],
)
def test_a_gate_without_tries_evaluations_or_a_point_inside_the_run_is_refused(changes, message):
    config = PPOConfig(
        num_envs=8, rollout_length=4, num_minibatches=2, total_env_steps=320, updates_per_chunk=5, eval_every_updates=2
    )
    dataclasses.replace(config, retry_below=0.5, retry_at_env_steps=319, tries=2).validate()
    dataclasses.replace(
        config, retry_below=0.5, retry_at_env_steps=319, tries=2, retry_train_below=0.1, retry_train_at_env_steps=318
    ).validate()
    with pytest.raises(ValueError, match=message):
        dataclasses.replace(config, **changes).validate()


def test_a_layer_too_wide_and_an_update_beyond_int32_env_steps_are_refused():
    # Before: XLA's out-of-memory traceback (two layers of 1e8 units), an OverflowError (1e8 steps per env).
    for config_class, field in [
        (PPOConfig, "policy_hidden_sizes"),
        (PPOConfig, "value_hidden_sizes"),
        (TD3Config, "hidden_sizes"),
    ]:
        with pytest.raises(ValueError, match=rf"^{field}\[1\] must be in \[1, 65536\], got 100000000$"):
            apply_overrides(config_class(), [f"{field}=(64,100000000)"], validate=False)
    with pytest.raises(ValueError, match="an update collects 102,400,000,000 env steps .* int32 step counters"):
        PPOConfig(num_envs=1024, rollout_length=100_000_000, num_minibatches=1).validate()


def test_an_edited_config_json_is_refused_on_reading(tmp_path):
    rundir.write_config(tmp_path, configs.get("ppo_arm2d"), "ppo_arm2d")
    path = tmp_path / "config.json"
    data = json.loads(path.read_text())
    for field, value in [("gamma", 2.0), ("num_minibatches", 0), ("activation", "foo"), ("num_envs", 2.5)]:
        path.write_text(json.dumps({**data, field: value}))
        with pytest.raises(ValueError, match=f"{field} must be"):
            rundir.read_config(tmp_path)
    path.write_text(json.dumps({**data, "env_params": [["goal_size", -40]]}))
    with pytest.raises(ValueError, match="env_params.goal_size must be > 0"):
        rundir.read_config(tmp_path)
    path.write_text(json.dumps({**data, "env_params": [["goal_colour", 1]]}))  # a param arm2d lacks: the file is named
    with pytest.raises(ValueError, match=r"config\.json: unknown env_params\.goal_colour"):
        rundir.read_config(tmp_path)


def test_a_word_for_a_number_says_what_the_field_takes():
    # float's own error, "could not convert string to float: 'abc'", named neither.
    with pytest.raises(ValueError, match="^bad value for num_envs: expected an integer, got 'abc'$"):
        apply_overrides(PPOConfig(), ["num_envs=abc"], validate=False)
    with pytest.raises(ValueError, match="^bad value for gamma: expected a number, got 'high'$"):
        apply_overrides(PPOConfig(), ["gamma=high"], validate=False)
    assert apply_overrides(PPOConfig(), ["total_env_steps=1e6"], validate=False).total_env_steps == 1_000_000


def test_env_kwargs_take_true_and_false_as_the_config_fields_do():
    # "false" kept as a string would build an env with a truthy flag.
    sorter = PPOConfig(env="panda_sort")
    config = apply_overrides(sorter, ["env_kwargs.tosser=false", "env_kwargs.running_target=True"])
    assert dict(config.env_kwargs) == {"tosser": False, "running_target": True}
    assert parse_literal("FALSE") is False and parse_literal("0.5") == 0.5 and parse_literal("ee") == "ee"


def test_every_teacher_a_preset_names_exists_and_observes_what_its_student_gives_it():
    students = [name for name in configs.names() if teacher.teacher_preset(configs.get(name))]
    assert {"ppo_sorter_pixels", "ppo_sorter_pixels_dr"} <= set(students)
    for name in students:
        teacher.teacher_config(configs.get(name), configs.get)  # raises on an unknown preset or another observation
