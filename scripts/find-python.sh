#!/usr/bin/env bash
# Print the path of a Python >= 3.12 interpreter, or fail with one clear line.
# Order: $PYTHON, versioned names on PATH, plain python3, then pyenv's version folders
# (pyenv shims exist on PATH but refuse to run a version that is not selected).
set -u
ok() { "$1" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 12) else 1)' >/dev/null 2>&1; }
candidates=()
[ -n "${PYTHON:-}" ] && candidates+=("$PYTHON")
for v in 3.14 3.13 3.12; do candidates+=("python$v"); done
candidates+=(python3 python)
pyroot=$(pyenv root 2>/dev/null || echo "$HOME/.pyenv")
for d in "$pyroot"/versions/3.1[2-9]*/bin /usr/local/bin /usr/bin /opt/python*/bin; do
  for v in 3.14 3.13 3.12; do candidates+=("$d/python$v"); done
done
for c in "${candidates[@]}"; do
  p=$(command -v "$c" 2>/dev/null) || continue
  if ok "$p"; then echo "$p"; exit 0; fi
done
echo "torsionfit needs Python >= 3.12 and found none (tried \$PYTHON, python3.12+, python3, pyenv versions); install one or set PYTHON=/path/to/python3.12" >&2
exit 1
