"""The built wheel carries every file jaxarm reads at run time: built from a copy of the checkout, installed outside
it, every registered env and every transfer plant is built from the installed files alone.

The wheel is built without build isolation (setuptools comes from the test extra, constraints.txt pins it), so the
test needs no package index. It takes ~10 s: no program is compiled.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

from jaxarm.envs import registry

CHECKOUT = Path(__file__).resolve().parents[1]
SOURCES = ("jaxarm", "pyproject.toml", "README.md", "LICENSE")
"""What the wheel is built from (pyproject.toml names the readme and the licence)."""

BUILD_EVERYTHING = """
import pathlib, sys
import jaxarm
from experiments import transfer
from jaxarm import deployable
from jaxarm.envs import registry

where = pathlib.Path(jaxarm.__file__).parent
assert where.is_relative_to(sys.argv[1]), f"jaxarm imported from {where}, not from the installed wheel"
for name in registry.names():
    env = registry.make(name)
    if deployable.runs(env):
        for model in transfer.MODELS:
            transfer.plant_model(env, env.default_params(), model)
        print(name, "with its transfer plants")
    else:
        print(name)
"""
"""Builds each env and its plants, printing its name; run with the installed jaxarm and a copy of experiments/."""


def run(command: list[str], **kwargs) -> subprocess.CompletedProcess:
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, **kwargs)
    assert done.returncode == 0, f"{' '.join(map(str, command))}:\n{done.stdout}\n{done.stderr}"
    return done


def copy_sources(destination: Path) -> None:
    """The wheel's sources in `destination`, so that the build's own files (build/, *.egg-info) stay out of the
    checkout and a stale build/ there cannot add files the sources no longer have."""
    ignore = shutil.ignore_patterns("__pycache__")
    for name in SOURCES:
        source = CHECKOUT / name
        if source.is_dir():
            shutil.copytree(source, destination / name, ignore=ignore)
        else:
            shutil.copy2(source, destination / name)


def test_every_env_and_transfer_plant_builds_from_the_installed_wheel(tmp_path):
    sources, wheels, site, work = (tmp_path / name for name in ("sources", "wheels", "site", "work"))
    copy_sources(sources)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
    run([*pip, "wheel", "--no-deps", "--no-build-isolation", "--check-build-dependencies", "-w", wheels, sources])
    (wheel,) = wheels.glob("jaxarm-*.whl")
    run([*pip, "install", "--no-deps", "--target", site, wheel])
    # The CLIs' package runs from a checkout (it is not in the wheel): a copy here, next to no jaxarm.
    shutil.copytree(CHECKOUT / "experiments", work / "experiments", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(site)}
    built = run([sys.executable, "-c", BUILD_EVERYTHING, str(site)], cwd=work, env=env).stdout.splitlines()
    assert [line.split()[0] for line in built] == registry.names()
    assert any("transfer plants" in line for line in built)
