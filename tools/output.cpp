#include "tools/output.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <unistd.h>

#include <Eigen/Core>
#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "core/digest.hpp"
#include "core/error.hpp"
#include "core/fault_injection.hpp"
#include "core/files.hpp"
#include "learn/checkpoint.hpp"
#include "tools/commands.hpp"
#include "worlds/dataset.hpp"

namespace scout {
const char* git_commit();  // generated at build time (cmake/GitVersion.cmake)
}

namespace scout::tools {

namespace fs = std::filesystem;

namespace {

// True when `inner` is `outer` or lies inside it (both absolute and normal).
bool is_within(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

}  // namespace

OutputDir::OutputDir(fs::path target, bool overwrite, const std::vector<fs::path>& keep)
    : display_(target.string()), overwrite_(overwrite) {
  if (target.empty()) throw InputError("--out: expected a folder path, got an empty one");
  // One spelling of the folder: absolute, normal, and without a trailing separator.
  target_ = fs::absolute(target).lexically_normal();
  if (!target_.has_filename()) target_ = target_.parent_path();
  if (target_ == target_.root_path()) throw InputError("--out: refusing to write the output over " + target_.string());
  // Replacing a folder that holds the caller's own work, or the inputs, would destroy it.
  std::vector<fs::path> guarded = {fs::current_path()};
  for (const fs::path& k : keep) guarded.push_back(fs::absolute(k).lexically_normal());
  for (const fs::path& g : guarded)
    if (is_within(g, target_))
      throw InputError("--out: refusing to write the output over " + display_ + ": it contains " + g.string());

  repair_after_kill();
  std::error_code ec;
  if (fs::exists(target_, ec)) {
    if (!fs::is_directory(target_, ec)) throw InputError("--out: " + display_ + " exists and is not a folder");
    if (!overwrite_) throw InputError("--out: " + display_ + " already exists (give --overwrite to replace it)");
    // --overwrite replaces earlier output, never an arbitrary folder.
    if (!fs::is_empty(target_, ec) && !fs::exists(target_ / kManifestFile, ec))
      throw InputError("--out: " + display_ +
                       " is not empty and holds no manifest.json, so it is not a Scout output folder; not replaced");
  }
  const fs::path parent = target_.parent_path();
  fs::create_directories(parent, ec);
  if (ec) throw InputError("--out: cannot create " + parent.string() + ": " + ec.message());
  // A staging folder beside the target (same file system, so the final rename is atomic).
  staging_ = core::stamped_path_beside(target_, "partial");
  fs::create_directory(staging_, ec);
  if (ec) throw InputError("--out: cannot create " + staging_.string() + ": " + ec.message());
}

// A killed run leaves its staging folder (never mistaken for output: it is hidden and named
// .partial); a run killed between the two renames of a replacement leaves the previous output
// aside as .old and none in place. Both are dead processes' entries, told apart by the process
// id in their names: the staging folders go, and the previous output returns to its place.
void OutputDir::repair_after_kill() {
  core::remove_stale_beside(target_, "partial");
  const std::string old_prefix = fmt::format(".{}.old", target_.filename().string());
  std::vector<fs::path> aside = core::stale_entries(target_.parent_path(), old_prefix);
  std::error_code ec;
  if (!aside.empty() && !fs::exists(target_, ec)) {
    fs::rename(aside.back(), target_, ec);
    if (!ec) aside.pop_back();
  }
  for (const fs::path& stale : aside) fs::remove_all(stale, ec);
}

OutputDir::~OutputDir() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(staging_, ec);
  }
}

void OutputDir::commit() {
  std::error_code ec;
  // The staging folder's entries reach the disk before it is renamed into place, and the rename
  // after (the files themselves were synced as they were written).
  core::sync_directory(staging_);
  if (!fs::exists(target_, ec)) {
    fs::rename(staging_, target_, ec);
    if (ec) throw InputError("--out: cannot move the results to " + display_ + ": " + ec.message());
    committed_ = true;
    core::sync_directory(target_.parent_path().empty() ? fs::path(".") : target_.parent_path());
    return;
  }
  if (!overwrite_) throw InputError("--out: " + display_ + " appeared while running; not replaced");
  if (!fs::is_empty(target_, ec) && !fs::exists(target_ / kManifestFile, ec))
    throw InputError("--out: " + display_ + " changed while running and holds no manifest.json; not replaced");
  // Old output aside, new output in, old output gone: at every moment one complete folder exists.
  const fs::path old = core::stamped_path_beside(target_, "old");
  fs::rename(target_, old, ec);
  if (ec) throw InputError("--out: cannot replace " + display_ + ": " + ec.message());
  core::fault_point("output-commit");  // the hard-kill tests' moment between the two renames
  fs::rename(staging_, target_, ec);
  if (ec) {
    std::error_code restore;
    fs::rename(old, target_, restore);
    throw InputError("--out: cannot move the results to " + display_ + ": " + ec.message());
  }
  committed_ = true;
  core::sync_directory(target_.parent_path().empty() ? fs::path(".") : target_.parent_path());
  fs::remove_all(old, ec);
}

