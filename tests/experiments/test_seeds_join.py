"""Studies of one preset's seeds run apart join into the row one study of all their seeds writes."""

import dataclasses
import json
import pathlib

import pytest

from experiments import seeds, seeds_join

PROTOCOL = seeds.Protocol(
    "ppo_arm2d", (0,), 0.9, 10.0, ("num_envs=8",), perturb=("action_scale=0.2",), worst_corner=True
)


def row(param: str, value: float | None, placed: float) -> dict:
    return {"param": param, "value": value, "success_rate": placed}


def tables(seed: int) -> list[dict]:
    """A seed's robustness rows as its run's table holds them: nominal, one change, its own worst corner."""
    return [
        row("nominal", None, 1.0),
        row("action_scale", 0.2, 0.5 + 0.1 * seed),
        row(f"worst corner: g={seed}", None, 0.8),
    ]


def result(seed: int, placed: float, wall_s: float = 60.0) -> seeds.SeedResult:
    return seeds.SeedResult(seed=seed, placed=placed, wall_s=wall_s, finished=True, device="cpu")


def write_study(out: pathlib.Path, protocol: seeds.Protocol, results: list[seeds.SeedResult]) -> pathlib.Path:
    """A study's summary.json as `experiments.seeds` writes it, its runs gone."""
    out.mkdir(parents=True)
    summary = seeds.summarise(protocol, results, {result.seed: tables(result.seed) for result in results})
    (out / "summary.json").write_text(json.dumps(summary))
    return out


def test_two_studies_join_into_the_row_one_study_of_all_their_seeds_writes(tmp_path):
    first = dataclasses.replace(PROTOCOL, seeds=(3, 0))
    second = dataclasses.replace(PROTOCOL, seeds=(1,))
    one = write_study(tmp_path / "a", first, [result(3, 0.97), result(0, 0.99)])
    other = write_study(tmp_path / "b", second, [result(1, 0.95, wall_s=700.0)])

    joined = seeds_join.join([seeds_join.read_study(one), seeds_join.read_study(other / "summary.json")])

    everything = dataclasses.replace(PROTOCOL, seeds=(0, 1, 3))
    results = [result(0, 0.99), result(1, 0.95, wall_s=700.0), result(3, 0.97)]
    alone = seeds.summarise(everything, results, {seed: tables(seed) for seed in (0, 1, 3)})
    as_written = json.loads(json.dumps({key: value for key, value in joined.items() if key != "joined"}))
    assert as_written == json.loads(json.dumps(alone))
    assert joined["worst"] == 0.95 and not joined["met"]  # seed 1 took 700 s of a 10-minute limit
    assert joined["worst_corners"] == {"0": "g=0", "1": "g=1", "3": "g=3"}
    assert joined["joined"] == [first.command, second.command]
    assert "(joined from `python -m experiments.seeds --config ppo_arm2d --seeds 3,0 " in seeds.markdown(joined)


def test_the_cli_writes_the_joined_row_and_refuses_to_overwrite_a_study(tmp_path, capsys):
    one = write_study(tmp_path / "a", dataclasses.replace(PROTOCOL, seeds=(0,)), [result(0, 0.99)])
    other = write_study(tmp_path / "b", dataclasses.replace(PROTOCOL, seeds=(1,)), [result(1, 0.92)])
    assert seeds_join.main([str(one), str(other), "--out", str(tmp_path / "joined")]) == 0
    summary = json.loads((tmp_path / "joined" / "summary.json").read_text())
    assert summary["worst"] == 0.92 and summary["met"] and [seed["seed"] for seed in summary["seeds"]] == [0, 1]
    assert "worst seed 92.0%" in (tmp_path / "joined" / "seeds.md").read_text()

    (tmp_path / "study").mkdir()
    (tmp_path / "study" / seeds.SEEDS_FILE).write_text("{}")
    assert seeds_join.main([str(one), str(other), "--out", str(tmp_path / "study")]) == 2
    assert "holds a study of its own" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"goal": 0.95}, "asked differently"),
        ({"overrides": ("num_envs=16",)}, "asked differently"),
        ({"perturb": ()}, "asked differently"),
        ({}, "seeds 0 were trained by more than one study"),
    ],
)
def test_studies_that_asked_differently_or_share_a_seed_are_refused(tmp_path, change, message):
    one = write_study(tmp_path / "a", dataclasses.replace(PROTOCOL, seeds=(0,)), [result(0, 0.99)])
    other = write_study(tmp_path / "b", dataclasses.replace(PROTOCOL, seeds=(0,), **change), [result(0, 0.9)])
    with pytest.raises(ValueError, match=message):
        seeds_join.join([seeds_join.read_study(one), seeds_join.read_study(other)])


def test_a_summary_missing_damaged_or_older_than_its_protocol_is_refused_in_one_line(tmp_path):
    with pytest.raises(ValueError, match="no such study summary"):
        seeds_join.read_study(tmp_path / "nowhere")
    (tmp_path / "summary.json").write_text("{not json")
    with pytest.raises(ValueError, match="unreadable"):
        seeds_join.read_study(tmp_path)
    (tmp_path / "summary.json").write_text(json.dumps({"command": "python -m experiments.seeds", "seeds": []}))
    with pytest.raises(ValueError, match="records no protocol .* --resume STUDY_DIR`, writes it again"):
        seeds_join.read_study(tmp_path)
    (tmp_path / "summary.json").write_text(json.dumps({"command": "c", "protocol": {"config": "ppo_arm2d"}}))
    with pytest.raises(ValueError, match="is damaged"):
        seeds_join.read_study(tmp_path)
