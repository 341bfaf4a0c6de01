# LibTorch for agent/ and learn/: the target scout::torch and the variable SCOUT_TORCH_VERSION.
#
# SCOUT_TORCH_DIR names a LibTorch: a folder with include/ and lib/libtorch_cpu.so, which is the
# layout of both the torch package of a PyTorch wheel (site-packages/torch) and an unzipped LibTorch
# from pytorch.org. Empty (the default), it is the torch package of the project's Python
# (SCOUT_PYTHON: the wheel that scripts/setup.sh installs into .venv/), so that the C++ program, the
# Python package and the Python examples run on one LibTorch. Where that Python has no torch, CMake's
# own find_package(Torch) is used (Debian's libtorch-dev, or what CMAKE_PREFIX_PATH names).
#
# Why not the wheel's own TorchConfig.cmake: PyPI's Linux wheel is a CUDA build, and its config
# stops with a fatal error where no CUDA toolkit is installed. Scout runs on the CPU, so it links
# libtorch_cpu and libc10 only (libtorch_cpu brings its own OpenMP runtime, MKL and oneDNN). Every
# LibTorch since 2.7 is built with the C++11 ABI, as Scout is.

set(SCOUT_TORCH_DIR "" CACHE PATH
    "A LibTorch: a folder with include/ and lib/libtorch_cpu.so (empty: the torch package of SCOUT_PYTHON)")
set(_scout_torch_dir "${SCOUT_TORCH_DIR}")
if(NOT _scout_torch_dir)
  # Asked at every configure, so that a build follows its environment's torch. Without PYTHONPATH:
  # under pip's build isolation it points at pip's own build environment, whose site customization
  # hides the environment SCOUT_PYTHON belongs to.
  execute_process(
    COMMAND ${CMAKE_COMMAND} -E env --unset=PYTHONPATH --unset=PYTHONNOUSERSITE "${SCOUT_PYTHON}" -c
            "import importlib.util as u; s = u.find_spec('torch'); print(s.submodule_search_locations[0] if s else '')"
    OUTPUT_VARIABLE _scout_python_torch OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
  if(_scout_python_torch AND EXISTS "${_scout_python_torch}/lib/libtorch_cpu.so"
     AND EXISTS "${_scout_python_torch}/include/torch")
    set(_scout_torch_dir "${_scout_python_torch}")
  endif()
endif()

if(_scout_torch_dir)
  foreach(_file include/torch/csrc/api/include/torch/torch.h lib/libtorch_cpu.so lib/libc10.so)
    if(NOT EXISTS "${_scout_torch_dir}/${_file}")
      message(FATAL_ERROR "LibTorch at ${_scout_torch_dir} is not usable: ${_file} is missing "
                          "(expected a PyTorch wheel's torch folder or an unzipped LibTorch)")
    endif()
  endforeach()
  # The version: the wheel's torch/version.py where there is one (it names the build, e.g.
  # 2.15.0+cu132), else LibTorch's build-version file.
  if(EXISTS "${_scout_torch_dir}/version.py")
    file(STRINGS "${_scout_torch_dir}/version.py" _line REGEX "^__version__ = ")
    string(REGEX REPLACE "^__version__ = '([^']*)'.*" "\\1" SCOUT_TORCH_VERSION "${_line}")
  elseif(EXISTS "${_scout_torch_dir}/build-version")
    file(STRINGS "${_scout_torch_dir}/build-version" SCOUT_TORCH_VERSION LIMIT_COUNT 1)
  else()
    set(SCOUT_TORCH_VERSION "unknown")
  endif()
  # The wheel's include/ also carries the fmt (12) and pybind11 that LibTorch was built with; on
  # the include path they would shadow Debian's fmt 9, which Scout links, in every torch-using
  # file. So the include path is a folder of links to everything else in include/.
  # One such folder per LibTorch (named by its path's hash), so nothing is ever removed there.
  string(MD5 _hash "${_scout_torch_dir}")
  set(_scout_torch_include "${CMAKE_BINARY_DIR}/torch-include/${_hash}")
  file(MAKE_DIRECTORY "${_scout_torch_include}")
  file(GLOB _entries RELATIVE "${_scout_torch_dir}/include" "${_scout_torch_dir}/include/*")
  foreach(_entry IN LISTS _entries)
    if(NOT _entry MATCHES "^(fmt|pybind11)$" AND NOT IS_SYMLINK "${_scout_torch_include}/${_entry}")
      file(CREATE_LINK "${_scout_torch_dir}/include/${_entry}" "${_scout_torch_include}/${_entry}" SYMBOLIC)
    endif()
  endforeach()
  add_library(scout::torch INTERFACE IMPORTED GLOBAL)
  # Torch's headers as system headers: their warnings are not ours.
  target_include_directories(scout::torch SYSTEM INTERFACE
    "${_scout_torch_include}" "${_scout_torch_dir}/include/torch/csrc/api/include")
  target_link_libraries(scout::torch INTERFACE "${_scout_torch_dir}/lib/libtorch_cpu.so"
                                               "${_scout_torch_dir}/lib/libc10.so" Threads::Threads)
  target_compile_definitions(scout::torch INTERFACE USE_C10D_GLOO USE_DISTRIBUTED)
  # A LibTorch built with glog (Debian's) logs through it, and learn/distributed.cpp quiets it.
  file(STRINGS "${_scout_torch_dir}/include/c10/macros/cmake_macros.h" _glog REGEX "^#define C10_USE_GLOG")
  if(_glog)
    find_library(SCOUT_GLOG_LIBRARY glog REQUIRED)
    target_link_libraries(scout::torch INTERFACE "${SCOUT_GLOG_LIBRARY}")
  endif()
  set(SCOUT_TORCH_SOURCE "${_scout_torch_dir}")
else()
  find_package(Torch QUIET)
  if(NOT Torch_FOUND)
    message(FATAL_ERROR "No LibTorch: ${SCOUT_PYTHON} has no torch package with include/ and lib/, and "
                        "find_package(Torch) found none. Run ./scripts/setup.sh (it installs PyTorch into "
                        ".venv/), or name one with -DSCOUT_TORCH_DIR=/path/to/libtorch; for `pip install .`, "
                        "install python/requirements.txt into the environment first (README, The Python side)")
  endif()
  add_library(scout::torch INTERFACE IMPORTED GLOBAL)
  target_include_directories(scout::torch SYSTEM INTERFACE ${TORCH_INCLUDE_DIRS})
  target_link_libraries(scout::torch INTERFACE ${TORCH_LIBRARIES})
  # LibTorch's CMake config says 1.13.0 for Debian's 1.13.1: ask the package manager first.
  execute_process(COMMAND dpkg-query -W "-f=\${Version}" libtorch-dev
    OUTPUT_VARIABLE SCOUT_TORCH_VERSION ERROR_QUIET RESULT_VARIABLE _dpkg_result)
  if(NOT _dpkg_result EQUAL 0 OR SCOUT_TORCH_VERSION STREQUAL "")
    set(SCOUT_TORCH_VERSION "${Torch_VERSION}")
  endif()
  set(SCOUT_TORCH_SOURCE "find_package(Torch): ${Torch_DIR}")
endif()
message(STATUS "LibTorch ${SCOUT_TORCH_VERSION} (${SCOUT_TORCH_SOURCE})")
