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
#include "learn/checkpoint.hpp"
#include "learn/distributed.hpp"
#include "learn/trainer.hpp"
#include "tools/commands.hpp"
#include "tools/group.hpp"
#include "tools/network_options.hpp"
#include "tools/output.hpp"
#include "worlds/dataset.hpp"

namespace scout::tools {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

// The library's defaults are the command's: one definition, in learn::TrainConfig.
const learn::TrainConfig& defaults() {
  static const learn::TrainConfig config;
  return config;
}

std::string epochs_text(const std::array<int, 3>& epochs) {
  return fmt::format("{},{},{}", epochs[0], epochs[1], epochs[2]);
}

struct TrainOptions {
  std::string world;
  std::string out;
  std::string resume;
  std::string data_root;
  std::string seed;
  std::string epochs = epochs_text(defaults().epochs);
  int pretrain_epochs = defaults().pretrain_epochs;
  NetworkOptions net;
  double lr = defaults().learning_rate;
  int batch = defaults().batch_images;
  int rollouts = defaults().rollouts;
  bool baseline = defaults().leave_one_out;
  double entropy_bonus = defaults().entropy_bonus;
  std::string freeze;
  int train_limit = defaults().train_limit;
  int validation_limit = defaults().validation_limit;
  int threads = 0;
  GroupFlags group;
  bool allow_nproc_change = false;
  bool force = false;
  double checkpoint_every_min = 5;
};

std::array<int, 3> parse_epochs(const std::string& text) {
  std::array<int, 3> epochs{};
  std::stringstream in(text);
  std::string part;
  int k = 0;
  const std::string expected = "expected three counts i,ii,iii (e.g. 2,2,2), got '" + one_line(text) + "'";
  while (std::getline(in, part, ',')) {
    if (k >= 3 || part.empty() || part.size() > 6 || part.find_first_not_of("0123456789") != std::string::npos)
      throw InputError(expected);
    epochs[k++] = std::stoi(part);
  }
  if (k != 3 || text.back() == ',') throw InputError(expected);
  return epochs;
}

std::array<bool, 3> parse_freeze(const std::string& text) {
  std::array<bool, 3> frozen{};
  if (text.empty()) return frozen;
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    if (part == "goal")
      frozen[0] = true;
    else if (part == "action")
      frozen[1] = true;
    else if (part == "classifier")
      frozen[2] = true;
    else
      throw InputError("expected a comma-separated list of goal, action, classifier; got '" + one_line(text) + "'");
  }
  return frozen;
}

std::string duration(double seconds) {
  if (!(seconds >= 0) || seconds > 1e7) return "?";
  const long s = static_cast<long>(seconds + 0.5);
  if (s >= 3600) return fmt::format("{}h{:02d}m", s / 3600, s / 60 % 60);
  if (s >= 60) return fmt::format("{}m{:02d}s", s / 60, s % 60);
  return fmt::format("{}s", s);
}

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
                                         p.images_per_s, p.reward, duration(p.eta_s));
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

