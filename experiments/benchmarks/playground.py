"""Playground's own recipe against jaxarm's PPO on Playground's Franka tasks: time to one success criterion.

For each task and seed, in one process on one device, two learners train one after the other:

- **Playground**: brax's PPO (`brax.training.agents.ppo.train`) with `manipulation_params.brax_ppo_config(task)`,
  on the task as `registry.load` builds it, wrapped by `wrapper.wrap_for_brax_training`: Playground's training
  entry points and settings. One change: its `num_evals` and `num_resets_per_eval` become `EVALS + 1` and
  (Playground's evaluation count × resets) / `EVALS`, so that its envs reset as often as Playground's recipe
  resets them while the clock stops at `EVALS` evaluation points; brax's own evaluation is off. Its Warp kernels
  print no overflow lines, as in jaxarm's adapter (`jaxarm.interop.playground.quiet_model`).
- **jaxarm**: our PPO with the task's preset (`PRESETS`), its budget in `EVALS` equal calls of one compiled
  program.

At each evaluation point both are judged alike: the deterministic policy on the same fresh episodes of jaxarm's
adapter of the task (`jaxarm.interop.playground`: the box within 2 cm of its target at the time limit, the
criterion BENCHMARKS.md#playground states), the evaluation's own time taken off the learner's clock. A learner's
time to the goal is its clock (set-up, compilation and training) at the first point whose success reaches
`--goal`; its steady rate is env steps/s over its fastest interval between points after the first.
"""

import argparse
import dataclasses
import functools
import time
from collections.abc import Callable, Sequence
from typing import Any

import jax
import numpy as np

from experiments import configs
from experiments.benchmarks.arguments import count, env_count
from experiments.benchmarks.record import add_out_argument, write_record
from jaxarm.agents.common.config import apply_overrides, with_pair
from jaxarm.agents.common.evaluate import evaluate
from jaxarm.agents.common.trainer import run_updates
from jaxarm.agents.ppo import PPOConfig, make_trainer

PRESETS = {"PandaPickCube": "ppo_playground_pick", "PandaPickCubeOrientation": "ppo_playground_pick_orientation"}
"""Each task this suite knows -> jaxarm's preset for it."""
LEARNERS = ("playground", "jaxarm")
MAX_EVALS = 1000
"""The most evaluation points a run may have: each is an evaluation of --eval-episodes fresh episodes."""


@dataclasses.dataclass(frozen=True)
class Point:
    """One evaluation point of a run: env steps trained, the learner's clock there (seconds since its start, without
    evaluations), and the success rate and mean return of the deterministic policy."""

    env_steps: int
    seconds: float
    success_rate: float
    return_mean: float


@dataclasses.dataclass(frozen=True)
class Run:
    """One learner's run on one task and seed, its `points` in order."""

    task: str
    learner: str
    seed: int
    points: tuple[Point, ...]

    def seconds_to(self, goal: float) -> float | None:
        """The clock at the first point whose success reaches `goal`; None where none does."""
        return next((point.seconds for point in self.points if point.success_rate >= goal), None)

    @property
    def steady_steps_per_second(self) -> float:
        """Env steps/s over the fastest interval between points after the first (which compiles)."""
        rates = [
            (later.env_steps - earlier.env_steps) / (later.seconds - earlier.seconds)
            for earlier, later in zip(self.points[1:], self.points[2:], strict=False)
            if later.seconds > earlier.seconds
        ]
        return max(rates, default=float("nan"))


