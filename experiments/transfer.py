"""Run a policy in stock MuJoCo through the deployment loop: `python -m experiments.transfer RUN [--model NAME]
[--episodes N] [--seed S] [--video [gif|mp4]] [--no-clip] [--pose-bias X,Y,Z]`.

The "robot" is the task's scene in MuJoCo's C engine (`mujoco.mj_step`: the scene's timestep, MuJoCo's default
constraint solver), with jaxarm's own model of the run's robot (`--model jaxarm`) or MuJoCo Menagerie's (`--model
menagerie`, same kinematics, its own inertials, actuators and gains, stepped at its own timestep, the robot
description's `menagerie_timestep`, where the scene's is longer). Between the policy and the robot runs only the
deployment loop (`jaxarm.deploy`): the robot's reading -> the env's observation -> RUN/export/policy.npz (written by
`python -m experiments.export RUN`) -> the env's controller in numpy -> servo targets within the robot's speed and
acceleration limits (clipped, and each clip counted; `--no-clip` only counts). Each episode starts where the run's
eval env would start one (its reset, drawn by JAX); from there no jaxarm env code runs, and success and return are
recomputed from MuJoCo's state in numpy (`jaxarm.deploy.scoring`). `--pose-bias X,Y,Z` (metres) adds a constant
error to every position estimate the policy is given (the sorter's objects' centres, the peg's hole), all episode,
as a miscalibrated camera would; the episodes are scored from the true positions. Writes
`RUN/transfer-<model>-<episodes>-<seed>-<update>[-noclip][-bias<X>_<Y>_<Z>mm].json` (<update>: the checkpoint the
policy was exported from, as RUN/export/export.json says) and, with --video, the same name .gif (or .mp4) of the first
episode.

A policy that reads cameras (a pixel run) gets, each tick, the env's camera image drawn by MuJoCo's own OpenGL
renderer (`mujoco.Renderer`: each of the env's cameras at its resolution, RGB to the env's gray, the depth buffer to
metres; `jaxarm.deploy.camera`) of the robot's scene, and the proprio part computed from the arm's reading; it needs
an offscreen GL (MUJOCO_GL=egl). Object estimates are still read, to score the episode, but never shown to it (so
it takes no --pose-bias).
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c(start_up.AT_ONCE)  # first: Ctrl-C ends it at once, from its first import on

import argparse
import copy
import pathlib
import time

import jax
import mujoco
import numpy as np
from scipy import stats

from jaxarm import deployable, envs, headless, ranges
from jaxarm.agents.common import checkpoint
from jaxarm.deploy.loop import Controller, DeploymentLoop, UnsafeAction
from jaxarm.deploy.mujoco_robot import MujocoRobot, stock_solver
from jaxarm.envs.observation import actor_observation
from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.export import numpy_policy, origin
from jaxarm.runner import metrics_log, paths, rundir, video

MODELS = ("jaxarm", "menagerie")
VIDEO_SIZE = (240, 320)
NO_BIAS = np.zeros(3)
MAX_POSE_BIAS = 0.1
"""The largest --pose-bias component (m), beyond the widest object (7.5 cm): a value meant in centimetres is refused."""


def plant_model(env, params, model_name: str) -> mujoco.MjModel:
    """A fresh copy of the task's scene with the env's robot as `model_name` names it, MuJoCo's default solver;
    menagerie's robot at most at its own timestep."""
    if model_name == "jaxarm":
        model = copy.copy(env.mj_model)
    else:
        model = copy.copy(deployable.entry(env).scene(env, params, env.robot.menagerie_xml))
    if model_name == "menagerie":
        # At the scenes' 0.01 s menagerie's Panda's wrist servos chatter: a numerical artefact, no property of the
        # robot, that cut ppo_sorter_dr's placements from 98.5% (at 0.002 s) to 33.5% (200 episodes each).
        model.opt.timestep = min(model.opt.timestep, env.robot.menagerie_timestep)
    if model.nq != env.mj_model.nq:
        raise ValueError(f"{model_name}'s scene has {model.nq} positions, the env's {env.mj_model.nq}")
    stock_solver(model)
    return model


def episode_starts(env, params, episodes: int, seed: int):
    """The eval env's reset sims of `episodes` episodes as numpy arrays (leading axis: episode)."""
    keys = jax.random.split(jax.random.PRNGKey(seed), episodes)
    states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    return jax.tree.map(np.asarray, states.sim)


def one(sims, index: int):
    return jax.tree.map(lambda leaf: leaf[index], sims)


class Recorder:
    """Frames of the scene from its `front` camera, or nothing."""

    def __init__(self, model: mujoco.MjModel | None):
        self.frames: list[np.ndarray] = []
        self._renderer = mujoco.Renderer(model, *VIDEO_SIZE) if model is not None else None

    def capture(self, data: mujoco.MjData) -> None:
        if self._renderer is not None:
            self._renderer.update_scene(data, camera="front")
            self.frames.append(self._renderer.render())

    def close(self) -> None:
        # Closed here: a renderer left to the interpreter's teardown prints a TypeError.
        if self._renderer is not None:
            self._renderer.close()


