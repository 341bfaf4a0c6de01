// scout export: a model file from a training run (weights, config and metrics history, without
// the optimizer's state), small enough to commit, e.g. models/mnist.safetensors.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <memory>
#include <string>

#include "core/error.hpp"
#include "learn/checkpoint.hpp"
#include "learn/trainer.hpp"
#include "tools/commands.hpp"

namespace scout::tools {

namespace {

namespace fs = std::filesystem;

struct ExportOptions {
  std::string checkpoint, out;
  bool overwrite = false;
};

void export_command(const ExportOptions& o) {
  const fs::path source = learn::resolve_checkpoint(o.checkpoint);
  std::error_code ec;
  if (fs::exists(o.out, ec)) {
    if (fs::is_directory(o.out, ec)) throw InputError("--out: " + o.out + " is a folder, expected a file name");
    if (!o.overwrite) throw InputError("--out: " + o.out + " exists (add --overwrite to replace it)");
    if (fs::equivalent(o.out, source, ec)) throw InputError("--out: " + o.out + " is the checkpoint itself");
  }
  if (fs::path(o.out).extension() != learn::kCheckpointExtension)
    throw InputError("--out: " + o.out + ": expected a file name ending in " + learn::kCheckpointExtension);
  const fs::path parent = fs::path(o.out).parent_path();
  if (!parent.empty() && !fs::is_directory(parent, ec))
    throw InputError("--out: " + o.out + ": the folder " + parent.string() + " does not exist");
  const learn::CheckpointInfo info = learn::export_model(learn::open_checkpoint(source), o.out);
  fmt::print("model: {} ({} bytes; {} epoch(s) of training, from {})\n", o.out, fs::file_size(o.out),
             info.history.size(), source.string());
  const learn::TrainConfig& c = info.config;
  const agent::NetworkConfig& n = c.network;
  // What a stranger needs to drive the model: a team's size, and the occupancy channel its planners read.
  const std::string team = c.world.team.single() ? "" : fmt::format(", K = {} robots a team", c.world.team.robots);
  fmt::print("task: m = {}, E = {}, T = {}, step {} px{}; N = {}, B = {}; planners {}, classifier {}, {}\n",
             c.world.camera.patch_px, c.world.task.episodes, c.world.task.steps, c.world.task.step_px, team, c.rollouts,
             c.batch_images, agent::describe_planners(n), agent::describe_classifier(n), agent::to_string(c.precision));
}

}  // namespace

void add_export_command(CLI::App& app, const Context& /*context*/) {
  auto o = std::make_shared<ExportOptions>();
  auto* cmd = app.add_subcommand(
      "export", "Writes a model file from a training run: weights, config and metrics history, no optimizer state.");
  cmd->add_option("CHECKPOINT", o->checkpoint, "A run folder or checkpoint file")->required();
  cmd->add_option("--out", o->out, "The model file to write, e.g. models/mnist.safetensors")->required();
  cmd->add_flag("--overwrite", o->overwrite, "Replace an existing model file");
  cmd->callback([o] { export_command(*o); });
}

}  // namespace scout::tools
