"""A trained deterministic policy as numpy arrays: `load("policy.npz")(obs) -> action`. Imports numpy alone.

The file holds what a jaxarm learner's deterministic action needs and nothing else: the observation
normaliser's mean and standard deviation, the policy MLP's dense layers, its hidden activation, and the affine
map from the network's squashed outputs to the env's action bounds:

    action = action_offset + action_scale * tanh(MLP((obs - obs_mean) / obs_std)[..., :action_size])

PPO's policy outputs the tanh-Gaussian's mean and scale (the mode is tanh of the mean: the first
`action_size` outputs), TD3's actor outputs the action itself; both are squashed by tanh. Observations are flat
vectors ([O] or [B, O]), or, for a policy that reads a camera (`NumpyEncoder`), dicts {"image": uint8 [H, W, C],
"proprio": [P]} (or [B, ...] each; no "proprio" where P is 0), as `jaxarm.envs.observation` makes them: then
obs_mean and obs_std standardise the proprio part, and the MLP reads the encoder's features with it appended

    MLP([relu(dense(flatten(convs(image / 255)))), (proprio - obs_mean) / obs_std])

each conv a relu of a strided convolution without padding (`jaxarm.agents.common.encoders`' "nature" and
"patches" stacks).
"""

import dataclasses
import pathlib
import zipfile
import zlib
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * x))


def _gelu(x: np.ndarray) -> np.ndarray:
    # flax.linen.gelu is the tanh approximation by default.
    return 0.5 * x * (1.0 + np.tanh(np.sqrt(2.0 / np.pi).astype(x.dtype) * (x + 0.044715 * x**3)))


def _elu(x: np.ndarray) -> np.ndarray:
    return np.where(x > 0, x, np.expm1(np.minimum(x, 0)))


def convolved(x: np.ndarray, kernel: np.ndarray, bias: np.ndarray, stride: int) -> np.ndarray:
    """[B, H, W, C] -> [B, H', W', C']: a strided convolution without padding (flax's "VALID") by `kernel`
    [k, k, C, C'] plus `bias` [C'], as one matmul over the image's k×k windows."""
    size = kernel.shape[0]
    windows = np.lib.stride_tricks.sliding_window_view(x, (size, size), axis=(1, 2))[:, ::stride, ::stride]
    # Windows are [B, H', W', C, k, k]: the kernel's rows are put in the same (C, k, k) order.
    rows = kernel.transpose(2, 0, 1, 3).reshape(-1, kernel.shape[3])
    return windows.reshape(*windows.shape[:3], -1) @ rows + bias


@dataclasses.dataclass(frozen=True)
class NumpyEncoder:
    """A conv encoder of camera images (see the module docstring), float32 arrays.

    Attributes:
      image_shape: [3] int, the image's (H, W, C).
      conv_kernels: per conv, its [k, k, C_in, C_out] kernel (the first C_in is C).
      conv_biases: per conv, its [C_out] bias.
      conv_strides: [convs] int, each conv's stride.
      dense_kernel: [flattened conv output, F] the dense layer after the convs.
      dense_bias: [F].
    """

    image_shape: np.ndarray
    conv_kernels: tuple[np.ndarray, ...]
    conv_biases: tuple[np.ndarray, ...]
    conv_strides: np.ndarray
    dense_kernel: np.ndarray
    dense_bias: np.ndarray

    @property
    def features(self) -> int:
        return int(self.dense_kernel.shape[1])

    def conv_output_shape(self) -> tuple[int, int, int]:
        """(H', W', C') of the last conv's output, from `image_shape` and the kernels."""
        height, width, channels = (int(n) for n in self.image_shape)
        for kernel, stride in zip(self.conv_kernels, self.conv_strides, strict=True):
            height, width = (height - kernel.shape[0]) // stride + 1, (width - kernel.shape[1]) // stride + 1
            channels = kernel.shape[3]
        return height, width, channels

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """uint8 images [B, H, W, C] -> features [B, F]."""
        x = image.astype(np.float32) / np.float32(255.0)
        for kernel, bias, stride in zip(self.conv_kernels, self.conv_biases, self.conv_strides, strict=True):
            x = np.maximum(convolved(x, kernel, bias, int(stride)), 0)
        return np.maximum(x.reshape(len(x), -1) @ self.dense_kernel + self.dense_bias, 0)


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


IMAGE = "image"
"""Key of the camera image in a dict observation (`jaxarm.envs.observation` takes it from here)."""
PROPRIO = "proprio"
"""Key of the proprioceptive part in a dict observation."""


