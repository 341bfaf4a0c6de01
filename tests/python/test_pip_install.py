"""`pip install .` and `pip wheel .` end to end (issue 43). Each goes into a fresh virtual
environment made as scripts/python_env.sh makes .venv (Debian's /usr/bin/python3 -m venv, without
its site packages); then, with the source tree out of reach (a mount namespace lays an empty folder
over it, and over the build folder inside it), from another folder, the installed package must:
import, make and step a registered id through gymnasium.make and gymnasium.make_vec, drive the
agent, and run the installed `scout` program (--help, a run of the installed world file that agrees
with the environment, and the agent's run move for move), on the project's LibTorch: found through
the installed RPATHs where torch is installed beside the package (the wheel's environment), through
the `scout` command and scout.Agent where it is only on sys.path (the other); `scout report` with
the installed script (once); a missing data folder is one line that says how to install it.

The pip builds reuse this build folder (scikit-build-core's build-dir; SCOUT_BUILD_DIR, default
<source>/build): CMake reconfigures it and finds nothing to compile. ctest runs this alone (label
`pip`, RUN_SERIAL: the reconfiguration rewrites the build folder's files) with SCOUT_SOURCE_DIR and
SCOUT_BUILD_DIR set; .ci/run runs it as its own step, which the time table shows."""
import glob
import os
import subprocess
import sysconfig
import textwrap
import time

import pytest

SOURCE = os.path.realpath(os.environ.get("SCOUT_SOURCE_DIR",
                                         os.path.dirname(os.path.dirname(os.path.dirname(__file__)))))
BUILD = os.path.realpath(os.environ.get("SCOUT_BUILD_DIR", os.path.join(SOURCE, "build")))
DATA = os.path.realpath(os.environ.get("SCOUT_DATA", os.path.join(SOURCE, "data")))
MODEL = os.path.join(SOURCE, "tests", "data", "mnist-8k-v1.safetensors")
# The project's environment (.venv, this test's Python): torch, NumPy, Gymnasium, pybind11 and the
# build backend, pinned by python/requirements.txt. Named as .venv/bin/pip names it (not resolved):
# scikit-build-core starts a build folder afresh when its own path differs from the last build's.
PROJECT_SITE = sysconfig.get_paths()["purelib"]
PIP = ["-m", "pip", "--disable-pip-version-check", "--no-input"]


def run(command, timeout=600, **kwargs):
    """Runs a command; its output in the failure's message."""
    result = subprocess.run([str(c) for c in command], capture_output=True, text=True, timeout=timeout, **kwargs)
    assert result.returncode == 0, f"{command} exited {result.returncode}:\n{result.stdout[-6000:]}\n{result.stderr[-6000:]}"
    return result


def fresh_environment(path, keep_site, torch_beside):
    """A virtual environment made as scripts/python_env.sh makes .venv. Its packages are the
    project's: a .pth file appends .venv's site-packages to its sys.path rather than installing
    python/requirements.txt again, which would download 2.4 GB (torch with its CUDA libraries) and
    put another 4.2 GB on a disk that CI machines have not always had. pip sees those packages as
    installed outside this environment and never changes them (--no-deps besides). Two lines: the
    project's folder as the pip builds see it, and where the namespace binds it once the source tree
    (which may hold .venv) is hidden; Python skips a line whose folder does not exist.

    torch_beside: torch also in the environment's own site-packages (a link to the project's, valid
    once the namespace binds it), where `pip install torch` would put it: there the installed
    modules' and program's RPATH ($ORIGIN/../torch/lib) find LibTorch by themselves. Without it,
    torch is only on another sys.path entry, and the `scout` command and scout.Agent find it."""
    run(["/usr/bin/python3", "-m", "venv", path])
    python = os.path.join(path, "bin", "python")
    site = run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip()
    with open(os.path.join(site, "scout-project-environment.pth"), "w") as f:
        f.write(f"{PROJECT_SITE}\n{keep_site}\n")
    if torch_beside:
        os.symlink(os.path.join(keep_site, "torch"), os.path.join(site, "torch"))
    return python, site


# Run in a private mount namespace: the project's packages and the data bound to folders outside
# the source tree, then an empty read-only tmpfs laid over the source tree (and so over build/).
HIDE_SOURCE = textwrap.dedent("""\
    set -eu
    mount --bind "$1" "$2"
    mount --bind "$3" "$4"
    mount -t tmpfs -o ro,size=64k,mode=0755 scout-source-hidden "$5"
    shift 5
    exec "$@"
    """)


def out_of_reach(keep_site, keep_data, command):
    """`command` with the source tree hidden: root makes the namespace itself, anyone else as root
    of a user namespace of their own."""
    unshare = ["unshare", "--mount", "--propagation", "private"] if os.geteuid() == 0 else \
        ["unshare", "--user", "--map-root-user", "--mount"]
    return unshare + ["sh", "-c", HIDE_SOURCE, "hide-source", PROJECT_SITE, keep_site, DATA, keep_data, SOURCE,
                      *command]


