"""Rehearse a sorter policy in real time against stock MuJoCo as the robot in its own process, behind a socket:
`python -m experiments.rehearse RUN [--episodes N] [--seed S] [--fault late|drop|stall] [--fault-tick K]
[--latency-budget MS]`.

Each episode starts where the run's eval env would start one (its reset, drawn by JAX), in the task's scene with
jaxarm's Panda and MuJoCo's default solver (`transfer.plant_model`), stepped at 1 kHz in wall-clock time by a robot
process (`jaxarm.deploy.driver`) that streams the policy's 25 Hz targets through a jerk-limited interpolation within
Franka's speed, acceleration and jerk limits. This process runs the deployment loop on its own 25 Hz schedule with
RUN/export/policy.npz (`python -m experiments.export RUN`), reading the robot's state (its joints and the objects'
poses, as a detector would report them) from the socket. An episode ends when no object is in play, at the env's
step limit, or when the robot holds and stops after a fault (`--fault` injects one at tick K of every episode).
Reports the objects placed, the policy's tick jitter (p50, p99) and deadline misses, the robot's servo-tick lateness,
each episode's fault, and the streamed setpoints' largest speed, acceleration and jerk as fractions of Franka's
limits; writes RUN/rehearse-<episodes>-<seed>-<update>-<budget>ms[-<fault>-tick<K>].json. An episode takes its
steps × 40 ms of wall clock (up to 30 s for ppo_sorter_dr's 750).
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c(start_up.AT_ONCE)  # first: Ctrl-C ends it at once, from its first import on

import argparse
import multiprocessing
import os
import pathlib
import shutil
import tempfile
import time

import mujoco
import numpy as np

from experiments import transfer
from jaxarm import deployable, ranges
from jaxarm.deploy import scoring, wire
from jaxarm.deploy.driver import DriverSetup
from jaxarm.deploy.loop import DeploymentLoop, UnsafeAction
from jaxarm.deploy.rehearsal import Rehearsal, rehearse
from jaxarm.deploy.remote import FAULT_KINDS, Fault, RobotStopped
from jaxarm.deploy.sort import SortController
from jaxarm.deploy.stream import limit_ratios
from jaxarm.deployable import panda_sort
from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.envs.panda_sort.objects import pose_index, velocity_index
from jaxarm.runner import paths, rundir

LATENCY_BUDGETS_MS = ranges.Range(gt=0, le=wire.Timing.connect_timeout * 1e3)
"""The latency budgets a rehearsal takes, ms: past the robot's wait for its first command, a stalled policy would
keep the robot (and the rehearsal) waiting longer than a policy that never started."""

SOCKET_PATH_MAX = 103 if sys.platform == "darwin" else 107
"""The longest path of a Unix socket here, in bytes: sockaddr_un holds 104 on macOS and 108 on Linux, a NUL
included."""
ROBOT_END_SECONDS = 5.0
"""How long a killed robot process may take to end before its directory is removed."""


def driver_setup(env, params, sim, directory: pathlib.Path, timing: wire.Timing) -> DriverSetup:
    """The robot process's start for the episode `sim`: its scene written to `directory`, its socket there;
    ValueError, before anything is written, where the socket's path is too long for one."""
    socket_path = directory / "robot.ipc"
    if len(os.fsencode(socket_path)) > SOCKET_PATH_MAX:  # zmq's "File name too long" traceback, and the robot's
        raise ValueError(
            f"the robot's socket {socket_path} is longer than a socket's path may be ({SOCKET_PATH_MAX} bytes): "
            "set TMPDIR to a shorter directory"
        )
    model = transfer.plant_model(env, params, "jaxarm")
    data = mujoco.MjData(model)
    ids = panda_sort.start_scene(model, data, env, params, sim)
    model_path = directory / "robot.mjb"
    mujoco.mj_saveModel(model, str(model_path))
    return DriverSetup(
        address=f"ipc://{socket_path}",
        model_path=str(model_path),
        qpos=data.qpos.copy(),
        ctrl=np.asarray(sim.ctrl, np.float64),
        object_qpos=pose_index(ids),
        object_qvel=velocity_index(ids),
        timing=timing,
        log_path=str(directory / "stream.npz"),
        description=env.robot,
    )


def placed(controller: SortController, sim, rehearsal: Rehearsal, bins: scoring.Bins) -> float:
    """The fraction of objects in their bins at the robot's last state."""
    position = rehearsal.final.object_pose[:, :3]
    outcome = scoring.next_outcome(controller.outcome, sim.shape, position, bins)
    return float(np.mean(outcome == scoring.IN_CORRECT_BIN))


def summary(rehearsals: list[Rehearsal], placements: list[float], timing: wire.Timing) -> dict:
    """The episodes' placements, the policy's timing, the robot's, and the setpoints against Franka's limits."""
    jitter = np.concatenate([rehearsal.jitter for rehearsal in rehearsals])
    lateness = np.concatenate([rehearsal.stream["lateness"] for rehearsal in rehearsals])
    ratios = [
        limit_ratios(rehearsal.stream["velocity"], rehearsal.stream["acceleration"], timing.servo_period)
        for rehearsal in rehearsals
    ]
    ticks = sum(rehearsal.steps for rehearsal in rehearsals)
    return {
        "episodes": len(rehearsals),
        "placed_fraction": float(np.mean(placements)),
        "success_rate": float(np.mean(np.array(placements) == 1.0)),
        "ticks": ticks,
        "tick_jitter_ms_p50": float(np.percentile(jitter, 50) * 1e3),
        "tick_jitter_ms_p99": float(np.percentile(jitter, 99) * 1e3),
        "tick_jitter_ms_max": float(np.max(jitter) * 1e3),
        "deadline_misses": sum(rehearsal.deadline_misses for rehearsal in rehearsals),
        "latency_budget_ms": timing.latency_budget * 1e3,
        "servo_ticks": len(lateness),
        "servo_lateness_ms_p99": float(np.percentile(lateness, 99) * 1e3),
        "servo_lateness_ms_max": float(np.max(lateness) * 1e3),
        "servo_ticks_late_over_1ms": int(np.sum(lateness > 1e-3)),
        "faults": [rehearsal.fault for rehearsal in rehearsals],
        **{f"max_{name}_of_limit": np.max([ratio[name] for ratio in ratios], 0).tolist() for name in ratios[0]},
    }


