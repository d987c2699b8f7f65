"""Our PPO beside brax's PPO on the same env, in the same run: wall clock, env steps/s, deterministic success.

Both learners get the same env (through `jaxarm.interop.brax_env.BraxEnv` for brax, with jaxarm's own time
limit and auto-reset, so both see freshly sampled episodes), the same env-step budget, the same network
sizes and activation, and the hyper-parameters of our preset for the env (see `base_ppo_config`)
mapped onto brax's names: brax's `unroll_length` = our `rollout_length`, `num_minibatches` and
`num_updates_per_batch` = our minibatches and epochs, `batch_size` = num_envs / num_minibatches, so an
update consumes the same env steps and each SGD step the same number of samples. What stays different,
by design of each library: brax's learning rate is constant (`--brax-learning-rate`, 1e-3 by default, the
top of its usual range) while ours anneals linearly from the preset's; brax's policy std is a learned
state-independent parameter, ours an output of the policy MLP; brax masks the advantage of time-limit steps,
ours bootstraps from the pre-reset observation; brax shuffles whole unrolls into minibatches, ours single steps.

Each learner runs the budget in `PARTS` equal parts (ours: calls of one program compiled ahead of time; brax:
training epochs). The fastest part after the first gives the steady rate; everything else in the wall clock
counts as compilation, set-up and one-off costs. So a one-off cost outside the first part cannot pass for
training: a learner that compiles again on a later call (as brax did when handed a state on a mesh axis other
than its pmap axis, see `jaxarm.interop.brax_compat`) has that compilation booked as one-off, not as training.
Evaluation is jaxarm's `evaluate` on the same fresh episodes of the preset's evaluation env for both,
with deterministic policies (tanh of the Gaussian's mean), outside the timings.

Both learners compile with the same XLA settings: the process's. Our runner would compile an env without MJX
with XLA:CPU's fusion emitters on (`Trainer.compiler_options`), which brax's own programs cannot be given here;
with jaxlib 0.10 on a CPU, run this suite with `JAXARM_KEEP_XLA_FLAGS=1` for such an env, so that both compile
the way our runner does (and as brax does without jaxarm imported).

With both learners, the suite then times the same envs stepping alone (same count, same steps per update, no
policy, no learning) and prints each learner's cost beyond that, and the ceiling: the throughput ratio against
brax that a learner costing nothing would reach. Where the env's physics dominates an update (the sorter on a
GPU), that ceiling bounds any learner. A trained policy makes the physics dearer than random actions do (it moves
the arm into the objects: more contacts), so each learner's trained policy then drives the same envs alone too,
and the ceiling is given again against our policy's stepping.

Overrides (key=value) edit the preset both learners map from; `anneal_learning_rate=false` gives ours a constant
learning rate, as brax's is.
"""

import argparse
import dataclasses
import functools
import time
from collections.abc import Sequence

import flax.linen as nn
import jax
import numpy as np

from experiments import configs
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.timing import env_seconds
from jaxarm import envs
from jaxarm.agents.common.config import apply_overrides, with_pair
from jaxarm.agents.common.evaluate import evaluate
from jaxarm.agents.common.trainer import run_updates
from jaxarm.agents.ppo import PPOConfig, make_trainer

QUICK_NUM_ENVS = 512
QUICK_ENV_STEPS = 600_000
PARTS = 4
"""Equal parts each learner's budget runs in (see the module docstring)."""


@dataclasses.dataclass(frozen=True)
class Result:
    """One learner's run. Seconds are wall clock.

    Attributes:
      env_steps: env steps trained.
      total_seconds: the whole run: set-up, network init, compilation and training.
      part_seconds: [PARTS] seconds of each equal part of the training, the first with any compilation brax
        does inside it.
      policy_env_seconds: seconds per update of the same envs stepping alone under the trained policy's
        deterministic actions (no learning): the update's physics as this learner's policy drives it.
    """

    env_steps: int
    total_seconds: float
    part_seconds: tuple[float, ...]
    success_rate: float
    return_mean: float
    policy_env_seconds: float

    @property
    def train_seconds(self) -> float:
        """Training at the steady rate: every part as fast as the fastest after the first."""
        return len(self.part_seconds) * min(self.part_seconds[1:])

    @property
    def compile_seconds(self) -> float:
        """Compilation, set-up and one-off costs: the rest of the wall clock."""
        return self.total_seconds - self.train_seconds

    @property
    def steps_per_second(self) -> float:
        return self.env_steps / self.train_seconds


