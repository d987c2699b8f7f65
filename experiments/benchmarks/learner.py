"""PPO's SGD phase alone, without the env: epochs × minibatches on random samples of a preset's shapes.

The update's other phases wait on the env; this one does not, so it can be timed apart and tuned where the env
would drown it. Each variant runs `ppo.train.sgd_epochs` (the learner's own code) with a different number of
minibatch steps per iteration of an epoch's loop (`--unrolls`; 0: every step of an epoch unrolled), on the same
random samples, parameters and optimiser state, compiled ahead of time; the ratio is against the first variant,
measured in the same run.
"""

import argparse
import dataclasses
import functools
import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp

from experiments import configs
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.timing import timed
from jaxarm.agents.common import normalizer as observation_normalizer
from jaxarm.agents.common.config import apply_overrides
from jaxarm.agents.ppo import PPOConfig
from jaxarm.agents.ppo.networks import make_networks
from jaxarm.agents.ppo.train import PPOSetup, Samples, SGDInputs, make_optimizer, sgd_epochs
from jaxarm.envs import AutoReset, EnvSpec, VmapEnv


def random_samples(key: jax.Array, spec: EnvSpec, rollout_length: int, num_envs: int) -> Samples:
    """[rollout_length, num_envs] training samples of random values in the env's observation and action shapes."""
    obs_key, action_key, log_prob_key, advantage_key, target_key = jax.random.split(key, 5)

    def random_part(part_key, part):
        shape = (rollout_length, num_envs, *part.shape)
        if jnp.issubdtype(part.dtype, jnp.integer):
            return jax.random.randint(part_key, shape, 0, 256).astype(part.dtype)
        return jax.random.normal(part_key, shape, part.dtype)

    parts = jax.tree.leaves(spec.observation)
    obs_leaves = [random_part(k, part) for k, part in zip(jax.random.split(obs_key, len(parts)), parts, strict=True)]
    return Samples(
        obs=jax.tree.unflatten(jax.tree.structure(spec.observation), obs_leaves),
        raw_action=jax.random.normal(action_key, (rollout_length, num_envs, spec.action_size)),
        log_prob=jax.random.normal(log_prob_key, (rollout_length, num_envs)),
        advantage=jax.random.normal(advantage_key, (rollout_length, num_envs)),
        target=jax.random.normal(target_key, (rollout_length, num_envs)),
    )


def sgd_seconds(config: PPOConfig, unrolls: Sequence[int], repeats: int) -> list[tuple[int, float, float]]:
    """[(unroll, best seconds of one update's SGD phase, compile seconds)] for each of `unrolls` (0: all)."""
    env, env_params = config.make_env()
    spec = env.spec
    networks = make_networks(config, spec.action_size, camera=not spec.flat_observation)
    setup = PPOSetup(config, networks, VmapEnv(AutoReset(env), config.num_envs), env_params)
    hparams = config.hparams()
    params_key, value_key, samples_key, run_key = jax.random.split(jax.random.PRNGKey(config.seed), 4)
    params = networks.init(params_key, value_key, spec)
    opt_state = make_optimizer(hparams, hparams.learning_rate).init(params)
    normalizer = observation_normalizer.init(spec)
    samples = random_samples(samples_key, spec, config.rollout_length, config.num_envs)
    inputs = SGDInputs(samples, normalizer, None, hparams, hparams.learning_rate, jnp.ones(()), hparams.imitation_coef)
    args = (params, opt_state, inputs, run_key)
    rows = []
    for unroll in unrolls:
        run = functools.partial(sgd_epochs, dataclasses.replace(setup, sgd_unroll=unroll or config.num_minibatches))
        start = time.perf_counter()
        compiled = jax.jit(run).lower(*args).compile()
        compile_seconds = time.perf_counter() - start
        timed(compiled, *args)  # warm-up
        rows.append((unroll, min(timed(compiled, *args) for _ in range(repeats)), compile_seconds))
    return rows


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench learner", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="ppo_sorter", help="PPO preset whose shapes and sizes are timed")
    parser.add_argument("--unrolls", default="1,4,0", help="minibatch steps per loop iteration to time (0: all)")
    parser.add_argument("--repeats", type=int, default=10, help="timed calls per variant; the best is reported")
    parser.add_argument("overrides", nargs="*", help="config overrides key=value (num_envs=..., num_minibatches=...)")
    add_out_argument(parser)
    args = parser.parse_args(argv)
    try:
        config = apply_overrides(configs.get(args.config), args.overrides)
        unrolls = [int(text) for text in args.unrolls.split(",")]
    except ValueError as error:
        parser.error(str(error))
    if not isinstance(config, PPOConfig):
        parser.error(f"{args.config} is not a PPO preset")
    if args.repeats < 1 or any(unroll < 0 for unroll in unrolls):
        parser.error("--repeats must be at least 1 and every unroll 0 or more")
    print(
        f"device: {jax.devices()[0].device_kind}; jax {jax.__version__}; {args.config} {' '.join(args.overrides)}: "
        f"{config.num_epochs} epochs × {config.num_minibatches} minibatches of {config.minibatch_size:,} samples"
    )
    rows = sgd_seconds(config, unrolls, args.repeats)
    first = rows[0][1]
    print("| minibatch steps per loop iteration | SGD ms per update | over the first | compile s |")
    print("|---|---:|---:|---:|")
    for unroll, seconds, compile_seconds in rows:
        label = "all" if unroll == 0 else str(unroll)
        print(f"| {label} | {seconds * 1e3:.2f} | {seconds / first:.2f} | {compile_seconds:.1f} |")
    write_record(
        args.out,
        "learner",
        argv,
        [{"unroll": unroll, "sgd_ms": seconds * 1e3, "compile_seconds": c} for unroll, seconds, c in rows],
        config=args.config,
        overrides=args.overrides,
        sgd_steps=config.num_epochs * config.num_minibatches,
        minibatch_size=config.minibatch_size,
    )