class Judge:
    """Evaluates deterministic policies of one task on the same fresh episodes (jaxarm's adapter), and keeps the
    seconds it spent, which the learners' clocks leave out."""

    def __init__(self, config: PPOConfig, episodes: int, seed: int):
        self.env, self.env_params = config.make_eval_env()
        self.episodes, self.key = episodes, jax.random.PRNGKey(seed + 1)
        self.spent = 0.0
        self._programs: dict[Callable, Callable] = {}

    def __call__(self, act: Callable[[Any, jax.Array], jax.Array], params: Any) -> tuple[float, float]:
        """(success rate, mean return) of the policy `act(params, obs [B, O]) -> action [B, A]`: one program per
        `act`, `params` its argument."""
        began = time.perf_counter()
        if act not in self._programs:

            def evaluated(params: Any, key: jax.Array):
                return evaluate(self.env, self.env_params, functools.partial(act, params), key, self.episodes)

            self._programs[act] = jax.jit(evaluated)
        summary = self._programs[act](params, self.key).summary()
        self.spent += time.perf_counter() - began
        return summary["success_rate"], summary["return_mean"]


def playground_kwargs(task: str, impl: str, evals: int, num_envs: int | None, env_steps: int | None) -> dict:
    """brax PPO's arguments as Playground's recipe for `task` sets them (see the module docstring for the change to
    its evaluation points); `num_envs` and `env_steps` (None: the recipe's) shrink it for a smoke run."""
    from brax.training.agents.ppo import networks as ppo_networks
    from mujoco_playground.config import manipulation_params

    recipe = manipulation_params.brax_ppo_config(task, impl).to_dict()
    resets = (recipe.pop("num_evals") - 1) * recipe.pop("num_resets_per_eval", 1)
    if resets % evals:
        divisors = ", ".join(str(divisor) for divisor in range(1, resets + 1) if resets % divisor == 0)
        raise ValueError(
            f"--evals {evals} must divide the {resets} resets of Playground's recipe for {task} (one of {divisors})"
        )
    network = recipe.pop("network_factory")
    if num_envs is not None:
        recipe["batch_size"] = max(1, recipe["batch_size"] * num_envs // recipe["num_envs"])
        recipe["num_envs"] = num_envs
    if env_steps is not None:
        recipe["num_timesteps"] = env_steps
    return {
        **recipe,
        "num_evals": evals + 1,
        "num_resets_per_eval": resets // evals,
        "run_evals": False,
        "network_factory": functools.partial(ppo_networks.make_ppo_networks, **network),
        "max_devices_per_host": 1,
    }


def train_playground(
    task: str, seed: int, impl: str, evals: int, judge: Judge, num_envs: int | None, env_steps: int | None
) -> Run:
    """Playground's recipe for `task` (see the module docstring), judged at each of its evaluation points."""
    from brax.training.agents.ppo import train as brax_ppo
    from mujoco_playground import registry, wrapper

    from jaxarm.envs.panda.mjx_impl import resolve_impl
    from jaxarm.interop.brax_compat import install_device_put_replicated
    from jaxarm.interop.playground import checked_overrides, quiet_model

    install_device_put_replicated()  # brax 0.14.2's trainers call what jax 0.10 removed

    began, points = time.perf_counter(), []
    policies: list[Callable] = []

    def act(params, obs: jax.Array) -> jax.Array:
        return policies[0](params, deterministic=True)(obs, jax.random.PRNGKey(0))[0]

    def judge_point(step: int, make_policy, params) -> None:
        policies[:] = [make_policy]  # the same function at every point of a run
        success, return_mean = judge(act, params)
        points.append(Point(int(step), time.perf_counter() - began - judge.spent, success, return_mean))

    engine = resolve_impl(impl)
    environment = registry.load(task, config_overrides=checked_overrides(task, engine, {}))
    # Its kernels' overflow lines off, as in jaxarm's adapter: a race of the same physics, printing alike.
    environment._mjx_model = quiet_model(environment._mjx_model, engine)
    brax_ppo.train(
        environment=environment,
        wrap_env_fn=wrapper.wrap_for_brax_training,
        policy_params_fn=judge_point,
        seed=seed,
        **playground_kwargs(task, impl, evals, num_envs, env_steps),
    )
    return Run(task, "playground", seed, tuple(points))


def jaxarm_config(
    task: str, seed: int, impl: str, evals: int, overrides: Sequence[str], num_envs: int | None, env_steps: int | None
) -> PPOConfig:
    """The task's preset with `overrides`, `impl` and `seed`, `num_envs` and `env_steps` (None: the preset's), its
    budget rounded up to `evals` equal calls."""
    config = apply_overrides(configs.get(PRESETS[task]), [*overrides, f"seed={seed}"])
    assert isinstance(config, PPOConfig), f"{PRESETS[task]} is a PPO preset"
    if num_envs:  # a smoke run's few envs: as many minibatches and groups as they split into
        config = dataclasses.replace(
            config, num_envs=num_envs, num_minibatches=min(config.num_minibatches, num_envs), shuffle_groups=1
        )
    steps_per_update = config.num_envs * config.rollout_length
    updates = evals * -(-(env_steps or config.total_env_steps) // (evals * steps_per_update))
    config = dataclasses.replace(
        config,
        env_kwargs=with_pair(config.env_kwargs, "impl", impl),
        total_env_steps=updates * steps_per_update,
        updates_per_chunk=updates // evals,
    )
    config.validate()
    return config


def train_jaxarm(config: PPOConfig, evals: int, judge: Judge) -> Run:
    """Our PPO on `config` in `evals` equal calls of one compiled program, judged before the first and after each."""
    began = time.perf_counter()
    trainer = make_trainer(config)
    hparams = config.hparams()
    state = jax.jit(trainer.init)(jax.random.PRNGKey(config.seed), hparams)
    runner = jax.jit(functools.partial(run_updates, trainer, num_updates=config.num_updates // evals), donate_argnums=0)
    compiled = runner.lower(state, hparams).compile()
    points = []
    for call in range(evals + 1):
        if call:
            state, _ = compiled(state, hparams)
        jax.block_until_ready(state)
        success, return_mean = judge(trainer.act, state)
        steps = int(state.updates) * trainer.env_steps_per_update
        points.append(Point(steps, time.perf_counter() - began - judge.spent, success, return_mean))
    task = config.env.removeprefix("playground:")
    return Run(task, "jaxarm", config.seed, tuple(points))


def summary_rows(runs: Sequence[Run], goal: float) -> list[dict]:
    """A row per task and learner: seconds to the goal per seed and the worst, steady env steps/s, final success."""
    rows = []
    for task in dict.fromkeys(run.task for run in runs):
        for learner in LEARNERS:
            mine = [run for run in runs if run.task == task and run.learner == learner]
            if not mine:
                continue
            times = [run.seconds_to(goal) for run in mine]
            rows.append(
                {
                    "task": task,
                    "learner": learner,
                    "seeds": [run.seed for run in mine],
                    "seconds_to_goal": times,
                    "worst_seconds_to_goal": None if None in times else max(times),  # type: ignore[type-var]
                    "steady_steps_per_second": float(np.median([run.steady_steps_per_second for run in mine])),
                    "final_success": [run.points[-1].success_rate for run in mine],
                }
            )
    return rows


def table(rows: Sequence[dict], goal: float) -> str:
    """The rows as markdown, with jaxarm's worst time to the goal over Playground's per task."""

    def seconds(value: float | None) -> str:
        return "never" if value is None else f"{value:.0f} s"

    lines = [
        f"| task | learner | seconds to {goal:.0%} (each seed) | worst | steady env steps/s | final success |",
        "|---|---|---|---:|---:|---|",
    ]
    for row in rows:
        each = ", ".join(seconds(value) for value in row["seconds_to_goal"])
        final = ", ".join(f"{value:.1%}" for value in row["final_success"])
        lines.append(
            f"| {row['task']} | {row['learner']} | {each} | {seconds(row['worst_seconds_to_goal'])} | "
            f"{row['steady_steps_per_second']:,.0f} | {final} |"
        )
    for task in dict.fromkeys(row["task"] for row in rows):
        worst = {row["learner"]: row["worst_seconds_to_goal"] for row in rows if row["task"] == task}
        if worst.get("jaxarm") and worst.get("playground"):
            ratio = worst["jaxarm"] / worst["playground"]
            lines.append(f"\n{task}: jaxarm's worst time to the goal over Playground's: {ratio:.2f}×")
    return "\n".join(lines)


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench playground", description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", default=",".join(PRESETS), help=f"comma-separated, of {', '.join(PRESETS)}")
    parser.add_argument("--seeds", default="0,1,2", help="comma-separated seeds, each a run of each learner")
    parser.add_argument("--learners", default=",".join(LEARNERS), help=f"comma-separated, of {', '.join(LEARNERS)}")
    parser.add_argument("--goal", type=float, default=0.9, help="the success rate a learner's time is measured to")
    parser.add_argument("--evals", type=count, default=10, help=f"evaluation points over each run (up to {MAX_EVALS})")
    parser.add_argument("--eval-episodes", type=env_count, default=1000, help="fresh episodes per evaluation point")
    parser.add_argument("--impl", default="auto", help='"jax", "warp" or "auto" (Warp on an NVIDIA GPU)')
    parser.add_argument("--num-envs", type=env_count, help="both learners' envs (default: each recipe's): smoke runs")
    parser.add_argument("--env-steps", type=count, help="both learners' budget (default: each recipe's): smoke runs")
    parser.add_argument("overrides", nargs="*", help="overrides key=value of jaxarm's presets")
    add_out_argument(parser)
    return parser


def main(argv: Sequence[str]) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    tasks, learners = args.tasks.split(","), args.learners.split(",")
    unknown = sorted({*tasks} - set(PRESETS)) + sorted({*learners} - set(LEARNERS))
    if unknown:
        parser.error(f"unknown {', '.join(unknown)}: tasks are {', '.join(PRESETS)}, learners {', '.join(LEARNERS)}")
    try:
        seeds = [int(seed) for seed in args.seeds.split(",")]
    except ValueError:
        parser.error(f"--seeds takes comma-separated whole numbers, got {args.seeds!r}")
    if args.evals > MAX_EVALS or not 0 < args.goal <= 1:
        parser.error(f"--evals must be at most {MAX_EVALS}, --goal in (0, 1]")
    try:  # every setting checked before anything trains
        configs_by_run = {
            (task, seed): jaxarm_config(
                task, seed, args.impl, args.evals, args.overrides, args.num_envs, args.env_steps
            )
            for task in tasks
            for seed in seeds
        }
        if "playground" in learners:
            for task in tasks:
                playground_kwargs(task, args.impl, args.evals, args.num_envs, args.env_steps)
    except ValueError as error:
        parser.error(str(error))
    print(f"device: {jax.devices()[0].device_kind}; jax {jax.__version__}; impl {args.impl}", flush=True)
    runs = []
    for task in tasks:
        for seed in seeds:
            config = configs_by_run[task, seed]
            for learner in learners:
                judge = Judge(config, args.eval_episodes, seed)
                if learner == "playground":
                    run = train_playground(task, seed, args.impl, args.evals, judge, args.num_envs, args.env_steps)
                else:
                    run = train_jaxarm(config, args.evals, judge)
                runs.append(run)
                last, reached = run.points[-1], run.seconds_to(args.goal)
                print(
                    f"{task} {learner} seed {seed}: {'never' if reached is None else f'{reached:.1f} s'} to "
                    f"{args.goal:.0%}; {last.success_rate:.1%} after {last.env_steps:,} env steps, "
                    f"{last.seconds:.1f} s",
                    flush=True,
                )
    rows = summary_rows(runs, args.goal)
    print(table(rows, args.goal))
    write_record(args.out, "playground", argv, rows, runs=[dataclasses.asdict(run) for run in runs], goal=args.goal)
