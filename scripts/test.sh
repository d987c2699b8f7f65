#!/usr/bin/env bash
# Sets up .venv (scripts/setup.sh), checks style and types (scripts/lint.sh), then runs the tests on 2 workers.
#
#   bash scripts/test.sh           # the whole suite: what CI runs
#   bash scripts/test.sh --quick   # the quick tier for the inner loop: every test marked neither slow nor mjx
#
# JAXARM_PYTHON and JAXARM_VENV choose the interpreter and its venv (scripts/setup.sh).
# Further arguments go to pytest. Compiled programs persist in ~/.cache/jaxarm/jax, shared with the commands
# (tests/conftest.py), so a second run compiles little; tests marked xdist_group (the MJX envs',
# tests/envs/compiled.py) stay in one worker with the programs they share.
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh || exit 1
bash scripts/lint.sh || exit 1
# MuJoCo renders offscreen through Mesa's software EGL where there is no GPU (eval videos, the Panda envs'
# render tests); CI machines run as root and have apt.
if ! ldconfig -p | grep -q libEGL_mesa; then
  { apt-get update -qq && apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri; } >/dev/null \
    || echo "could not install Mesa EGL: rendering tests will fail" >&2
fi
export MUJOCO_GL="${MUJOCO_GL:-egl}"
tier=()
if [ "${1:-}" = "--quick" ]; then
  tier=(-m "not slow and not mjx")
  shift
fi
"${JAXARM_VENV:-.venv}/bin/python" -m pytest -n 2 --dist loadgroup --durations=10 "${tier[@]}" "$@"
status=$?
if [ "$status" -eq 5 ]; then
  echo "pytest collected no tests: the suite is broken" >&2
  exit 1
fi
exit "$status"
