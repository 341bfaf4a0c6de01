#pragma once
/// Where Scout's own files are at run time: the world files (worlds/) and `scout report`'s script
/// (tools/report/). A build (build/tools/scout, build/python/scout/) reads them from the source tree
/// it was built from. An installed package (`pip install .`: site-packages/scout/, with the Python
/// modules beside __init__.py, the program in bin/ and the files in share/, laid out as in the
/// source tree) reads them from its share/ folder, so that it runs with the source tree gone.
#include <filesystem>
#include <optional>

namespace scout::core {

/// The installed package's share/ folder, where this code runs from one: the program or Python
/// module it is linked into lies in a folder (or, for the program, in a bin/ folder under one)
/// that has share/worlds/. Empty for a build. Found once, at the first call.
const std::optional<std::filesystem::path>& installed_files();

/// The folder of Scout's own files, laid out as the source tree (worlds/mnist.yaml,
/// tools/report/scout_report.py): the installed package's share/, else the source tree.
std::filesystem::path files_root();

/// The user's folder for Scout's data where nothing else names one: $XDG_DATA_HOME/scout, else
/// ~/.local/share/scout (an installed package's default data folder: worlds/dataset.hpp).
std::filesystem::path user_data_folder();

}  // namespace scout::core
