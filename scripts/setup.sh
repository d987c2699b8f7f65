#!/usr/bin/env bash
# Creates a venv and installs jaxarm with its test extras at the exact versions of constraints.txt. Idempotent;
# needs only Python 3.11+, pip and gcc. JAXARM_VENV names the venv's directory (default .venv). A new venv takes
# JAXARM_PYTHON, else the newest supported Python on the PATH or in pyenv: 3.13, 3.12, then 3.11 (pyproject's
# requires-python): 3.12 and later get jax 0.11.2 (constraints.txt), without the process-wide XLA:CPU flag jaxarm
# sets for jax 0.10 (jaxarm/_runtime.py). An existing venv keeps its Python unless JAXARM_PYTHON is set:
# `JAXARM_PYTHON=python3.12 JAXARM_VENV=.venv-3.12` makes a second one beside it.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${JAXARM_VENV:-.venv}"
if [ -n "${JAXARM_PYTHON:-}" ] || [ ! -x "$venv/bin/python" ]; then
  if ! python="${JAXARM_PYTHON:-$(bash scripts/find_python.sh 3.13 3.12 3.11)}"; then
    echo "setup: no Python 3.13, 3.12 or 3.11 on the PATH or in pyenv; set JAXARM_PYTHON to one" >&2
    exit 1
  fi
  echo "setup: $venv with $("$python" --version) ($python)"
  "$python" -m venv "$venv"
else
  echo "setup: $venv keeps its $("$venv/bin/python" --version) (JAXARM_PYTHON, or removing $venv, picks another)"
fi
"$venv/bin/python" -m pip install -q --upgrade pip
"$venv/bin/python" -m pip install -q -c constraints.txt -e ".[test]"
# MuJoCo Playground, so that tests/interop/test_playground.py runs its adapter: without the warp-lang it requires,
# which would switch on tests/envs/test_warp.py's Warp runs (minutes each on a CPU); Playground's MJX-JAX path
# imports neither it nor mediapy; it does import tqdm, which nothing else installs in a fresh venv. 23 MB, installed
# in ~1.3 s from the local package index (2026-11-28). The whole extra: `pip install -c constraints.txt -e
# ".[playground]"`.
"$venv/bin/python" -m pip install -q --no-deps -c constraints.txt playground lxml tqdm
