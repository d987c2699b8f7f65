"""A run's teacher as the runner finds it (through the learner registry: `registry.teacher_of`), and the stages
trained before a run's own learner: its teacher where named by preset (`teacher=preset:NAME`, into `<run
dir>/teacher`), and the run it warm-starts from where named by preset (`init_from=preset:NAME`, into `<run
dir>/warm_start`), each trained (or resumed) by the run loop (loop.py), which calls a stage only for such a run.
Nothing here builds the run's learner or runs its chunks.
"""

import dataclasses
import functools
import pathlib
import sys
from collections.abc import Callable, Mapping, Sequence

import jax

from jaxarm.agents import registry
from jaxarm.agents.common.config import RunConfig, apply_overrides
from jaxarm.agents.common.teachers import WARM_START_TEACHER, teacher_input, teacher_preset_name
from jaxarm.runner import processes, rundir, tries
from jaxarm.runner.options import Options


def teacher_preset(config: RunConfig) -> str:
    """The preset `config`'s teacher names (`teacher=preset:NAME`), or "" (a run directory, or no teacher)."""
    return teacher_preset_name(registry.teacher_of(config)) or ""


def teacher_run(config: RunConfig, run_dir: pathlib.Path | None) -> pathlib.Path | None:
    """The run directory of `config`'s teacher (None for none): the one it names, for a teacher named by preset
    `run_dir/teacher`, and for `teacher=init_from` the run it warm-starts from (RunDirError without `run_dir` where
    that is a stage of the student's: such a student is read from its run directory)."""
    teacher = registry.teacher_of(config)
    if not teacher:
        return None
    kickstart = teacher == WARM_START_TEACHER
    named = config.init_from if kickstart else teacher
    if teacher_preset_name(named) is None:
        return pathlib.Path(named)
    if run_dir is None:
        raise rundir.RunDirError(
            f"teacher={teacher} is trained into the student's run directory: build the trainer of a run from it"
        )
    return pathlib.Path(run_dir) / (rundir.WARM_START_DIR if kickstart else rundir.TEACHER_DIR)


@dataclasses.dataclass(frozen=True)
class Stage:
    """A run trained before a run's own learner, in a directory of the run's: what it is for (its messages say
    "<kind> stage"), its preset and its directory."""

    kind: str
    preset: str
    directory: pathlib.Path


def stages(config: RunConfig, run_dir: pathlib.Path, options: Options) -> list[tuple[Stage, Callable[[], RunConfig]]]:
    """The stages `config` trains before its own learner, in order, each with how its config is made: the run it
    warm-starts from where named by preset (`init_from=preset:NAME`, into `run_dir/warm_start`), then its teacher
    where named by preset (`teacher=preset:NAME`, into `run_dir/teacher`)."""
    # Each try its own warm start where the run trains it again (retry_warm_start); else every try shares the first.
    try_index = tries.tries_set_aside(run_dir) if config.retry_warm_start else 0
    seed = tries.warm_start_seed(config.seed, try_index)
    candidates = [
        (
            Stage("warm-start", warm_start_preset(config), run_dir / rundir.WARM_START_DIR),
            functools.partial(warm_start_config, config, options.presets, seed),
        ),
        (
            Stage("teacher", teacher_preset(config), run_dir / rundir.TEACHER_DIR),
            functools.partial(teacher_config, config, options.presets),
        ),
    ]
    return [(stage, make) for stage, make in candidates if stage.preset]


def train_stage(
    stage: Stage,
    stage_config: Callable[[], RunConfig],
    config: RunConfig,
    preset: str,
    run_dir: pathlib.Path,
    resuming: bool,
    options: Options,
    *,
    train: Callable[..., dict],
    resume: Callable[..., tuple[dict, RunConfig]],
) -> dict | None:
    """Trains `stage`'s run (its config from `stage_config()`) into its directory, or resumes it there, having
    first written the run's own config.json, so that a run stopped in this stage resumes as the run's. Returns None
    once the stage has finished (at once where it had), else its evaluation (stopped by `options.stop_after_s`).
    Bad names and mismatches raise ValueError before anything is written. `train` and `resume` are the run loop's
    (`jaxarm.runner.loop`), given by it: the stage is a run of its own, in its own directory and lock, and the loop,
    which calls this stage, is not imported here."""
    name, directory = stage.preset, stage.directory
    if (directory / "config.json").exists():
        trained, trained_preset = rundir.read_config(directory)
        if trained_preset != name:
            raise rundir.RunDirError(
                f"{directory} holds a {stage.kind} run trained from preset {trained_preset!r}, not {name!r}; use "
                "another run directory"
            )
        if rundir.finished_evaluation(directory, trained) is not None:
            return None
        if not resuming and rundir.any_checkpoint_files(directory):
            raise rundir.resumable(
                rundir.RunDirError(
                    f"{run_dir} already holds a run, in its {stage.kind} stage; resume it (resume=True)"
                ),
                run_dir,
            )
    else:
        trained = stage_config()
    if processes.is_primary():
        if not (run_dir / "config.json").exists():
            rundir.write_config(run_dir, config, preset)
        print(f"{stage.kind} stage: {name} into {directory}", file=sys.stderr)
    try:
        if (directory / "config.json").exists():
            result, _ = resume(directory, options=options)
        else:
            result = train(trained, directory, preset=name, options=options)
    except Exception as error:
        # Resuming the run goes on with its stage, and then with the run's own learner: point there.
        if getattr(error, "resume_dir", None) is not None:
            rundir.resumable(error, run_dir)
        raise
    if result["finished"]:
        return None
    if processes.is_primary():
        print(f"stopped in the {stage.kind} stage; resume {run_dir} to go on", file=sys.stderr)
    return result


