#!/usr/bin/env bash
# Prints the path of the first of the Python versions given (e.g. `3.13 3.12 3.11`) installed on the PATH or in
# pyenv; exits 1, printing nothing, where none is. Used by scripts/setup.sh and .ci/run.
set -uo pipefail
for version in "$@"; do
  # pyenv's python3.X shim is on the PATH wherever pyenv has 3.X, and exits 127 unless 3.X is selected: run it to
  # know, else take pyenv's interpreter by its path.
  if "python$version" -c "" >/dev/null 2>&1; then
    command -v "python$version"
    exit 0
  fi
  if command -v pyenv >/dev/null; then
    found=$(find "$(pyenv root)/versions" -path "*/$version*/bin/python$version" 2>/dev/null | sort -V | tail -n 1)
    if [ -n "$found" ]; then
      echo "$found"
      exit 0
    fi
  fi
done
exit 1
