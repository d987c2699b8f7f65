"""Convolutional encoders that turn a camera observation into features for the learners' MLP heads.

A dict observation ({"image": uint8 [..., H, W, C], optionally "proprio": float32 [..., P]}, see
`jaxarm.envs.observation`) becomes [..., features + P]: the image, scaled to [0, 1] here (frames stay uint8
everywhere else: rollouts, replay), through a conv stack and a dense layer, then the proprio part appended as
it arrives (the learner normalises it first, when it keeps statistics). Flat observations have no encoder.

Stacks (`ENCODERS`): "nature", the Nature-DQN stack (Mnih et al. 2015); "impala", the small IMPALA stack
(Espeholt et al. 2018: three sections of conv, max-pool and two residual blocks, channels 16, 32, 32); and
"patches", convs whose kernel equals their stride (4×4, then 2×2), computed as reshapes and matmuls.

"patches" is the one for CPUs. XLA:CPU (jaxlib 0.10.2, 2-core AMD EPYC) computes a convolution's gradient
15–100× slower inside a loop (`lax.scan`, as every update's SGD is) than outside: 4 gradient steps of a two-layer
strided conv over 1,024 32×32 images took 6.7 s in a scan against 0.11 s each outside one, stride-1 convs
52 s against 0.44 s; the same two layers as patch matmuls took 0.08 s for all four, in the scan.
"""

import functools
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.envs.observation import IMAGE, PROPRIO
from jaxarm.export.numpy_policy import NumpyEncoder
from jaxarm.ranges import Range


def scaled_init() -> Callable:
    """Orthogonal initialisation with gain √2 (for relu layers), as the learners' MLPs use."""
    return nn.initializers.orthogonal(jnp.sqrt(2.0))


class StridedConvs(nn.Module):
    """[B, H, W, C] -> [B, H', W', C']: relu convs given as (channels, kernel, stride) triples, no padding."""

    layers: Sequence[tuple[int, int, int]]

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for channels, kernel, stride in self.layers:
            if min(x.shape[1:3]) < kernel:
                raise ValueError(
                    f"a {x.shape[1]}x{x.shape[2]} feature map is smaller than this conv stack's {kernel}x{kernel} "
                    "kernel: use a larger resolution or encoder=patches"
                )
            x = nn.relu(nn.Conv(channels, (kernel, kernel), (stride, stride), "VALID", kernel_init=scaled_init())(x))
        return x


class ImpalaStack(nn.Module):
    """[B, H, W, C] -> [B, H/8, W/8, 32]: IMPALA's three sections of conv, 3×3 max-pool (stride 2) and two
    residual blocks."""

    channels: Sequence[int] = (16, 32, 32)

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for channels in self.channels:
            x = nn.Conv(channels, (3, 3), padding="SAME", kernel_init=scaled_init())(x)
            x = nn.max_pool(x, (3, 3), strides=(2, 2), padding="SAME")
            for _ in range(2):
                block = nn.Conv(channels, (3, 3), padding="SAME", kernel_init=scaled_init())(nn.relu(x))
                x = x + nn.Conv(channels, (3, 3), padding="SAME", kernel_init=scaled_init())(nn.relu(block))
        return nn.relu(x)


