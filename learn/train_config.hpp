#pragma once
/// The configuration of a training run (METHOD.md § Training modes): the stages of the schedule,
/// the layers, and everything that determines a run, as stored in every checkpoint. Torch-free.
#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "agent/config.hpp"
#include "worlds/world.hpp"

namespace scout::learn {

/// A stage of the schedule, in the order it runs. Pretrain trains the classifier on full images
/// (u_c = x), the transfer variant's first step; modes (i) - (iii) are METHOD.md's; Done is where a
/// finished schedule's cursor stands. The values are what checkpoints store.
enum class Stage { Pretrain = 0, ModeI = 1, ModeII = 2, ModeIII = 3, Done = 4 };
inline constexpr int kTrainingStages = 4;  ///< the stages before Done
/// The stage's position in the schedule (0 .. kTrainingStages; Done is kTrainingStages).
constexpr int index(Stage stage) { return static_cast<int>(stage); }
/// The stage that follows `stage` (Done follows ModeIII and itself).
constexpr Stage next(Stage stage) { return stage == Stage::Done ? Stage::Done : static_cast<Stage>(index(stage) + 1); }
const char* to_string(Stage stage);  ///< "full", "i", "ii", "iii", "done"

/// The layers, in the order of TrainConfig::frozen.
enum class Layer { Goal = 0, Action = 1, Classifier = 2 };

struct TrainSetting;  // below
/// How messages name a setting (nullptr: setting_key).
using SettingName = std::string (*)(const TrainSetting& setting);

/// The most digits a data set may have (train_limit and validation_limit are at most this).
inline constexpr int kMaxDigits = 100000000;
/// The most epochs of one stage (pretraining, or a mode).
inline constexpr int kMaxEpochs = 100000;
/// The most processes of one run (WORLD_SIZE) and LibTorch threads per process (--threads).
inline constexpr int kMaxProcesses = 4096;
inline constexpr int kMaxThreads = 256;

/// Everything that determines a training run (stored in every checkpoint).
struct TrainConfig {
  worlds::World world;                ///< task, camera, robot and physics (floor.dataset names the data)
  std::filesystem::path data_folder;  ///< IDX folder with train-* (and t10k-*, validation-* if any)
  agent::NetworkConfig network;
  int pretrain_epochs = 0;                ///< epochs of the classifier alone on full images, first
  std::array<int, 3> epochs = {2, 2, 2};  ///< epochs of modes (i), (ii), (iii)
  int rollouts = 4;                       ///< N: rollouts per image
  int batch_images = 60;                  ///< B: images per mini-batch (B x N robots)
  double learning_rate = 1e-3;            ///< Adam's step size
  bool leave_one_out = false;             ///< leave-one-out baseline (beyond the paper)
  double entropy_bonus = 0;               ///< beta of the entropy bonus (beyond the paper)
  /// lambda of the full-image teacher (beyond the paper): the classifier also learns, from what a
  /// rollout revealed, the probabilities it gives the whole floor (EstimatorOptions::distillation).
  double distillation = 0;
  /// kappa: what each move that does not arrive (blocked by an obstacle or a teammate) costs the
  /// planners' reward (beyond the paper; EstimatorOptions::stalled_move_cost).
  double stalled_move_cost = 0;
  /// The networks' arithmetic (weights stay fp32). A new run resolves Auto for its CPU
  /// (agent::resolve_precision); checkpoints and manifests hold the resolved fp32 or bf16.
  agent::Precision precision = agent::Precision::Auto;
  std::array<bool, 3> frozen = {false, false, false};  ///< per Layer: not updated in modes (i)-(iii)
  std::uint64_t seed = 1;                              ///< initialisation, data order, starts and sampling
  int train_limit = 0;                                 ///< train on the first K training digits only (0: all)
  int validation_limit = 0;                            ///< validate on the first K validation digits only (0: all)

