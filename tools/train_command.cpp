// scout train: the hierarchical training schedule with the physics and the camera in the loop,
// checkpointed every epoch into a run folder (learn/trainer.hpp).
#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/digest.hpp"
#include "core/error.hpp"
#include "core/folder_lock.hpp"
#include "learn/auto_precision.hpp"
#include "learn/checkpoint.hpp"
#include "learn/distributed.hpp"
#include "learn/trainer.hpp"
#include "tools/commands.hpp"
#include "tools/group.hpp"
#include "tools/network_options.hpp"
#include "tools/output.hpp"
#include "tools/progress.hpp"
#include "worlds/dataset.hpp"

namespace scout::tools {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

struct TrainOptions {
  std::string world;
  std::string out;
  std::string resume;
  std::string data_root;
  std::string init_from;    // a model or checkpoint whose weights a new run starts from
  SettingOptions settings;  // the training settings (learn::train_settings())
  int threads = 0;
  GroupFlags group;
  bool allow_nproc_change = false;
  bool force = false;
  double checkpoint_every_min = 5;
};

// Prints progress on one line that overwrites itself on a terminal; elsewhere (logs, CI) one
// line every 30 seconds, so logs stay readable.
class ProgressPrinter {
 public:
  ProgressPrinter() : tty_(isatty(fileno(stderr)) != 0) {}
  void show(const learn::Progress& p) {
    const auto now = std::chrono::steady_clock::now();
    if (!tty_ && now - last_ < std::chrono::seconds(30) && p.batch != p.batches) return;
    last_ = now;
    const std::string line = fmt::format("mode {:<3} epoch {}/{}  batch {}/{}  {:.1f} images/s  reward {:.3f}  ETA {}",
                                         learn::to_string(p.stage), p.epoch, p.epochs, p.batch, p.batches,
                                         p.images_per_s, p.reward, format_duration(p.eta_s));
    if (tty_) {
      std::fprintf(stderr, "\r%-90s", line.c_str());
      pending_ = true;
    } else {
      std::fprintf(stderr, "%s\n", line.c_str());
    }
    std::fflush(stderr);
  }
  void end_line() {
    if (pending_) std::fprintf(stderr, "\r%-90s\r", "");
    pending_ = false;
  }

