"""Checkpoints read back on another machine's devices, and by a learner that has gained leaves since."""

import json
import logging
import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.agents.common import checkpoint


def _as_if_saved_on_a_gpu(step_dir) -> None:
    """Rewrites every leaf's recorded placement to a device this machine lacks, as a GPU run's checkpoint has."""
    for sharding_file in step_dir.rglob("_sharding"):
        placements = json.loads(sharding_file.read_text())
        gpu = json.dumps({"sharding_type": "SingleDeviceSharding", "device_str": "cuda:0"})
        sharding_file.write_text(json.dumps(dict.fromkeys(placements, gpu)))


def test_a_checkpoint_saved_on_other_devices_restores_onto_this_one(tmp_path):
    state = {"params": jnp.arange(6.0).reshape(2, 3), "updates": jnp.int32(7)}
    checkpoint.save(tmp_path, 7, state)
    _as_if_saved_on_a_gpu(tmp_path / "7")

    # The runner restores into abstract shapes (`jax.eval_shape` of the learner's init), which name no device.
    restored = checkpoint.restore(tmp_path, jax.eval_shape(lambda: state))

    np.testing.assert_array_equal(restored["params"], state["params"])
    assert int(restored["updates"]) == 7
    assert restored["params"].devices() == {jax.devices()[0]}


def test_latest_step_looks_again_when_a_live_run_prunes_a_step_it_is_listing(tmp_path, monkeypatch):
    checkpoint.save(tmp_path, 3, {"updates": jnp.int32(3)})
    real_manager = checkpoint.ocp.CheckpointManager
    calls = []

    def pruned_while_listing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 1:
            raise FileNotFoundError("checkpoints/2: removed by the run that wrote it")
        return real_manager(*args, **kwargs)

    monkeypatch.setattr(checkpoint.ocp, "CheckpointManager", pruned_while_listing)
    assert checkpoint.latest_step(tmp_path) == 3
    assert len(calls) == 2


@pytest.mark.parametrize("relative", [False, True])
def test_a_checkpoint_lacking_leaves_added_since_takes_them_from_a_fresh_state(tmp_path, monkeypatch, relative):
    if relative:  # a run directory named relative to the working directory, as on a command line
        monkeypatch.chdir(tmp_path.parent)
        tmp_path = pathlib.Path(tmp_path.name)
    saved = {"params": jnp.arange(3.0), "env": {"mass": jnp.ones(4)}}
    checkpoint.save(tmp_path, 5, saved)
    fresh = {"params": jnp.zeros(3), "env": {"mass": jnp.zeros(4), "gain": jnp.full(4, 2.0)}}

    with pytest.warns(UserWarning, match=r"predates 1 leaves of this learner \(env.gain\)"):
        restored = checkpoint.restore(tmp_path, jax.eval_shape(lambda: fresh), fresh=lambda: fresh)

    np.testing.assert_array_equal(restored["params"], saved["params"])
    np.testing.assert_array_equal(restored["env"]["mass"], saved["env"]["mass"])
    np.testing.assert_array_equal(restored["env"]["gain"], fresh["env"]["gain"])
    # Without a fresh state, or where a saved leaf is gone or reshaped, the mismatch stays an error.
    with pytest.raises(checkpoint.CheckpointError, match="cannot be restored"):
        checkpoint.restore(tmp_path, jax.eval_shape(lambda: fresh))
    for other in ({"params": jnp.zeros(3), "env": {"gain": jnp.ones(4)}}, {**fresh, "params": jnp.zeros(2)}):
        with pytest.raises(checkpoint.CheckpointError, match="cannot be restored"):
            checkpoint.restore(tmp_path, jax.eval_shape(lambda other=other: other), fresh=lambda other=other: other)