std::unique_ptr<learn::RolloutEngine> make_engine(const worlds::World& world, const grid::FloorFrame& frame,
                                                  int robots) {
  try {
    return std::make_unique<learn::RolloutEngine>(world, frame, robots);
  } catch (const std::runtime_error& e) {
    throw InputError(std::string("the camera cannot start: ") + e.what());
  }
}

std::vector<std::string> command_line(int argc, char** argv) { return {argv, argv + argc}; }

nlohmann::ordered_json make_manifest(const std::vector<std::string>& argv, const std::string& world_yaml,
                                     const std::vector<fs::path>& data_files, const std::string& gl_description) {
  nlohmann::ordered_json m;
  m["command_line"] = argv;
  m["git_commit"] = git_commit();
  m["scout_version"] = SCOUT_VERSION;
  m["created_utc"] = fmt::format("{:%Y-%m-%dT%H:%M:%SZ}",
                                 fmt::gmtime(std::chrono::system_clock::to_time_t(std::chrono::system_clock::now())));
  // Versions of the Debian packages found at configure time (Box2D 2.4.1's own b2_version still
  // says 2.4.0, so the package's version is the one to trust).
  nlohmann::ordered_json libs;
  libs["box2d"] = SCOUT_BOX2D_VERSION;
  libs["opencv"] = SCOUT_OPENCV_VERSION;
  libs["eigen"] = fmt::format("{}.{}.{}", EIGEN_WORLD_VERSION, EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION);
  libs["yaml-cpp"] = SCOUT_YAML_CPP_VERSION;
  libs["nlohmann_json"] =
      fmt::format("{}.{}.{}", NLOHMANN_JSON_VERSION_MAJOR, NLOHMANN_JSON_VERSION_MINOR, NLOHMANN_JSON_VERSION_PATCH);
  libs["cli11"] = SCOUT_CLI11_VERSION;
  libs["fmt"] = fmt::format("{}.{}.{}", FMT_VERSION / 10000, FMT_VERSION / 100 % 100, FMT_VERSION % 100);
  libs["zlib"] = SCOUT_ZLIB_VERSION;
  libs["openssl"] = SCOUT_OPENSSL_VERSION;
  libs["libtorch"] = SCOUT_TORCH_VERSION;
  if (!gl_description.empty()) libs["gl"] = gl_description;
  m["libraries"] = libs;
  if (!world_yaml.empty()) m["world"] = world_yaml;
  nlohmann::ordered_json hashes = nlohmann::ordered_json::object();
  for (const fs::path& f : data_files) hashes[fs::absolute(f).lexically_normal().string()] = core::sha256_hex(f);
  m["data_sha256"] = hashes;
  return m;
}

void check_output_file(const char* option, const std::string& file, const std::vector<std::string>& inputs) {
  if (file.empty()) return;
  std::error_code ec;
  if (fs::is_directory(file, ec))
    throw InputError(fmt::format("{}: {} is a folder, expected a file name", option, file));
  for (const std::string& input : inputs)
    if (!input.empty() && fs::equivalent(file, input, ec))
      throw InputError(fmt::format("{}: {}: expected a file other than the inputs", option, file));
  const fs::path probe = fs::path(file).parent_path() / fmt::format(".scout-probe-{}", ::getpid());
  const bool writable = static_cast<bool>(std::ofstream(probe));
  fs::remove(probe, ec);
  if (!writable) throw InputError(fmt::format("{}: cannot write {}", option, file));
}

nlohmann::ordered_json eval_document(const std::string& report_json, const std::vector<std::string>& argv,
                                     const fs::path& checkpoint, const fs::path& images, const fs::path& labels,
                                     int world_size) {
  nlohmann::ordered_json j = nlohmann::ordered_json::parse(report_json);
  j["manifest"] = make_manifest(argv, "", {images, labels}, "");
  j["manifest"]["checkpoint_sha256"] = core::sha256_hex(learn::resolve_checkpoint(checkpoint));
  j["manifest"]["world_size"] = world_size;
  return j;
}

}  // namespace scout::tools
