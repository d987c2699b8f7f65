#!/usr/bin/env bash
# Creates .venv and installs jaxarm with its test extras. Idempotent; needs only Python 3.11+, pip and gcc.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[test]"
