"""A run's teacher as the runner finds it (through the learner registry: `registry.teacher_of`), and the teacher
stage of a run whose teacher is named by preset (`teacher=preset:NAME`): the teacher is trained (or resumed) into
`<run dir>/teacher` before the student, by the run loop (loop.py), which calls this stage only for such a run.
Nothing here builds the student's learner or runs its chunks.
"""

import pathlib
import sys
from collections.abc import Callable

import jax

from jaxarm.agents import registry
from jaxarm.agents.common.config import RunConfig, apply_overrides
from jaxarm.agents.common.teachers import teacher_input, teacher_preset_name
from jaxarm.runner import processes, rundir
from jaxarm.runner.options import Options


def teacher_preset(config: RunConfig) -> str:
    """The preset `config`'s teacher names (`teacher=preset:NAME`), or "" (a run directory, or no teacher)."""
    return teacher_preset_name(registry.teacher_of(config)) or ""


def teacher_run(config: RunConfig, run_dir: pathlib.Path | None) -> pathlib.Path | None:
    """The run directory of `config`'s teacher (None for none): the one it names, or for a teacher named by preset
    `run_dir/teacher` (RunDirError without `run_dir`: such a student is read from its run directory)."""
    teacher = registry.teacher_of(config)
    if not teacher:
        return None
    if not teacher_preset(config):
        return pathlib.Path(teacher)
    if run_dir is None:
        raise rundir.RunDirError(
            f"teacher={teacher} is trained into the student's run directory: build the trainer of a run from it"
        )
    return pathlib.Path(run_dir) / rundir.TEACHER_DIR


def train_teacher(
    config: RunConfig,
    preset: str,
    run_dir: pathlib.Path,
    resuming: bool,
    options: Options,
    *,
    train: Callable[..., dict],
    resume: Callable[..., tuple[dict, RunConfig]],
) -> dict | None:
    """Trains the teacher `config` names by preset into `run_dir/teacher`, or resumes it there, having first
    written the student's config.json, so that a run stopped in this stage resumes as the student's. Returns None
    once the teacher has finished (at once where it had), else its evaluation (stopped by `options.stop_after_s`).
    Bad names and mismatches raise ValueError before anything is written. `train` and `resume` are the run
    loop's (`jaxarm.runner.loop`), given by it: the teacher is a run of its own, in its own directory and lock,
    and the loop, which calls this stage, is not imported here."""
    name = teacher_preset(config)
    teacher_dir = run_dir / rundir.TEACHER_DIR
    if (teacher_dir / "config.json").exists():
        teacher, trained_preset = rundir.read_config(teacher_dir)
        if trained_preset != name:
            raise rundir.RunDirError(
                f"{teacher_dir} holds a teacher trained from preset {trained_preset!r}, not {name!r}; use another "
                "run directory"
            )
        if rundir.finished_evaluation(teacher_dir, teacher) is not None:
            return None
        if not resuming and rundir.any_checkpoint_files(teacher_dir):
            raise rundir.resumable(
                rundir.RunDirError(f"{run_dir} already holds a run, in its teacher stage; resume it (resume=True)"),
                run_dir,
            )
    else:
        teacher = teacher_config(config, options.presets)
    if processes.is_primary():
        if not (run_dir / "config.json").exists():
            rundir.write_config(run_dir, config, preset)
        print(f"teacher stage: {name} into {teacher_dir}", file=sys.stderr)
    try:
        if (teacher_dir / "config.json").exists():
            result, _ = resume(teacher_dir, options=options)
        else:
            result = train(teacher, teacher_dir, preset=name, options=options)
    except Exception as error:
        # Resuming the student's run goes on with its teacher, and then with the student: point there.
        if getattr(error, "resume_dir", None) is not None:
            rundir.resumable(error, run_dir)
        raise
    if result["finished"]:
        return None
    if processes.is_primary():
        print(f"stopped in the teacher stage; resume {run_dir} to go on", file=sys.stderr)
    return result


def teacher_config(config: RunConfig, presets: Callable[[str], RunConfig] | None) -> RunConfig:
    """The config of the teacher `config` names by preset, with `teacher_overrides`; ValueError in one line for
    an unknown preset, a bad override, a teacher with a preset teacher of its own, or one that does not observe
    what this run's env gives a teacher (`jaxarm.agents.common.teachers.teacher_input`)."""
    name = teacher_preset(config)
    if presets is None:
        raise ValueError(
            f"teacher=preset:{name}: give Options(presets=...) a lookup of presets (experiments.configs.get)"
        )
    try:
        teacher = apply_overrides(presets(name), registry.teacher_overrides_of(config))
    except ValueError as error:
        raise ValueError(f"teacher=preset:{name}: {error}") from None
    if teacher_preset(teacher):
        raise ValueError(
            f"teacher=preset:{name} has a teacher preset of its own; train that run first and give teacher=RUN_DIR"
        )
    given = teacher_input(config.make_env(randomized=False)[0].spec.observation)
    observed = teacher.make_env(randomized=False)[0].spec.observation
    if given != observed:
        shapes = jax.tree.map(lambda part: part.shape, (given, observed))
        raise ValueError(
            f"teacher=preset:{name} observes {shapes[1]} but this run's env gives a teacher {shapes[0]} (a camera "
            "student's env needs env_kwargs.privileged=true)"
        )
    return teacher
