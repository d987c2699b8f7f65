"""Ceilings: the most this device does at the work our goals need, beside what we do, in the same run.

Two goals that BENCHMARKS.md reports out of reach on the 2-core CPU rest on these numbers:

- 64 seeds of `ppo_arm2d` in ≤ 8× one seed's wall time. A PPO update is mostly matrix products (the two MLPs'
  forward and backward passes). XLA's rate on one large square matmul is the most any batching of seeds can
  reach, so N seeds take at least N × (one seed's FLOP rate / that rate) × one seed's update time. The suite
  prints that bound beside a direct measurement of N vmapped seeds (the sweep's program).
- arm2d at ≥ 10,000× the numpy reference. The two-link maths alone (angle update, finger position, on-goal
  test, hold count; no observation, reward, reset or statistics) is an upper bound on the full env. It is timed
  with XLA's sine and cosine and with a trig-free rotation of kept sines and cosines, each written the way
  XLA:CPU runs fastest, beside the full env and the numpy reference.

FLOPs are counted from the layer shapes (2 per multiply-add of the matmuls); elementwise work is left out, so
the rates are conservative.
"""

import argparse
import functools
import itertools
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from experiments import configs
from experiments.benchmarks.arguments import count, env_counts
from experiments.benchmarks.arm2d import (
    default_max_env_steps,
    jax_steps_per_second,
    numpy_steps_per_second,
    scan_length,
)
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.timing import time_jitted
from experiments.sweep import init_members
from jaxarm import envs
from jaxarm.agents.common.trainer import run_updates
from jaxarm.agents.ppo import PPOConfig
from jaxarm.runner import learners

GOAL_RATIO = 10_000
"""arm2d's CPU goal: env steps/s as a multiple of the numpy reference's single env."""


def matmul_flops_per_second(size: int = 2048, repeats: int = 5) -> float:
    """FLOP/s of XLA's best repeat of one float32 [size, size] @ [size, size] product."""
    key = jax.random.PRNGKey(0)
    matrix = jax.random.normal(key, (size, size), jnp.float32)
    # Each repeat multiplies the last product by itself: scaled so the values stay finite.
    _, best = time_jitted(jax.jit(lambda m: m @ m * (1.0 / size)), matrix, repeats)
    return 2 * size**3 / best


def mlp_flops(sizes: Sequence[int]) -> int:
    """FLOPs of one sample's forward pass through the dense layers `sizes[0] -> sizes[1] -> ...`."""
    return sum(2 * inputs * outputs for inputs, outputs in itertools.pairwise(sizes))


def ppo_update_flops(config: PPOConfig, observation_size: int, action_size: int) -> int:
    """Matmul FLOPs of one PPO update: the rollout's policy pass and two value passes per sample, then
    `num_epochs` × (forward + backward ≈ 3 forward passes) of both networks per sample."""
    policy = mlp_flops((observation_size, *config.policy_hidden_sizes, 2 * action_size))
    value = mlp_flops((observation_size, *config.value_hidden_sizes, 1))
    samples = config.env_steps_per_update
    return samples * (policy + 2 * value) + samples * config.num_epochs * 3 * (policy + value)


def ppo_update_seconds(config: PPOConfig, seeds: int, repeats: int = 2) -> float:
    """Best seconds of one update of `seeds` vmapped seeds of `config`: the sweep's program, compile excluded."""
    trainer = learners.make_trainer(config)
    hparams = jax.tree.map(lambda leaf: jnp.stack([leaf] * seeds), config.hparams())
    state = init_members(trainer, jax.random.split(jax.random.PRNGKey(config.seed), seeds), hparams)
    update = jax.jit(jax.vmap(lambda s, h: run_updates(trainer, s, h, 1)[0]), compiler_options=trainer.compiler_options)
    _, best = time_jitted(functools.partial(update, h=hparams), state, repeats)
    return best