def test_a_partial_restore_reads_only_the_parts_it_is_given(tmp_path):
    saved = {"params": jnp.arange(3.0), "env": {"mass": jnp.ones(4)}}
    checkpoint.save(tmp_path, 5, saved)
    acting = {"params": jnp.zeros(3), "env": None}  # a state for acting: its envs are not read

    restored = checkpoint.restore(tmp_path, jax.eval_shape(lambda: acting), partial=True)

    np.testing.assert_array_equal(restored["params"], saved["params"])
    assert restored["env"] is None
    # The part it reads is held to the same standard: a leaf added since comes fresh, with a warning ...
    grown = {"params": jnp.zeros(3), "gain": jnp.full(2, 2.0), "env": None}
    with pytest.warns(UserWarning, match=r"predates 1 leaves of this learner \(gain\)"):
        restored = checkpoint.restore(tmp_path, jax.eval_shape(lambda: grown), fresh=lambda: grown, partial=True)
    np.testing.assert_array_equal(restored["params"], saved["params"])
    np.testing.assert_array_equal(restored["gain"], grown["gain"])
    # ... and a reshaped one is an error.
    reshaped = {"params": jnp.zeros(2), "env": None}
    with pytest.raises(checkpoint.CheckpointError, match="cannot be restored"):
        checkpoint.restore(tmp_path, jax.eval_shape(lambda: reshaped), fresh=lambda: reshaped, partial=True)


def test_a_checkpoint_of_another_config_names_its_differing_leaves_in_one_line(tmp_path, capfd):
    saved = {"params": {"w": jnp.ones((9, 64)), "b": jnp.zeros(64)}, "key": jax.random.split(jax.random.key(0), 3)}
    checkpoint.save(tmp_path, 5, saved)
    # A typed PRNG key is saved as its data (uint32 [3, 2]) and fits the key it came from.
    restored = checkpoint.restore(tmp_path, jax.eval_shape(lambda: saved))
    np.testing.assert_array_equal(jax.random.key_data(restored["key"]), jax.random.key_data(saved["key"]))
    params = saved["params"]
    for message, like in {
        "params.w is (9, 64) float32 there, (12, 64) float32 here": {**params, "w": jnp.ones((12, 64))},
        "it holds params.b, which this learner lacks": {"w": params["w"]},
        "it lacks params.c": {**params, "c": jnp.zeros(2)},
    }.items():
        with pytest.raises(checkpoint.CheckpointError) as refused:
            checkpoint.restore(tmp_path, jax.eval_shape(lambda like=like: {**saved, "params": like}))
        assert str(refused.value) == (
            f"checkpoint 5 in {tmp_path} cannot be restored into this learner (saved by a different config): {message}"
        )
    # Orbax's own message and its abandoned reads' tensorstore specs once reached the user.
    assert "TensorStore" not in capfd.readouterr().err


def test_after_a_failed_save_orbax_s_late_thread_errors_stay_quiet_and_others_do_not(tmp_path, monkeypatch):
    # A write that failed only after the save had raised logged its 38-line absl traceback from orbax's thread (2 of
    # 40 sweeps on a file-size limit).
    absl = logging.getLogger("absl")
    monkeypatch.setattr(absl, "filters", [])
    (tmp_path / "checkpoints").write_text("a file where the folder goes")
    with pytest.raises(checkpoint.CheckpointError):
        checkpoint.save(tmp_path / "checkpoints", 1, {"w": jnp.ones(3)})

    def logged(pathname: str) -> bool:
        record = logging.makeLogRecord({"name": "absl", "levelno": logging.ERROR, "pathname": pathname, "msg": "x"})
        return absl.filter(record)

    assert not logged("/site-packages/orbax/checkpoint/_src/futures/future.py")
    assert logged("/site-packages/jax/_src/dispatch.py")


@pytest.mark.parametrize("error", [FileNotFoundError, NotADirectoryError])
def test_a_step_folder_that_vanishes_while_listed_is_listed_again(error, tmp_path, monkeypatch):
    # A live run prunes a step while another process lists the folder: orbax stats the gone folder, or sees it
    # there and then not a folder.
    checkpoint.save(tmp_path / "checkpoints", 3, {"w": jnp.ones(3)})
    listed = checkpoint._listed_latest_step
    calls = []

    def racing(directory):
        calls.append(directory)
        if len(calls) == 1:
            raise error(f"{directory}/2")
        return listed(directory)

    monkeypatch.setattr(checkpoint, "_listed_latest_step", racing)
    assert checkpoint.latest_step(tmp_path / "checkpoints") == 3 and len(calls) == 2
