"""A trained policy in the forms that run without the learner: numpy arrays, a serialised `jax.export` module,
and ONNX (with the `export` extra: `pip install -e ".[export]"`). Each is the learner's own deterministic action,
`trainer.act(state, obs)`, for a batch of observations [B, ...] -> actions [B, A], the state's arrays built in:
flat observations float32 [B, O], or a camera's parts by name (`policy_inputs`: the uint8 image [B, H, W, C] and
the float32 proprio [B, P] where the env observes one).
"""

import contextlib
import functools
import io
import logging

import jax

from jaxarm.agents.common.trainer import Trainer
from jaxarm.envs import EnvSpec
from jaxarm.envs.observation import actor_observation
from jaxarm.export.numpy_policy import NumpyPolicy

JAX_EXPORT_PLATFORMS = ("cpu", "cuda")
"""The serialised module runs on either (both are lowered into it, whatever device exports it)."""
FLAT_INPUT = "obs"
"""The ONNX input's name for flat observations."""


def check_flat_observations(spec: EnvSpec) -> int:
    """The observation size O of an env whose observations are flat vectors [O]; ValueError otherwise."""
    shape = spec.observation_shape
    if not (isinstance(shape, tuple) and len(shape) == 1 and isinstance(shape[0], int)):
        raise ValueError(f"export takes flat observations of shape [O]; this env's observations are {shape!r}")
    return shape[0]


def policy_inputs(spec: EnvSpec) -> dict[str, jax.ShapeDtypeStruct]:
    """What a policy of `spec`'s env reads, one observation's parts by name: {"obs": [O]} for flat observations,
    else the dict observation's parts but the privileged one (which only a critic reads)."""
    if spec.flat_observation:
        return {FLAT_INPUT: spec.observation}
    return dict(actor_observation(spec.observation))


def _batched(spec: EnvSpec):
    """`spec`'s observation (the policy's parts of it) with a symbolic leading batch axis, for `jax.export`."""
    (batch,) = jax.export.symbolic_shape("batch")
    parts = {name: jax.ShapeDtypeStruct((batch, *part.shape), part.dtype) for name, part in policy_inputs(spec).items()}
    return parts[FLAT_INPUT] if spec.flat_observation else parts


def numpy_policy(trainer: Trainer, state) -> NumpyPolicy:
    """`trainer.act` at `state` as numpy arrays; ValueError for a learner without a numpy policy."""
    if trainer.numpy_policy is None:
        raise ValueError("this learner has no numpy policy to export")
    return trainer.numpy_policy(state)


def serialized_jax_policy(trainer: Trainer, state, spec: EnvSpec) -> bytearray:
    """`trainer.act` at `state`, for any batch size B, serialised by `jax.export`.

    Run it with `jax.export.deserialize(data).call(obs)`, obs float32 [B, O] (or a dict of `policy_inputs`' parts,
    [B, ...] each) -> actions [B, A].
    """
    act = jax.jit(functools.partial(trainer.act, state))
    return jax.export.export(act, platforms=JAX_EXPORT_PLATFORMS)(_batched(spec)).serialize()


def onnx_policy(trainer: Trainer, state, spec: EnvSpec) -> bytes:
    """`trainer.act` at `state` as a serialised ONNX model with one input per `policy_inputs` part, named as it is
    ([B, ...] each); ImportError without the `export` extra (jax2onnx)."""
    from jax2onnx import to_onnx

    # jax2onnx logs every optional plugin it cannot load with this jax (dm_pix's, none of which a policy uses), and
    # onnx_ir a warning per shape constant of a conv encoder's reshapes.
    for name in ("jax2onnx", "onnx_ir"):
        logging.getLogger(name).setLevel(logging.ERROR)
    parts = policy_inputs(spec)

    def act(*arrays):
        if spec.flat_observation:
            return trainer.act(state, arrays[0])
        return trainer.act(state, dict(zip(parts, arrays, strict=True)))

    inputs = [jax.ShapeDtypeStruct(("B", *part.shape), part.dtype) for part in parts.values()]
    # jax2onnx 0.13.0's conv plugin prints its debugging lines (66 for the Nature stack) to stdout.
    with contextlib.redirect_stdout(io.StringIO()):
        model = to_onnx(act, inputs, input_names=list(parts))
    return model.SerializeToString()
