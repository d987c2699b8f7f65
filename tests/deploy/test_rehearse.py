"""`python -m experiments.rehearse`: an exported sorter policy rehearsed in real time against MuJoCo in its own
process. The episodes' starts come from the env's reset (one MJX program: marked mjx)."""

import json

import numpy as np
import pytest

from experiments import rehearse
from tests.deploy.exported import export_random_policy, sorter_run

STEPS = 10


@pytest.mark.mjx
@pytest.mark.slow
def test_the_rehearsal_cli_reports_placements_jitter_and_misses(tmp_path, capsys):
    config = sorter_run(tmp_path, STEPS)
    assert rehearse.main([str(tmp_path)]) == 2
    assert "export the run first" in capsys.readouterr().err
    export_random_policy(tmp_path, config, "24")
    assert rehearse.main([str(tmp_path), "--episodes", "2"]) == 0
    result = json.loads((tmp_path / "rehearse-2-12345-24-20ms.json").read_text())
    assert result["episodes"] == 2 and result["ticks"] == 2 * STEPS and result["faults"] == ["ended", "ended"]
    assert 0.0 <= result["placed_fraction"] <= 1.0 and result["tick_jitter_ms_p99"] >= 0.0
    assert all(np.max(result[f"max_{name}_of_limit"]) <= 1 + 1e-6 for name in ("speed", "acceleration", "jerk"))
    assert "rehearsed in real time" in capsys.readouterr().out
    # A stall: the robot holds and stops, and the episodes end early.
    assert rehearse.main([str(tmp_path), "--episodes", "1", "--fault", "stall", "--fault-tick", "3"]) == 0
    result = json.loads((tmp_path / "rehearse-1-12345-24-20ms-stall-tick3.json").read_text())
    assert result["faults"] == ["missed"] and result["ticks"] < STEPS


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--seed", "99999999999999999999999"], "--seed must fit in int32"),  # JAX's OverflowError before
        (["--latency-budget", "nan"], "--latency-budget must be finite"),  # rehearse-...-nanms.json before
        (["--latency-budget", "-1"], "--latency-budget must be in (0, 20000], got -1.0"),
        (["--latency-budget", "1e300"], "--latency-budget must be in (0, 20000], got 1e+300"),
        (["--fault", "stall", "--fault-tick", "-1"], "a fault's tick counts the policy's ticks from 0, got -1"),
    ],
)
def test_bad_options_are_one_line_before_anything_runs(options, message, tmp_path, capsys):
    assert rehearse.main([str(tmp_path), *options]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {message}") and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []
