"""Adapters that let other RL stacks drive jaxarm envs: brax's trainers and Gymnasium.

- `jaxarm.interop.brax_env`: `BraxEnv(env, params)`, a `brax.envs.base.Env`, and `wrap_for_training`.
- `jaxarm.interop.brax_compat`: `install_device_put_replicated()`, which brax 0.14.2's trainers need on jax >= 0.10
  (`BraxEnv` calls it).
- `jaxarm.interop.gymnasium_env`: `GymnasiumEnv` and `GymnasiumVectorEnv` (numpy in/out; needs `gymnasium`).

Submodules are imported by name, not here, so that using one adapter never imports the other's library.
"""