def run_episodes(
    env,
    params,
    policy,
    model_name: str,
    episodes: int,
    seed: int,
    clip: bool,
    record: bool,
    pose_bias: np.ndarray = NO_BIAS,
) -> dict:
    """Runs `episodes` episodes of `policy` (observation -> action, numpy) in the eval `env`'s scene with
    `model_name`'s model of its robot, from the env's resets drawn from `seed`, every position estimate off by
    `pose_bias` [3] (m); the summary, and the first episode's frames under "frames" when `record`. A camera's policy
    sees the scene drawn by MuJoCo's renderer at each tick (`jaxarm.deploy.camera`)."""
    run_episode = deployable.entry(env).episode
    model = plant_model(env, params, model_name)
    robot = MujocoRobot(model, CONTROL_DT, env.robot)
    camera = None if env.spec.flat_observation else deployable.camera_renderer(env, model)
    if camera is None:
        controller: Controller = deployable.controller(env, params)
    else:
        controller = deployable.camera_controller(env, params, camera, robot.data)
    loop = DeploymentLoop(policy, controller, CONTROL_DT, clip=clip, description=env.robot)
    sims = episode_starts(env, params, episodes, seed)
    began = time.perf_counter()
    results: list[dict] = []
    frames: list[np.ndarray] = []
    try:
        for index in range(episodes):
            recorder = Recorder(model if record and index == 0 else None)
            results.append(run_episode(robot, loop, env, params, one(sims, index), recorder.capture, pose_bias))
            recorder.close()
            frames = frames or recorder.frames
    finally:
        if camera is not None:
            camera.close()
    successes = sum(result["success"] for result in results)
    interval = stats.binomtest(successes, episodes).proportion_ci(method="wilson")
    ticks = np.array(loop.tick_seconds)
    summary = {
        "robot": env.robot.name,
        "model": model_name,
        "episodes": episodes,
        "seed": seed,
        "success_rate": successes / episodes,
        "success_ci95": [interval.low, interval.high],
        "return_mean": float(np.mean([result["return"] for result in results])),
        "steps_mean": float(np.mean([result["steps"] for result in results])),
        "clip": clip,
        "pose_bias": [float(component) for component in pose_bias],
        "ticks": len(ticks),
        "acceleration_clips": loop.counts.acceleration.tolist(),
        "speed_clips": loop.counts.speed.tolist(),
        "tick_ms_p50": float(np.percentile(ticks, 50) * 1e3),
        "tick_ms_p99": float(np.percentile(ticks, 99) * 1e3),
        "timestep": float(model.opt.timestep),
        "solver_iterations": int(model.opt.iterations),
        "wall_seconds": time.perf_counter() - began,
    }
    if "placed" in results[0]:
        summary["placed_fraction"] = float(np.mean([result["placed"] for result in results]))
    return summary | {"frames": frames} if record else summary


def fits(policy: numpy_policy.NumpyPolicy, spec) -> bool:
    """Whether `policy` reads `spec`'s observations (a camera's: the parts its actor reads) and acts as it does."""
    if spec.flat_observation:
        observed = policy.encoder is None and policy.observation_size == spec.observation_shape[0]
    else:
        parts = {name: part.shape for name, part in actor_observation(spec.observation_parts).items()}
        observed = policy.observation_parts() == parts
    return observed and policy.action_size == spec.action_shape[0]


def transferable_envs() -> list[str]:
    """The registered envs the deployment loop runs as registered (the sorter's and the peg's, with state
    observations or cameras)."""
    return [name for name in envs.names() if deployable.runs(envs.make(name))]


def parse_pose_bias(text: str) -> np.ndarray:
    """'X,Y,Z' (metres) -> [3]; ValueError unless three finite numbers, each within ±MAX_POSE_BIAS."""
    try:
        bias = np.array([float(part) for part in text.split(",")])
    except ValueError:
        bias = np.array([])
    if bias.shape != (3,) or not np.all(np.abs(bias) <= MAX_POSE_BIAS):
        raise ValueError(f"--pose-bias is X,Y,Z in metres, each within ±{MAX_POSE_BIAS:g}, got {text!r}")
    return bias


def bias_words(pose_bias: np.ndarray) -> str:
    """', position estimates off by (X, Y, Z) mm' where `pose_bias` [3] (m) is not zero; '' otherwise."""
    if not np.any(pose_bias):
        return ""
    return f", position estimates off by ({', '.join(f'{component * 1e3:g}' for component in pose_bias)}) mm"