  /// Throws InputError with one line when a setting is out of range or two disagree (B x N more
  /// robots than one camera draws). The line names each setting with `name`: its JSON key by
  /// default (a checkpoint's "config: rollouts: ..."); the command line passes its options' names.
  void validate(SettingName name = nullptr) const;
  /// The config as JSON text (the world as YAML inside) and back; `origin` names the source in errors.
  std::string to_json() const;
  static TrainConfig from_json(const std::string& text, const std::string& origin);
};

/// What a resumed run does with a setting.
enum class OnResume {
  Kept,     ///< the run's own: an option given again must agree with it
  Changes,  ///< a resume may change it (learn::ResumeOptions)
  Derived,  ///< not asked for on the command line (from the data, or the world file's own check)
};

/// The parts of a config that the processes of a data-parallel run must agree on
/// (Trainer::distribute), each refused with its own line.
enum class Agreement {
  None,      ///< may differ: paths, and what comes from the data (compared by SHA-256)
  World,     ///< the world
  Networks,  ///< the networks and their arithmetic
  Training,  ///< the training settings
};
const char* to_string(Agreement part);  ///< "world", "networks", "training settings"

/// How a setting's value is written (JSON, command line). The first four are checked against the
/// row's range alone; each of the others has its own reader in learn/train_config.cpp.
enum class SettingType {
  Integer,     ///< int, a plain decimal integer in [lo, hi]
  Number,      ///< double, in the row's interval
  Flag,        ///< bool: "on" / "off" in messages, a flag on the command line
  Unsigned,    ///< std::uint64_t, any decimal integer in [0, 2^64 - 1]
  Epochs,      ///< three counts "i,ii,iii", each in [lo, hi]
  Frozen,      ///< a comma-separated list of goal, action, classifier
  Classifier,  ///< a name of agent::kClassifierVariants
  Precision,   ///< auto, bf16 or fp32 (stored resolved)
  World,       ///< the world, stored as YAML with the file it came from
  Folder,      ///< a path
};

/// The commands that take a setting as an option.
enum class SettingCommands { None, Train, TrainAndBench };

/// One training setting: a row of the schema table in learn/train_config.cpp, which drives the
/// JSON stored in every checkpoint (TrainConfig::to_json, from_json), the range checks and their
/// messages (validate), the options of `scout train` and `scout bench train` (tools/), what a
/// resume may change and what the ranks of a data-parallel run must agree on. A new training
/// setting is a member of TrainConfig (its default is the command line's) and one row.
struct TrainSetting {
  std::string_view key;      ///< the JSON key (inside "network" for the networks' rows)
  std::string_view section;  ///< "network" for agent::NetworkConfig's fields, else ""
  SettingType type;
  double lo = 0, hi = 0;                  ///< the range (Integer, Epochs, Number)
  bool lo_open = false, hi_open = false;  ///< Number: the interval's open ends
  std::string_view option;                ///< the command line's option ("--rollouts"); "" where there is none
  std::string_view value_name;            ///< the option's value in --help and usage errors ("I,II,III")
  std::string_view help;                  ///< the option's help
  SettingCommands commands = SettingCommands::None;
  bool shows_default = true;  ///< --help shows the default (not for the seed: the world file's)
  OnResume on_resume = OnResume::Kept;
  Agreement agreement = Agreement::Training;
  /// A flag added after checkpoints without it were written: stored only when on, and a config
  /// without it reads off, so that older files and every file with it off stay as they were.
  bool stored_unless_default = false;
};

/// The table, in the order to_json writes it.
std::span<const TrainSetting> train_settings();
/// The row of a JSON key ("rollouts", "network.planner_width"); std::out_of_range for another.
const TrainSetting& train_setting(std::string_view key);
/// The default name of a setting in messages: its JSON path ("rollouts", "network.planner_width").
std::string setting_key(const TrainSetting& setting);
/// A setting's help: the row's, and for the classifier every variant with its own help.
std::string setting_help(const TrainSetting& setting);
/// The option's value in --help and usage errors: the row's, or "INT in [1, 64]", "FLOAT in (0, 10)".
std::string setting_value_name(const TrainSetting& setting);
/// A setting's value as its option spells it: "4", "0.003", "on", "2,2,2", "goal,action" ("none"),
/// "paper", "auto" (the resume's messages, --help's defaults).
std::string setting_text(const TrainConfig& config, const TrainSetting& setting);
/// Sets a setting from its option's text, range-checked; throws InputError "expected ..., got
/// 'TEXT'" (the caller puts the option or key before it).
void set_setting(TrainConfig& config, const TrainSetting& setting, const std::string& text);
/// One part of the config as JSON text (what the ranks compare for that part).
std::string agreement_text(const TrainConfig& config, Agreement part);

/// About how much memory training `config` on floors of width x height takes at its peak (mode
/// (iii), where both planners keep their activations for the backward pass of every robot), with
/// each of `world_size` processes driving its share of a batch: the weights, their gradients and
/// Adam's moments, the planners' and the classifier's saved activations per robot, the physics
/// and camera per robot, and the process's own base (LibTorch, Mesa). An estimate for refusing
/// requests that cannot fit (`scout train` refuses them unless --force), not an exact figure:
/// learn/README.md compares it with measured peaks.
std::uint64_t estimate_training_bytes(const TrainConfig& config, int width_px, int height_px, int world_size = 1);

}  // namespace scout::learn