def end_robot_and_remove(directory: pathlib.Path) -> None:
    """Ends the robot process at once and removes its `directory`, for a rehearsal that Ctrl-C ends mid-episode:
    left to itself, the robot (deaf to Ctrl-C) held, stopped and wrote its log there after its parent had gone."""
    for child in multiprocessing.active_children():
        child.kill()
        child.join(ROBOT_END_SECONDS)
    shutil.rmtree(directory, ignore_errors=True)


def rehearse_run(run_dir: pathlib.Path, episodes: int, seed: int, fault: Fault | None, timing: wire.Timing) -> dict:
    """`episodes` rehearsed episodes of RUN's exported sorter policy; ValueError if RUN's env is not the sorter with
    state observations, or its exported policy is missing, damaged or does not fit the env."""
    config, _ = rundir.read_config(run_dir)
    env, params = config.make_eval_env()
    if not deployable.runs(env) or deployable.entry(env) is not panda_sort.DEPLOYABLE:
        raise ValueError(f"{run_dir}'s env is {config.env}; the rehearsal runs the sorter (panda_sort, panda_sort3)")
    if not env.spec.flat_observation:  # a traceback before: a camera's spec has no flat observation shape
        raise ValueError(
            f"{run_dir}'s policy reads cameras; the rehearsal runs state policies (experiments.transfer runs camera "
            "policies in stock MuJoCo)"
        )
    steps = int(params.max_episode_steps)
    if fault is not None and fault.tick >= steps:  # a fault no episode reaches: reported as none before
        raise ValueError(f"--fault-tick {fault.tick}: an episode of the run's env has ticks 0 to {steps - 1}")
    policy, checkpoint_name = transfer.exported_policy(run_dir, env.spec)
    controller = panda_sort.controller(env, params)
    bins = panda_sort.scoring_bins(env.layout)
    sims = transfer.episode_starts(env, params, episodes, seed)

    def done() -> bool:
        return not np.any(controller.outcome == scoring.IN_PLAY)

    began = time.perf_counter()
    rehearsals, placements = [], []
    for index in range(episodes):
        sim = transfer.one(sims, index)
        with (
            tempfile.TemporaryDirectory(prefix="rehearse-") as directory,
            start_up.CleanedOnCtrlC(lambda: end_robot_and_remove(pathlib.Path(directory))),
        ):
            setup = driver_setup(env, params, sim, pathlib.Path(directory), timing)
            loop = DeploymentLoop(policy, controller, CONTROL_DT, description=env.robot)
            size = np.asarray(sim.size, np.float64)
            rehearsal = rehearse(loop, setup, sim.shape, size, steps, done, fault)
        rehearsals.append(rehearsal)
        placements.append(placed(controller, sim, rehearsal, bins))
    result = {"checkpoint": checkpoint_name, "seed": seed, "fault": fault and fault.kind}
    return result | summary(rehearsals, placements, timing) | {"wall_seconds": time.perf_counter() - began}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.rehearse", description=__doc__)
    parser.add_argument("run_dir")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=12345)
    parser.add_argument("--fault", choices=FAULT_KINDS, help="inject this fault in every episode")
    parser.add_argument("--fault-tick", type=int, default=50, help="the policy's tick of the fault")
    parser.add_argument(
        "--latency-budget", type=float, default=wire.Timing.latency_budget * 1e3, help="ms a command may take"
    )
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    run_dir = pathlib.Path(args.run_dir)
    try:
        ranges.check_value("--episodes", args.episodes, int, ranges.AT_ONCE)
        ranges.check_value("--seed", args.seed, int, ranges.SEED)
        ranges.check_value("--latency-budget", args.latency_budget, float, LATENCY_BUDGETS_MS)
        fault = Fault(args.fault, args.fault_tick) if args.fault else None
        timing = wire.Timing(control_period=CONTROL_DT, latency_budget=args.latency_budget / 1e3)
        result = rehearse_run(run_dir, args.episodes, args.seed, fault, timing)
        suffix = f"-{args.fault}-tick{args.fault_tick}" if args.fault else ""
        budget = f"{args.latency_budget:g}ms"
        path = run_dir / f"rehearse-{args.episodes}-{args.seed}-{result['checkpoint']}-{budget}{suffix}.json"
        rundir.write_json(path, result)
        print(
            f"{run_dir} rehearsed in real time: placed {result['placed_fraction']:.3f}, success_rate "
            f"{result['success_rate']:.3f} over {args.episodes} episodes; policy tick jitter p50 "
            f"{result['tick_jitter_ms_p50']:.2f} ms, p99 {result['tick_jitter_ms_p99']:.2f} ms; "
            f"{result['deadline_misses']} of {result['ticks']} commands past the {result['latency_budget_ms']:.0f} ms "
            f"budget; servo lateness p99 {result['servo_lateness_ms_p99']:.2f} ms; "
            f"faults {sorted(set(result['faults']))}"
        )
        print(f"wrote {path}")
    except (ValueError, UnsafeAction, RobotStopped, mujoco.FatalError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"error: {paths.os_error_message(error)}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    start_up.exit_with(main)
