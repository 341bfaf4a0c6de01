#pragma once
/// A folder taken by one process at a time: two `scout train` processes writing one run folder
/// would overwrite each other's checkpoints and metrics.
#include <filesystem>

namespace scout::core {

/// Takes `folder` for this process until it exits (an exclusive flock on the folder itself, so
/// no lock file is left behind and a killed process, SIGKILL included, releases it). Returns
/// false, taking nothing, while another process holds it; throws InputError naming the folder if
/// it cannot be opened or locked.
bool take_folder_for_this_process(const std::filesystem::path& folder);

}  // namespace scout::core
