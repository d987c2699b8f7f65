"""Multi-layer perceptrons for policies, values and critics (flax.linen)."""

from collections.abc import Mapping, Sequence
from typing import Any, cast

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.agents.common.encoders import statistics_part
from jaxarm.agents.common.normalizer import numpy_mean_std
from jaxarm.envs import EnvSpec
from jaxarm.export.numpy_policy import NumpyEncoder, NumpyPolicy
from jaxarm.ranges import Range

ACTIVATIONS = {
    name: getattr(nn, name)
    for name in ("relu", "tanh", "swish", "silu", "gelu", "elu", "selu", "celu", "leaky_relu", "softplus", "sigmoid")
}
"""Hidden-layer activations by the name configs give (flax.linen's functions)."""
ACTIVATION = Range(choices=tuple(ACTIVATIONS))
"""The allowed values of a config's `activation`."""


class MLP(nn.Module):
    """[..., in] -> [..., out]: hidden layers with `activation`, a linear output layer.

    `output_scale` scales the last layer's initialisation (small for policy heads, as PPO practice has it).
    """

    hidden_sizes: Sequence[int]
    output_size: int
    activation: str = "tanh"
    output_scale: float = 1.0

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        act = ACTIVATIONS[self.activation]
        for size in self.hidden_sizes:
            x = act(nn.Dense(size, kernel_init=nn.initializers.orthogonal(jnp.sqrt(2.0)))(x))
        return nn.Dense(self.output_size, kernel_init=nn.initializers.orthogonal(self.output_scale))(x)


def apply_module(module: nn.Module, variables: Mapping[str, Any], *inputs: jax.Array) -> jax.Array:
    """`module.apply(variables, *inputs)`, typed as the array it is: flax types `apply` as perhaps also
    returning mutated variables, which it does only when asked to (never in these learners)."""
    return cast(jax.Array, module.apply(variables, *inputs))


DENSE = "Dense_"
"""The prefix of flax's names for a module's dense layers, numbered from 0 in the order they apply."""


def dense_layer_names(layers: Mapping[str, Any]) -> list[str]:
    """The names of the dense layers among one flax module's `layers` (its params), the input layer first."""
    return sorted((name for name in layers if name.startswith(DENSE)), key=lambda name: int(name.removeprefix(DENSE)))


def mlp_layers(variables: Mapping[str, Any]) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    """The dense layers of the one `MLP` in a module's flax variables, in order: ([in, out] kernels, [out] biases)
    as float32 numpy arrays (the form `jaxarm.export.numpy_policy` runs)."""
    tree = variables["params"]
    while not dense_layer_names(tree):
        # A module wrapping one MLP (TD3's actor), perhaps beside its encoder (a camera policy's).
        (tree,) = (part for name, part in tree.items() if name != "encoder")
    names = dense_layer_names(tree)
    return (
        tuple(np.asarray(tree[name]["kernel"], np.float32) for name in names),
        tuple(np.asarray(tree[name]["bias"], np.float32) for name in names),
    )


def numpy_mlp_policy(
    variables: Mapping[str, Any],
    spec: EnvSpec,
    normalizer,
    normalize: bool,
    activation: str,
    offset,
    scale,
    encoder: NumpyEncoder | None = None,
) -> NumpyPolicy:
    """The `NumpyPolicy` of the MLP in `variables` (its first A outputs are the action's) for an env of `spec`:
    observations (a camera's: their proprio part) standardised as `normalizer` does where the learner
    `normalize`s them, read through `encoder` where they are a camera's, actions `offset + scale * output` ([A]
    each)."""
    kernels, biases = mlp_layers(variables)
    size = int(statistics_part(spec.zero_observation()).shape[-1])
    mean, std = numpy_mean_std(normalizer, normalize, size)
    return NumpyPolicy(
        kernels=kernels,
        biases=biases,
        activation=activation,
        obs_mean=mean,
        obs_std=std,
        action_offset=np.asarray(offset, np.float32),
        action_scale=np.asarray(scale, np.float32),
        encoder=encoder,
    )
