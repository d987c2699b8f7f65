"""The numpy policy on its own: it imports no JAX, its activations are flax's, it refuses what it cannot run."""

import subprocess
import sys

import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.agents.common.networks import ACTIVATIONS
from jaxarm.envs import EnvSpec
from jaxarm.export import numpy_policy
from jaxarm.export.policy import check_flat_observations


def test_the_numpy_policy_imports_no_jax():
    # A meta-path entry that refuses jax and jaxlib: any import of either, direct or indirect, fails.
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('jax', 'jaxlib', 'flax'):\n"
        "            raise ImportError('blocked: ' + name)\n"
        "sys.meta_path.insert(0, Block())\n"
        "from jaxarm.export.numpy_policy import load, NumpyPolicy\n"
        "import numpy as np\n"
        "policy = NumpyPolicy((np.eye(3, dtype=np.float32),), (np.zeros(3, np.float32),), 'relu',\n"
        "    np.zeros(3, np.float32), np.ones(3, np.float32), np.zeros(2, np.float32), np.ones(2, np.float32))\n"
        "loaded = [name for name in sys.modules if name.split('.')[0] in ('jax', 'jaxlib', 'flax')]\n"
        "print(bool(np.allclose(policy(np.ones(3)), np.tanh(1.0))), loaded)\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "True []"


def test_numpy_activations_are_flax_activations():
    assert set(numpy_policy.ACTIVATIONS) == set(ACTIVATIONS)
    x = np.linspace(-6, 6, 1001, dtype=np.float32)
    for name, flax_activation in ACTIVATIONS.items():
        np.testing.assert_allclose(numpy_policy.ACTIVATIONS[name](x), flax_activation(jnp.asarray(x)), atol=2e-6)


def test_a_saved_policy_loads_equal_and_refuses_what_is_not_a_flat_observation(tmp_path):
    rng = np.random.default_rng(0)
    policy = numpy_policy.NumpyPolicy(
        kernels=(rng.normal(size=(4, 8)).astype(np.float32), rng.normal(size=(8, 6)).astype(np.float32)),
        biases=(rng.normal(size=8).astype(np.float32), rng.normal(size=6).astype(np.float32)),
        activation="gelu",
        obs_mean=rng.normal(size=4).astype(np.float32),
        obs_std=rng.uniform(0.5, 2, size=4).astype(np.float32),
        action_offset=np.full(3, 0.5, np.float32),
        action_scale=np.full(3, 1.5, np.float32),
    )
    policy.save(tmp_path / "policy.npz")
    loaded = numpy_policy.load(tmp_path / "policy.npz")
    obs = rng.normal(size=(5, 4)).astype(np.float32)
    np.testing.assert_array_equal(loaded(obs), policy(obs))
    np.testing.assert_allclose(loaded(obs[0]), policy(obs)[0], atol=1e-6)
    assert loaded(obs).shape == (5, 3) and np.all(np.abs(loaded(obs) - 0.5) <= 1.5)
    for bad in ({"image": obs, "proprio": obs}, obs[:, :3], obs[None], np.array(["a"] * 4)):
        with pytest.raises(ValueError, match=r"observations must be numeric arrays of shape \[4\] or \[B, 4\]"):
            loaded(bad)


def test_export_refuses_observations_that_are_not_flat():
    assert check_flat_observations(EnvSpec(observation_shape=(9,), action_shape=(2,))) == 9
    with pytest.raises(ValueError, match=r"flat observations of shape \[O\]; this env's observations are \(2, 3\)"):
        check_flat_observations(EnvSpec(observation_shape=(2, 3), action_shape=(2,)))
