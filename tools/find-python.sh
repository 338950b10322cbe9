#!/usr/bin/env bash
# Print the path of a Python >= 3.12 interpreter: first on PATH, then under pyenv.
# lerobot 0.6.1 and drake 1.58.0 need 3.12+, while many machines default to an older python3.
set -u
ok() { "$1" -c 'import sys, venv; sys.exit(0 if sys.version_info >= (3, 12) else 1)' >/dev/null 2>&1; }
# 3.12 first: it is what the pinned wheels are tested with here.
for name in python3.12 python3 python3.13 python; do
  p=$(command -v "$name" 2>/dev/null) || continue
  if ok "$p"; then "$p" -c 'import sys; print(sys.executable)'; exit 0; fi
done
root=$(pyenv root 2>/dev/null || echo "${PYENV_ROOT:-$HOME/.pyenv}")
for p in $(ls -d "$root"/versions/3.12*/bin/python3 2>/dev/null | sort -rV) \
         $(ls -d "$root"/versions/3.1[3-9]*/bin/python3 2>/dev/null | sort -V); do
  if ok "$p"; then echo "$p"; exit 0; fi
done
echo "error: no Python >= 3.12 found on PATH or under pyenv ($root/versions)." >&2
echo "       lerobot 0.6.1 and drake 1.58.0 need it: install one (e.g. 'pyenv install 3.12')" >&2
echo "       or put it on PATH, then run 'make install' again." >&2
exit 1
