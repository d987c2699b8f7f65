"""Test-wide set-up: importing jaxarm first applies its XLA settings before any test starts JAX."""

import jaxarm  # noqa: F401
