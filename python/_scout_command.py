"""The `scout` command of an installed Scout (`pip install .`; pyproject.toml's [project.scripts]):
runs the program the package carries, site-packages/scout/bin/scout, with the command's arguments.
It finds the package without importing it (that would load NumPy, the environment module and
Gymnasium for nothing), and tells the program two things that only Python knows:
  - SCOUT_PYTHON: the Python this command runs on, which `scout report` draws its figures with
    (matplotlib), unless the variable is set already;
  - where LibTorch is, when the torch package is not installed beside scout (the program's RPATH
    looks in site-packages/torch/lib): the lib/ folder of the torch this Python imports (one on
    another sys.path entry: a .pth file, the system's site packages), through LD_LIBRARY_PATH."""
import importlib.util
import os
import sys


def torch_library_folder(package):
    """The lib/ folder of the torch package Python imports, where the RPATH of the modules and the
    program in `package` (site-packages/scout) would not find it (None where it would, or where
    there is no torch). scout.Agent asks it too, for scout._scout_agent."""
    if os.path.isfile(os.path.join(package, os.pardir, "torch", "lib", "libtorch_cpu.so")):
        return None
    spec = importlib.util.find_spec("torch")
    if spec is None or not spec.submodule_search_locations:
        return None
    folder = os.path.join(spec.submodule_search_locations[0], "lib")
    return folder if os.path.isfile(os.path.join(folder, "libtorch_cpu.so")) else None


def main():
    spec = importlib.util.find_spec("scout")
    if spec is None or not spec.submodule_search_locations:
        sys.exit(f"scout: the scout package is not installed for {sys.executable} (pip install .)")
    package = spec.submodule_search_locations[0]
    program = os.path.join(package, "bin", "scout")
    if not os.access(program, os.X_OK):
        sys.exit(f"scout: {program} is missing: install the package again (pip install .)")
    env = dict(os.environ)
    env.setdefault("SCOUT_PYTHON", sys.executable)
    torch = torch_library_folder(package)
    if torch is not None:
        env["LD_LIBRARY_PATH"] = os.pathsep.join(p for p in (torch, env.get("LD_LIBRARY_PATH")) if p)
    os.execve(program, ["scout", *sys.argv[1:]], env)


if __name__ == "__main__":
    main()
