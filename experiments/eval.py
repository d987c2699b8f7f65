"""Evaluate a saved run: `python -m experiments.eval RUN_DIR [--episodes N] [--video]`.

Loads the run's config and latest checkpoint, runs the deterministic policy on N fresh episodes, writes
eval.json, and with --video writes video.gif of a few episodes drawn without a window.
"""

import argparse
import operator
import pathlib
import sys

import imageio.v2 as imageio
import jax
import numpy as np
import numpy.typing as npt

from experiments import configs, rundir
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.evaluate import rollout_episodes
from jaxarm.envs.observation import with_camera_views


def episode_frames(env, env_params, trainer, state, key, episodes: int) -> list[np.ndarray]:
    """Frames of `episodes` deterministic episodes played one after another, each until it ends; a policy that
    sees has its camera's image beside each frame."""
    max_steps = int(env_params.max_episode_steps)
    policy = jax.jit(lambda obs: trainer.act(state, obs))
    states = jax.device_get(rollout_episodes(env, env_params, policy, key, episodes, max_steps))
    frames = []
    for episode in range(episodes):
        length = int(states.episode.length[-1, episode])
        for step in range(length):
            state_now = jax.tree.map(operator.itemgetter((step, episode)), states)
            frames.append(with_camera_views(env.render(state_now, env_params), state_now.obs))
    return frames


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.eval", description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--video", action="store_true", help="also write video.gif of 3 episodes")
    parser.add_argument("--seed", type=int, default=12345)
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    run_dir = pathlib.Path(args.run_dir)
    try:
        if args.episodes <= 0:
            raise ValueError(f"--episodes must be positive, got {args.episodes}")
        config, _ = rundir.read_config(run_dir)
        trainer = configs.make_trainer(config)
        state = rundir.restore_state(run_dir, trainer, config)
    except (ValueError, checkpoint.CheckpointError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    result = rundir.evaluate_state(trainer, config, state, args.episodes, args.seed)
    result["checkpoint_update"] = int(state.updates)
    rundir.write_json(run_dir / "eval.json", result)
    print(
        f"{run_dir}: success_rate {result['success_rate']:.3f} return_mean {result['return_mean']:.2f} "
        f"over {result['episodes']} episodes"
    )
    if args.video:
        env, env_params = config.make_eval_env()
        frames: list[npt.ArrayLike] = [
            *episode_frames(env, env_params, trainer, state, jax.random.PRNGKey(args.seed + 1), 3)
        ]
        imageio.mimsave(run_dir / "video.gif", frames, duration=0.04, loop=0)
        print(f"wrote {run_dir / 'video.gif'} ({len(frames)} frames)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