 private:
  bool tty_;
  bool pending_ = false;
  std::chrono::steady_clock::time_point last_{};
};

// A resumed run keeps its config: an option given again must agree with it (the settings the
// schema table marks OnResume::Kept), and WORLD given again must be the run's world.
void check_resume_options(const TrainOptions& o, const learn::TrainConfig& c, const learn::TrainConfig& asked,
                          const std::string& run) {
  for (const learn::TrainSetting& s : learn::train_settings()) {
    if (s.on_resume != learn::OnResume::Kept || !o.settings.given(s)) continue;
    const std::string stored = learn::setting_text(c, s), wanted = learn::setting_text(asked, s);
    if (stored != wanted)
      throw InputError(
          fmt::format("{}: the run at {} was trained with {}, the command line asks for {} (a resumed run "
                      "keeps its config; start a new run to change it)",
                      s.option, run, stored, wanted));
  }
  if (!o.world.empty()) {
    worlds::World w = worlds::load_world(o.world);
    w.seed = c.world.seed;
    if (worlds::to_yaml(w) != worlds::to_yaml(c.world))
      throw InputError(o.world + ": differs from the world the run at " + run +
                       " was trained on (a resumed run keeps its world; omit WORLD or start a new run)");
  }
}

// The precision a resumed run continues in. A run continues in its own precision, bit for bit,
// except a bf16 run on a CPU without native bf16, where bf16 would be emulated several times
// slower (and trains differently): that needs --precision, fp32 to continue in fp32 (no longer bit
// for bit) or bf16 to continue emulated. --precision may always change it; auto is this CPU's.
std::optional<agent::Precision> resume_precision(const TrainOptions& o, const learn::TrainConfig& c,
                                                 const std::string& run) {
  if (o.settings.given("precision")) {
    o.settings.announce_precision();  // also warns when bf16 would be emulated
    return learn::resolve_precision(agent::parse_precision(o.settings.precision()));
  }
  const agent::NativeBf16 cpu = agent::native_bf16();
  if (c.precision == agent::Precision::BFloat16 && !cpu.any()) {
    const std::string why =
        cpu.capped_by.empty() ? "this CPU has no native bf16 instructions" : cpu.capped_by + " leaves no native bf16";
    const std::string emulated =
        agent::bf16_unavailable().empty() ? ", or --precision bf16 to continue emulated (several times slower)" : "";
    throw InputError(fmt::format(
        "--precision: the run at {} trains in bf16 and {}; resume with --precision fp32 to continue in fp32 (not "
        "bit for bit){}",
        run, why, emulated));
  }
  return std::nullopt;
}

// The data a resumed run reads: its own folder, or --data (the same data, moved). Every data file
// read must have a SHA-256 that the run's manifest recorded, so changed data is never trained on
// silently.
fs::path resume_data_folder(const TrainOptions& o, const learn::TrainConfig& c, const fs::path& run) {
  const fs::path folder =
      o.data_root.empty() ? c.data_folder : worlds::dataset_folder(c.world.floor.dataset, o.data_root);
  const std::string what = o.data_root.empty() ? c.data_folder.string() : "--data: " + folder.string();
  std::set<std::string> recorded;
  try {
    std::ifstream in(run / kManifestFile);
    const json manifest = json::parse(in);
    for (const auto& [file, hash] : manifest.at("data_sha256").items()) recorded.insert(hash.get<std::string>());
  } catch (const std::exception&) {
    throw InputError(what + ": " + (run / kManifestFile).string() +
                     " has no readable data_sha256 to check the run's data against");
  }
  std::vector<fs::path> files = worlds::load_split(folder, worlds::Split::Train).files;
  for (const fs::path& f : worlds::load_split(folder, worlds::Split::Validation).files) files.push_back(f);
  for (const fs::path& f : files)
    if (!recorded.count(core::sha256_hex(f)))
      throw InputError(f.string() + ": not one of the data files the run at " + run.string() +
                       " was trained on (its SHA-256 is not in manifest.json)");
  return folder;
}

// Writes RUN/manifest.json and returns its text (the checkpoints hold it too).
std::string write_manifest(const fs::path& run, const Context& context, const learn::Trainer& trainer, bool resumed,
                           const std::string& init_from) {
  json manifest = make_manifest(context.argv, worlds::to_yaml(trainer.config().world), trainer.data_files(), "");
  const fs::path file = run / kManifestFile;
  // A resumed run keeps the first manifest and records each resumption under "resumed".
  if (resumed && fs::exists(file)) {
    try {
      std::ifstream in(file);
      json first = json::parse(in);
      first["resumed"].push_back({{"command_line", manifest["command_line"]},
                                  {"git_commit", manifest["git_commit"]},
                                  {"created_utc", manifest["created_utc"]},
                                  {"torch_threads", trainer.threads()},
                                  {"world_size", trainer.world_size()},
                                  {"epochs", trainer.config().epochs},
                                  {"learning_rate", trainer.config().learning_rate},
                                  {"precision", agent::to_string(trainer.config().precision)}});
      write_file_atomic(file, first.dump(2) + "\n");
      return first.dump();
    } catch (const std::exception&) {
      // An unreadable manifest is replaced by a fresh one below.
    }
  }
  manifest["torch_threads"] = trainer.threads();
  manifest["world_size"] = trainer.world_size();
  manifest["config"] = json::parse(trainer.config().to_json());
  if (!init_from.empty()) {  // the weights the run started from, as the data: by path and SHA-256
    const fs::path model = learn::resolve_checkpoint(init_from);
    manifest["init_from"] = {{"file", fs::absolute(model).string()}, {"sha256", core::sha256_hex(model)}};
  }
  manifest["outputs"] = {{"checkpoint", learn::kCheckpointFile}, {"metrics", learn::kMetricsFile}};
  write_file_atomic(file, manifest.dump(2) + "\n");
  return manifest.dump();
}

// The config a new run's command line asks for (every rank of a group builds it, to compare).
// The library's defaults (learn::TrainConfig's) are the command's.
// --init-from: the model's networks are the new run's; a network option given as well must agree.
void take_init_networks(const TrainOptions& o, const learn::Checkpoint& init, learn::TrainConfig& config) {
  const learn::TrainConfig& model = init.info().config;
  // The changes allowed: an occupancy channel or a goal context branch added to a model without one
  // (the weights that read them start at zero).
  const bool adds_occupancy = config.network.occupancy && !model.network.occupancy;
  const bool adds_context = config.network.goal_context > 0 && model.network.goal_context == 0;
  const bool drops_actions = config.network.goals_only && !model.network.goals_only;
  const bool adds_team = config.network.team_channels && !model.network.team_channels;
  const bool adds_wide = config.network.wide_view && !model.network.wide_view;
  const bool adds_routes = config.network.free_routes && !model.network.free_routes;
  for (const learn::TrainSetting& s : learn::train_settings()) {
    if (s.section != "network" || !o.settings.given(s) || (adds_occupancy && s.key == "occupancy") ||
        (adds_context && s.key == "goal_context") || (drops_actions && s.key == "goals_only") ||
        (adds_team && s.key == "team_channels") || (adds_wide && s.key == "wide_view") ||
        (adds_routes && s.key == "free_routes"))
      continue;
    const std::string has = learn::setting_text(model, s), asked = learn::setting_text(config, s);
    if (has != asked)
      throw InputError(
          fmt::format("{}: --init-from {} has {}, the command line asks for {} (a run started from a "
                      "model keeps its networks, but may add --occupancy, --team-channels, --wide-view, --goal-context "
                      "or --free-routes, or "
                      "drop its action planner with --goals-only; leave {} out)",
                      s.option, o.init_from, has, asked, s.option));
  }
  const int goal_context = config.network.goal_context;
  config.network = model.network;
  config.network.occupancy = model.network.occupancy || adds_occupancy;
  if (adds_context) config.network.goal_context = goal_context;
  config.network.goals_only = model.network.goals_only || drops_actions;
  config.network.team_channels = model.network.team_channels || adds_team;
  config.network.wide_view = model.network.wide_view || adds_wide;
  config.network.free_routes = model.network.free_routes || adds_routes;
}

learn::TrainConfig new_run_config(const TrainOptions& o, const learn::Checkpoint* init) {
  learn::TrainConfig config = o.settings.applied_to(learn::TrainConfig{});
  if (init) take_init_networks(o, *init, config);
  config.world = worlds::load_world(o.world);
  if (o.settings.given("seed")) config.world.seed = config.seed;  // --seed overrides the world file's
  config.seed = config.world.seed;
  if (config.world.floor.dataset.empty())
    throw InputError(o.world + ": floor.dataset: training needs a data set (a PNG floor has no labels)");
  const fs::path data_root = o.data_root.empty() ? worlds::default_data_root() : fs::path(o.data_root);
  config.data_folder = fs::absolute(worlds::dataset_folder(config.world.floor.dataset, data_root));
  config.precision = learn::resolve_precision(config.precision);
  config.validate(setting_option);
  const std::array<int, 3>& epochs = config.epochs;
  if (config.pretrain_epochs + epochs[0] + epochs[1] + epochs[2] == 0)
    throw InputError("--epochs: nothing to train (every stage has 0 epochs); expected at least one epoch");
  return config;
}

// --init-from's file: a model (scout export) or a checkpoint, or a run folder's checkpoint.safetensors.
learn::Checkpoint open_init_model(const TrainOptions& o) {
  return learn::open_checkpoint(learn::resolve_checkpoint(o.init_from));
}

// A run's processes split each batch's images evenly, an image's N rollouts in one process.
void check_batch_split(int batch_images, int world_size) {
  if (batch_images % world_size != 0)
    throw InputError(
        fmt::format("--batch: B = {} images do not divide evenly over {} processes (each drives B / "
                    "{} images and their N rollouts); choose B a multiple of {}",
                    batch_images, world_size, world_size, world_size));
}

// Rank 0's (or a lone process's) trainer: a new run in a new folder, or the run resumed.
std::unique_ptr<learn::Trainer> open_trainer(const TrainOptions& o, const fs::path& run, int threads, int world_size) {
  if (!o.resume.empty()) {
    if (!fs::is_regular_file(run / learn::kCheckpointFile)) {
      if (fs::is_regular_file(run / "checkpoint.pt"))
        throw InputError("--resume: " + o.resume +
                         " holds a checkpoint.pt of Scout's older format; if you trust it, convert it once (scout "
                         "convert " +
                         o.resume + " --trusted), then resume");
      throw InputError("--resume: " + o.resume +
                       " holds no checkpoint.safetensors (expected a folder written by scout train)");
    }
    if (!core::take_folder_for_this_process(run))
      throw InputError("--resume: " + o.resume +
                       ": another scout train is writing this run; resume it once that one has ended");
    // Opened once: read, checked and parsed here, and the trainer continues from it.
    const learn::Checkpoint checkpoint = learn::open_checkpoint(run / learn::kCheckpointFile);
    const learn::CheckpointInfo& info = checkpoint.info();
    const learn::TrainConfig asked = o.settings.applied_to(info.config);
    check_resume_options(o, info.config, asked, o.resume);
    if (info.world_size != world_size && !o.allow_nproc_change)
      throw InputError(fmt::format(
          "--nproc: the run at {} trained with {} process(es), this resume has {}; resume with --nproc {} to continue "
          "it exactly, or add --allow-nproc-change (the gradient sums change order: weights then agree to about 1e-5, "
          "not bit for bit)",
          o.resume, info.world_size, world_size, info.world_size));
    check_batch_split(info.config.batch_images, world_size);
    const fs::path data_folder = resume_data_folder(o, info.config, run);
    // --lr on resume sets the rate from the next batch on (metrics.csv records each epoch's rate).
    const bool lr_given = o.settings.given("learning_rate");
    const double lr = asked.learning_rate;
    learn::ResumeOptions resume;
    if (o.settings.given("epochs")) resume.epochs = asked.epochs;
    resume.data_folder = data_folder;
    if (lr_given) resume.learning_rate = lr;
    const bool distill_given = o.settings.given("distillation");
    if (distill_given) resume.distillation = asked.distillation;
    resume.precision = resume_precision(o, info.config, o.resume);
    auto trainer = learn::Trainer::resume(checkpoint, run, threads, resume);
    if (lr_given && lr != info.config.learning_rate && !trainer->finished())
      fmt::print("learning rate {} -> {} from the next batch on\n", info.config.learning_rate, lr);
    if (distill_given && asked.distillation != info.config.distillation && !trainer->finished())
      fmt::print("full-image teacher's weight {} -> {} from the next batch on\n", info.config.distillation,
                 asked.distillation);
    if (resume.precision && *resume.precision != info.config.precision && !trainer->finished())
      fmt::print("precision {} -> {} from the next batch on (not bit for bit what {} would give)\n",
                 agent::to_string(info.config.precision), agent::to_string(*resume.precision),
                 agent::to_string(info.config.precision));
    return trainer;
  }
  // Opened once: its networks make the config, and the trainer starts from its weights.
  std::optional<learn::Checkpoint> init;
  if (!o.init_from.empty()) init = open_init_model(o);
  const learn::TrainConfig config = new_run_config(o, init ? &*init : nullptr);
  check_batch_split(config.batch_images, world_size);
  std::error_code ec;
  // Created here, not found: of two runs started on one folder at once, exactly one creates it.
  const fs::path folder = run.has_filename() ? run : run.parent_path();  // "runs/x/" is runs/x
  if (folder.has_parent_path()) fs::create_directories(folder.parent_path(), ec);
  if (!fs::create_directory(folder, ec)) {
    if (ec) throw InputError(fmt::format("--out: {}: cannot create ({})", o.out, ec.message()));
    throw InputError("--out: " + o.out + " exists (continue it with --resume " + o.out + ", or name a new folder)");
  }
  // A resume of the new run cannot start before it has a checkpoint; the lock keeps it out after.
  core::take_folder_for_this_process(run);
  try {
    return std::make_unique<learn::Trainer>(config, run, threads, o.force, init ? &*init : nullptr);
  } catch (...) {
    fs::remove_all(run, ec);
    throw;
  }
}

// A run's processes and trainer: one process, or this rank of a group (which holds the group).
struct OpenedRun {
  std::unique_ptr<learn::ProcessGroup> group;
  std::unique_ptr<learn::Trainer> trainer;
};

// This rank's trainer in a data-parallel run: rank 0 opens the run, the others compare what their
// own command line asks for with it; on a resume they take rank 0's config, and read the data
// from --data or the run's own data path.
OpenedRun open_group_run(const TrainOptions& o, const fs::path& run, const learn::GroupOptions& options) {
  const bool resuming = !o.resume.empty();
  OpenedRun opened;
  set_rank(options.rank);
  opened.group = learn::ProcessGroup::connect(options);
  learn::ProcessGroup& group = *opened.group;
  const int threads = threads_per_process(o.threads);
  std::optional<learn::TrainConfig> own;
  std::optional<fs::path> data_folder;
  if (group.rank() != 0 && !resuming) {
    std::optional<learn::Checkpoint> init;
    if (!o.init_from.empty()) init = open_init_model(o);
    own = new_run_config(o, init ? &*init : nullptr);
    data_folder = own->data_folder;
  } else if (group.rank() != 0 && !o.data_root.empty()) {
    data_folder = fs::path(o.data_root);
  }
  const bool created = group.rank() == 0 && !resuming;
  try {
    opened.trainer = learn::Trainer::distribute(
        group, threads, [&] { return open_trainer(o, run, threads, group.size()); }, own, data_folder);
  } catch (const learn::LeaderFailed&) {
    throw ExitStatus{1};  // rank 0 said why
  } catch (...) {
    // A new run that never started leaves no folder behind (rank 0 had created it).
    std::error_code ec;
    if (created && !fs::exists(run / learn::kCheckpointFile, ec)) fs::remove_all(run, ec);
    throw;
  }
  return opened;
}

// What the leader prints before training: the run and its settings, and where a resume goes on.
void print_run_header(const learn::Trainer& trainer, const fs::path& run, bool resuming) {
  const learn::TrainConfig& c = trainer.config();
  fmt::print("training {} -> {} ({}{} LibTorch threads, {}; planner {}, classifier {}; N = {}, B = {}, lr {})\n",
             c.world.file.string(), run.string(),
             trainer.world_size() > 1 ? fmt::format("{} processes x ", trainer.world_size()) : "", trainer.threads(),
             agent::to_string(c.precision), agent::describe_planners(c.network), agent::describe_classifier(c.network),
             c.rollouts, c.batch_images, c.learning_rate);
  if (resuming) {
    const learn::ScheduleCursor& k = trainer.cursor();
    fmt::print("resuming after {} epoch(s) (stage {}, epoch {}, batch {})\n", trainer.history().size(),
               learn::to_string(k.stage), k.epoch, k.batch);
  }
  std::fflush(stdout);
}

// One line per epoch. A baseline a mode does not have (learned goals before mode ii) is "-", as
// metrics.csv leaves it empty; never a 0 that reads as a measurement.
void print_epoch(const learn::EpochMetrics& m) {
  const auto figure = [](const std::optional<double>& v) { return v ? fmt::format("{:.4f}", *v) : "-"; };
  fmt::print(
      "mode {:<3} epoch {:>3}: reward {:.4f}  loss {:.4f}  train {:.4f}  validation {:.4f} (i.i.d. {}, "
      "goals only {}, full images {})  {:.1f} images/s  {:.1f} s\n",
      learn::to_string(m.stage), m.epoch, m.reward, m.loss, m.train_accuracy, m.validation_accuracy,
      figure(m.validation_iid), figure(m.validation_goals_only), figure(m.validation_full_image), m.images_per_s,
      m.seconds);
  std::fflush(stdout);
}

void train_command(const TrainOptions& o, const Context& context) {
  const bool resuming = !o.resume.empty();
  if (resuming && !o.out.empty() && fs::path(o.out) != fs::path(o.resume))
    throw InputError("--out: a resumed run writes into its own folder (" + o.resume + "); leave --out out");
  if (resuming && !o.init_from.empty())
    throw InputError("--init-from: a resumed run continues from its own checkpoint; --init-from starts a new run");
  if (!resuming && o.world.empty()) throw InputError("WORLD: a world file is required (or --resume RUN)");
  if (!resuming && o.out.empty()) throw InputError("--out: a run folder is required (or --resume RUN)");
  const fs::path run = resuming ? fs::path(o.resume) : fs::path(o.out);
  const std::optional<learn::GroupOptions> group_options = group_from_flags(o.group);
  OpenedRun opened;
  if (group_options)
    opened = open_group_run(o, run, *group_options);
  else
    opened.trainer = open_trainer(o, run, o.threads, 1);
  learn::Trainer& trainer = *opened.trainer;

  const bool leader = trainer.rank() == 0;
  if (resuming && trainer.finished()) {
    if (leader)
      fmt::print("the run's schedule is complete after {} epoch(s); nothing to do (a longer --epochs continues it)\n",
                 trainer.history().size());
    return;
  }
  ProgressPrinter progress;
  learn::TrainHooks hooks;
  hooks.stop = interrupt_token();
  hooks.checkpoint_every = std::chrono::milliseconds(std::llround(o.checkpoint_every_min * 60000));
  if (leader) {
    if (!resuming) o.settings.announce_precision();
    trainer.set_manifest(write_manifest(run, context, trainer, resuming, o.init_from));
    print_run_header(trainer, run, resuming);
    hooks.on_progress = [&](const learn::Progress& p) { progress.show(p); };
    hooks.on_epoch = [&](const learn::EpochMetrics& m) {
      progress.end_line();
      print_epoch(m);
    };
  }
  const learn::TrainResult result = trainer.run(hooks);
  progress.end_line();
  switch (result.outcome) {
    case learn::TrainOutcome::Finished:
      if (leader)
        fmt::print("checkpoint: {}\nmetrics:    {}\n", (run / learn::kCheckpointFile).string(),
                   (run / learn::kMetricsFile).string());
      return;
    case learn::TrainOutcome::NonFinite:
      throw InputError(result.message);
  }
}

}  // namespace