# What the installed package must do, run with the fresh environment's Python, from another folder.
CHECK = textwrap.dedent('''\
    import json, os, shutil, subprocess, sys
    source, model, work, keep_site, torch_beside = sys.argv[1:6]
    assert not os.path.exists(os.path.join(source, "CMakeLists.txt")), "the source tree is still in reach"
    assert os.getcwd() == work
    import numpy as np
    import gymnasium
    import scout

    # The environment's own package, with its own files, none of the source tree's.
    package = os.path.dirname(scout.__file__)
    assert package.startswith(sys.prefix + os.sep), (package, sys.prefix)
    assert scout._scout.installed and scout._scout.files_dir == os.path.join(package, "share")
    for name, world in scout.WORLDS.items():
        spec = gymnasium.spec(f"scout/{name}")
        assert spec.kwargs["world"] == os.path.join(package, "share", "worlds", world)
        assert os.path.isfile(spec.kwargs["world"]), spec.kwargs["world"]
    assert os.path.isfile(os.path.join(package, "share", "tools", "report", "scout_report.py"))
    import _scout_command
    assert (_scout_command.torch_library_folder(package) is None) == (torch_beside == "beside")

    # A registered id, one robot: a whole run of E x T = 20 moves.
    env = gymnasium.make("scout/MNIST-v0")
    obs, info = env.reset(seed=5)
    assert obs["pose"].shape == (2,) and obs["revealed"].shape == (28, 28) and 0 <= info["label"] <= 9
    for move in range(20):
        obs, reward, terminated, truncated, info = env.step({"move": move % 4, "prediction": np.zeros(10, np.float32)})
        assert np.isfinite(reward) and not truncated
        assert terminated == (move == 19)
    assert obs["seen"].sum() > 36  # more than the first 6 x 6 patch
    env.close()

    # The vector environment: its starts, digits and labels are `scout run`'s (the installed program).
    envs = gymnasium.make_vec("scout/MNIST-v0", num_envs=3)
    obs, info = envs.reset(seed=11)
    starts = obs["pose"].copy()
    obs, reward, terminated, truncated, _ = envs.step({"move": np.array([0, 1, 2])})
    assert reward.shape == (3,) and not terminated.any()
    envs.close()
    world = os.path.join(package, "share", "worlds", "mnist.yaml")
    program = shutil.which("scout")
    assert program == os.path.join(sys.prefix, "bin", "scout"), program
    help_text = subprocess.run([program, "--help"], check=True, capture_output=True, text=True).stdout
    assert "run" in help_text and "data" in help_text and "report" in help_text
    subprocess.run([program, "run", world, "--seed", "11", "--count", "3", "--no-images", "--out", "run"],
                   check=True, capture_output=True)
    runs = json.load(open("run/trajectory.json"))["runs"]
    assert len(runs) == 3
    for i, r in enumerate(runs):
        assert info["index"][i] == r["index"] and info["label"][i] == r["label"] and list(starts[i]) == r["start"]
        assert len(r["steps"]) == 20
    # The agent (scout._scout_agent, LibTorch) through make_vec chooses what the program chooses.
    agent = scout.Agent(model, precision="fp32")
    envs = scout.make_vec(world, 2, seed=4)
    obs, info = envs.reset(seed=4)
    poses = [obs["pose"].copy()]
    while True:
        obs, reward, terminated, truncated, info = envs.step(agent.act(obs, info))
        poses.append(obs["pose"].copy())
        if terminated.all():
            break
    logits = agent.classify(obs)
    subprocess.run([program, "run", world, "--checkpoint", model, "--precision", "fp32", "--seed", "4", "--count", "2",
                    "--no-images", "--out", "agent-run"], check=True, capture_output=True)
    for i, r in enumerate(json.load(open("agent-run/trajectory.json"))["runs"]):
        assert [list(p[i]) for p in poses[1:]] == [s["grid_pose"] for s in r["steps"]]
        assert int(np.argmax(logits[i])) == r["prediction"]
    # Both took the project's LibTorch, not another on the machine (Debian's libtorch-dev, 1.13,
    # would be found by name if the RPATH missed).
    project_libtorch = os.path.join(keep_site, "torch", "lib", "libtorch_cpu.so")
    [mapped] = {line.split()[-1] for line in open("/proc/self/maps") if line.rstrip().endswith("/libtorch_cpu.so")}
    assert os.path.samefile(mapped, project_libtorch), mapped
    if torch_beside == "beside":  # the program's own RPATH, no LD_LIBRARY_PATH
        linked = subprocess.run(["ldd", os.path.join(package, "bin", "scout")], check=True, capture_output=True,
                                text=True).stdout
        [line] = [line for line in linked.splitlines() if "libtorch_cpu.so =>" in line]
        assert "/scout/bin/../../torch/lib/" in line and os.path.samefile(line.split()[2], project_libtorch), line

    if torch_beside == "beside":  # once: `scout report`, its figures drawn by the installed script
        digits = os.path.join(os.environ["SCOUT_DATA"], "mnist-10k", "t10k")
        subprocess.run([program, "report", model, "--out", "report", "--runs", "1", "--sweep-digits", "0",
                        "--episodes", "2", "--images", digits + "-images-idx3-ubyte", "--labels",
                        digits + "-labels-idx1-ubyte", "--precision", "fp32"], check=True, capture_output=True)
        assert os.path.getsize("report/REPORT.md") > 0 and os.path.getsize("report/confusion.png") > 0

    # Without data: one line that says how to install it, in the installed package's data folder.
    os.environ.pop("SCOUT_DATA")
    os.environ["HOME"] = work
    try:
        scout.make_vec(world, 1)
        raise AssertionError("no error without data")
    except ValueError as e:
        message = str(e)
    expected = os.path.join(work, ".local", "share", "scout", "mnist")
    assert "\\n" not in message and expected in message and "run `scout data`" in message, message
    print("installed package checked:", package)
    ''')


