"""What the entry points offer: --help on each, --show, the compilation cache, metric sinks and video files."""

import importlib
import json
import os
import pathlib
import subprocess
import sys
import threading
import time
import types

import numpy as np
import pytest

from experiments import bench, compare, configs, run, sweep
from experiments import eval as eval_cli
from experiments.configs.td3 import td3_peg
from jaxarm import headless
from jaxarm.agents.common.config import apply_overrides
from jaxarm.runner import cache, learners, progress, provenance, rundir, sinks, video

INSTALL_PAGE = (pathlib.Path(__file__).resolve().parents[2] / "docs" / "install.md").read_text()

SMALL = [
    "num_envs=64",
    "rollout_length=16",
    "num_minibatches=2",
    "total_env_steps=8192",
    "updates_per_chunk=4",
    "checkpoint_every_updates=4",
    "eval_episodes=4",
]


@pytest.mark.parametrize("entry", [run.main, eval_cli.main, sweep.main, compare.main, bench.main])
def test_help_exits_0_on_every_entry_point(entry, capsys):
    with pytest.raises(SystemExit) as exited:
        entry(["--help"])
    assert exited.value.code == 0
    assert "usage:" in capsys.readouterr().out


def test_bench_lists_its_suites_and_refuses_an_unknown_one(capsys):
    with pytest.raises(SystemExit):
        bench.main(["--help"])
    out = capsys.readouterr().out
    assert all(suite in out for suite in bench.SUITES)
    with pytest.raises(SystemExit) as exited:
        bench.main(["nonesuch"])
    assert exited.value.code == 2 and "invalid choice: 'nonesuch'" in capsys.readouterr().err


def test_show_lists_config_fields_and_env_params_with_defaults_and_docs(capsys):
    assert run.main(["--config", "ppo_arm2d", "--show", "learning_rate=1e-3"]) == 0
    out = capsys.readouterr().out
    assert "learning_rate (float [dynamic], in (0, 1]) = 0.001  (default 0.0003)" in out
    assert "Adam step size (linearly annealed to 0 when `anneal_learning_rate`)." in out
    assert "policy_hidden_sizes (tuple[int, ...], in [1, 65536]) = (64, 64)" in out
    assert "num_epochs (int, in [1, 4096]) = " in out and "updates_per_chunk (int, in [1, 1048576]) = " in out
    assert "eval_every_updates (int, >= 0) = 20  (default 0)" in out and 'logging "eval/..." in metrics' in out
    assert "env_params.success_bonus = 10.0  (default 0.0)" in out
    assert "env_params.goal_mode (one of 0, 1, 2) = 2  (default 0)" in out
    assert "reward on the step that completes the hold" in out
    assert "env_params.max_episode_steps (>= 1) = 200" in out and "time limit (truncation)." in out


def test_show_lists_the_env_constructor_arguments_with_defaults_and_docs(capsys):
    assert run.main(["--config", "ppo_arm2d_pixels", "--show", "env_kwargs.resolution=24"]) == 0
    out = capsys.readouterr().out
    assert "env 'arm2d_pixels_proprio' constructor arguments (env_kwargs.NAME=VALUE):" in out
    assert "env_kwargs.obs_mode = 'pixels+proprio'  (default 'state')" in out, "the registered variant's"
    assert "env_kwargs.resolution = 24  (default 64)" in out and "env_kwargs.num_links = 2\n" in out


def test_show_lists_a_panda_envs_options_as_flat_env_kwargs(capsys):
    assert run.main(["--config", "ppo_peg", "--show", "env_kwargs.max_action_latency=1"]) == 0
    out = capsys.readouterr().out
    assert "env_kwargs.max_action_latency = 1  (default 2)" in out and "env_kwargs.dynamics = " in out
    assert "env_kwargs.options" not in out and "the most control steps of action latency" in out


