#!/usr/bin/env bash
# Sets up .venv (scripts/setup.sh) and runs the whole test suite on 2 workers.
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh || exit 1
# MuJoCo renders offscreen through Mesa's software EGL where there is no GPU (eval videos, the sorter's
# render test); CI machines run as root and have apt.
if ! ldconfig -p | grep -q libEGL_mesa; then
  { apt-get update -qq && apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri; } >/dev/null \
    || echo "could not install Mesa EGL: rendering tests will fail" >&2
fi
export MUJOCO_GL="${MUJOCO_GL:-egl}"
.venv/bin/python -m pytest -n 2 --durations=15 "$@"
status=$?
if [ "$status" -eq 5 ]; then
  echo "pytest collected no tests: the suite is broken" >&2
  exit 1
fi
exit "$status"
