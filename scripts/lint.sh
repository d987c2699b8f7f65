#!/usr/bin/env bash
# Style and types: ruff's lint and format check over the tree, mypy over jaxarm/ and experiments/ (settings in
# pyproject.toml). Exits non-zero on any finding. Needs the venv of scripts/setup.sh (JAXARM_VENV, default .venv).
set -uo pipefail
cd "$(dirname "$0")/.."
venv="${JAXARM_VENV:-.venv}"
status=0
"$venv/bin/ruff" check . || status=1
"$venv/bin/ruff" format --check . || status=1
"$venv/bin/mypy" || status=1
exit "$status"