def test_list_describes_every_preset_in_one_line(capsys):
    assert run.main(["--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(configs.names()) and all(len(line.split(maxsplit=1)) == 2 for line in lines)
    assert not any("comment" in line for line in lines), "no pointer to a source comment"


def test_cache_directory_follows_the_environment(tmp_path):
    home = {"HOME": str(tmp_path)}
    assert cache.cache_dir(home) == tmp_path / ".cache" / "jaxarm" / "jax"
    assert cache.cache_dir({**home, "XDG_CACHE_HOME": "/x"}) == pathlib.Path("/x/jaxarm/jax")
    assert cache.cache_dir({**home, cache.ENV_VAR: str(tmp_path / "c")}) == tmp_path / "c"
    assert cache.cache_dir({**home, cache.ENV_VAR: "off"}) is None
    assert cache.cache_dir({**home, "JAX_COMPILATION_CACHE_DIR": "/jax"}) is None, "JAX's own setting wins"


def test_the_cache_directory_gets_used(tmp_path):
    """A fresh process (the test session's own cache is set by JAX_COMPILATION_CACHE_DIR, which would win)."""
    env = {key: value for key, value in os.environ.items() if key != "JAX_COMPILATION_CACHE_DIR"}
    env.update({cache.ENV_VAR: str(tmp_path / "cache"), "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0"})
    program = (
        "import jax, jax.numpy as jnp\n"
        "from jaxarm.runner.cache import enable_compilation_cache\n"
        "print(enable_compilation_cache())\n"
        "jax.jit(lambda x: jnp.sin(x) @ x)(jnp.ones((8, 8))).block_until_ready()\n"
    )
    done = subprocess.run([sys.executable, "-c", program], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == str(tmp_path / "cache")
    assert any((tmp_path / "cache").iterdir()), "nothing was written to the cache"


class Recorder:
    def __init__(self):
        self.calls = []

    def add_scalar(self, name, value, step):
        self.calls.append((name, value, step))

    def close(self):
        pass


def test_an_evaluation_takes_gpu_memory_on_demand_unless_told():
    untold: dict[str, str] = {}
    eval_cli.reserve_gpu_memory_on_demand(untold)
    assert untold == {"XLA_PYTHON_CLIENT_PREALLOCATE": "false"}
    told = {"XLA_PYTHON_CLIENT_PREALLOCATE": "true"}
    eval_cli.reserve_gpu_memory_on_demand(told)
    assert told == {"XLA_PYTHON_CLIENT_PREALLOCATE": "true"}


def test_tensorboard_draws_against_env_steps(tmp_path):
    sink = sinks.TensorBoardSink(tmp_path)
    sink.writer.close()
    sink.writer = Recorder()
    sink.write({"updates": 3, "env_steps": 3072, "loss": 0.5})
    assert ("loss", 0.5, 3072) in sink.writer.calls and {step for _, _, step in sink.writer.calls} == {3072}


def test_tensorboard_starts_without_importing_torch(tmp_path):
    # A torch that says when it is imported, and lacks the `Tensor` tensorboardX would read from it at its import.
    (tmp_path / "torch").mkdir()
    (tmp_path / "torch" / "__init__.py").write_text("print('torch imported')\n")
    script = (
        "import pathlib, sys\n"
        "from jaxarm.runner.sinks import TensorBoardSink\n"
        f"TensorBoardSink(pathlib.Path({str(tmp_path / 'tb')!r})).close()\n"
        "print('torch after the sink:', 'torch' in sys.modules)\n"
        "import torch\n"
    )
    paths = [str(tmp_path), *filter(None, [os.environ.get("PYTHONPATH")])]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(paths)}
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, env=env)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.splitlines() == ["torch after the sink: False", "torch imported"]


def test_torch_is_hidden_from_the_importing_thread_alone(tmp_path, monkeypatch):
    # A module in place of torch: the run's compile thread may import it while tensorboardX imports.
    (tmp_path / "hidden_probe.py").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))
    elsewhere = []
    with sinks.hidden_from_this_thread("hidden_probe"):
        with pytest.raises(ModuleNotFoundError, match="hidden while tensorboardX imports"):
            importlib.import_module("hidden_probe")
        assert "hidden_probe" not in sys.modules, "hidden by a finder, not by a None in sys.modules"
        other = threading.Thread(target=lambda: elsewhere.append(importlib.import_module("hidden_probe")))
        other.start()
        other.join()
    assert elsewhere and importlib.import_module("hidden_probe") is elsewhere[0]
    monkeypatch.delitem(sys.modules, "hidden_probe")