@dataclasses.dataclass(frozen=True)
class NumpyPolicy:
    """A deterministic policy: float32 arrays and the activation's name (see the module docstring). Made only of
    arrays that form one: ValueError in one line naming the first field that does not (`_problem`).

    Attributes:
      kernels: per dense layer, its [in, out] weight matrix (the first in is `input_size`, the last out ≥
        action_size).
      biases: per dense layer, its [out] bias.
      activation: hidden-layer activation, a key of `ACTIVATIONS`.
      obs_mean: [O] subtracted from observations (a camera policy's: from their proprio part, [P]; zeros for a
        learner without a normaliser).
      obs_std: [O] observations are divided by it after the mean is subtracted (ones without a normaliser).
      action_offset: [A] added to the squashed output.
      action_scale: [A] multiplies the squashed output.
      encoder: the conv encoder of a policy that reads a camera; None for flat observations.
    """

    kernels: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    activation: str
    obs_mean: np.ndarray
    obs_std: np.ndarray
    action_offset: np.ndarray
    action_scale: np.ndarray
    encoder: NumpyEncoder | None = None

    def __post_init__(self):
        # Here, not in `load` alone: an export of a diverged run's NaN weights is refused before it is written.
        problem = _problem(self)
        if problem:
            raise ValueError(problem)

    @property
    def observation_size(self) -> int:
        """O of flat observations; P, the proprio part's size, of a camera policy's."""
        return int(self.obs_mean.shape[0])

    @property
    def input_size(self) -> int:
        """What the MLP reads: O, or the encoder's features and P."""
        return self.observation_size + (0 if self.encoder is None else self.encoder.features)

    @property
    def action_size(self) -> int:
        return int(self.action_offset.shape[0])

    def observation_parts(self) -> dict[str, tuple[int, ...]]:
        """A camera policy's observation parts and their shapes ({"image": (H, W, C)}, and {"proprio": (P,)} where
        P > 0); {} for flat observations."""
        if self.encoder is None:
            return {}
        parts = {IMAGE: tuple(int(n) for n in self.encoder.image_shape)}
        return parts | ({PROPRIO: (self.observation_size,)} if self.observation_size else {})

    def __call__(self, obs) -> np.ndarray:
        """Actions [A] (or [B, A]) for observations [O] (or [B, O]), or a camera policy's dicts of parts (each
        [...] or [B, ...]); ValueError on anything else."""
        single, x = self._inputs(obs)
        act = ACTIVATIONS[self.activation]
        for index, (kernel, bias) in enumerate(zip(self.kernels, self.biases, strict=True)):
            x = x @ kernel + bias
            if index < len(self.kernels) - 1:
                x = act(x)
        actions = self.action_offset + self.action_scale * np.tanh(x[..., : self.action_size])
        return actions[0] if single else actions

    def _inputs(self, obs) -> tuple[bool, np.ndarray]:
        """(whether `obs` is one observation, the MLP's inputs [B, input_size])."""
        if self.encoder is None:
            array = _checked(obs, "observations", (self.observation_size,), "fiu")
            single = array.ndim == 1
            return single, (array.astype(np.float32).reshape(-1, self.observation_size) - self.obs_mean) / self.obs_std
        parts = self.observation_parts()
        if not isinstance(obs, Mapping) or set(obs) != set(parts):
            raise ValueError(f"observations must be dicts of {', '.join(parts)}, got {type(obs).__name__}")
        image = _checked(obs[IMAGE], IMAGE, parts[IMAGE], "u")
        single = image.ndim == 3
        features = self.encoder(image.reshape(-1, *parts[IMAGE]))
        proprio = np.zeros((len(features), 0), np.float32)
        if PROPRIO in parts:
            proprio = _checked(obs[PROPRIO], PROPRIO, parts[PROPRIO], "fiu").astype(np.float32)
            proprio = (proprio.reshape(len(features), -1) - self.obs_mean) / self.obs_std
        return single, np.concatenate([features, proprio], axis=-1)

    def save(self, path: str | pathlib.Path) -> None:
        """Writes the policy as one .npz file (arrays and the activation's name; no pickled objects)."""
        arrays: dict[str, Any] = {"activation": np.array(self.activation), **_named_arrays(self)}
        np.savez(path, **arrays)


