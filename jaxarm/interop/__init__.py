"""Adapters between jaxarm and other RL stacks: brax's trainers and Gymnasium drive jaxarm envs, and MuJoCo
Playground's envs run as jaxarm envs.

- `jaxarm.interop.brax_env`: `BraxEnv(env, params)`, a `brax.envs.base.Env`, and `wrap_for_training`.
- `jaxarm.interop.brax_compat`: `install_device_put_replicated()`, which brax 0.14.2's trainers need on jax >= 0.10
  (`BraxEnv` calls it).
- `jaxarm.interop.gymnasium_env`: `GymnasiumEnv` and `GymnasiumVectorEnv` (numpy in/out; needs `gymnasium`).
- `jaxarm.interop.playground`: `PlaygroundEnv`, any Playground task as `envs.make("playground:NAME")` (needs the
  `playground` extra); assets/ holds the menagerie files its Franka tasks load, so that they build offline.

Submodules are imported by name, not here, so that using one adapter never imports the other's library.
"""
