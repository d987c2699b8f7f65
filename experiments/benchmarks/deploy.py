"""The deployment loop's control tick on one CPU core: observation, numpy policy, IK and limits, p50 and p99.

For each preset (its eval env's numpy controller, `jaxarm.deploy`) a policy of the preset's own network sizes
and activation with random weights (the tick's cost does not depend on the weights) acts on readings drawn around
the arm's start posture: the tick is what a robot's computer would run every control period, against the goal
of 2 ms (p99), 5% of the 40 ms period. The process is pinned to one core; timings include Python's overhead.
Wall time counts every preemption by other processes on the core; the CPU time the process spent in a tick does
not, and is what a core of its own would give.
"""

import argparse
import os
import time
from collections.abc import Sequence

import numpy as np

from experiments import configs
from experiments.benchmarks.arguments import count
from experiments.benchmarks.record import add_out_argument, write_record
from jaxarm import deployable
from jaxarm.deploy.loop import Controller, DeploymentLoop
from jaxarm.deploy.reading import ArmReading, HoleEstimate, ObjectEstimate
from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.export.numpy_policy import NumpyEncoder, NumpyPolicy

GOAL_P99_MS = 2.0


def random_policy(config, observation_size: int, action_size: int, rng: np.random.Generator) -> NumpyPolicy:
    """A policy of `config`'s network sizes and activation with random weights (PPO's outputs: mean and scale)."""
    hidden = getattr(config, "policy_hidden_sizes", None) or config.hidden_sizes
    outputs = 2 * action_size if hasattr(config, "policy_hidden_sizes") else action_size
    sizes = [observation_size, *hidden, outputs]
    kernels = tuple(
        (rng.normal(size=(n_in, n_out)) / np.sqrt(n_in)).astype(np.float32)
        for n_in, n_out in zip(sizes[:-1], sizes[1:], strict=True)
    )
    return NumpyPolicy(
        kernels=kernels,
        biases=tuple(np.zeros(size, np.float32) for size in sizes[1:]),
        activation=config.activation,
        obs_mean=np.zeros(observation_size, np.float32),
        obs_std=np.ones(observation_size, np.float32),
        action_offset=np.zeros(action_size, np.float32),
        action_scale=np.ones(action_size, np.float32),
    )


