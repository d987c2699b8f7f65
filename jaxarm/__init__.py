"""jaxarm: pure-JAX robot-arm environments and learners compiled end to end."""

from jaxarm._runtime import apply_xla_settings

apply_xla_settings()

__version__ = "0.1.0"