def _checked(obs, name: str, shape: tuple[int, ...], kinds: str) -> np.ndarray:
    """`obs` as an array of `shape` or [B, *shape] whose dtype kind is one of `kinds`; ValueError otherwise."""
    array = np.asarray(obs)
    ranks = (len(shape), len(shape) + 1)
    if array.dtype.kind not in kinds or array.shape[-len(shape) :] != shape or array.ndim not in ranks:
        described = ", ".join(str(n) for n in shape)
        raise ValueError(
            f"{name} must be numeric arrays of shape [{described}] or [B, {described}]"
            f"{' of uint8' if kinds == 'u' else ''}, got {type(obs).__name__} of shape {array.shape} ({array.dtype})"
        )
    return array


class PolicyFileError(ValueError):
    """A file that `load` cannot read as a policy; the message names the file and what is wrong, in one line."""


EXPORT_AGAIN = "export the run again (python -m experiments.export RUN)"
"""What to do about an exported file that cannot be read."""
NAMED_FIELDS = ("activation", "obs_mean", "obs_std", "action_offset", "action_scale")
"""The arrays of a policy file besides its layers (`kernel_<i>`, `bias_<i>`), as `NumpyPolicy.save` names them."""
ENCODER_FIELDS = ("image_shape", "conv_strides", "dense_kernel", "dense_bias")
"""The arrays of a camera policy's encoder besides its convs (`conv_kernel_<i>`, `conv_bias_<i>`)."""
INTEGER_FIELDS = ("image_shape", "conv_strides")
RANKS = {"kernel": 2, "conv_kernel": 4, "dense_kernel": 2, "image_shape": 1, "conv_strides": 1}
"""Dimensions of each array by its name without the layer index (any other array is a vector)."""


def _layers(prefix: str, kernels: tuple[np.ndarray, ...], biases: tuple[np.ndarray, ...]) -> dict[str, np.ndarray]:
    arrays = {f"{prefix}kernel_{i}": np.asarray(kernel) for i, kernel in enumerate(kernels)}
    return arrays | {f"{prefix}bias_{i}": np.asarray(bias) for i, bias in enumerate(biases)}


def _named_arrays(policy: NumpyPolicy) -> dict[str, np.ndarray]:
    """The policy's number arrays by the names `save` gives them."""
    arrays = {name: np.asarray(getattr(policy, name)) for name in NAMED_FIELDS[1:]}
    arrays.update(_layers("", policy.kernels, policy.biases))
    if policy.encoder is not None:
        encoder = policy.encoder
        arrays.update({name: np.asarray(getattr(encoder, name)) for name in ENCODER_FIELDS})
        arrays.update(_layers("conv_", encoder.conv_kernels, encoder.conv_biases))
    return arrays


def _expected_shapes(policy: NumpyPolicy) -> dict[str, tuple[int, ...]]:
    """Each array's shape as the others make it: obs_std as obs_mean, action_scale as action_offset, each layer's
    inputs the previous layer's outputs (the first's the observation's, or the encoder's features and the
    proprio part), each bias its layer's outputs; an encoder's first conv reads the image's channels, each conv
    the previous one's, a stride per conv, its dense layer the convs' flattened output."""
    shapes = {"obs_std": np.shape(policy.obs_mean), "action_scale": np.shape(policy.action_offset)}
    inputs = np.shape(policy.obs_mean)[:1]
    if policy.encoder is not None:
        encoder = policy.encoder
        shapes["image_shape"] = (3,)
        shapes["conv_strides"] = (len(encoder.conv_kernels),)
        channels = int(encoder.image_shape[2])
        for index, kernel in enumerate(encoder.conv_kernels):
            shapes[f"conv_kernel_{index}"] = (*kernel.shape[:2], channels, kernel.shape[3])
            shapes[f"conv_bias_{index}"] = kernel.shape[3:]
            channels = kernel.shape[3]
        shapes["dense_kernel"] = (int(np.prod(encoder.conv_output_shape())), encoder.dense_kernel.shape[1])
        shapes["dense_bias"] = encoder.dense_kernel.shape[1:]
        inputs = (policy.input_size,)
    for index, kernel in enumerate(policy.kernels):
        outputs = np.shape(kernel)[1:2]
        shapes[f"kernel_{index}"] = (*inputs, *outputs)
        shapes[f"bias_{index}"] = outputs
        inputs = outputs
    return shapes


def _kind_problem(arrays: Mapping[str, np.ndarray]) -> str | None:
    """The first array (by its name in the file) not of floating-point numbers (`INTEGER_FIELDS` aside), or of
    another number of dimensions than its kind has (`RANKS`); or None."""
    for name, array in arrays.items():
        if array.dtype.kind != "f" and name not in INTEGER_FIELDS:
            return f"{name} holds {array.dtype}, not floating-point numbers"
    for name, array in arrays.items():
        rank = RANKS.get(name.rstrip("0123456789").removesuffix("_"), 1)
        if array.ndim != rank:
            return f"{name} has shape {list(array.shape)}, not a {rank}-d array"
    return None