// A resumed run keeps its config: an option given again must agree with it.
void check_resume_options(const CLI::App& cmd, const TrainOptions& o, const learn::TrainConfig& c,
                          const std::string& run) {
  auto refuse = [&](const std::string& option, const std::string& stored, const std::string& asked) {
    if (stored == asked) return;
    throw InputError(
        fmt::format("{}: the run at {} was trained with {}, the command line asks for {} (a resumed run "
                    "keeps its config; start a new run to change it)",
                    option, run, stored, asked));
  };
  auto given = [&](const char* name) { return cmd.get_option(name)->count() > 0; };
  auto on_off = [](bool on) { return std::string(on ? "on" : "off"); };
  auto number = [](auto value) { return fmt::format("{}", value); };
  // An option given again must say what the run was trained with: {option, stored, asked}.
  struct Kept {
    const char* option;
    std::string stored, asked;
  };
  const Kept kept[] = {
      {.option = "--planner-width", .stored = number(c.network.planner_width), .asked = number(o.net.planner_width)},
      {.option = "--planner-depth", .stored = number(c.network.planner_depth), .asked = number(o.net.planner_depth)},
      {.option = "--classifier", .stored = agent::to_string(c.network.classifier), .asked = o.net.classifier},
      {.option = "--classifier-width",
       .stored = number(c.network.classifier_width),
       .asked = number(o.net.classifier_width)},
      {.option = "--classifier-depth",
       .stored = number(c.network.classifier_depth),
       .asked = number(o.net.classifier_depth)},
      {.option = "--batch", .stored = number(c.batch_images), .asked = number(o.batch)},
      {.option = "--rollouts", .stored = number(c.rollouts), .asked = number(o.rollouts)},
      {.option = "--baseline", .stored = on_off(c.leave_one_out), .asked = on_off(o.baseline)},
      {.option = "--entropy-bonus", .stored = number(c.entropy_bonus), .asked = number(o.entropy_bonus)},
      {.option = "--pretrain-epochs", .stored = number(c.pretrain_epochs), .asked = number(o.pretrain_epochs)},
      {.option = "--seed", .stored = number(c.seed), .asked = o.seed},
      {.option = "--train-limit", .stored = number(c.train_limit), .asked = number(o.train_limit)},
      {.option = "--validation-limit", .stored = number(c.validation_limit), .asked = number(o.validation_limit)},
  };
  for (const Kept& k : kept)
    if (given(k.option)) refuse(k.option, k.stored, k.asked);
  if (given("--freeze")) {
    const auto f = parse_freeze(o.freeze);
    if (f != c.frozen)
      throw InputError("--freeze: differs from the run's frozen layers (a resumed run keeps its config)");
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
std::optional<agent::Precision> resume_precision(const CLI::App& cmd, const TrainOptions& o,
                                                 const learn::TrainConfig& c, const std::string& run) {
  if (cmd.get_option("--precision")->count() > 0) {
    announce_auto_precision(o.net.precision);  // also warns when bf16 would be emulated
    return agent::resolve_precision(agent::parse_precision(o.net.precision));
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

void write_manifest(const fs::path& run, const Context& context, const learn::Trainer& trainer, bool resumed) {
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
      return;
    } catch (const std::exception&) {
      // An unreadable manifest is replaced by a fresh one below.
    }
  }
  manifest["torch_threads"] = trainer.threads();
  manifest["world_size"] = trainer.world_size();
  manifest["config"] = json::parse(trainer.config().to_json());
  manifest["outputs"] = {{"checkpoint", learn::kCheckpointFile}, {"metrics", learn::kMetricsFile}};
  write_file_atomic(file, manifest.dump(2) + "\n");
}

// The config a new run's command line asks for (every rank of a group builds it, to compare).
learn::TrainConfig new_run_config(const TrainOptions& o, const std::array<int, 3>& epochs) {
  learn::TrainConfig config;
  config.world = worlds::load_world(o.world);
  if (!o.seed.empty()) config.world.seed = parse_seed(o.seed);
  config.seed = config.world.seed;
  if (config.world.floor.dataset.empty())
    throw InputError(o.world + ": floor.dataset: training needs a data set (a PNG floor has no labels)");
  const fs::path data_root = o.data_root.empty() ? worlds::default_data_root() : fs::path(o.data_root);
  config.data_folder = fs::absolute(worlds::dataset_folder(config.world.floor.dataset, data_root));
  config.network = o.net.network();
  config.pretrain_epochs = o.pretrain_epochs;
  config.epochs = epochs;
  config.rollouts = o.rollouts;
  config.batch_images = o.batch;
  config.learning_rate = o.lr;
  config.leave_one_out = o.baseline;
  config.entropy_bonus = o.entropy_bonus;
  config.precision = o.net.arithmetic();
  config.frozen = parse_freeze(o.freeze);
  config.train_limit = o.train_limit;
  config.validation_limit = o.validation_limit;
  config.validate();
  if (config.pretrain_epochs + epochs[0] + epochs[1] + epochs[2] == 0)
    throw InputError("--epochs: nothing to train (every stage has 0 epochs); expected at least one epoch");
  return config;
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
std::unique_ptr<learn::Trainer> open_trainer(const CLI::App& cmd, const TrainOptions& o, const fs::path& run,
                                             int threads, int world_size) {
  const std::array<int, 3> epochs = parse_epochs(o.epochs);
  const bool epochs_given = cmd.get_option("--epochs")->count() > 0;
  if (!o.resume.empty()) {
    if (!fs::is_regular_file(run / learn::kCheckpointFile))
      throw InputError("--resume: " + o.resume + " holds no checkpoint.pt (expected a folder written by scout train)");
    const learn::CheckpointInfo info = learn::read_checkpoint_info(run / learn::kCheckpointFile);
    check_resume_options(cmd, o, info.config, o.resume);
    if (info.world_size != world_size && !o.allow_nproc_change)
      throw InputError(fmt::format(
          "--nproc: the run at {} trained with {} process(es), this resume has {}; resume with --nproc {} to continue "
          "it exactly, or add --allow-nproc-change (the gradient sums change order: weights then agree to about 1e-5, "
          "not bit for bit)",
          o.resume, info.world_size, world_size, info.world_size));
    check_batch_split(info.config.batch_images, world_size);
    const fs::path data_folder = resume_data_folder(o, info.config, run);
    // --lr on resume sets the rate from the next batch on (metrics.csv records each epoch's rate).
    const bool lr_given = cmd.get_option("--lr")->count() > 0;
    learn::ResumeOptions resume;
    if (epochs_given) resume.epochs = epochs;
    resume.data_folder = data_folder;
    if (lr_given) resume.learning_rate = o.lr;
    resume.precision = resume_precision(cmd, o, info.config, o.resume);
    auto trainer = learn::Trainer::resume(run, threads, resume);
    if (lr_given && o.lr != info.config.learning_rate && !trainer->finished())
      fmt::print("learning rate {} -> {} from the next batch on\n", info.config.learning_rate, o.lr);
    if (resume.precision && *resume.precision != info.config.precision && !trainer->finished())
      fmt::print("precision {} -> {} from the next batch on (not bit for bit what {} would give)\n",
                 agent::to_string(info.config.precision), agent::to_string(*resume.precision),
                 agent::to_string(info.config.precision));
    return trainer;
  }
  const learn::TrainConfig config = new_run_config(o, epochs);
  check_batch_split(config.batch_images, world_size);
  std::error_code ec;
  if (fs::exists(run, ec))
    throw InputError("--out: " + o.out + " exists (continue it with --resume " + o.out + ", or name a new folder)");
  fs::create_directories(run);
  try {
    return std::make_unique<learn::Trainer>(config, run, threads, o.force);
  } catch (...) {
    fs::remove_all(run, ec);
    throw;
  }
}

void train_command(const CLI::App& cmd, const TrainOptions& o, const Context& context) {
  const bool resuming = !o.resume.empty();
  if (resuming && !o.out.empty() && fs::path(o.out) != fs::path(o.resume))
    throw InputError("--out: a resumed run writes into its own folder (" + o.resume + "); leave --out out");
  if (!resuming && o.world.empty()) throw InputError("WORLD: a world file is required (or --resume RUN)");
  if (!resuming && o.out.empty()) throw InputError("--out: a run folder is required (or --resume RUN)");
  const fs::path run = resuming ? fs::path(o.resume) : fs::path(o.out);
  const std::optional<learn::GroupOptions> group_options = group_from_flags(o.group);

  std::unique_ptr<learn::ProcessGroup> group;
  std::unique_ptr<learn::Trainer> trainer;
  if (!group_options) {
    trainer = open_trainer(cmd, o, run, o.threads, 1);
  } else {
    set_rank(group_options->rank);
    group = learn::ProcessGroup::connect(*group_options);
    const int threads = threads_per_process(o.threads);
    // The others compare what their own command line asks for with rank 0's run; on a resume
    // they take rank 0's config, and read the data from --data or the run's own data path.
    std::optional<learn::TrainConfig> own;
    std::optional<fs::path> data_folder;
    if (group->rank() != 0 && !resuming) {
      own = new_run_config(o, parse_epochs(o.epochs));
      data_folder = own->data_folder;
    } else if (group->rank() != 0 && !o.data_root.empty()) {
      data_folder = fs::path(o.data_root);
    }
    const bool created = group->rank() == 0 && !resuming;
    try {
      trainer = learn::Trainer::distribute(
          *group, threads, [&] { return open_trainer(cmd, o, run, threads, group->size()); }, own, data_folder);
    } catch (const learn::LeaderFailed&) {
      throw ExitStatus{1};  // rank 0 said why
    } catch (...) {
      // A new run that never started leaves no folder behind (rank 0 had created it).
      std::error_code ec;
      if (created && !fs::exists(run / learn::kCheckpointFile, ec)) fs::remove_all(run, ec);
      throw;
    }
  }
  const bool leader = trainer->rank() == 0;
  if (resuming && trainer->finished()) {
    if (leader)
      fmt::print("the run's schedule is complete after {} epoch(s); nothing to do (a longer --epochs continues it)\n",
                 trainer->history().size());
    return;
  }
  ProgressPrinter progress;
  learn::TrainHooks hooks;
  hooks.stop = interrupt_token();
  hooks.checkpoint_every = std::chrono::milliseconds(std::llround(o.checkpoint_every_min * 60000));
  if (leader) {
    if (!resuming) o.net.announce_precision();
    write_manifest(run, context, *trainer, resuming);
    const learn::TrainConfig& c = trainer->config();
    fmt::print("training {} -> {} ({}{} LibTorch threads, {}; planner {}x{}, classifier {}; N = {}, B = {}, lr {})\n",
               c.world.file.string(), run.string(),
               trainer->world_size() > 1 ? fmt::format("{} processes x ", trainer->world_size()) : "",
               trainer->threads(), agent::to_string(c.precision), c.network.planner_width, c.network.planner_depth,
               agent::describe_classifier(c.network), c.rollouts, c.batch_images, c.learning_rate);
    if (resuming) {
      const learn::ScheduleCursor& k = trainer->cursor();
      fmt::print("resuming after {} epoch(s) (stage {}, epoch {}, batch {})\n", trainer->history().size(), k.stage,
                 k.epoch, k.batch);
    }
    std::fflush(stdout);
    hooks.on_progress = [&](const learn::Progress& p) { progress.show(p); };
    hooks.on_epoch = [&](const learn::EpochMetrics& m) {
      progress.end_line();
      // A baseline a mode does not have (learned goals before mode ii) is "-", as metrics.csv
      // leaves it empty; never a 0 that reads as a measurement.
      const auto figure = [](const std::optional<double>& v) { return v ? fmt::format("{:.4f}", *v) : "-"; };
      fmt::print(
          "mode {:<3} epoch {:>3}: reward {:.4f}  loss {:.4f}  train {:.4f}  validation {:.4f} (i.i.d. {}, "
          "goals only {}, full images {})  {:.1f} images/s  {:.1f} s\n",
          learn::to_string(m.stage), m.epoch, m.reward, m.loss, m.train_accuracy, m.validation_accuracy,
          figure(m.validation_iid), figure(m.validation_goals_only), figure(m.validation_full_image), m.images_per_s,
          m.seconds);
      std::fflush(stdout);
    };
  }
  const learn::TrainResult result = trainer->run(hooks);
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
      "physics and the camera in the loop. Writes RUN/checkpoint.pt every epoch, RUN/metrics.csv, RUN/manifest.json.");
  cmd->add_option("world", o->world, "World file (YAML), e.g. worlds/mnist.yaml (omit with --resume)");
  cmd->add_option("--out", o->out, "Run folder to create (must not exist)");
  cmd->add_option("--resume", o->resume, "Continue the run in this folder from its checkpoint.pt");
  cmd->add_option("--data", o->data_root,
                  "Data folder: the project's (default: $SCOUT_DATA, else <source>/data) or any "
                  "folder with train-*/t10k-* IDX files");
  cmd->add_option("--epochs", o->epochs, "Epochs of modes i,ii,iii")
      ->capture_default_str()
      ->check(parsed_by(parse_epochs, "I,II,III"));
  cmd->add_option("--pretrain-epochs", o->pretrain_epochs, "Epochs of the classifier on full images, first")
      ->capture_default_str()
      ->check(decimal_in(0, 100000));
  cmd->add_option("--seed", o->seed, "Seed (overrides the world file's): init, data order, starts, sampling")
      ->check(seed_validator());
  add_network_options(*cmd, o->net);
  cmd->add_option("--lr", o->lr, "Adam's learning rate")->capture_default_str();
  cmd->add_option("--batch", o->batch, "B: images per mini-batch")->capture_default_str()->check(decimal_in(1, 4096));
  cmd->add_option("--rollouts", o->rollouts, "N: rollouts per image")->capture_default_str()->check(decimal_in(1, 64));
  cmd->add_flag("--baseline", o->baseline, "Leave-one-out baseline (beyond the paper; off in the paper preset)");
  cmd->add_option("--entropy-bonus", o->entropy_bonus, "Entropy bonus beta (beyond the paper; 0 in the paper preset)")
      ->capture_default_str();
  cmd->add_option("--freeze", o->freeze, "Layers not updated in modes i-iii: goal,action,classifier")
      ->check(parsed_by(parse_freeze, "LAYERS"));
  cmd->add_option("--train-limit", o->train_limit, "Train on the first K training digits only (0: all)")
      ->capture_default_str()
      ->check(decimal_in(0, 100000000));
  cmd->add_option("--validation-limit", o->validation_limit, "Validate on the first K validation digits (0: all)")
      ->capture_default_str()
      ->check(decimal_in(0, 100000000));
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
  cmd->callback([cmd, o, &context] {
    install_interrupt_handler();
    if (const std::optional<int> status = launch_local_group(o->group, context)) throw ExitStatus{*status};
    train_command(*cmd, *o, context);
  });
}

}  // namespace scout::tools