@pytest.fixture
def fake_wandb(monkeypatch):
    """A stand-in `wandb` module recording what the runner asks of it."""
    record: dict = {"logged": [], "finished": 0, "inits": []}

    def init(**kwargs):
        record["init"] = kwargs
        record["inits"].append(kwargs)
        return types.SimpleNamespace(
            log=lambda row, step: record["logged"].append((row, step)),
            finish=lambda: record.__setitem__("finished", record["finished"] + 1),
        )

    monkeypatch.setitem(sys.modules, "wandb", types.SimpleNamespace(init=init))
    return record


def test_wandb_is_imported_only_when_asked_and_honours_offline(fake_wandb, tmp_path, capsys):
    assert run.main(["--config", "ppo_arm2d_fixed", *SMALL, "--out", str(tmp_path / "plain")]) == 0
    assert "init" not in fake_wandb
    out = tmp_path / "tracked"
    assert (
        run.main(["--config", "ppo_arm2d_fixed", *SMALL, "--out", str(out), "--wandb", "arms", "--wandb-offline"]) == 0
    )
    init = fake_wandb["init"]
    assert init["project"] == "arms" and init["mode"] == "offline" and init["name"] == "tracked"
    assert init["id"] == sinks.wandb_run_id("tracked", provenance.first_provenance(out))
    assert init["config"]["num_envs"] == 64 and init["dir"] == str(out)
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert [step for _, step in fake_wandb["logged"]] == [row["env_steps"] for row in rows]
    assert fake_wandb["finished"] == 1


def test_each_try_of_a_gated_run_is_a_wandb_run_of_its_own(fake_wandb, tmp_path):
    out = tmp_path / "gated"
    # Below 100% at update 4 (4 episodes of a barely trained policy): the first try fails its gate.
    gate = ["total_env_steps=16384", "eval_every_updates=4", "retry_below=1.0", "retry_at_env_steps=4096", "tries=2"]
    assert run.main(["--config", "ppo_arm2d_fixed", *SMALL, *gate, "--out", str(out), "--wandb", "arms"]) == 0
    first = sinks.wandb_run_id("gated", provenance.first_provenance(out))
    assert [(init["name"], init["id"]) for init in fake_wandb["inits"]] == [
        ("gated", first),
        ("gated-try2", f"{first}-try2"),
    ]
    assert fake_wandb["finished"] == 2


def test_runs_of_one_name_get_their_own_wandb_id_and_a_resumed_run_keeps_it(tmp_path):
    start = {"hostname": "lab", "time": "2026-11-28T08:00:00+00:00", "command": ["run", "--out", "a/mine"]}
    ids = {
        sinks.wandb_run_id("mine", start),
        sinks.wandb_run_id("mine", start | {"time": "2026-11-28T08:00:01+00:00"}),
        sinks.wandb_run_id("mine", start | {"hostname": "cluster"}),
        sinks.wandb_run_id("mine", start | {"command": ["run", "--out", "b/mine"]}),
    }
    assert len(ids) == 4 and all(run_id.startswith("mine-") for run_id in ids)
    provenance.append_provenance(tmp_path, "start")
    started = sinks.wandb_run_id("mine", provenance.first_provenance(tmp_path))
    provenance.append_provenance(tmp_path, "resume")
    assert sinks.wandb_run_id("mine", provenance.first_provenance(tmp_path)) == started


def test_wandb_missing_is_a_one_line_error(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "wandb", None)  # import wandb raises ImportError
    assert run.main(["--config", "ppo_arm2d_fixed", *SMALL, "--out", str(tmp_path / "r"), "--wandb", "arms"]) == 2
    assert "pip install 'jaxarm[wandb]'" in capsys.readouterr().err