void add_train_command(CLI::App& app, const Context& context) {
  auto o = std::make_shared<TrainOptions>();
  auto* cmd = app.add_subcommand(
      "train",
      "Train the agent (METHOD.md): optional full-image pretraining, then modes (i) -> (ii) -> (iii), with the "
      "physics and the camera in the loop. Writes RUN/checkpoint.safetensors every epoch, RUN/metrics.csv, "
      "RUN/manifest.json.");
  cmd->add_option("world", o->world, "World file (YAML), e.g. worlds/mnist.yaml (omit with --resume)");
  cmd->add_option("--out", o->out, "Run folder to create (must not exist)");
  cmd->add_option("--resume", o->resume, "Continue the run in this folder from its checkpoint.safetensors");
  cmd->add_option(
      "--init-from", o->init_from,
      "Start a new run from this model's weights (a model file, a checkpoint or a run folder): its "
      "networks (with --occupancy: plus the occupancy channel, its weights zero), fresh Adam state, the world "
      "and the training settings of this command line (fine-tuning a trained agent in another world, "
      "e.g. --epochs 0,0,3)");
  cmd->add_option("--data", o->data_root,
                  "Data folder: the project's (default: $SCOUT_DATA, else <source>/data; installed: "
                  "~/.local/share/scout) or any folder with train-*/t10k-* IDX files");
  o->settings.add_to(*cmd, /*bench=*/false);
  cmd->add_option("--threads", o->threads,
                  "LibTorch threads per process (0: the cores divided among the processes; on --resume, the run's own, "
                  "which continues it bit for bit)")
      ->capture_default_str()
      ->check(decimal_in(0, 256));
  cmd->add_option("--checkpoint-every", o->checkpoint_every_min,
                  "Also checkpoint inside an epoch every this many minutes, so that a kill loses minutes, not an "
                  "epoch (0: at epoch ends only)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  add_group_options(*cmd, o->group);
  cmd->add_flag("--force", o->force,
                "Start even when the estimated memory exceeds what is available (the smallest of MemAvailable, "
                "the cgroup limit and $SCOUT_MEMORY_LIMIT)");
  cmd->add_flag("--allow-nproc-change", o->allow_nproc_change,
                "Resume a run with another number of processes (not bit-identical to an uninterrupted run)");
  add_camera_backend_option(*cmd);
  cmd->callback([o, &context] {
    install_interrupt_handler();
    if (const std::optional<int> status = launch_local_group(o->group, context)) throw ExitStatus{*status};
    train_command(*o, context);
  });
}

}  // namespace scout::tools
