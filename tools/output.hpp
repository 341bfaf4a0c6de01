#pragma once
// Output folders and files of the CLI: written to a staging folder and moved into place at the
// end, so that a failed or interrupted command never leaves a half-written --out folder.
#include <filesystem>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "core/files.hpp"

namespace scout::tools {

/// The manifest every output folder of Scout holds (and what marks a folder as Scout's).
inline constexpr const char* kManifestFile = "manifest.json";

/// An output folder being written. `path()` is where to write; commit() moves it to its final
/// place (replacing an old one only when overwriting was allowed).
class OutputDir {
 public:
  /// Refuses (InputError) an existing `target` unless `overwrite`, and with `overwrite` refuses a
  /// non-empty folder that holds no manifest.json (not Scout's output). Never writes over the
  /// current folder or a folder holding any of `keep` (the inputs).
  OutputDir(std::filesystem::path target, bool overwrite, const std::vector<std::filesystem::path>& keep = {});
  ~OutputDir();
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;

  const std::filesystem::path& path() const { return staging_; }
  /// The folder as the user named it (for messages).
  const std::string& target() const { return display_; }
  void commit();

 private:
  void repair_after_kill();
  std::string display_;
  std::filesystem::path target_;
  std::filesystem::path staging_;
  bool overwrite_;
  bool committed_ = false;
};

/// Writes a file atomically: a temporary file beside it, then a rename.
using core::write_file_atomic;

/// Refuses, before minutes of work, an output file (`option`'s value; empty: nothing to check)
/// that is a folder, one of `inputs`, or in a place that cannot be written. The probe file has a
/// name of its own, so no file of the user's is touched.
void check_output_file(const char* option, const std::string& file, const std::vector<std::string>& inputs = {});

/// The manifest every output folder gets: command line, git commit, library versions, the
/// resolved world (YAML text, may be empty) and the SHA-256 of each data file.
nlohmann::ordered_json make_manifest(const std::vector<std::string>& argv, const std::string& world_yaml,
                                     const std::vector<std::filesystem::path>& data_files,
                                     const std::string& gl_description);

/// An evaluation's JSON file (what `scout eval --json` and `scout report` write): the report
/// (learn::report_json) with a manifest naming the digits, the checkpoint's SHA-256 (so a report
/// never pairs it with another model) and the processes that evaluated it.
nlohmann::ordered_json eval_document(const std::string& report_json, const std::vector<std::string>& argv,
                                     const std::filesystem::path& checkpoint, const std::filesystem::path& images,
                                     const std::filesystem::path& labels, int world_size);

/// The command line as one string, for manifests.
std::vector<std::string> command_line(int argc, char** argv);

}  // namespace scout::tools
