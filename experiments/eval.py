"""Evaluate a saved run: `python -m experiments.eval RUN_DIR [--episodes N] [--seed S] [--video gif|mp4]`.

Loads the run's config and latest checkpoint (or the best one from evaluation during training, `--best`),
runs the deterministic policy on N fresh episodes, prints the result and writes it to its own file,
eval-<episodes>-<seed>.json (training's eval.json is kept). With --video it writes video.gif or video.mp4 of a
few episodes drawn without a window. The run directory is locked while this writes.
"""

import argparse
import pathlib
import sys
import time

import jax

from experiments import configs
from experiments.run import quiet_libraries
from jaxarm.agents.common import checkpoint
from jaxarm.runner import rundir, video
from jaxarm.runner.cache import enable_compilation_cache

VIDEO_EPISODES = 3


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.eval", description=__doc__)
    parser.add_argument("run_dir")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument(
        "--video",
        nargs="?",
        const="gif",
        choices=video.FORMATS,
        help=f"also write video.gif (default) or video.mp4 of {VIDEO_EPISODES} episodes",
    )
    parser.add_argument(
        "--best", action="store_true", help="evaluate the best checkpoint (best/) instead of the latest"
    )
    parser.add_argument("--seed", type=int, default=12345)
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    run_dir = pathlib.Path(args.run_dir)
    try:
        if args.episodes <= 0:
            raise ValueError(f"--episodes must be positive, got {args.episodes}")
        enable_compilation_cache()
        config, _ = rundir.read_config(run_dir)
        trainer = configs.make_trainer(config)
        with rundir.locked(run_dir):
            state = rundir.restore_state(run_dir, trainer, config, best=args.best)
            start = time.perf_counter()
            result = rundir.evaluate_state(trainer, config, state, args.episodes, args.seed)
            result["checkpoint_update"] = int(state.updates)
            print(
                f"{run_dir}: success_rate {result['success_rate']:.3f} return_mean {result['return_mean']:.2f} "
                f"over {result['episodes']} episodes (update {result['checkpoint_update']}; "
                f"{time.perf_counter() - start:.1f} s with compilation)",
                flush=True,
            )
            path = rundir.eval_path(run_dir, args.episodes, args.seed)
            rundir.write_json(path, result)
            print(f"wrote {path}")
            if args.video:
                env, env_params = config.make_eval_env()
                key = jax.random.PRNGKey(args.seed + 1)
                start = time.perf_counter()
                frames = video.episode_frames(env, env_params, trainer, state, key, VIDEO_EPISODES)
                video_path = run_dir / f"video.{args.video}"
                video.write_video(video_path, frames)
                print(f"wrote {video_path} ({len(frames)} frames, {time.perf_counter() - start:.1f} s)")
    except (ValueError, OSError, checkpoint.CheckpointError, video.RenderError) as error:
        print(f"error: {error}", file=sys.stderr)
        quiet_libraries()
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