@pytest.mark.parametrize("suffix", ["gif", "mp4"])
def test_videos_are_written_as_gif_and_mp4(suffix, tmp_path):
    import imageio.v3 as iio

    frames = [np.full((48, 64, 3), value, np.uint8) for value in range(0, 250, 25)]
    path = tmp_path / f"video.{suffix}"
    video.write_video(path, frames)
    read = iio.imread(path)
    assert read.shape[0] == len(frames) and read.shape[1:3] == (48, 64)


def test_a_missing_gl_platform_gets_a_one_line_hint():
    import jax
    import mujoco

    from jaxarm import envs

    class Headless:
        def __getattr__(self, name):
            return getattr(env, name)

        def render(self, state, params):
            raise mujoco.FatalError("an OpenGL platform library has not been loaded into this process")

    env = envs.make("arm2d")
    params = env.default_params().replace(max_episode_steps=np.int32(3))
    trainer = types.SimpleNamespace(act=lambda learner, obs: np.zeros((obs.shape[0], 2), np.float32))
    with pytest.raises(video.RenderError) as raised:
        video.episode_frames(Headless(), params, trainer, None, jax.random.PRNGKey(0), 1)
    assert str(raised.value).endswith(headless.GL_HINT) and "\n" not in str(raised.value)


def test_a_mujoco_gl_that_cannot_load_fails_at_import_with_the_install_pages_hint():
    """mujoco loads MUJOCO_GL's platform when imported, before any command can probe it."""
    env = {**os.environ, "MUJOCO_GL": "bogus"}
    command = [sys.executable, "-m", "experiments.eval", "no-such-run", "--video"]
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and done.stderr.strip().endswith(headless.GL_HINT)
    assert "MUJOCO_GL=bogus" in done.stderr


EVAL_RECORDING_COMPILES = """
import json, sys
import jax
compiles = []
jax.monitoring.register_event_duration_secs_listener(
    lambda event, duration, **kwargs: compiles.append(event) if "compile" in event else None
)
from experiments import eval as eval_cli
status = eval_cli.main(sys.argv[1:])
heavy = [name for name in ("experiments.configs", "jaxarm.runner", "jaxarm.agents") if name in sys.modules]
print(json.dumps({"status": status, "compiles": compiles, "imported": heavy}))
"""


def test_eval_video_of_a_panda_run_without_a_display_fails_before_the_learners_import(tmp_path):
    """A real GL failure (GLFW with no display) of a Panda env's run, in a process of its own as a user meets it:
    the hint, nothing compiled, and neither the presets nor the learners nor the runner imported (their imports
    took most of the 14 s this failure took on the busy 2-core CPU)."""
    run_dir = tmp_path / "peg"
    run_dir.mkdir()
    rundir.write_config(run_dir, apply_overrides(td3_peg(), ["num_envs=2"]), "td3_peg")
    env = {name: value for name, value in os.environ.items() if name not in ("DISPLAY", "WAYLAND_DISPLAY")}
    command = [sys.executable, "-c", EVAL_RECORDING_COMPILES, str(run_dir), "--video"]
    done = subprocess.run(command, env={**env, "MUJOCO_GL": "glfw"}, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.strip().splitlines()[-1]) == {"status": 2, "compiles": [], "imported": []}
    assert done.stderr.count("\n") == 1 and done.stderr.strip().endswith(headless.GL_HINT)
    assert done.stderr.startswith("error: cannot draw here (FatalError: ")


