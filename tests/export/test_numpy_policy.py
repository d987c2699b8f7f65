"""The numpy policy on its own: it imports no JAX, its activations are flax's, it refuses what it cannot run."""

import re
import subprocess
import sys

import jax
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


def small_policy(**changes) -> numpy_policy.NumpyPolicy:
    """A two-layer policy of 4 observations and 3 actions, with `changes` to its fields (arrays as numpy takes them)."""
    fields = {
        "kernels": (np.ones((4, 8), np.float32), np.ones((8, 6), np.float32)),
        "biases": (np.zeros(8, np.float32), np.zeros(6, np.float32)),
        "activation": "relu",
        "obs_mean": np.zeros(4, np.float32),
        "obs_std": np.ones(4, np.float32),
        "action_offset": np.zeros(3, np.float32),
        "action_scale": np.ones(3, np.float32),
    }
    return numpy_policy.NumpyPolicy(**(fields | changes))


def test_a_policy_file_that_is_no_policy_is_refused_in_one_line_naming_it(tmp_path):
    path = tmp_path / "policy.npz"
    small_policy().save(path)
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    whole = path.read_bytes()
    damaged = bytearray(whole)
    # A byte of kernel_0's numbers (past its 128-byte array header): the archive's CRC no longer holds.
    damaged[whole.find(b"\x93NUMPY", whole.find(b"kernel_0.npy")) + 128 + 40] ^= 0xFF
    cases = {
        b"": "is not an .npz archive",
        whole[: len(whole) // 2]: "is not an .npz archive",
        b"\x93NUMPY" + bytes(200): "is not an .npz archive",
        bytes(damaged): "is a damaged .npz archive (BadZipFile: Bad CRC-32",
    }
    for content, message in cases.items():
        path.write_bytes(content)
        with pytest.raises(numpy_policy.PolicyFileError) as raised:
            numpy_policy.load(path)
        assert str(raised.value).startswith(f"{path} {message}") and "\n" not in str(raised.value)
    edits = {
        "it lacks activation, bias_1": {"activation": None, "bias_1": None},
        "it lacks kernel_0;": {"kernel_0": None, "kernel_1": None},
        "activation 'relux' is none of relu": {"activation": np.array("relux")},
        "kernel_1 holds <U1, not floating-point numbers": {"kernel_1": np.full((8, 6), "a")},
        "obs_std has shape [5]; the arrays before it make it [4]": {"obs_std": np.ones(5, np.float32)},
        "kernel_1 has shape [7, 6]; the arrays before it make it [8, 6]": {"kernel_1": np.ones((7, 6), np.float32)},
        "bias_0 has shape [8, 1], not a 1-d array": {"bias_0": np.zeros((8, 1), np.float32)},
        "the last layer has fewer outputs than action_offset's 3 actions": {
            "kernel_1": np.ones((8, 2), np.float32),
            "bias_1": np.zeros(2, np.float32),
        },
        "bias_1 holds NaN or infinite numbers": {"bias_1": np.full(6, np.nan, np.float32)},
        "obs_mean holds NaN or infinite numbers": {"obs_mean": np.array([0, np.inf, 0, 0], np.float32)},
    }
    for message, edit in edits.items():
        np.savez(path, **{name: array for name, array in (arrays | edit).items() if array is not None})
        with pytest.raises(numpy_policy.PolicyFileError, match=re.escape(message)) as raised:
            numpy_policy.load(path)
        assert str(raised.value).startswith(str(path)) and "\n" not in str(raised.value)
        assert str(raised.value).endswith("export the run again (python -m experiments.export RUN)")


def camera_policy(rng: np.random.Generator) -> numpy_policy.NumpyPolicy:
    """A policy of 12x12x2 images alone (no proprio): convs 3x3 by 2 then 2x2 by 1, 5 features, 2 actions."""
    encoder = numpy_policy.NumpyEncoder(
        image_shape=np.array([12, 12, 2]),
        conv_kernels=(
            rng.normal(size=(3, 3, 2, 4)).astype(np.float32),
            rng.normal(size=(2, 2, 4, 3)).astype(np.float32),
        ),
        conv_biases=(rng.normal(size=4).astype(np.float32), rng.normal(size=3).astype(np.float32)),
        conv_strides=np.array([2, 1]),
        dense_kernel=rng.normal(size=(4 * 4 * 3, 5)).astype(np.float32) / 4,
        dense_bias=rng.normal(size=5).astype(np.float32),
    )
    return small_policy(
        kernels=(rng.normal(size=(5, 2)).astype(np.float32),),
        biases=(np.zeros(2, np.float32),),
        obs_mean=np.zeros(0, np.float32),
        obs_std=np.ones(0, np.float32),
        action_offset=np.zeros(2, np.float32),
        action_scale=np.ones(2, np.float32),
        encoder=encoder,
    )


def test_a_camera_policy_convolves_as_xla_and_saves_whole(tmp_path):
    rng = np.random.default_rng(1)
    policy = camera_policy(rng)
    images = rng.integers(0, 256, (3, 12, 12, 2), np.uint8)
    x = jnp.asarray(images, jnp.float32) / 255.0
    for kernel, bias, stride in zip(policy.encoder.conv_kernels, policy.encoder.conv_biases, (2, 1), strict=True):
        x = jax.nn.relu(
            jax.lax.conv_general_dilated(
                x, kernel, (stride, stride), "VALID", dimension_numbers=("NHWC", "HWIO", "NHWC")
            )
            + bias
        )
    features = jax.nn.relu(x.reshape(3, -1) @ policy.encoder.dense_kernel + policy.encoder.dense_bias)
    expected = np.tanh(np.asarray(features @ policy.kernels[0] + policy.biases[0]))
    np.testing.assert_allclose(policy({"image": images}), expected, atol=1e-5)
    np.testing.assert_allclose(policy({"image": images[0]}), expected[0], atol=1e-5)
    assert policy.observation_parts() == {"image": (12, 12, 2)}

    policy.save(tmp_path / "policy.npz")
    loaded = numpy_policy.load(tmp_path / "policy.npz")
    np.testing.assert_array_equal(loaded({"image": images}), policy({"image": images}))
    for bad, message in (
        (images, "observations must be dicts of image"),
        ({"image": images, "proprio": np.zeros((3, 1))}, "observations must be dicts of image"),
        ({"image": images.astype(np.float32)}, r"image must be numeric arrays of shape \[12, 12, 2\]"),
    ):
        with pytest.raises(ValueError, match=message):
            loaded(bad)
    with np.load(tmp_path / "policy.npz") as data:
        arrays = {name: data[name] for name in data.files}
    for edit, message in (
        ({"conv_strides": np.array([2.0, 1.0])}, "conv_strides holds float64"),
        ({"image_shape": np.array([2, 2, 2])}, r"the convs do not fit a \[2, 2, 2\] image"),
        ({"dense_kernel": np.ones((47, 5), np.float32)}, r"dense_kernel has shape \[47, 5\]; .* make it \[48, 5\]"),
        ({"conv_bias_1": None}, "it lacks conv_bias_1"),
    ):
        np.savez(tmp_path / "policy.npz", **{k: v for k, v in (arrays | edit).items() if v is not None})
        with pytest.raises(numpy_policy.PolicyFileError, match=message):
            numpy_policy.load(tmp_path / "policy.npz")
