#!/usr/bin/env bash
# Makes the project's Python environment .venv/, idempotently (scripts/setup.sh runs it after the
# Debian packages): Debian's /usr/bin/python3 with Debian's site packages visible, so that
# Debian's NumPy 1.24, PyTorch 1.13, matplotlib 3.6 and pytest keep serving, plus the pinned
# packages Debian lacks (python/requirements.txt: Gymnasium) from PyPI, installed under
# python/constraints.txt, which holds NumPy and torch at Debian's versions (a second NumPy or
# LibTorch in the environment would break Debian's PyTorch and Scout's own modules).
#
# Where PyPI cannot be reached, one line says so and the environment is left without Gymnasium:
# the Gymnasium tests then skip with one line each (and fail under CI=true). Nothing else fails.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv
# A folder left by a venv made before python3-venv was installed has no pip: made again.
if ! "$venv/bin/python" -c "import pip" 2>/dev/null; then
  rm -rf "$venv"
  /usr/bin/python3 -m venv --system-site-packages "$venv"
fi
if ! "$venv/bin/python" -m pip install -q --disable-pip-version-check --no-input --timeout 20 --retries 1 \
  -r python/requirements.txt -c python/constraints.txt >"$venv/pip.log" 2>&1; then
  echo "setup: could not install python/requirements.txt from PyPI (unreachable? pip's log: $venv/pip.log);" \
    "going on without Gymnasium, whose tests will skip"
  exit 0
fi
# NumPy and torch must still be Debian's (the constraints make pip fail rather than replace them).
"$venv/bin/python" - <<'PY'
import numpy, torch
for module in (numpy, torch):
    if not module.__file__.startswith("/usr/lib/python3/dist-packages/"):
        raise SystemExit(f"setup: {module.__name__} in .venv is {module.__file__}, not Debian's: remove .venv and run ./scripts/setup.sh again")
PY