def transfer(
    run_dir: pathlib.Path,
    model_name: str,
    episodes: int,
    seed: int,
    clip: bool,
    record: bool,
    pose_bias: np.ndarray = NO_BIAS,
) -> dict:
    """`run_episodes` of RUN's exported policy in its eval env, with the checkpoint it came from ("checkpoint");
    ValueError if the deployment loop does not run the env, or the policy or its export.json is missing or damaged,
    or the policy does not fit the env, or `pose_bias` is asked of a camera's policy (which sees no estimate)."""
    config, _ = rundir.read_config(run_dir)
    env, params = config.make_eval_env()
    if not deployable.runs(env):
        kwargs = f" with env_kwargs {dict(config.env_kwargs)}" if config.env_kwargs else ""
        raise ValueError(f"{run_dir}'s env is {config.env}{kwargs}; transfer runs {', '.join(transferable_envs())}")
    if np.any(pose_bias) and not env.spec.flat_observation:
        raise ValueError("--pose-bias: a camera's policy is shown no position estimate to bias")
    policy, checkpoint_name = exported_policy(run_dir, env.spec)
    summary = run_episodes(env, params, policy, model_name, episodes, seed, clip, record, pose_bias)
    return {"checkpoint": checkpoint_name} | summary


def exported_policy(run_dir: pathlib.Path, spec) -> tuple[numpy_policy.NumpyPolicy, str]:
    """RUN's exported numpy policy and the checkpoint it came from (its export.json); ValueError where there is
    none or it does not fit `spec` (`fits`), PolicyFileError where it or its export.json is damaged. Warns on
    standard error where the export is older than the run (`stale_export`)."""
    policy_path = run_dir / "export" / "policy.npz"
    if not policy_path.exists():
        raise ValueError(f"no {policy_path}: export the run first (python -m experiments.export {run_dir})")
    policy = numpy_policy.load(policy_path)
    if not fits(policy, spec):
        raise ValueError(f"{policy_path} does not fit the run's env ({spec})")
    checkpoint_name = origin.read(policy_path.parent)
    if warning := stale_export(run_dir, checkpoint_name):
        print(warning, file=sys.stderr, flush=True)
    return policy, checkpoint_name


def stale_export(run_dir: pathlib.Path, checkpoint_name: str) -> str | None:
    """A warning where RUN/export holds the policy of an earlier update (`checkpoint_name`, from its export.json)
    than the run has trained to since (its latest checkpoint, or where its checkpoints are gone its metrics' last
    row): an export made before the run finished or was resumed, whose figures would not be the run's. None where
    the export is of the latest update, or of the best checkpoint."""
    if not checkpoint_name.isdigit():
        return None
    latest = checkpoint.latest_step(run_dir / "checkpoints")
    if latest is None:
        latest = max(
            (int(row["updates"]) for row in metrics_log.read_metrics(run_dir, drop_partial_last=True)), default=0
        )
    if latest <= int(checkpoint_name):
        return None
    return (
        f"warning: {run_dir / 'export'} holds update {checkpoint_name}'s policy, and the run has trained to update "
        f"{latest} since; python -m experiments.export {run_dir} exports its latest"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.transfer", description=__doc__)
    parser.add_argument("run_dir")
    parser.add_argument(
        "--model", choices=MODELS, default="jaxarm", help="whose model of the run's robot the scene holds"
    )
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=12345)
    parser.add_argument("--video", nargs="?", const="gif", choices=headless.FORMATS, help="write the first episode")
    parser.add_argument("--no-clip", action="store_true", help="count commands beyond the robot's limits, send them")
    parser.add_argument(
        "--pose-bias", default="0,0,0", metavar="X,Y,Z", help="metres added to every position estimate, all episode"
    )
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    run_dir = pathlib.Path(args.run_dir)
    # Probed first, as eval does: a renderer failing after the episodes ran gives GLFW's warnings and no hint.
    problem = headless.gl_problem() if args.video else None
    if problem is not None:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    try:
        ranges.check_value("--episodes", args.episodes, int, ranges.AT_ONCE)
        ranges.check_value("--seed", args.seed, int, ranges.SEED)
        pose_bias = parse_pose_bias(args.pose_bias)
        clip, record = not args.no_clip, args.video is not None
        result = transfer(run_dir, args.model, args.episodes, args.seed, clip, record, pose_bias)
        frames = result.pop("frames", [])
        checkpoint = result["checkpoint"]
        stem = rundir.transfer_stem(run_dir, args.model, args.episodes, args.seed, checkpoint, clip, pose_bias.tolist())
        path = stem.with_suffix(".json")
        rundir.write_json(path, result)
        low, high = result["success_ci95"]
        print(
            f"{run_dir} in stock MuJoCo ({args.model}'s {result['robot']}{bias_words(pose_bias)}): "
            f"success_rate {result['success_rate']:.3f} "
            f"[{low:.3f}, {high:.3f}] return_mean {result['return_mean']:.2f} over {args.episodes} episodes; "
            f"tick p50 {result['tick_ms_p50']:.2f} ms, p99 {result['tick_ms_p99']:.2f} ms; "
            f"{'clipped' if result['clip'] else 'beyond'} the {result['robot']}'s limits in {result['ticks']} ticks: "
            f"acceleration {result['acceleration_clips']}, speed {result['speed_clips']}"
        )
        print(f"wrote {path}")
        if args.video:
            video_path = stem.with_suffix(f".{args.video}")
            video.write_video(video_path, frames)
            print(f"wrote {video_path} ({len(frames)} frames)")
    except (ValueError, UnsafeAction, video.RenderError, mujoco.FatalError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"error: {paths.os_error_message(error)}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    start_up.exit_with(main)
