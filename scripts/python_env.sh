#!/usr/bin/env bash
# Makes the project's Python environment .venv/, idempotently (scripts/setup.sh runs it after the
# Debian packages): a virtual environment of Debian's /usr/bin/python3, isolated from Debian's
# site packages, with python/requirements.txt from PyPI, pinned exactly: PyTorch (whose wheel
# carries the LibTorch the C++ program is built against: one LibTorch for the program, the Python
# package and the examples), NumPy, matplotlib, pytest, pybind11 and Gymnasium.
#
# Scout cannot be built without a LibTorch: where PyPI cannot be reached, this stops with one line
# saying so and how to build against another LibTorch (README, "Which PyTorch").
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv
requirements=python/requirements.txt
stamp="$venv/requirements.installed"

# A venv of another kind (made before with Debian's site packages visible, or left half-made
# without pip) is made again.
if ! "$venv/bin/python" -c "import pip" 2>/dev/null ||
  grep -q "^include-system-site-packages = true" "$venv/pyvenv.cfg" 2>/dev/null; then
  rm -rf "$venv"
  /usr/bin/python3 -m venv "$venv"
fi

# Installed unless up to date (the stamp is the requirements file this environment was made from).
if ! [ -f "$stamp" ] || ! cmp -s "$stamp" "$requirements"; then
  # --no-deps: the file pins the whole environment, and leaves out on purpose what torch needs only
  # on a GPU. --no-cache-dir: pip's cache would hold a second copy of the 2 GB of wheels.
  # A full disk would otherwise surface as pip's OSError half-way through 2 GB of downloads.
  free_mb=$(($(df -Pk . | awk 'NR == 2 {print $4}') / 1024))
  if ((free_mb < 5000)); then
    echo "setup: $venv needs about 5,000 MB of disk while it installs (4.2 GB once made); $(df -P . | awk 'NR == 2 {print $6}') has $free_mb MB free" >&2
    exit 1
  fi
  echo "setup: installing $requirements into $venv (PyTorch with the CUDA libraries it loads: about 2.4 GB from PyPI)"
  if ! "$venv/bin/python" -m pip install -q --disable-pip-version-check --no-input --timeout 60 --retries 3 \
    --only-binary :all: --no-deps --no-cache-dir -r "$requirements" >"$venv/pip.log" 2>&1; then
    echo "setup: could not install $requirements from PyPI (pip's log: $venv/pip.log; the last line:" \
      "$(grep -v '^\s*$' "$venv/pip.log" | tail -1)); Scout needs its PyTorch to build: reach PyPI and run" \
      "./scripts/setup.sh again, or build against a LibTorch of your own (README, \"Which PyTorch\")" >&2
    exit 1
  fi
fi
# Every time (a tenth of a second): the environment must hold exactly what the file names. A
# package changed by hand (a pip install of another torch) would make the C++ build and the Python
# side disagree.
"$venv/bin/python" - "$requirements" <<'PY'
import sys
from importlib import metadata

wanted = {}
for line in open(sys.argv[1]):
    line = line.split("#", 1)[0].strip()
    if line:
        name, version = line.split("==")
        wanted[name.lower().replace("_", "-")] = version
for name, version in wanted.items():
    try:
        found = metadata.version(name)
    except metadata.PackageNotFoundError:
        raise SystemExit(f"setup: {name} is missing from .venv, which {sys.argv[1]} pins at {version}:"
                         " remove .venv/requirements.installed and run ./scripts/setup.sh again")
    if found.split("+")[0] != version:
        raise SystemExit(f"setup: .venv has {name} {found}, {sys.argv[1]} pins {version}: remove"
                         " .venv/requirements.installed and run ./scripts/setup.sh again")
PY
cp "$requirements" "$stamp"
