"""Compile the Warp kernels of presets' scenes ahead, for images and clusters: `python -m experiments.prepare
--config ppo_sorter [--config td3_peg ...]` on a machine with the GPU the runs will use.

Every run already compiles its scene's kernels in the background while XLA compiles (`jaxarm.envs.panda.
warp_kernels`); this does the same alone and waits for it, so that an image or a cluster's shared cache holds
them before the first run (Warp's cache: `~/.cache/warp/<version>`, or `WARP_CACHE_PATH`). A preset that does not
step on Warp here (no NVIDIA GPU, no warp-lang, or not a Panda scene) is named and left out.
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c()  # first, as in experiments.run: nothing is written before main()

import argparse


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.prepare", description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", action="append", required=True, help="a preset name (repeat for several)")
    args = parser.parse_args(argv)

    from experiments import configs

    try:
        chosen = [configs.get(name, validate=False) for name in args.config]
    except ValueError as error:
        print(f"prepare: {error}", file=sys.stderr)
        return 2
    from jaxarm.envs.panda.mjx_impl import Impl

    on_warp = []
    for name, config in zip(args.config, chosen, strict=True):
        env, _ = config.make_env(randomized=False)
        if getattr(env, "impl", None) == Impl.WARP:
            on_warp.append(name)
        else:
            print(f"{name}: nothing to compile (its scene does not step on Warp here)")
    if on_warp:
        from jaxarm.envs.panda import warp_kernels

        for result in warp_kernels.finish_preloads():
            if result is None:
                print("a scene's kernels failed to compile ahead: its first step compiles them")
            else:
                print(f"{result[0]} kernel modules compiled in {result[1]:.1f} s")
    return 0


if __name__ == "__main__":
    start_up.exit_with(main)