def warm_start_preset(config: RunConfig) -> str:
    """The preset `config`'s warm start names (`init_from=preset:NAME`), or "" (a run directory, or none)."""
    return teacher_preset_name(config.init_from) or ""


def warm_start_run(config: RunConfig, run_dir: pathlib.Path) -> pathlib.Path:
    """The run directory `config` warm-starts from: the one `init_from` names, or for a preset `run_dir/warm_start`."""
    return run_dir / rundir.WARM_START_DIR if warm_start_preset(config) else pathlib.Path(config.init_from)


def preset_config(
    setting: str, name: str, presets: Callable[[str], RunConfig] | None, overrides: Sequence[str]
) -> RunConfig:
    """Preset `name`'s config with `overrides`, for a stage the config field `setting` names (`setting=preset:NAME`);
    ValueError in one line, naming the setting, without a lookup of presets, for an unknown preset or a bad
    override."""
    if presets is None:
        raise ValueError(
            f"{setting}=preset:{name}: give Options(presets=...) a lookup of presets (experiments.configs.get)"
        )
    try:
        return apply_overrides(presets(name), overrides)
    except ValueError as error:
        raise ValueError(f"{setting}=preset:{name}: {error}") from None


def warm_start_config(config: RunConfig, presets: Callable[[str], RunConfig] | None, seed: int) -> RunConfig:
    """The config of the run `config` warm-starts from, named by preset, with `seed` (the run's own, or its try's:
    each seed of the run its own first stage); ValueError in one line for an unknown preset, or one with a preset
    stage of its own."""
    name = warm_start_preset(config)
    stage = preset_config("init_from", name, presets, [f"seed={seed}"])
    if warm_start_preset(stage) or teacher_preset(stage):
        raise ValueError(f"init_from=preset:{name} trains a stage of its own first; train it and give init_from=RUN")
    learner = registry.learner_for(config)
    if learner.warm_start is None or registry.learner_for(stage) is not learner:
        raise ValueError(
            f"init_from=preset:{name}: a {registry.name_of(config)} run warm-starts from a run of its own learner "
            f"with a warm start, and {name} is {registry.name_of(stage)}"
        )
    return stage


def teacher_config(config: RunConfig, presets: Callable[[str], RunConfig] | None) -> RunConfig:
    """The config of the teacher `config` names by preset, with `teacher_overrides`; ValueError in one line for
    an unknown preset, a bad override, a teacher with a preset teacher of its own, or one that does not observe
    what this run's env gives a teacher (`jaxarm.agents.common.teachers.teacher_input`)."""
    name = teacher_preset(config)
    teacher = preset_config("teacher", name, presets, registry.teacher_overrides_of(config))
    if teacher_preset(teacher):
        raise ValueError(
            f"teacher=preset:{name} has a teacher preset of its own; train that run first and give teacher=RUN_DIR"
        )
    check_teacher_fits(config, teacher, f"preset:{name}")
    return teacher


def check_teacher_fits(config: RunConfig, teacher: RunConfig, named: str) -> None:
    """ValueError in one line naming both envs where `teacher` (the config of the teacher `config` names as
    `teacher=<named>`) does not observe what this run's env gives a teacher (`teachers.teacher_input`), or acts
    with actions of another shape."""
    student_spec = config.make_env(randomized=False)[0].spec
    teacher_spec = teacher.make_env(randomized=False)[0].spec
    given, observed = teacher_input(student_spec.observation), teacher_spec.observation
    if given != observed:
        shapes = jax.tree.map(lambda part: part.shape, (given, observed))
        # A camera student's env gives its teacher the image unless it observes the state too.
        hint = " (a camera student's env needs env_kwargs.privileged=true)" if isinstance(given, Mapping) else ""
        raise ValueError(
            f"teacher={named} observes {shapes[1]} of {teacher.env} but this run's env, {config.env}, gives a teacher "
            f"{shapes[0]}{hint}"
        )
    if student_spec.action_shape != teacher_spec.action_shape:
        raise ValueError(
            f"teacher={named} acts {teacher_spec.action_shape} in {teacher.env} but this run's env, {config.env}, "
            f"acts {student_spec.action_shape}"
        )
