#!/usr/bin/env bash
# Creates a venv and installs jaxarm with its test extras at the exact versions of constraints.txt. Idempotent;
# needs only Python 3.11+, pip and gcc. JAXARM_PYTHON picks the interpreter (default python3) and JAXARM_VENV the
# venv's directory (default .venv), e.g. JAXARM_PYTHON=python3.12 JAXARM_VENV=.venv-3.12 for a second Python.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${JAXARM_VENV:-.venv}"
"${JAXARM_PYTHON:-python3}" -m venv "$venv"
"$venv/bin/python" -m pip install -q --upgrade pip
"$venv/bin/python" -m pip install -q -c constraints.txt -e ".[test]"
