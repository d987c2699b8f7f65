"""`python -m experiments.export`: every exported form of a PPO and a TD3 policy acts as `trainer.act` does.

The learner states are built directly (random networks and a random observation normaliser) and
checkpointed into a run directory, as a run would leave them: exporting needs no training.
"""

import dataclasses
import importlib.util

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from experiments import export as export_cli
from jaxarm import envs
from jaxarm.agents.common import checkpoint
from jaxarm.agents.ppo import PPOConfig
from jaxarm.agents.td3 import TD3Config
from jaxarm.export import numpy_policy, origin
from jaxarm.interop.gymnasium_env import GymnasiumEnv
from jaxarm.runner import learners, rundir

TOLERANCE = 1e-5
CONFIGS = {
    "ppo": PPOConfig(
        num_envs=8,
        rollout_length=4,
        num_minibatches=2,
        total_env_steps=32,
        policy_hidden_sizes=(32, 32),
        value_hidden_sizes=(16,),
        activation="swish",
    ),
    "td3": TD3Config(num_envs=4, total_env_steps=16, hidden_sizes=(32, 32), buffer_size=64, batch_size=8),
    "td3_normalized": TD3Config(
        num_envs=4, total_env_steps=16, hidden_sizes=(32, 32), buffer_size=64, batch_size=8, normalize_observations=True
    ),
}


def perturbed(tree, key, scale: float):
    """`tree` with Gaussian noise added to every float leaf (so the policy's outputs span its range)."""
    leaves, treedef = jax.tree.flatten(tree)
    keys = jax.random.split(key, len(leaves))
    return treedef.unflatten(
        [leaf + scale * jax.random.normal(k, leaf.shape) for leaf, k in zip(leaves, keys, strict=True)]
    )


def learner_state(name: str, trainer, config):
    """A fresh state with perturbed policy weights and a random observation normaliser (which a learner that
    does not normalise ignores)."""
    state = trainer.init(jax.random.PRNGKey(0), config.hparams())
    obs_size = state.normalizer.mean.shape[0]
    state = state.replace(
        normalizer=state.normalizer.replace(
            mean=jax.random.normal(jax.random.PRNGKey(2), (obs_size,)),
            std=jax.random.uniform(jax.random.PRNGKey(3), (obs_size,), minval=0.2, maxval=3.0),
        )
    )
    if name.startswith("td3"):
        return state.replace(actor_params=perturbed(state.actor_params, jax.random.PRNGKey(1), 0.3))
    params = dataclasses.replace(state.params, policy=perturbed(state.params.policy, jax.random.PRNGKey(1), 0.3))
    return state.replace(params=params)


@pytest.fixture(scope="module", params=list(CONFIGS))
def exported(request, tmp_path_factory):
    """(run dir, trainer, learner state, files written) of a checkpointed tiny run and its export."""
    config = CONFIGS[request.param]
    run_dir = tmp_path_factory.mktemp(request.param)
    trainer = learners.make_trainer(config)
    state = learner_state(request.param, trainer, config)
    rundir.write_config(run_dir, config, f"tiny_{request.param}")
    checkpoint.save(run_dir / "checkpoints", 1, state)
    assert export_cli.main([str(run_dir)]) == 0
    return run_dir, trainer, state


def random_observations(size: int) -> np.ndarray:
    return np.random.default_rng(0).normal(scale=2.0, size=(64, size)).astype(np.float32)


def test_every_exported_form_acts_as_the_learner(exported):
    run_dir, trainer, state = exported
    obs = random_observations(9)
    expected = np.asarray(trainer.act(state, jnp.asarray(obs)))
    assert np.std(expected) > 0.1, "a policy this flat would hide errors in the export"
    files = sorted(path.name for path in (run_dir / "export").iterdir())
    with_onnx = importlib.util.find_spec("jax2onnx") is not None
    assert files == ["export.json", "policy.jax_export", "policy.npz", *(["policy.onnx"] if with_onnx else [])]
    assert origin.read(run_dir / "export") == str(int(state.updates))  # as experiments.eval names a checkpoint

    policy = numpy_policy.load(run_dir / "export" / "policy.npz")
    np.testing.assert_allclose(policy(obs), expected, atol=TOLERANCE)
    np.testing.assert_allclose(policy(obs[3]), expected[3], atol=TOLERANCE)

    serialized = jax.export.deserialize(bytearray((run_dir / "export" / "policy.jax_export").read_bytes()))
    for batch in (obs, obs[:1]):
        np.testing.assert_allclose(np.asarray(serialized.call(batch)), expected[: len(batch)], atol=TOLERANCE)

    if not with_onnx:
        pytest.skip("jax2onnx is not installed (the export extra)")
    import onnxruntime

    session = onnxruntime.InferenceSession(str(run_dir / "export" / "policy.onnx"))
    (output,) = session.run(None, {session.get_inputs()[0].name: obs})
    np.testing.assert_allclose(output, expected, atol=TOLERANCE)


def test_the_numpy_policy_drives_the_gymnasium_adapter(exported):
    # docs/tutorials/deploy.md's example: the policy file alone acts in the Gymnasium env.
    run_dir, _, _ = exported
    policy = numpy_policy.load(run_dir / "export" / "policy.npz")
    env = GymnasiumEnv(envs.make("arm2d"))
    obs, _ = env.reset(seed=0)
    steps, done = 0, False
    while not done:
        obs, _, terminated, truncated, _ = env.step(policy(obs))
        steps, done = steps + 1, terminated or truncated
    assert 1 <= steps <= 200


def test_export_errors_are_one_line(tmp_path, capsys):
    assert export_cli.main([str(tmp_path)]) == 2
    assert "no config.json" in capsys.readouterr().err
    rundir.write_config(tmp_path, CONFIGS["ppo"], "tiny_ppo")
    assert export_cli.main([str(tmp_path)]) == 2
    assert "checkpoint" in capsys.readouterr().err
    assert not (tmp_path / "export").exists()