def two_link_maths(rotation: bool):
    """The two-link arm's per-step maths for one env, `(carry, action (a0, a1)) -> carry`, without observation,
    reward, reset or statistics, written for XLA:CPU's elementwise loops: every quantity a scalar per env, no
    reductions or concatenations (those split a step into several loops and halve its rate). carry:
    (angle0, angle1, goal_x, goal_y, hold) with XLA's sine and cosine of the absolute angles, or
    (cos0, sin0, cos1, sin1, goal_x, goal_y, hold) with each joint's cosine and sine rotated by the small angle
    change (Taylor polynomials, |change| ≤ 0.1 rad) instead of recomputed."""
    params = envs.make("arm2d").default_params()
    (length0, length1), (base_x, base_y) = params.link_lengths, params.base_pos
    half_goal, scale = params.goal_size / 2, params.action_scale

    def hold_count(cos0, sin0, cos_sum, sin_sum, goal_x, goal_y, hold):
        finger_x = base_x + length0 * cos0 + length1 * cos_sum
        finger_y = base_y + length0 * sin0 + length1 * sin_sum
        on_goal = (jnp.abs(finger_x - goal_x) < half_goal) & (jnp.abs(finger_y - goal_y) < half_goal)
        return jnp.where(on_goal, hold + 1, 0)

    def with_trigonometry(carry, action):
        angle0, angle1, goal_x, goal_y, hold = carry
        angle0 = jnp.mod(angle0 + action[0] * scale, 2 * jnp.pi)
        angle1 = jnp.mod(angle1 + action[1] * scale, 2 * jnp.pi)
        hold = hold_count(
            jnp.cos(angle0), jnp.sin(angle0), jnp.cos(angle0 + angle1), jnp.sin(angle0 + angle1), goal_x, goal_y, hold
        )
        return angle0, angle1, goal_x, goal_y, hold

    def rotate(cos, sin, change):
        squared = change * change
        cos_change = 1 - squared * (0.5 - squared / 24)
        sin_change = change * (1 - squared * (1 / 6 - squared / 120))
        return cos * cos_change - sin * sin_change, sin * cos_change + cos * sin_change

    def with_rotation(carry, action):
        cos0, sin0, cos1, sin1, goal_x, goal_y, hold = carry
        cos0, sin0 = rotate(cos0, sin0, action[0] * scale)
        cos1, sin1 = rotate(cos1, sin1, action[1] * scale)
        hold = hold_count(cos0, sin0, cos0 * cos1 - sin0 * sin1, sin0 * cos1 + cos0 * sin1, goal_x, goal_y, hold)
        return cos0, sin0, cos1, sin1, goal_x, goal_y, hold

    return with_rotation if rotation else with_trigonometry


def two_link_steps_per_second(num_envs: int, steps: int, rotation: bool, unroll: int = 8, repeats: int = 3) -> float:
    """Env steps/s of `two_link_maths` over `num_envs` envs in one jitted scan of `steps` steps, driven by the
    arm2d benchmark's bang-bang action pattern."""
    maths = jax.vmap(two_link_maths(rotation))
    pattern = jnp.sign(jax.random.normal(jax.random.PRNGKey(1), (2, num_envs)))
    angles = jax.random.uniform(jax.random.PRNGKey(2), (2, num_envs)) * 2 * jnp.pi
    goal = (jnp.full((num_envs,), 100.0), jnp.full((num_envs,), 100.0))
    hold = jnp.zeros((num_envs,), jnp.int32)
    joints = (
        (jnp.cos(angles[0]), jnp.sin(angles[0]), jnp.cos(angles[1]), jnp.sin(angles[1]))
        if rotation
        else (angles[0], angles[1])
    )
    carry = (*joints, *goal, hold)

    @functools.partial(jax.jit, compiler_options=envs.compiler_options(envs.make("arm2d")))
    def run(carry):
        def body(carry, step):
            action = pattern * jnp.cos(step * 0.05)
            return maths(carry, (action[0], action[1])), None

        return jax.lax.scan(body, carry, jnp.arange(steps, dtype=jnp.float32), unroll=unroll)[0]

    _, best = time_jitted(run, carry, repeats)
    return num_envs * steps / best


