"""A trained deterministic policy as numpy arrays: `load("policy.npz")(obs) -> action`. Imports numpy alone.

The file holds what a jaxarm learner's deterministic action needs and nothing else: the observation
normaliser's mean and standard deviation, the policy MLP's dense layers, its hidden activation, and the affine
map from the network's squashed outputs to the env's action bounds:

    action = action_offset + action_scale * tanh(MLP((obs - obs_mean) / obs_std)[..., :action_size])

PPO's policy outputs the tanh-Gaussian's mean and scale (the mode is tanh of the mean: the first
`action_size` outputs), TD3's actor outputs the action itself; both are squashed by tanh. Observations must be
flat vectors ([O] or [B, O]).
"""

import dataclasses
import pathlib
from collections.abc import Callable
from typing import Any

import numpy as np


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * x))


def _gelu(x: np.ndarray) -> np.ndarray:
    # flax.linen.gelu is the tanh approximation by default.
    return 0.5 * x * (1.0 + np.tanh(np.sqrt(2.0 / np.pi).astype(x.dtype) * (x + 0.044715 * x**3)))


def _elu(x: np.ndarray) -> np.ndarray:
    return np.where(x > 0, x, np.expm1(np.minimum(x, 0)))


SELU_ALPHA = 1.6732632423543772848170429916717
SELU_SCALE = 1.0507009873554804934193349852946

ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "relu": lambda x: np.maximum(x, 0),
    "tanh": np.tanh,
    "swish": lambda x: x * _sigmoid(x),
    "silu": lambda x: x * _sigmoid(x),
    "gelu": _gelu,
    "elu": _elu,
    "selu": lambda x: SELU_SCALE * np.where(x > 0, x, SELU_ALPHA * np.expm1(np.minimum(x, 0))),
    "celu": _elu,  # flax's default alpha of 1 makes it ELU
    "leaky_relu": lambda x: np.where(x >= 0, x, 0.01 * x),
    "softplus": lambda x: np.logaddexp(x, 0),
    "sigmoid": _sigmoid,
}
"""numpy versions of `jaxarm.agents.common.networks.ACTIVATIONS`, the same names (a test checks both tables)."""


@dataclasses.dataclass(frozen=True)
class NumpyPolicy:
    """A deterministic policy: float32 arrays and the activation's name (see the module docstring).

    Attributes:
      kernels: per dense layer, its [in, out] weight matrix (the first in is O, the last out ≥ action_size).
      biases: per dense layer, its [out] bias.
      activation: hidden-layer activation, a key of `ACTIVATIONS`.
      obs_mean: [O] subtracted from observations (zeros for a learner without a normaliser).
      obs_std: [O] observations are divided by it after the mean is subtracted (ones without a normaliser).
      action_offset: [A] added to the squashed output.
      action_scale: [A] multiplies the squashed output.
    """

    kernels: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    activation: str
    obs_mean: np.ndarray
    obs_std: np.ndarray
    action_offset: np.ndarray
    action_scale: np.ndarray

    @property
    def observation_size(self) -> int:
        return int(self.obs_mean.shape[0])

    @property
    def action_size(self) -> int:
        return int(self.action_offset.shape[0])

    def __call__(self, obs) -> np.ndarray:
        """Actions [A] (or [B, A]) for flat observations [O] (or [B, O]); ValueError on anything else."""
        array = np.asarray(obs)
        if array.dtype.kind not in "fiu" or array.ndim not in (1, 2) or array.shape[-1] != self.observation_size:
            raise ValueError(
                f"observations must be numeric arrays of shape [{self.observation_size}] or "
                f"[B, {self.observation_size}], got {type(obs).__name__} of shape {array.shape} ({array.dtype})"
            )
        x = (array.astype(np.float32) - self.obs_mean) / self.obs_std
        act = ACTIVATIONS[self.activation]
        for index, (kernel, bias) in enumerate(zip(self.kernels, self.biases, strict=True)):
            x = x @ kernel + bias
            if index < len(self.kernels) - 1:
                x = act(x)
        return self.action_offset + self.action_scale * np.tanh(x[..., : self.action_size])

    def save(self, path: str | pathlib.Path) -> None:
        """Writes the policy as one .npz file (arrays and the activation's name; no pickled objects)."""
        arrays: dict[str, Any] = {
            "activation": np.array(self.activation),
            "obs_mean": self.obs_mean,
            "obs_std": self.obs_std,
            "action_offset": self.action_offset,
            "action_scale": self.action_scale,
        }
        arrays.update({f"kernel_{i}": kernel for i, kernel in enumerate(self.kernels)})
        arrays.update({f"bias_{i}": bias for i, bias in enumerate(self.biases)})
        np.savez(path, **arrays)


def load(path: str | pathlib.Path) -> NumpyPolicy:
    """The policy a `NumpyPolicy.save` (or `python -m experiments.export`) wrote to `path`."""
    with np.load(path, allow_pickle=False) as data:
        count = sum(1 for name in data.files if name.startswith("kernel_"))
        return NumpyPolicy(
            kernels=tuple(data[f"kernel_{i}"] for i in range(count)),
            biases=tuple(data[f"bias_{i}"] for i in range(count)),
            activation=str(data["activation"]),
            obs_mean=data["obs_mean"],
            obs_std=data["obs_std"],
            action_offset=data["action_offset"],
            action_scale=data["action_scale"],
        )
