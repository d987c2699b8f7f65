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
import zipfile
import zlib
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
    """A deterministic policy: float32 arrays and the activation's name (see the module docstring). Made only of
    arrays that form one: ValueError in one line naming the first field that does not (`_problem`).

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

    def __post_init__(self):
        # Here, not in `load` alone: an export of a diverged run's NaN weights is refused before it is written.
        problem = _problem(self)
        if problem:
            raise ValueError(problem)

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


class PolicyFileError(ValueError):
    """A file that `load` cannot read as a policy; the message names the file and what is wrong, in one line."""


EXPORT_AGAIN = "export the run again (python -m experiments.export RUN)"
"""What to do about an exported file that cannot be read."""
NAMED_FIELDS = ("activation", "obs_mean", "obs_std", "action_offset", "action_scale")
"""The arrays of a policy file besides its layers (`kernel_<i>`, `bias_<i>`), as `NumpyPolicy.save` names them."""


def _named_arrays(policy: NumpyPolicy) -> dict[str, np.ndarray]:
    """The policy's number arrays by the names `save` gives them."""
    arrays = {name: np.asarray(getattr(policy, name)) for name in NAMED_FIELDS[1:]}
    arrays.update({f"kernel_{i}": np.asarray(kernel) for i, kernel in enumerate(policy.kernels)})
    arrays.update({f"bias_{i}": np.asarray(bias) for i, bias in enumerate(policy.biases)})
    return arrays


def _expected_shapes(policy: NumpyPolicy) -> dict[str, tuple[int, ...]]:
    """Each array's shape as the others make it: obs_std as obs_mean, action_scale as action_offset, each layer's
    inputs the previous layer's outputs (the first's the observation's), each bias its layer's outputs."""
    shapes = {"obs_std": np.shape(policy.obs_mean), "action_scale": np.shape(policy.action_offset)}
    inputs = np.shape(policy.obs_mean)[:1]
    for index, kernel in enumerate(policy.kernels):
        outputs = np.shape(kernel)[1:2]
        shapes[f"kernel_{index}"] = (*inputs, *outputs)
        shapes[f"bias_{index}"] = outputs
        inputs = outputs
    return shapes


def _problem(policy: NumpyPolicy) -> str | None:
    """What keeps `policy`'s arrays from being a policy (naming the array as its file does), or None: an unknown
    activation, no layers or a bias per layer missing, arrays not of floating-point numbers, shapes that do not
    chain from the observation to at least the action's outputs, or numbers that are NaN or infinite (a diverged
    training's weights would drive a robot with NaN)."""
    if policy.activation not in ACTIVATIONS:
        return f"activation {policy.activation!r} is none of {', '.join(ACTIVATIONS)}"
    if not policy.kernels or len(policy.kernels) != len(policy.biases):
        return f"{len(policy.kernels)} kernels and {len(policy.biases)} biases; a policy has one of each per layer"
    arrays = _named_arrays(policy)
    for name, array in arrays.items():
        if array.dtype.kind != "f":
            return f"{name} holds {array.dtype}, not floating-point numbers"
    for name, array in arrays.items():
        if array.ndim != (2 if name.startswith("kernel_") else 1):
            return f"{name} has shape {list(array.shape)}, not {'[in, out]' if name.startswith('kernel_') else '[n]'}"
    for name, shape in _expected_shapes(policy).items():
        if arrays[name].shape != shape:
            return f"{name} has shape {list(arrays[name].shape)}; the arrays before it make it {list(shape)}"
    if arrays[f"kernel_{len(policy.kernels) - 1}"].shape[1] < policy.action_size:
        return f"the last layer has fewer outputs than action_offset's {policy.action_size} actions"
    for name, array in arrays.items():
        if not np.all(np.isfinite(array)):
            return f"{name} holds NaN or infinite numbers (a diverged training?)"
    return None


def load(path: str | pathlib.Path) -> NumpyPolicy:
    """The policy a `NumpyPolicy.save` (or `python -m experiments.export`) wrote to `path`; PolicyFileError naming
    `path` and what is wrong for any other file: not an .npz archive (empty, cut short, another format), a damaged
    one, one without a policy's fields, or arrays that are not a policy (`_problem`). OSError where it cannot be
    read."""
    path = pathlib.Path(path)
    with path.open("rb") as handle:
        if not zipfile.is_zipfile(handle):
            raise PolicyFileError(f"{path} is not an .npz archive (empty, cut short or another format); {EXPORT_AGAIN}")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (zipfile.BadZipFile, zlib.error, EOFError, ValueError, MemoryError) as error:
        # ValueError: an array header numpy cannot read, or pickled objects; MemoryError: a header claiming a size
        # beyond this machine's memory.
        raise PolicyFileError(
            f"{path} is a damaged .npz archive ({type(error).__name__}: {error}); {EXPORT_AGAIN}"
        ) from None
    count = sum(1 for name in arrays if name.startswith("kernel_"))
    layers = [f"{kind}_{i}" for i in range(max(count, 1)) for kind in ("kernel", "bias")]
    missing = [name for name in (*NAMED_FIELDS, *layers) if name not in arrays]
    if missing:
        raise PolicyFileError(f"{path} is not a jaxarm policy: it lacks {', '.join(missing)}; {EXPORT_AGAIN}")
    try:
        return NumpyPolicy(
            kernels=tuple(arrays[f"kernel_{i}"] for i in range(count)),
            biases=tuple(arrays[f"bias_{i}"] for i in range(count)),
            activation=str(arrays["activation"]),
            obs_mean=arrays["obs_mean"],
            obs_std=arrays["obs_std"],
            action_offset=arrays["action_offset"],
            action_scale=arrays["action_scale"],
        )
    except ValueError as error:
        raise PolicyFileError(f"{path} is not a usable policy: {error}; {EXPORT_AGAIN}") from None