@pytest.fixture(scope="module")
def hiding(tmp_path_factory):
    """Folders outside the source tree for the project's packages and the data; checks that this
    machine can make the namespace that hides the source tree."""
    assert os.path.isfile(os.path.join(DATA, "mnist", "t10k-images-idx3-ubyte")), (
        f"{DATA}/mnist is missing: install the data with ./scripts/setup.sh (MNIST alone: scout data)")
    root = tmp_path_factory.mktemp("kept")
    keep_site, keep_data = root / "project-site-packages", root / "data"
    keep_site.mkdir()
    keep_data.mkdir()
    probe = subprocess.run(out_of_reach(str(keep_site), str(keep_data), ["true"]), capture_output=True, text=True)
    if probe.returncode != 0:
        reason = f"cannot hide the source tree in a mount namespace here (unshare: {probe.stderr.strip()})"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"{reason}, and CI runs every test", pytrace=False)
        pytest.skip(reason)
    return str(keep_site), str(keep_data)


def install_and_check(tmp_path, hiding, how, torch_beside):
    keep_site, keep_data = hiding
    started = time.monotonic()
    python, site = fresh_environment(tmp_path / "venv", keep_site, torch_beside)
    made = time.monotonic()
    # Nothing from an index, nothing into pip's cache (the disk is kept for what matters).
    build = ["--no-index", "--no-cache-dir", "--no-build-isolation", "--no-deps", f"--config-settings=build-dir={BUILD}"]
    if how == "install":
        run([python, *PIP, "install", *build, SOURCE])
    else:
        wheels = tmp_path / "wheels"
        run([python, *PIP, "wheel", *build, "--wheel-dir", wheels, SOURCE])
        [wheel] = glob.glob(str(wheels / "scout-*.whl"))
        print(f"{os.path.basename(wheel)}: {os.path.getsize(wheel) / 1e6:.1f} MB")
        run([python, *PIP, "install", "--no-index", "--no-cache-dir", "--no-deps", wheel])
    installed = time.monotonic()
    # The installed program and module: RPATHs relative to the package, into the torch beside it.
    for file, rpath in [(os.path.join(site, "scout", "bin", "scout"), "$ORIGIN/../../torch/lib"),
                        (glob.glob(os.path.join(site, "scout", "_scout_agent.*.so"))[0], "$ORIGIN/../torch/lib")]:
        dynamic = run(["readelf", "-d", file]).stdout
        assert f"[{rpath}]" in dynamic, dynamic
        assert SOURCE not in dynamic and BUILD not in dynamic, dynamic
    work = tmp_path / "elsewhere"
    work.mkdir()
    (tmp_path / "model.safetensors").write_bytes(open(MODEL, "rb").read())
    (tmp_path / "check.py").write_text(CHECK)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "SCOUT_PYTHON", "SCOUT_BINARY")}
    env.update(SCOUT_DATA=keep_data, SCOUT_CACHE_DIR=str(tmp_path / "cache"),
               PATH=os.path.dirname(python) + os.pathsep + env.get("PATH", ""))
    check = run(out_of_reach(keep_site, keep_data,
                             [python, tmp_path / "check.py", SOURCE, tmp_path / "model.safetensors", work, keep_site,
                              "beside" if torch_beside else "elsewhere"]),
                cwd=work, env=env)
    print(check.stdout)
    print(f"pip {how}: environment {made - started:.1f} s, build and install {installed - made:.1f} s, "
          f"checks {time.monotonic() - installed:.1f} s")


def test_pip_install_into_a_fresh_environment(tmp_path, hiding):
    install_and_check(tmp_path, hiding, "install", torch_beside=False)


def test_pip_wheel_installs_the_same_way(tmp_path, hiding):
    install_and_check(tmp_path, hiding, "wheel", torch_beside=True)