def random_camera_policy(
    image_shape: tuple[int, int, int], proprio_size: int, action_size: int, rng: np.random.Generator
) -> NumpyPolicy:
    """A policy of a camera's images (patch convs 4 by 4, then 2 by 2: H and W divide by 8) and `proprio_size`
    values, with random weights (PPO's outputs: mean and scale)."""
    height, width, channels = image_shape

    def normal(*shape: int) -> np.ndarray:
        return (rng.normal(size=shape) / np.sqrt(np.prod(shape[:-1]))).astype(np.float32)

    encoder = NumpyEncoder(
        image_shape=np.array(image_shape),
        conv_kernels=(normal(4, 4, channels, 8), normal(2, 2, 8, 8)),
        conv_biases=(np.zeros(8, np.float32), np.zeros(8, np.float32)),
        conv_strides=np.array([4, 2]),
        dense_kernel=normal(height // 8 * width // 8 * 8, 16),
        dense_bias=np.zeros(16, np.float32),
    )
    return NumpyPolicy(
        kernels=(normal(16 + proprio_size, 2 * action_size),),
        biases=(np.zeros(2 * action_size, np.float32),),
        activation="tanh",
        obs_mean=np.zeros(proprio_size, np.float32),
        obs_std=np.ones(proprio_size, np.float32),
        action_offset=np.zeros(action_size, np.float32),
        action_scale=np.ones(action_size, np.float32),
        encoder=encoder,
    )


def random_inputs(controller: Controller, start_qpos: np.ndarray, rng: np.random.Generator):
    """(ArmReading, the task's estimate) near the start posture, objects or hole near the arm."""
    reading = ArmReading(
        arm_q=start_qpos + rng.uniform(-0.1, 0.1, 7), arm_qvel=rng.normal(0.0, 0.2, 7), finger_q=np.full(2, 0.02)
    )
    count = getattr(getattr(controller, "task", None), "objects_count", 0)
    if not count:
        return reading, HoleEstimate(np.array([0.5, 0.0]) + rng.uniform(-0.1, 0.1, 2))
    yaw = rng.uniform(0.0, 2 * np.pi, count)
    position = rng.uniform([0.3, -0.26, 0.02], [0.72, 0.16, 0.05], (count, 3))
    zero = np.zeros(count)
    pose = np.concatenate([position, np.stack([np.cos(yaw / 2), zero, zero, np.sin(yaw / 2)], -1)], -1)
    objects = ObjectEstimate(pose, rng.normal(0.0, 0.05, (count, 6)), rng.integers(0, 3, count), np.full(count, 0.025))
    return reading, objects


def tick_times(preset: str, ticks: int, warmup: int, seed: int) -> tuple[np.ndarray, np.ndarray, int]:
    """(wall seconds [ticks], CPU seconds [ticks] of each timed tick, the observation size) of `preset`'s
    deployment loop."""
    config = configs.get(preset)
    env, params = config.make_eval_env()
    controller = deployable.controller(env, params)
    task = controller.task
    rng = np.random.default_rng(seed)
    observation_size = env.spec.observation_shape[0]
    policy = random_policy(config, observation_size, controller.action_size, rng)
    loop = DeploymentLoop(policy, controller, CONTROL_DT, description=env.robot)
    loop.begin(np.concatenate([task.start_qpos, np.full(2, 0.02)]))
    inputs = [random_inputs(controller, task.start_qpos, rng) for _ in range(64)]
    cpu_seconds = []
    for index in range(warmup + ticks):
        start = time.process_time()
        loop.tick(*inputs[index % len(inputs)])
        cpu_seconds.append(time.process_time() - start)
    return np.array(loop.tick_seconds[warmup:]), np.array(cpu_seconds[warmup:]), observation_size


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench deploy", description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="ppo_sorter_dr,ppo_sorter3,ppo_peg", help="comma-separated presets")
    parser.add_argument("--ticks", type=count, default=5000, help="timed ticks per preset")
    parser.add_argument("--warmup", type=int, default=200, help="untimed ticks first")
    parser.add_argument("--seed", type=int, default=0)
    add_out_argument(parser)
    args = parser.parse_args(argv)
    core = min(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {core})
    print(f"one CPU core (#{core} of {os.cpu_count()}); numpy {np.__version__}; goal p99 <= {GOAL_P99_MS} ms")
    print("| preset | obs | p50 ms | p99 ms | max ms | CPU p50 ms | CPU p99 ms | ticks |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    rows = []
    for preset in args.presets.split(","):
        seconds, cpu_seconds, observation_size = tick_times(preset, args.ticks, args.warmup, args.seed)
        p50, p99 = np.percentile(seconds, [50, 99]) * 1e3
        cpu_p50, cpu_p99 = np.percentile(cpu_seconds, [50, 99]) * 1e3
        print(
            f"| {preset} | {observation_size} | {p50:.3f} | {p99:.3f} | {seconds.max() * 1e3:.3f} | {cpu_p50:.3f} "
            f"| {cpu_p99:.3f} | {len(seconds)} |",
            flush=True,
        )
        rows.append(
            {
                "preset": preset,
                "observation_size": observation_size,
                "p50_ms": p50,
                "p99_ms": p99,
                "max_ms": seconds.max() * 1e3,
                "cpu_p50_ms": cpu_p50,
                "cpu_p99_ms": cpu_p99,
                "ticks": len(seconds),
            }
        )
    load = os.getloadavg()[0]
    print(f"load average (1 min) {load:.1f} over {os.cpu_count()} cores")
    write_record(args.out, "deploy", argv, rows, cpu_core=core, goal_p99_ms=GOAL_P99_MS, load_average=load)
