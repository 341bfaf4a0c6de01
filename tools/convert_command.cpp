// scout convert: a checkpoint or model of Scout's format 1 (.pt: LibTorch's zip of pickles) to
// format 2 (.safetensors), once, for a file the user trusts. Nothing else in Scout reads .pt.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "core/error.hpp"
#include "learn/checkpoint.hpp"
#include "learn/trainer.hpp"
#include "tools/commands.hpp"
#include "tools/output.hpp"

namespace scout::tools {

namespace {

namespace fs = std::filesystem;

struct ConvertOptions {
  std::string legacy, out;
  bool trusted = false, overwrite = false;
};

// The manifest that came with a .pt file: RUN/manifest.json beside a run's checkpoint.pt, or
// X-manifest.json beside X.pt (how models/ keeps them). Empty where there is none.
std::string manifest_beside(const fs::path& legacy) {
  std::error_code ec;
  const fs::path folder = legacy.parent_path();
  for (const fs::path& candidate : {folder / kManifestFile, folder / (legacy.stem().string() + "-manifest.json")}) {
    if (legacy.filename() != "checkpoint.pt" && candidate.filename() == kManifestFile) continue;
    if (!fs::is_regular_file(candidate, ec)) continue;
    std::ifstream in(candidate);
    std::stringstream text;
    text << in.rdbuf();
    const nlohmann::json manifest = nlohmann::json::parse(text.str(), nullptr, /*allow_exceptions=*/false);
    if (!manifest.is_object()) throw InputError(candidate.string() + ": expected a JSON object (the manifest)");
    return manifest.dump();
  }
  return "";
}

void convert_command(const ConvertOptions& o) {
  std::error_code ec;
  const fs::path legacy = fs::is_directory(o.legacy, ec) ? fs::path(o.legacy) / "checkpoint.pt" : fs::path(o.legacy);
  if (!fs::exists(legacy, ec))
    throw InputError(legacy.string() + ": no such file (expected a .pt checkpoint or model)");
  if (!o.trusted)
    throw InputError(legacy.string() +
                     ": reading a .pt file runs LibTorch's unpickler, which trusts its input (a crafted file can "
                     "crash it or run code); add --trusted if you made this file or trust who did");
  const fs::path out =
      o.out.empty() ? fs::path(legacy).replace_extension(learn::kCheckpointExtension) : fs::path(o.out);
  if (fs::exists(out, ec)) {
    if (fs::is_directory(out, ec)) throw InputError("--out: " + out.string() + " is a folder, expected a file name");
    if (!o.overwrite) throw InputError("--out: " + out.string() + " exists (add --overwrite to replace it)");
  }
  if (out.extension() != learn::kCheckpointExtension)
    throw InputError("--out: " + out.string() + ": expected a file name ending in " + learn::kCheckpointExtension);
  const fs::path parent = out.parent_path();
  if (!parent.empty() && !fs::is_directory(parent, ec))
    throw InputError("--out: " + out.string() + ": the folder " + parent.string() + " does not exist");
  const std::string manifest = manifest_beside(legacy);
  const learn::CheckpointInfo info = learn::convert_legacy_checkpoint(legacy, out, manifest);
  fmt::print("converted: {} -> {} ({} bytes, format {}; {} epoch(s) of training{}{})\n", legacy.string(), out.string(),
             fs::file_size(out), info.format_version, info.history.size(),
             info.cursor.stage == learn::Stage::Done ? "" : ", resumable",
             manifest.empty() ? "" : ", with its manifest");
}

}  // namespace

void add_convert_command(CLI::App& app, const Context& /*context*/) {
  auto o = std::make_shared<ConvertOptions>();
  auto* cmd = app.add_subcommand(
      "convert",
      "Converts a checkpoint or model of Scout's older format (.pt, LibTorch's pickles) to .safetensors, the "
      "only format Scout reads: the same weights, Adam's state and schedule (a converted run resumes as before).");
  cmd->add_option("FILE", o->legacy, "A .pt model file, or a run folder holding checkpoint.pt")->required();
  cmd->add_option("--out", o->out, "The file to write (default: FILE with the extension .safetensors)");
  cmd->add_flag("--trusted", o->trusted,
                "Required: you trust FILE (LibTorch's reader of .pt files trusts its input; Scout no longer checks "
                "it)");
  cmd->add_flag("--overwrite", o->overwrite, "Replace an existing output file");
  cmd->callback([o] { convert_command(*o); });
}

}  // namespace scout::tools
