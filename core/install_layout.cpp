#include "core/install_layout.hpp"

#include <dlfcn.h>
#include <link.h>

#include <cstdlib>
#include <system_error>

namespace scout::core {
namespace {

namespace fs = std::filesystem;

// The file of the program or shared object (a Python module) that this code is linked into.
fs::path this_object() {
  Dl_info info{};
  link_map* map = nullptr;
  if (dladdr1(reinterpret_cast<void*>(&this_object), &info, reinterpret_cast<void**>(&map), RTLD_DL_LINKMAP) != 0 &&
      map != nullptr && map->l_name != nullptr && map->l_name[0] != '\0')
    return map->l_name;  // a shared object: the path it was loaded from
  // The program itself: the dynamic linker names it "" (and dladdr's dli_fname is argv[0]).
  std::error_code ec;
  fs::path program = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : program;
}

std::optional<fs::path> find_installed_files() {
  const fs::path object = this_object();
  if (object.empty()) return std::nullopt;
  std::error_code ec;
  fs::path folder = fs::weakly_canonical(fs::absolute(object, ec), ec).parent_path();
  if (ec) return std::nullopt;
  if (folder.filename() == "bin") folder = folder.parent_path();  // the program, in the package's bin/
  const fs::path share = folder / "share";
  if (fs::is_directory(share / "worlds", ec)) return share;
  return std::nullopt;
}

}  // namespace

const std::optional<fs::path>& installed_files() {
  static const std::optional<fs::path> files = find_installed_files();
  return files;
}

fs::path files_root() {
  if (const std::optional<fs::path>& files = installed_files()) return *files;
  return fs::path(SCOUT_SOURCE_DIR);
}

fs::path user_data_folder() {
  if (const char* dir = std::getenv("XDG_DATA_HOME"); dir != nullptr && *dir != '\0') return fs::path(dir) / "scout";
  const char* home = std::getenv("HOME");
  return fs::path(home != nullptr && *home != '\0' ? home : "/tmp") / ".local" / "share" / "scout";
}

}  // namespace scout::core
