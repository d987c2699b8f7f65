"""`python -m experiments.bench deploy`: the tick benchmark times the loop of a preset and writes its rows."""

import json

from experiments.benchmarks import deploy


def test_the_tick_suite_writes_its_rows(tmp_path, capsys):
    deploy.main(["--presets", "ppo_sorter_dr,ppo_peg", "--ticks", "40", "--warmup", "5", "--out", str(tmp_path)])
    record = json.loads((tmp_path / "deploy.json").read_text())
    rows = {row["preset"]: row for row in record["rows"]}
    assert rows["ppo_peg"]["observation_size"] == 12 and rows["ppo_sorter_dr"]["observation_size"] == 54
    for row in rows.values():
        assert row["ticks"] == 40
        assert 0 < row["p50_ms"] <= row["p99_ms"] <= row["max_ms"]
    assert "| ppo_peg | 12 |" in capsys.readouterr().out