def test_eval_video_without_gl_fails_at_once_with_the_install_pages_hint(tmp_path, monkeypatch, capsys):
    """Checked before the checkpoint loads or anything compiles (a Panda env compiled for 9.5 minutes first)."""

    def no_gl():
        raise AttributeError("'NoneType' object has no attribute 'glGetError'")  # MUJOCO_GL=osmesa, no libOSMesa

    def never(*args, **kwargs):
        raise AssertionError("restored a checkpoint before checking GL")

    run_dir = tmp_path / "run"
    run_dir.mkdir()
    config = apply_overrides(td3_peg(), ["num_envs=2"])
    rundir.write_config(run_dir, config, "td3_peg")
    monkeypatch.setattr(headless, "probe_gl", no_gl)
    monkeypatch.setattr(learners, "restore_state", never)
    start = time.perf_counter()
    assert eval_cli.main([str(run_dir), "--video"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.strip().endswith(headless.GL_HINT) and "glGetError" in error
    install_words = ("MUJOCO_GL=egl", "libegl1 libegl-mesa0 libgl1-mesa-dri")
    assert all(part in INSTALL_PAGE and part in headless.GL_HINT for part in install_words)
    assert time.perf_counter() - start < 10


def test_eval_of_an_mjx_run_on_the_cpu_explains_xlas_slow_compile_banners_first(tmp_path, monkeypatch, capsys):
    def stop(*args, **kwargs):
        raise ValueError("stopped where the checkpoint would load")

    run_dir = tmp_path / "run"
    run_dir.mkdir()
    rundir.write_config(run_dir, apply_overrides(td3_peg(), ["num_envs=2"]), "td3_peg")
    monkeypatch.setattr(progress, "_slow_compiles_explained", False)
    monkeypatch.setattr(learners, "restore_state", stop)
    assert eval_cli.main([str(run_dir)]) == 2
    assert capsys.readouterr().err == f"{progress.SLOW_COMPILE_NOTE}\nerror: stopped where the checkpoint would load\n"


def test_a_run_over_several_devices_explains_xlas_gspmd_warnings_once(monkeypatch, capsys):
    monkeypatch.setattr(progress, "_gspmd_explained", False)
    progress.explain_gspmd(1)
    assert capsys.readouterr().err == ""  # one device: nothing is partitioned, XLA does not warn
    progress.explain_gspmd(2)
    progress.explain_gspmd(4)
    assert capsys.readouterr().err == f"{progress.GSPMD_NOTE}\n"


@pytest.mark.parametrize(
    ("flag", "value", "message"),
    [
        ("--episodes", "100000000", "--episodes must be in [1, 1048576], got 100000000"),
        ("--seed", "99999999999999999999999", "--seed must fit in int32 (at most 2,147,483,647 in magnitude), got "),
        ("--seed", "-1", "--seed must be >= 0, got -1"),
    ],
)
def test_eval_refuses_more_episodes_than_it_can_step_at_once_and_a_seed_a_run_refuses(
    flag, value, message, tmp_path, capsys
):
    rundir.write_config(tmp_path, apply_overrides(td3_peg(), ["num_envs=2"]), "td3_peg")
    assert eval_cli.main([str(tmp_path), flag, value]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {message}") and err.count("\n") == 1, err


@pytest.mark.parametrize(
    "bad",
    [
        "gamma=2",
        "learning_rate=-1",
        "learning_rate=1e9",
        "clip_epsilon=5",
        "gae_lambda=5",
        "max_grad_norm=0",
        "num_minibatches=0",
        "rollout_length=0",
        "activation=foo",
        "env_params.goal_size=-40",
        "env_params.success_bonus=nan",
        "env_params.max_episode_steps=0",
        "env_params.max_episode_steps=1e10",
        "randomize.goal_size=-40..-10",
        "randomize.hold_steps=1..1e10",
    ],
)
def test_a_bad_value_is_refused_before_any_directory_is_written(bad, tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert run.main(["--config", "ppo_arm2d", bad, "--out", str(run_dir)]) == 2
    assert bad.split("=")[0].split(".")[-1] in capsys.readouterr().err
    assert not run_dir.exists()


def test_sweep_bands_stay_in_0_1_and_numpy_stays_quiet(tmp_path):
    import warnings

    from jaxarm.runner import plots, stats

    # Two seeds far apart: the success CI spans well beyond [0, 1]; an update no seed finished is all NaN; one
    # where a single seed finished has no spread.
    success = np.array([[0.0, np.nan, 0.9, 1.0], [1.0, np.nan, np.nan, 0.0]])
    steps = np.tile(np.arange(4.0), (2, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mean, lower, upper = stats.mean_band(success, 0.0, 1.0)
        plots.sweep_curves({"a": (steps, success, success * 10)}, tmp_path / "curves.png", "t")
    assert np.all(lower[[0, 2, 3]] >= 0.0) and np.all(upper[[0, 2, 3]] <= 1.0) and lower[0] == 0.0
    assert np.isnan(mean[1]) and mean[2] == lower[2] == upper[2] == 0.9
    assert (tmp_path / "curves.png").stat().st_size > 0


def test_a_sweep_labels_its_settings_by_what_sets_them_apart():
    base = configs.get("ppo_sorter")
    assignments = ["num_envs=1024", "env_kwargs.max_envs=16384", "learning_rate=2e-4,8e-4"]
    grid = sweep.parse_grid(base, assignments)
    shared = sweep.shared_changes(grid, base)
    assert shared == ["env_kwargs.max_envs=16384", "num_envs=1024"]
    labels = [sweep.describe(sweep.changes(grid.groups[0], base, combo), shared) for combo in grid.dynamic]
    assert labels == ["learning_rate=0.0002", "learning_rate=0.0008"]


LAMBDAS = ("learning_rate", "gamma", "gae_lambda")
"""Dynamic fields that take values in (0, 1]."""


@pytest.mark.parametrize(
    ("assignments", "message"),
    [
        (["learning_rate=1e-3,0.001"], "gives learning_rate=0.001 twice"),
        (["num_envs=8,8"], "gives num_envs=8 twice"),
        (["learning_rate=1e-3,2e-3", "learning_rate=5e-4"], "overrides the values of learning_rate swept before"),
        (["num_minibatches=1,2", "num_minibatches=4"], "overrides the values of num_minibatches swept before"),
        # Before: a 400^3 grid grew to 13 GB before it was refused.
        (
            [f"{key}=" + ",".join(f"{(index + 1) / 1000:g}" for index in range(128)) for key in LAMBDAS],
            "gae_lambda= (128 values) makes 2,097,152 settings, more than a sweep may (in [1, 1048576])",
        ),
    ],
)
def test_a_sweep_refuses_settings_alike_in_one_line_before_anything_is_written(assignments, message, tmp_path, capsys):
    out = tmp_path / "sweep"
    assert sweep.main(["--config", "ppo_arm2d", "--seeds", "1", "--out", str(out), *assignments]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: sweep assignment") and message in err and err.count("\n") == 1
    assert not out.exists()


def test_a_sweep_of_a_config_with_a_gate_is_refused_in_one_line_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "sweep"
    gate = ["eval_every_updates=4", "retry_below=0.5", "retry_at_env_steps=4096", "tries=2"]
    assert sweep.main(["--config", "ppo_arm2d", "--seeds", "1", "--out", str(out), *SMALL, *gate]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: retry_below=0.5 starts a run again when it fails its gate") and err.count("\n") == 1
    assert not out.exists()


def test_a_plain_override_then_the_values_swept_of_one_key_sweep_those_values():
    base = configs.get("ppo_arm2d")
    grid = sweep.parse_grid(
        base, ["num_minibatches=2", "num_minibatches=1,4", "learning_rate=1e-3", "learning_rate=2e-3,1e-4"]
    )
    assert [config.num_minibatches for config in grid.groups] == [1, 4]
    assert [combo["learning_rate"] for combo in grid.dynamic] == pytest.approx([2e-3, 1e-4])


def test_prepare_names_the_presets_it_has_nothing_to_compile_for_and_refuses_an_unknown_one(capsys):
    from experiments import prepare

    assert prepare.main(["--config", "ppo_arm2d"]) == 0
    assert capsys.readouterr().out == "ppo_arm2d: nothing to compile (its scene does not step on Warp here)\n"
    assert prepare.main(["--config", "ppo_armd2"]) == 2
    assert "unknown config 'ppo_armd2'" in capsys.readouterr().err
