#include "tools/output.hpp"

#include <unistd.h>

#include <chrono>
#include <fstream>
#include <random>

#include <Eigen/Core>
#include <fmt/chrono.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "render/snapshot.hpp"
#include "sim/robots.hpp"
#include "worlds/dataset.hpp"
#include "worlds/error.hpp"

namespace scout {
const char* git_commit();  // generated at build time (cmake/GitVersion.cmake)
}

namespace scout::tools {

namespace fs = std::filesystem;

OutputDir::OutputDir(fs::path target, bool overwrite) : target_(std::move(target)), overwrite_(overwrite) {
  if (target_.empty()) throw InputError("--out: expected a folder path, got an empty one");
  if (fs::exists(target_) && !overwrite_)
    throw InputError("--out: " + target_.string() + " already exists (give --overwrite to replace it)");
  if (fs::exists(target_) && !fs::is_directory(target_))
    throw InputError("--out: " + target_.string() + " exists and is not a folder");
  const fs::path parent = fs::absolute(target_).parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) throw InputError("--out: cannot create " + parent.string() + ": " + ec.message());
  // A staging folder beside the target (same file system, so the final rename is atomic).
  std::random_device rd;
  staging_ = parent / fmt::format(".{}.partial-{:08x}", fs::absolute(target_).filename().string(), rd());
  fs::create_directory(staging_, ec);
  if (ec) throw InputError("--out: cannot create " + staging_.string() + ": " + ec.message());
}

OutputDir::~OutputDir() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(staging_, ec);
  }
}

void OutputDir::commit() {
  std::error_code ec;
  if (fs::exists(target_)) {
    if (!overwrite_) throw InputError("--out: " + target_.string() + " appeared while running; not replaced");
    fs::remove_all(target_, ec);
    if (ec) throw InputError("--out: cannot replace " + target_.string() + ": " + ec.message());
  }
  fs::rename(staging_, target_, ec);
  if (ec) throw InputError("--out: cannot move results to " + target_.string() + ": " + ec.message());
  committed_ = true;
}

void write_file_atomic(const fs::path& file, const std::string& text) {
  const fs::path tmp = file.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw InputError(file.string() + ": cannot write");
    }
  }
  std::error_code ec;
  fs::rename(tmp, file, ec);
  if (ec) throw InputError(file.string() + ": cannot write: " + ec.message());
}

std::vector<std::string> command_line(int argc, char** argv) { return {argv, argv + argc}; }

nlohmann::ordered_json make_manifest(const std::vector<std::string>& argv, const std::string& world_yaml,
                             const std::vector<fs::path>& data_files, const std::string& gl_description) {
  nlohmann::ordered_json m;
  m["command_line"] = argv;
  m["git_commit"] = git_commit();
  m["scout_version"] = SCOUT_VERSION;
  m["created_utc"] = fmt::format("{:%Y-%m-%dT%H:%M:%SZ}", fmt::gmtime(std::chrono::system_clock::to_time_t(std::chrono::system_clock::now())));
  nlohmann::ordered_json libs;
  libs["box2d"] = sim::physics_library_version();  // as b2_version reports it
  libs["opencv"] = render::image_library_version();
  libs["eigen"] = fmt::format("{}.{}.{}", EIGEN_WORLD_VERSION, EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION);
  libs["nlohmann_json"] = fmt::format("{}.{}.{}", NLOHMANN_JSON_VERSION_MAJOR, NLOHMANN_JSON_VERSION_MINOR, NLOHMANN_JSON_VERSION_PATCH);
  libs["fmt"] = fmt::format("{}.{}.{}", FMT_VERSION / 10000, FMT_VERSION / 100 % 100, FMT_VERSION % 100);
  if (!gl_description.empty()) libs["gl"] = gl_description;
  m["libraries"] = libs;
  if (!world_yaml.empty()) m["world"] = world_yaml;
  nlohmann::ordered_json hashes = nlohmann::ordered_json::object();
  for (const fs::path& f : data_files) hashes[fs::absolute(f).lexically_normal().string()] = worlds::sha256_file(f);
  m["data_sha256"] = hashes;
  return m;
}

}  // namespace scout::tools
