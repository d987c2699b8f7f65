"""Join studies of one preset's seeds into one row: `python -m experiments.seeds_join STUDY [STUDY ...] --out OUT`.

A preset's seeds often train in several studies of `experiments.seeds`: on hosts lent one at a time, on days apart.
Each STUDY (a study's directory, or its summary.json) must have asked what the others asked (preset, goal, time
limit, overrides, runs per GPU, perturbations) of seeds none of the others trained; the row is then the one a single
study of all their seeds would write: each seed as its study measured it, the worst seed, the mean with its
bootstrap interval, "met" only when the worst seed met the goal in time, and the perturbations' table. Writes
OUT/summary.json and OUT/seeds.md, naming every study joined; reads nothing but the studies' summaries, so that
summaries kept after their runs are gone still join.
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c()  # first, as in experiments.run: nothing is written before main()

import argparse
import dataclasses
import json
import pathlib

from experiments import seeds
from jaxarm.runner import paths, robustness, rundir


@dataclasses.dataclass(frozen=True)
class Study:
    """What one study's summary says: what it asked (its command is `protocol.command`), each seed's result and
    robustness rows."""

    protocol: seeds.Protocol
    results: tuple[seeds.SeedResult, ...]
    tables: dict[int, list[dict] | None]


def read_study(study: pathlib.Path) -> Study:
    """The study whose summary.json is `study` or lies in it; ValueError in one line where it is missing, damaged
    or older than the protocol it records."""
    path = study / "summary.json" if study.is_dir() else study
    try:
        summary = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"{path}: no such study summary (a study's directory or its summary.json)") from None
    except (OSError, ValueError) as error:
        raise ValueError(f"{path} is unreadable ({type(error).__name__}: {error})") from None
    if not isinstance(summary, dict) or "protocol" not in summary:
        raise ValueError(
            f"{path} records no protocol (written before studies did): resuming its study, `python -m "
            "experiments.seeds --resume STUDY_DIR`, writes it again"
        )
    try:
        return Study(
            protocol=seeds.protocol_from(summary["protocol"]),
            results=tuple(seeds.SeedResult(**result) for result in summary["seeds"]),
            tables=robustness_rows(summary),
        )
    except (TypeError, KeyError, ValueError, AttributeError) as error:
        raise ValueError(f"{path} is damaged ({type(error).__name__}: {error})") from None


def robustness_rows(summary: dict) -> dict[int, list[dict] | None]:
    """seed -> the rows of its robustness table as `seeds.robustness_tables` reads them from its run, rebuilt from
    the study's summary: one row per perturbation the seed was measured under (its worst corner named as its
    table named it), None where it has none."""
    corners = summary["worst_corners"]
    tables: dict[int, list[dict] | None] = {}
    for seed in (int(result["seed"]) for result in summary["seeds"]):
        rows = []
        for row in summary["robustness"]:
            placed = row["placed"].get(str(seed))
            label = row["perturbation"]
            if label == robustness.WORST_CORNER:
                label = f"{robustness.WORST_CORNER}: {corners[str(seed)]}"
            if placed is not None:
                rows.append({"param": label, "value": None, "success_rate": placed})
        tables[seed] = rows or None
    return tables


def join(studies: list[Study]) -> dict:
    """The row one study of all the `studies`' seeds would write, with "joined": each study's command; ValueError
    in one line where two studies asked differently or trained a seed twice."""
    first = studies[0].protocol
    for study in studies:
        if dataclasses.replace(study.protocol, seeds=()) != dataclasses.replace(first, seeds=()):
            raise ValueError(
                f"`{study.protocol.command}` asked differently from `{first.command}`: only studies that ask the same "
                "(preset, goal, minutes, overrides, runs per GPU, perturbations) join"
            )
    trained = [result.seed for study in studies for result in study.results]
    if twice := sorted({seed for seed in trained if trained.count(seed) > 1}):
        raise ValueError(f"seeds {', '.join(map(str, twice))} were trained by more than one study: join each once")
    results = sorted((result for study in studies for result in study.results), key=lambda result: result.seed)
    protocol = dataclasses.replace(first, seeds=tuple(result.seed for result in results))
    tables = {seed: rows for study in studies for seed, rows in study.tables.items()}
    ordered = {result.seed: tables[result.seed] for result in results} if protocol.robustness_request else {}
    return {**seeds.summarise(protocol, results, ordered), "joined": [study.protocol.command for study in studies]}


def main(argv=None) -> int:
    start_up.start_up_over()
    parser = argparse.ArgumentParser(
        prog="python -m experiments.seeds_join",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("studies", nargs="+", type=pathlib.Path, help="study directories or their summary.json")
    parser.add_argument("--out", required=True, type=paths.given, help="where the joined row goes")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    out = pathlib.Path(args.out)
    try:
        summary = join([read_study(study) for study in args.studies])
        paths.check_output_dir(out, "--out")
        if (out / seeds.SEEDS_FILE).exists():
            raise ValueError(f"{out} holds a study of its own: give another --out")
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    rundir.write_json(out / "summary.json", summary)
    (out / "seeds.md").write_text(seeds.markdown(summary))
    print(seeds.markdown(summary), end="")
    return 0


if __name__ == "__main__":
    start_up.exit_with(main)