def base_ppo_config(env_name: str) -> PPOConfig:
    """Our PPO preset for `env_name`: `ppo_<env_name>`, else the first PPO preset (by name) on that env,
    else PPOConfig's defaults on it."""
    preset = f"ppo_{env_name}"
    names = [preset] if preset in configs.names() else []
    candidates = (configs.get(name) for name in [*names, *configs.names()])
    return next(
        (config for config in candidates if isinstance(config, PPOConfig) and config.env == env_name),
        PPOConfig(env=env_name),
    )


def ppo_config(env_name: str, num_envs: int | None, env_steps: int | None, overrides: Sequence[str] = ()) -> PPOConfig:
    """`base_ppo_config(env_name)` with `overrides` (key=value), for `num_envs` and `env_steps` (None: the
    preset's), in `PARTS` equal parts.

    The budget is rounded up to a multiple of `PARTS` updates.
    """
    base = apply_overrides(base_ppo_config(env_name), overrides)
    num_envs = num_envs or base.num_envs
    env_steps = env_steps or base.total_env_steps
    steps_per_update = num_envs * base.rollout_length
    num_updates = PARTS * -(-env_steps // (PARTS * steps_per_update))
    config = dataclasses.replace(
        base,
        num_envs=num_envs,
        total_env_steps=num_updates * steps_per_update,
        updates_per_chunk=num_updates // PARTS,
    )
    config.validate()
    if num_envs % config.num_minibatches:
        raise ValueError(f"num_envs={num_envs} must divide by num_minibatches={config.num_minibatches} for brax")
    return config


def evaluate_policy(config: PPOConfig, policy, episodes: int, seed: int) -> tuple[float, float]:
    """(success rate, mean return) of a deterministic `policy: obs [B, O] -> action [B, A]` on fresh episodes of
    `config`'s evaluation env (training-only curricula off, as in every evaluation); NaNs for no episodes."""
    if episodes == 0:
        return float("nan"), float("nan")
    env, env_params = config.make_eval_env()
    result = jax.jit(lambda key: evaluate(env, env_params, policy, key, episodes))(jax.random.PRNGKey(seed + 1))
    summary = result.summary()
    return summary["success_rate"], summary["return_mean"]


def trained_result(
    config: PPOConfig,
    policy,
    eval_episodes: int,
    env_steps: int,
    total_seconds: float,
    part_seconds: tuple[float, ...],
) -> Result:
    """A learner's `Result` from its training's timings and its trained deterministic `policy` (obs [B, ...] ->
    action [B, A]): evaluated on fresh episodes, then timed driving the envs alone."""
    success, return_mean = evaluate_policy(config, policy, eval_episodes, config.seed)
    policy_env_seconds = env_stepping_seconds(config, policy)
    return Result(env_steps, total_seconds, part_seconds, success, return_mean, policy_env_seconds)


def run_ours(config: PPOConfig, eval_episodes: int) -> Result:
    """Trains our PPO (`PARTS` calls of one AOT-compiled program) and evaluates it."""
    trainer = make_trainer(config)
    hparams = config.hparams()
    start = time.perf_counter()
    state = jax.block_until_ready(jax.jit(trainer.init)(jax.random.PRNGKey(config.seed), hparams))
    # Compiled with the process's XLA settings, as brax's programs are (not `trainer.compiler_options`): see the
    # module docstring.
    runner = jax.jit(functools.partial(run_updates, trainer, num_updates=config.num_updates // PARTS), donate_argnums=0)
    compiled = runner.lower(state, hparams).compile()
    part_seconds = []
    for _ in range(PARTS):
        part_start = time.perf_counter()
        state, _ = jax.block_until_ready(compiled(state, hparams))
        part_seconds.append(time.perf_counter() - part_start)
    total_seconds = time.perf_counter() - start

    def policy(obs):
        return trainer.act(state, obs)

    env_steps = int(state.updates) * trainer.env_steps_per_update
    return trained_result(config, policy, eval_episodes, env_steps, total_seconds, tuple(part_seconds))


def brax_ppo_kwargs(config: PPOConfig, learning_rate: float) -> dict:
    """brax.training.agents.ppo.train arguments equivalent to `config` (see the module docstring)."""
    from brax.training.agents.ppo import networks as ppo_networks

    from jaxarm.interop.brax_env import wrap_for_training

    return dict(
        num_timesteps=config.total_env_steps,
        num_envs=config.num_envs,
        unroll_length=config.rollout_length,
        num_minibatches=config.num_minibatches,
        batch_size=config.num_envs // config.num_minibatches,
        num_updates_per_batch=config.num_epochs,
        learning_rate=learning_rate,
        discounting=config.gamma,
        gae_lambda=config.gae_lambda,
        clipping_epsilon=config.clip_epsilon,
        entropy_cost=config.entropy_coef,
        vf_loss_coefficient=config.value_coef,
        max_grad_norm=config.max_grad_norm,
        reward_scaling=config.reward_scale,
        normalize_observations=config.normalize_observations,
        normalize_advantage=config.normalize_advantages,
        network_factory=functools.partial(
            ppo_networks.make_ppo_networks,
            policy_hidden_layer_sizes=config.policy_hidden_sizes,
            value_hidden_layer_sizes=config.value_hidden_sizes,
            activation=getattr(nn, config.activation),
        ),
        wrap_env_fn=wrap_for_training,
        # PARTS training epochs (num_evals - 1) and no brax evaluation: jaxarm's evaluate scores both learners.
        num_evals=PARTS + 1,
        run_evals=False,
        num_eval_envs=config.num_minibatches,
        max_devices_per_host=1,
        seed=config.seed,
    )


def run_brax(config: PPOConfig, learning_rate: float, eval_episodes: int) -> Result:
    """Trains brax's PPO on the same env through the adapter (`PARTS` epochs) and evaluates it."""
    from brax.training.agents.ppo import train as brax_ppo

    from jaxarm.interop.brax_env import BraxEnv

    env, env_params = config.make_env()
    epochs = []
    start = time.perf_counter()

    def record_epoch(step, metrics):
        epochs.append((step, float(metrics["training/walltime"])))
        print(f"  brax: {step:,} env steps, {time.perf_counter() - start:.1f} s", flush=True)

    make_policy, params, _ = brax_ppo.train(
        environment=BraxEnv(env, env_params),
        episode_length=int(env_params.max_episode_steps),
        progress_fn=record_epoch,
        **brax_ppo_kwargs(config, learning_rate),
    )
    total_seconds = time.perf_counter() - start
    steps = epochs[-1][0]
    # brax reports its training wall clock cumulatively, epoch by epoch.
    part_seconds = tuple(np.diff([0.0] + [walltime for _, walltime in epochs]))
    inference = make_policy(params, deterministic=True)
    unused_key = jax.random.PRNGKey(0)

    def policy(obs):
        return inference(obs, unused_key)[0]

    return trained_result(config, policy, eval_episodes, int(steps), total_seconds, part_seconds)


def env_stepping_seconds(config: PPOConfig, policy=None) -> float:
    """Seconds per update of stepping `config`'s envs alone (`num_envs` × `rollout_length` env steps, no learner),
    compiled with the process's XLA settings as both learners are; timed over one part's updates. Actions are
    random (an untrained policy's), or `policy`'s (observations [B, ...] -> actions [B, A])."""
    updates = config.num_updates // PARTS
    steps = config.rollout_length * updates
    seconds, _ = env_seconds(config, config.num_envs, steps, compiler_options={}, policy=policy)
    return seconds / updates


def ceiling_figures(config: PPOConfig, ours: Result, brax: Result, env_seconds_per_update: float) -> dict[str, float]:
    """What each learner costs beyond stepping the envs, and the most any learner could run at against brax.

    A learner that cost nothing would take `env_seconds_per_update` per update (random actions): brax's steady
    update time over that is the ceiling on the throughput ratio. The learners' own costs are their steady update
    times less it. Where the physics costs more under a trained policy than under random actions (contacts), the
    same figures against each learner's own policy's stepping (`Result.policy_env_seconds`) book that cost to the
    physics: `ceiling_vs_brax_our_policy` is the ratio a learner costing nothing would reach with the envs doing
    what our policy makes them do. Times are in milliseconds per update.
    """
    ours_update, brax_update = (result.train_seconds / config.num_updates for result in (ours, brax))
    return {
        "env_ms": env_seconds_per_update * 1e3,
        "env_steps_per_second": config.env_steps_per_update / env_seconds_per_update,
        "ours_update_ms": ours_update * 1e3,
        "brax_update_ms": brax_update * 1e3,
        "ours_learner_ms": (ours_update - env_seconds_per_update) * 1e3,
        "brax_learner_ms": (brax_update - env_seconds_per_update) * 1e3,
        "ceiling_vs_brax": brax_update / env_seconds_per_update,
        "ours_vs_brax": brax_update / ours_update,
        "ours_policy_env_ms": ours.policy_env_seconds * 1e3,
        "brax_policy_env_ms": brax.policy_env_seconds * 1e3,
        "ours_learner_beyond_own_policy_ms": (ours_update - ours.policy_env_seconds) * 1e3,
        "brax_learner_beyond_own_policy_ms": (brax_update - brax.policy_env_seconds) * 1e3,
        "ceiling_vs_brax_our_policy": brax_update / ours.policy_env_seconds,
    }


def ceiling_line(config: PPOConfig, ours: Result, brax: Result, env_seconds_per_update: float) -> str:
    """`ceiling_figures` in words."""
    figures = ceiling_figures(config, ours, brax, env_seconds_per_update)
    return (
        f"env stepping alone ({config.num_envs:,} envs × {config.rollout_length} steps per update, no learner): "
        f"{figures['env_ms']:.1f} ms per update, {figures['env_steps_per_second']:,.0f} env steps/s. "
        f"Steady update: ours {figures['ours_update_ms']:.1f} ms, brax {figures['brax_update_ms']:.1f} ms; beyond "
        f"the env stepping our learner costs {figures['ours_learner_ms']:.1f} ms, brax's "
        f"{figures['brax_learner_ms']:.1f} ms. Ceiling: a learner that cost nothing would run at "
        f"{figures['ceiling_vs_brax']:.2f}× brax's steady rate; ours runs at {figures['ours_vs_brax']:.2f}×. "
        f"Under each learner's trained policy the env stepping alone takes {figures['ours_policy_env_ms']:.1f} ms "
        f"(ours) and {figures['brax_policy_env_ms']:.1f} ms (brax's); beyond it our learner costs "
        f"{figures['ours_learner_beyond_own_policy_ms']:.1f} ms, brax's "
        f"{figures['brax_learner_beyond_own_policy_ms']:.1f} ms; a learner that cost nothing, its envs driven as "
        f"ours drives them, would run at {figures['ceiling_vs_brax_our_policy']:.2f}× brax."
    )


def result_row(name: str, result: Result) -> dict:
    """One learner's figures for the suite's JSON record: the run's fields and the steady-rate split."""
    return {
        "learner": name,
        **dataclasses.asdict(result),
        "train_seconds": result.train_seconds,
        "compile_seconds": result.compile_seconds,
        "steps_per_second": result.steps_per_second,
    }


def format_parts(result: Result) -> str:
    return " + ".join(f"{seconds:.2f}" for seconds in result.part_seconds) + " s"


def format_table(ours: Result, brax: Result) -> str:
    rows = [
        ("env steps", f"{ours.env_steps:,}", f"{brax.env_steps:,}", ours.env_steps / brax.env_steps),
        (
            "wall clock, compile included (s)",
            f"{ours.total_seconds:.1f}",
            f"{brax.total_seconds:.1f}",
            ours.total_seconds / brax.total_seconds,
        ),
        (
            "compile, set-up, one-off (s)",
            f"{ours.compile_seconds:.1f}",
            f"{brax.compile_seconds:.1f}",
            ours.compile_seconds / max(brax.compile_seconds, 1e-9),
        ),
        (
            "training at the steady rate (s)",
            f"{ours.train_seconds:.1f}",
            f"{brax.train_seconds:.1f}",
            ours.train_seconds / brax.train_seconds,
        ),
        (
            "env steps/s at the steady rate",
            f"{ours.steps_per_second:,.0f}",
            f"{brax.steps_per_second:,.0f}",
            ours.steps_per_second / brax.steps_per_second,
        ),
        (
            "deterministic success rate",
            f"{ours.success_rate:.1%}",
            f"{brax.success_rate:.1%}",
            ours.success_rate / max(brax.success_rate, 1e-9),
        ),
        ("mean return", f"{ours.return_mean:.1f}", f"{brax.return_mean:.1f}", ours.return_mean / brax.return_mean),
    ]
    lines = ["| | jaxarm PPO | brax PPO | jaxarm / brax |", "|---|---:|---:|---:|"]
    lines += [f"| {name} | {ours_text} | {brax_text} | {ratio:.2f} |" for name, ours_text, brax_text, ratio in rows]
    return "\n".join(lines)


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench training", description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="arm2d", help=f"registered env name ({', '.join(envs.names())})")
    parser.add_argument("--env-steps", type=int, help="env-step budget of each learner (default: the preset's)")
    parser.add_argument("--num-envs", type=int, help="parallel envs of each learner (default: the preset's)")
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"CPU smoke run: {QUICK_NUM_ENVS} envs, {QUICK_ENV_STEPS:,} env steps unless given",
    )
    parser.add_argument("--brax-learning-rate", type=float, default=1e-3, help="brax's constant learning rate")
    parser.add_argument(
        "--eval-episodes",
        type=int,
        default=1000,
        help="fresh deterministic episodes per learner (0: no evaluation, throughput alone)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--impl",
        default="jax",
        help='MJX implementation of a Panda env for both learners: "jax" or "warp" (warp-lang, an NVIDIA GPU)',
    )
    parser.add_argument(
        "overrides",
        nargs="*",
        help="overrides key=value of the preset both learners map from (learning_rate, anneal_learning_rate: ours)",
    )
    parser.add_argument(
        "--learners",
        choices=("both", "jaxarm", "brax"),
        default="both",
        help="run one learner alone (its line, no table): for budgets one call cannot hold both",
    )
    add_out_argument(parser)
    return parser


def config_from_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> PPOConfig:
    """The config both learners map from; bad arguments end the process through `parser.error`."""
    if args.env not in envs.names():
        parser.error(f"unknown env {args.env!r}; registered: {', '.join(envs.names())}")
    if args.eval_episodes < 0:
        parser.error(f"--eval-episodes must be 0 or more, not {args.eval_episodes}")
    num_envs, env_steps = args.num_envs, args.env_steps
    if args.quick:
        num_envs, env_steps = num_envs or QUICK_NUM_ENVS, env_steps or QUICK_ENV_STEPS
    try:
        config = dataclasses.replace(ppo_config(args.env, num_envs, env_steps, args.overrides), seed=args.seed)
    except ValueError as error:
        parser.error(str(error))
    if args.impl != "jax":
        # Warp's contact buffer is shared by the batch: sized for this run's envs.
        kwargs = with_pair(with_pair(config.env_kwargs, "impl", args.impl), "max_envs", config.num_envs)
        config = dataclasses.replace(config, env_kwargs=kwargs)
        try:
            config.validate()
        except ValueError as error:
            parser.error(f"--impl {args.impl}: {error}")
    return config


def print_setup(config: PPOConfig, impl: str, brax_learning_rate: float, brax_version: str) -> None:
    """What the run compares, printed before it starts: the device and versions, the env and both learners."""
    schedule = "linear decay" if config.anneal_learning_rate else "constant"
    print(
        f"device: {jax.devices()[0].device_kind} (1 of {jax.device_count()} used by each learner); "
        f"jax {jax.__version__}, brax {brax_version}"
    )
    print(
        f"env {config.env} ({impl}) {dict(config.env_params)}; {config.num_envs:,} envs × "
        f"{config.rollout_length} steps per update, {config.num_updates} updates, {config.num_minibatches} "
        f"minibatches × {config.num_epochs} epochs, MLPs {config.policy_hidden_sizes}/{config.value_hidden_sizes} "
        f"{config.activation}, γ {config.gamma}; "
        f"lr ours {config.learning_rate:g} ({schedule}), brax {brax_learning_rate:g} (constant)",
        flush=True,
    )


def run_learners(config: PPOConfig, learners: str, brax_learning_rate: float, eval_episodes: int) -> dict[str, Result]:
    """Runs "both" learners (ours first) or the one named, printing each one's line as it ends."""
    runs = {
        "jaxarm": lambda: run_ours(config, eval_episodes),
        "brax": lambda: run_brax(config, brax_learning_rate, eval_episodes),
    }
    results = {}
    for name in runs if learners == "both" else [learners]:
        result = results[name] = runs[name]()
        print(
            f"{name} PPO: {result.total_seconds:.1f} s, parts {format_parts(result)}, "
            f"{result.steps_per_second:,.0f} env steps/s at the steady rate, success {result.success_rate:.1%}, "
            f"return {result.return_mean:.1f}",
            flush=True,
        )
    return results


def main(argv: Sequence[str]) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    config = config_from_args(parser, args)
    import brax

    print_setup(config, args.impl, args.brax_learning_rate, brax.__version__)
    results = run_learners(config, args.learners, args.brax_learning_rate, args.eval_episodes)
    ceiling = {}
    if len(results) == 2:
        ours, brax_result = results["jaxarm"], results["brax"]
        env_seconds_per_update = env_stepping_seconds(config)
        print(format_table(ours, brax_result))
        print(ceiling_line(config, ours, brax_result, env_seconds_per_update), flush=True)
        ceiling = ceiling_figures(config, ours, brax_result, env_seconds_per_update)
    write_record(
        args.out,
        "training",
        argv,
        [result_row(name, result) for name, result in results.items()],
        env=config.env,
        impl=args.impl,
        num_envs=config.num_envs,
        rollout_length=config.rollout_length,
        num_updates=config.num_updates,
        brax_version=brax.__version__,
        brax_learning_rate=args.brax_learning_rate,
        ceiling=ceiling,
    )