def print_arithmetic(config_name: str, seeds: int) -> dict[str, float]:
    """The PPO part: XLA's matmul rate, one seed's rate, the bound for `seeds` seeds and their measured time.

    Returns the printed figures by name.
    """
    config = configs.get(config_name)
    if not isinstance(config, PPOConfig):
        raise ValueError(f"{config_name} is not a PPO preset: the ceilings count a PPO update's matmuls")
    env, _ = config.make_env()
    peak = matmul_flops_per_second()
    flops = ppo_update_flops(config, env.spec.observation_size, env.spec.action_size)
    one = ppo_update_seconds(config, 1)
    many = ppo_update_seconds(config, seeds)
    share = flops / one / peak
    print(f"XLA matmul, float32 2048x2048: {peak / 1e9:.1f} GFLOP/s")
    print(
        f"{config_name}, one seed: {flops / 1e9:.2f} GFLOP of matmuls per update in {one * 1e3:.1f} ms = "
        f"{flops / one / 1e9:.1f} GFLOP/s ({share:.0%} of the matmul rate)"
    )
    print(
        f"{seeds} seeds: at least {seeds * share:.1f}x one seed's update time at the matmul rate; "
        f"measured {many * 1e3:,.0f} ms = {many / one:.1f}x",
        flush=True,
    )
    return {
        "matmul_gflop_per_second": peak / 1e9,
        "update_gflop": flops / 1e9,
        "one_seed_update_ms": one * 1e3,
        "one_seed_gflop_per_second": flops / one / 1e9,
        "one_seed_share_of_matmul_rate": share,
        "seeds": seeds,
        "seeds_bound_x_one_seed": seeds * share,
        "seeds_update_ms": many * 1e3,
        "seeds_measured_x_one_seed": many / one,
    }


def print_arm2d(sizes: Sequence[int], steps: int, unroll: int) -> tuple[float, list[dict[str, float]]]:
    """The arm2d part: the full env and the two-link maths at each size, as multiples of the numpy reference.

    Returns (the numpy reference's env steps/s, one dict of env steps/s per printed row).
    """
    reference = numpy_steps_per_second(None)
    print(
        f"numpy reference, single env: {reference:,.0f} steps/s; goal {GOAL_RATIO:,}x = "
        f"{GOAL_RATIO * reference:.3g} env steps/s"
    )
    print("| envs | full env (auto-reset, statistics) | two-link maths, XLA sin/cos | two-link maths, rotation |")
    print("|---:|---:|---:|---:|")
    max_env_steps = default_max_env_steps(jax.default_backend())
    rows = []
    for size in sizes:
        length = scan_length(size, steps, max_env_steps)
        rates = (
            jax_steps_per_second(size, length, unroll=unroll)[0],
            two_link_steps_per_second(size, length, rotation=False, unroll=unroll),
            two_link_steps_per_second(size, length, rotation=True, unroll=unroll),
        )
        print(
            f"| {size:,} | " + " | ".join(f"{rate:.3g} ({rate / reference:,.0f}x)" for rate in rates) + " |", flush=True
        )
        full, trigonometry, rotation = rates
        rows.append(
            {
                "envs": size,
                "full_env_steps_per_second": full,
                "two_link_trigonometry_steps_per_second": trigonometry,
                "two_link_rotation_steps_per_second": rotation,
            }
        )
    return reference, rows


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench ceilings", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="ppo_arm2d", help="PPO preset whose update is counted and timed")
    parser.add_argument("--seeds", type=count, default=64, help="seeds vmapped in the measured sweep update")
    parser.add_argument("--sizes", type=env_counts, default="4096,65536", help="comma-separated arm2d env counts")
    parser.add_argument(
        "--steps", type=count, default=1000, help="arm2d steps per timed scan (capped as in the arm2d suite)"
    )
    parser.add_argument("--unroll", type=count, default=8, help="arm2d env steps per scan iteration")
    add_out_argument(parser)
    args = parser.parse_args(argv)
    print(f"device: {jax.devices()[0].device_kind}; jax {jax.__version__}; numpy {np.__version__}")
    arithmetic = print_arithmetic(args.config, args.seeds)
    reference, rows = print_arm2d(args.sizes, args.steps, args.unroll)
    write_record(
        args.out,
        "ceilings",
        argv,
        rows,
        config=args.config,
        arithmetic=arithmetic,
        numpy_single_env_steps_per_second=reference,
        goal_env_steps_per_second=GOAL_RATIO * reference,
    )
