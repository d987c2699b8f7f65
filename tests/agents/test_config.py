"""Run configs: the hyper-parameters a config declares dynamic, and the presets' validity."""

import jax
import jax.numpy as jnp
import pytest

from experiments import configs
from jaxarm.agents.common.config import HParams
from jaxarm.agents.ppo import PPOConfig
from jaxarm.agents.td3 import TD3Config


@pytest.mark.parametrize(
    "config_class, dynamic, static", [(PPOConfig, "gamma", "num_epochs"), (TD3Config, "tau", "policy_delay")]
)
def test_hparams_hold_the_fields_declared_dynamic_and_no_others(config_class, dynamic, static):
    hparams = config_class().hparams()
    paths = [jax.tree_util.keystr(path) for path, _ in jax.tree_util.tree_flatten_with_path(hparams)[0]]
    assert paths == [f".{name}" for name in config_class.dynamic_fields()]
    assert dynamic in config_class.dynamic_fields() and static not in config_class.dynamic_fields()
    assert all(leaf.dtype == jnp.float32 and leaf.shape == () for leaf in jax.tree.leaves(hparams))
    changed = hparams.replace(**{dynamic: jnp.float32(0.5)})
    assert isinstance(changed, HParams) and float(getattr(changed, dynamic)) == 0.5
    with pytest.raises(TypeError, match=static):
        hparams.replace(**{static: jnp.float32(1.0)})
    with pytest.raises(AttributeError, match=static):
        getattr(hparams, static)


def test_every_preset_is_valid():
    for name in configs.names():
        configs.get(name)  # validates
