"""The conv encoders of camera observations: every stack gives features, with the proprio part appended."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.agents.common.encoders import PixelEncoder


@pytest.mark.parametrize("encoder", ["nature", "impala", "patches"])
def test_every_encoder_turns_a_camera_observation_into_features(encoder):
    obs = {"image": jnp.zeros((2, 64, 64, 4), jnp.uint8), "proprio": jnp.ones((2, 3))}
    module = PixelEncoder(encoder, 8)
    features = module.apply(module.init(jax.random.PRNGKey(0), obs), obs)
    assert features.shape == (2, 8 + 3)
    np.testing.assert_array_equal(features[:, 8:], 1.0)