class PatchConvs(nn.Module):
    """[B, H, W, C] -> [B, H/P, W/P, C']: relu convs whose kernel equals their stride, given as (channels, patch)
    pairs, each a reshape into non-overlapping patches and one matmul. H and W must divide by P, the patches'
    product."""

    layers: Sequence[tuple[int, int]]

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for channels, patch in self.layers:
            batch, height, width, depth = x.shape
            if height % patch or width % patch:
                raise ValueError(f"a {height}x{width} image does not split into {patch}x{patch} patches")
            x = x.reshape(batch, height // patch, patch, width // patch, patch, depth).transpose(0, 1, 3, 2, 4, 5)
            x = x.reshape(batch, height // patch, width // patch, patch * patch * depth)
            x = nn.relu(nn.Dense(channels, kernel_init=scaled_init())(x))
        return x


ENCODERS: Mapping[str, Callable[[], nn.Module]] = {
    "nature": functools.partial(StridedConvs, ((32, 8, 4), (64, 4, 2), (64, 3, 1))),
    "impala": ImpalaStack,
    "patches": functools.partial(PatchConvs, ((32, 4), (64, 2))),
}
"""Conv stack name -> constructor (a learner config's `encoder`)."""


ENCODER = Range(choices=tuple(ENCODERS))
"""The allowed values of a config's `encoder`."""


class PixelEncoder(nn.Module):
    """A dict observation -> features [..., `features` + P] (see the module docstring).

    Attributes:
      stack: a name in `ENCODERS`.
      features: width of the dense layer after the convs.
    """

    stack: str
    features: int

    @nn.compact
    def __call__(self, obs: Mapping[str, jax.Array]) -> jax.Array:
        image = obs[IMAGE]
        lead = image.shape[:-3]
        pixels = image.reshape((-1, *image.shape[-3:])).astype(jnp.float32) / 255.0
        conv = ENCODERS[self.stack]()(pixels)
        flat = conv.reshape((*lead, -1))
        features = nn.relu(nn.Dense(self.features, kernel_init=scaled_init())(flat))
        if PROPRIO in obs:
            features = jnp.concatenate([features, obs[PROPRIO]], axis=-1)
        return features


def numpy_encoder(stack: str, params: Mapping[str, Any], image_shape: tuple[int, ...]) -> NumpyEncoder:
    """A `PixelEncoder` of `stack` with `params` (its flax params, without the "params" key) for images of
    `image_shape` (H, W, C), as the numpy policy runs it; ValueError for "impala" (max-pools and residual blocks,
    which the numpy policy does not run: export a run of "nature" or "patches")."""
    convs = ENCODERS[stack]()
    if isinstance(convs, StridedConvs):
        layers = [params["StridedConvs_0"][f"Conv_{i}"] for i in range(len(convs.layers))]
        kernels = [layer["kernel"] for layer in layers]
        strides = [stride for _, _, stride in convs.layers]
    elif isinstance(convs, PatchConvs):
        layers = [params["PatchConvs_0"][f"Dense_{i}"] for i in range(len(convs.layers))]
        # A patch layer's [P·P·C, C'] matmul is the [P, P, C, C'] conv of stride P: its rows are a patch's pixels
        # row by row, each pixel's channels together, as `PatchConvs` reshapes them.
        kernels = [
            np.reshape(layer["kernel"], (patch, patch, -1, channels))
            for layer, (channels, patch) in zip(layers, convs.layers, strict=True)
        ]
        strides = [patch for _, patch in convs.layers]
    else:
        raise ValueError(f"the numpy policy runs the encoders nature and patches, not {stack}")
    return NumpyEncoder(
        image_shape=np.asarray(image_shape, np.int64),
        conv_kernels=tuple(np.asarray(kernel, np.float32) for kernel in kernels),
        conv_biases=tuple(np.asarray(layer["bias"], np.float32) for layer in layers),
        conv_strides=np.asarray(strides, np.int64),
        dense_kernel=np.asarray(params["Dense_0"]["kernel"], np.float32),
        dense_bias=np.asarray(params["Dense_0"]["bias"], np.float32),
    )


class EncodedMLP(nn.Module):
    """A dict observation -> the head's output: `encoder`, then `head` (an MLP of the features)."""

    encoder: PixelEncoder
    head: nn.Module

    def __call__(self, obs: Mapping[str, jax.Array]) -> jax.Array:
        return self.head(self.encoder(obs))


def statistics_part(obs) -> jax.Array:
    """The part of an observation a learner keeps running statistics of and normalises: a flat observation
    whole, a dict observation's proprio part ([..., 0] where it has none; images are never normalised)."""
    if not isinstance(obs, Mapping):
        return obs
    if PROPRIO in obs:
        return obs[PROPRIO]
    return jnp.zeros((*obs[IMAGE].shape[:-3], 0), jnp.float32)


def with_statistics_part(obs, part: jax.Array):
    """`obs` with its `statistics_part` replaced by `part` (e.g. normalised)."""
    if not isinstance(obs, Mapping):
        return part
    if PROPRIO in obs:
        return {**obs, PROPRIO: part}
    return obs