def _encoder_problem(encoder: NumpyEncoder) -> str | None:
    """What keeps an encoder's integers from describing convs that fit its image, or None."""
    for name in INTEGER_FIELDS:
        array = np.asarray(getattr(encoder, name))
        if array.dtype.kind not in "iu" or array.ndim != 1 or np.any(array < 1):
            return f"{name} holds {array.dtype} of shape {list(array.shape)}, not positive integers [n]"
    if len(encoder.conv_kernels) != len(encoder.conv_biases) or len(encoder.conv_kernels) != len(encoder.conv_strides):
        return "an encoder has one conv kernel, bias and stride per conv"
    if not encoder.conv_kernels or min(encoder.conv_output_shape()[:2]) < 1:
        return f"the convs do not fit a {np.asarray(encoder.image_shape).tolist()} image"
    return None


def _problem(policy: NumpyPolicy) -> str | None:
    """What keeps `policy`'s arrays from being a policy (naming the array as its file does), or None: an unknown
    activation, no layers or a bias per layer missing, arrays not of floating-point numbers (an encoder's image
    shape and strides: of positive integers), shapes that do not chain from the observation to at least the
    action's outputs, or numbers that are NaN or infinite (a diverged training's weights would drive a robot with
    NaN)."""
    if policy.activation not in ACTIVATIONS:
        return f"activation {policy.activation!r} is none of {', '.join(ACTIVATIONS)}"
    if not policy.kernels or len(policy.kernels) != len(policy.biases):
        return f"{len(policy.kernels)} kernels and {len(policy.biases)} biases; a policy has one of each per layer"
    arrays = _named_arrays(policy)
    problem = _kind_problem(arrays) or (policy.encoder and _encoder_problem(policy.encoder))
    if problem:
        return problem
    for name, shape in _expected_shapes(policy).items():
        if arrays[name].shape != shape:
            return f"{name} has shape {list(arrays[name].shape)}; the arrays before it make it {list(shape)}"
    if arrays[f"kernel_{len(policy.kernels) - 1}"].shape[1] < policy.action_size:
        return f"the last layer has fewer outputs than action_offset's {policy.action_size} actions"
    for name, array in arrays.items():
        if not np.all(np.isfinite(array)):
            return f"{name} holds NaN or infinite numbers (a diverged training?)"
    return None


def _count(arrays: Mapping[str, np.ndarray], prefix: str) -> int:
    return sum(1 for name in arrays if name.startswith(prefix))


def _layer_names(prefix: str, count: int) -> list[str]:
    """The kernel and bias names of `count` layers (of one, where there are none: what a file lacks)."""
    return [f"{prefix}{kind}_{i}" for i in range(max(count, 1)) for kind in ("kernel", "bias")]


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
    count = _count(arrays, "kernel_")
    expected = [*NAMED_FIELDS, *_layer_names("", count)]
    camera = any(name in arrays for name in ENCODER_FIELDS)
    convs = _count(arrays, "conv_kernel_")
    if camera:
        expected += [*ENCODER_FIELDS, *_layer_names("conv_", convs)]
    missing = [name for name in expected if name not in arrays]
    if missing:
        raise PolicyFileError(f"{path} is not a jaxarm policy: it lacks {', '.join(missing)}; {EXPORT_AGAIN}")
    try:
        encoder = None
        if camera:
            encoder = NumpyEncoder(
                **{name: arrays[name] for name in ENCODER_FIELDS},
                conv_kernels=tuple(arrays[f"conv_kernel_{i}"] for i in range(convs)),
                conv_biases=tuple(arrays[f"conv_bias_{i}"] for i in range(convs)),
            )
        return NumpyPolicy(
            kernels=tuple(arrays[f"kernel_{i}"] for i in range(count)),
            biases=tuple(arrays[f"bias_{i}"] for i in range(count)),
            activation=str(arrays["activation"]),
            obs_mean=arrays["obs_mean"],
            obs_std=arrays["obs_std"],
            action_offset=arrays["action_offset"],
            action_scale=arrays["action_scale"],
            encoder=encoder,
        )
    except ValueError as error:
        raise PolicyFileError(f"{path} is not a usable policy: {error}; {EXPORT_AGAIN}") from None
