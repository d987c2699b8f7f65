"""A trained policy in the forms that run without the learner: numpy arrays, a serialised `jax.export` module,
and ONNX (with the `export` extra: `pip install -e ".[export]"`). Each is the learner's own deterministic action,
`trainer.act(state, obs)`, for flat observations [B, O] -> actions [B, A], the state's arrays built in.
"""

import functools
import logging

import jax
import jax.numpy as jnp

from jaxarm.agents.common.trainer import Trainer
from jaxarm.envs import EnvSpec
from jaxarm.export.numpy_policy import NumpyPolicy

JAX_EXPORT_PLATFORMS = ("cpu", "cuda")
"""The serialised module runs on either (both are lowered into it, whatever device exports it)."""


def check_flat_observations(spec: EnvSpec) -> int:
    """The observation size O of an env whose observations are flat vectors [O]; ValueError otherwise."""
    shape = spec.observation_shape
    if not (isinstance(shape, tuple) and len(shape) == 1 and isinstance(shape[0], int)):
        raise ValueError(f"export takes flat observations of shape [O]; this env's observations are {shape!r}")
    return shape[0]


def numpy_policy(trainer: Trainer, state) -> NumpyPolicy:
    """`trainer.act` at `state` as numpy arrays; ValueError for a learner without a numpy policy."""
    if trainer.numpy_policy is None:
        raise ValueError("this learner has no numpy policy to export")
    return trainer.numpy_policy(state)


def serialized_jax_policy(trainer: Trainer, state, observation_size: int) -> bytearray:
    """`trainer.act` at `state`, for any batch size B, serialised by `jax.export`.

    Run it with `jax.export.deserialize(data).call(obs)`, obs float32 [B, O] -> actions [B, A].
    """
    act = jax.jit(functools.partial(trainer.act, state))
    obs = jax.ShapeDtypeStruct(jax.export.symbolic_shape(f"batch, {observation_size}"), jnp.float32)
    return jax.export.export(act, platforms=JAX_EXPORT_PLATFORMS)(obs).serialize()


def onnx_policy(trainer: Trainer, state, observation_size: int) -> bytes:
    """`trainer.act` at `state` as a serialised ONNX model with one input float32 [B, O]; ImportError without the
    `export` extra (jax2onnx)."""
    from jax2onnx import to_onnx

    # jax2onnx logs every optional plugin it cannot load with this jax (dm_pix's, none of which an MLP uses).
    logging.getLogger("jax2onnx").setLevel(logging.ERROR)
    model = to_onnx(functools.partial(trainer.act, state), [("B", observation_size)])
    return model.SerializeToString()
