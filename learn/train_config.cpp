// TrainConfig: its schema table, which drives validation, its JSON form (stored in checkpoints and
// manifests), the command line's options, what a resume may change and what ranks agree on.
#include "learn/train_config.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <iterator>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <variant>
#include <vector>

#include "core/error.hpp"
#include "env/batch_env.hpp"
#include "learn/auto_precision.hpp"
#include "learn/internal/json_limits.hpp"

namespace scout::learn {

using json = nlohmann::ordered_json;
namespace fs = std::filesystem;

namespace {

// Upper bounds that catch typos before hours are spent, not research limits.
constexpr int kMaxRollouts = 64;
constexpr int kMaxBatchImages = 4096;

// ---------------------------------------------------------------------------------------------
// The schema: one row per TrainConfig field (worlds/world.cpp's tables are the model). The rows
// decide the JSON a checkpoint stores and reads, each value's range and its messages, the options
// of `scout train` and `scout bench train` (tools/network_options.cpp builds them from the rows),
// what a resume may change (tools/train_command.cpp) and what ranks compare (learn/trainer.cpp).

/// The member a row reads and writes: its alternative follows the row's SettingType (Integer
/// takes either of the first two).
using Member =
    std::variant<int TrainConfig::*, int agent::NetworkConfig::*, double TrainConfig::*, bool TrainConfig::*,
                 std::uint64_t TrainConfig::*, std::array<int, 3> TrainConfig::*, std::array<bool, 3> TrainConfig::*,
                 agent::ClassifierKind agent::NetworkConfig::*, agent::Precision TrainConfig::*,
                 worlds::World TrainConfig::*, fs::path TrainConfig::*, bool agent::NetworkConfig::*>;

struct Row {
  TrainSetting setting;
  Member member;
};

using agent::NetworkConfig;
constexpr auto kTrain = SettingCommands::Train;
constexpr auto kBoth = SettingCommands::TrainAndBench;
constexpr auto kNone = SettingCommands::None;

/// A row: key, section, type, member, range [lo, hi], option, value name, help, commands, on
/// resume, what ranks agree on, then (for numbers) open ends and whether --help shows the default.
constexpr Row row(std::string_view key, std::string_view section, SettingType type, Member member, double lo, double hi,
                  std::string_view option, std::string_view value_name, std::string_view help, SettingCommands commands,
                  OnResume on_resume, Agreement agreement, bool lo_open = false, bool hi_open = false,
                  bool shows_default = true, bool stored_unless_default = false) {
  return {TrainSetting{.key = key,
                       .section = section,
                       .type = type,
                       .lo = lo,
                       .hi = hi,
                       .lo_open = lo_open,
                       .hi_open = hi_open,
                       .option = option,
                       .value_name = value_name,
                       .help = help,
                       .commands = commands,
                       .shows_default = shows_default,
                       .on_resume = on_resume,
                       .agreement = agreement,
                       .stored_unless_default = stored_unless_default},
          member};
}

using T = SettingType;
using R = OnResume;
using A = Agreement;

// clang-format off
constexpr Row kRows[] = {
    row("world_yaml", "", T::World, &TrainConfig::world, 0, 0, "", "", "", kNone, R::Derived, A::World),
    row("data_folder", "", T::Folder, &TrainConfig::data_folder, 0, 0, "", "", "", kNone, R::Changes, A::None),
    row("image_channels", "network", T::Integer, &NetworkConfig::image_channels, 1, agent::kMaxImageChannels, "", "",
        "", kNone, R::Derived, A::None),
    row("classes", "network", T::Integer, &NetworkConfig::classes, 2, 1000, "", "", "", kNone, R::Derived, A::None),
    row("planner_width", "network", T::Integer, &NetworkConfig::planner_width, 1, agent::kMaxWidth, "--planner-width",
        "", "Channels each planner block adds (d)", kBoth, R::Kept, A::Networks),
    row("planner_depth", "network", T::Integer, &NetworkConfig::planner_depth, 1, agent::kMaxPlannerDepth,
        "--planner-depth", "", "Planner blocks (r)", kBoth, R::Kept, A::Networks),
    row("classifier", "network", T::Classifier, &NetworkConfig::classifier, 0, 0, "--classifier", "KIND", "Classifier: ",
        kBoth, R::Kept, A::Networks),
    row("classifier_width", "network", T::Integer, &NetworkConfig::classifier_width, 1, agent::kMaxWidth,
        "--classifier-width", "", "Classifier's first block width (doubles each block)", kBoth, R::Kept, A::Networks),
    row("classifier_depth", "network", T::Integer, &NetworkConfig::classifier_depth, 1, agent::kMaxClassifierDepth,
        "--classifier-depth", "", "Classifier blocks", kBoth, R::Kept, A::Networks),
    row("occupancy", "network", T::Flag, &NetworkConfig::occupancy, 0, 0, "--occupancy", "",
        "Planners also read the occupancy channel o: where the robot cannot stand beside its run's obstacles "
        "(beyond the paper)", kBoth, R::Kept, A::Networks, false, false, true, /*stored_unless_default=*/true),
    row("goal_context", "network", T::Integer, &NetworkConfig::goal_context, 0, agent::kMaxWidth, "--goal-context", "",
        "Channels of the goal planner's context branch, which sees the whole floor at 1/4 resolution (beyond the "
        "paper; 0: none, the paper's planner)", kBoth, R::Kept, A::Networks, false, false, true,
        /*stored_unless_default=*/true),
    row("team_channels", "network", T::Flag, &NetworkConfig::team_channels, 0, 0, "--team-channels", "",
        "Planners also read where the teammates stand and where their goals are, and a team's robots choose their "
        "goals one after the other (beyond the paper)", kBoth, R::Kept, A::Networks, false, false, true,
        /*stored_unless_default=*/true),
    row("wide_view", "network", T::Flag, &NetworkConfig::wide_view, 0, 0, "--wide-view", "",
        "Planners also read the wider view (camera.wide_px): its coarse map y_w and where it has looked, h_w (beyond "
        "the paper)", kBoth, R::Kept, A::Networks, false, false, true, /*stored_unless_default=*/true),
    row("goals_only", "network", T::Flag, &NetworkConfig::goals_only, 0, 0, "--goals-only", "",
        "No action planner: every move's axis is drawn i.i.d. 1/2 - 1/2, no f2 parameters or arithmetic; trains in "
        "modes i and ii only (beyond the paper)", kBoth, R::Kept, A::Networks, false, false, true,
        /*stored_unless_default=*/true),
    row("free_routes", "network", T::Flag, &NetworkConfig::free_routes, 0, 0, "--free-routes", "",
        "The route rule: goals only where a monotone route of free cells reaches, and an axis forced where only one "
        "keeps such a route to the goal (worlds with obstacles; no parameters; beyond the paper)", kBoth, R::Kept,
        A::Networks, false, false, true, /*stored_unless_default=*/true),
    row("pretrain_epochs", "", T::Integer, &TrainConfig::pretrain_epochs, 0, kMaxEpochs, "--pretrain-epochs", "",
        "Epochs of the classifier on full images, first", kTrain, R::Kept, A::Training),
    row("epochs", "", T::Epochs, &TrainConfig::epochs, 0, kMaxEpochs, "--epochs", "I,II,III", "Epochs of modes i,ii,iii",
        kTrain, R::Changes, A::Training),
    row("rollouts", "", T::Integer, &TrainConfig::rollouts, 1, kMaxRollouts, "--rollouts", "", "N: rollouts per image",
        kBoth, R::Kept, A::Training),
    row("batch_images", "", T::Integer, &TrainConfig::batch_images, 1, kMaxBatchImages, "--batch", "",
        "B: images per mini-batch", kBoth, R::Kept, A::Training),
    row("learning_rate", "", T::Number, &TrainConfig::learning_rate, 0, 10, "--lr", "", "Adam's learning rate", kTrain,
        R::Changes, A::Training, /*lo_open=*/true, /*hi_open=*/true),
    row("leave_one_out", "", T::Flag, &TrainConfig::leave_one_out, 0, 0, "--baseline", "",
        "Leave-one-out baseline (beyond the paper; off in the paper preset)", kBoth, R::Kept, A::Training),
    row("entropy_bonus", "", T::Number, &TrainConfig::entropy_bonus, 0, 100, "--entropy-bonus", "",
        "Entropy bonus beta (beyond the paper; 0 in the paper preset)", kTrain, R::Kept, A::Training, /*lo_open=*/false, /*hi_open=*/true),
    row("distillation", "", T::Number, &TrainConfig::distillation, 0, 100, "--distill", "",
        "Weight lambda of the full-image teacher: the classifier also learns, from what each rollout revealed, the "
        "probabilities it gives the whole floor (beyond the paper; 0 in the paper preset)", kTrain, R::Changes,
        A::Training, /*lo_open=*/false, /*hi_open=*/true, /*shows_default=*/true, /*stored_unless_default=*/true),
    row("stalled_move_cost", "", T::Number, &TrainConfig::stalled_move_cost, 0, 100, "--stalled-move-cost", "",
        "Cost kappa of each move that does not arrive (blocked by an obstacle or a teammate) in the planners' reward "
        "r - kappa * stalled moves (beyond the paper; 0 in the paper preset)", kTrain, R::Kept, A::Training,
        /*lo_open=*/false, /*hi_open=*/true, /*shows_default=*/true, /*stored_unless_default=*/true),
    row("precision", "", T::Precision, &TrainConfig::precision, 0, 0, "--precision", "PRECISION",
        "Networks' arithmetic: auto (the faster on this CPU, measured once; bf16 only where native) | bf16 (bfloat16 "
        "convolutions, "
        "fp32 weights and optimizer) | fp32", kBoth, R::Changes, A::Networks),
    row("frozen", "", T::Frozen, &TrainConfig::frozen, 0, 0, "--freeze", "LAYERS",
        "Layers not updated in modes i-iii: goal,action,classifier", kTrain, R::Kept, A::Training, false, false,
        /*shows_default=*/false),
    row("seed", "", T::Unsigned, &TrainConfig::seed, 0, 0, "--seed", "UINT64",
        "Seed (overrides the world file's): init, data order, starts, sampling", kTrain, R::Kept, A::Training, false,
        false, /*shows_default=*/false),
    row("train_limit", "", T::Integer, &TrainConfig::train_limit, 0, kMaxDigits, "--train-limit", "",
        "Train on the first K training digits only (0: all)", kTrain, R::Kept, A::Training),
    row("validation_limit", "", T::Integer, &TrainConfig::validation_limit, 0, kMaxDigits, "--validation-limit", "",
        "Validate on the first K validation digits (0: all)", kTrain, R::Kept, A::Training),
};
// clang-format on

/// A row's member matches its type, and integer ranges are closed and integral: checked at compile
/// time, so that a mistyped new row does not build.
constexpr bool well_formed() {
  constexpr std::size_t kIndex[] = {0, 2, 3, 4, 5, 6, 7, 8, 9, 10};  // by SettingType
  for (const Row& r : kRows) {
    const TrainSetting& s = r.setting;
    const std::size_t want = kIndex[static_cast<int>(s.type)];
    if (r.member.index() != want && !(s.type == SettingType::Integer && r.member.index() == 1) &&
        !(s.type == SettingType::Flag && r.member.index() == 11))
      return false;
    if ((r.member.index() == 1 || r.member.index() == 7 || r.member.index() == 11) != (s.section == "network"))
      return false;
    if (s.stored_unless_default && s.type != SettingType::Flag && s.type != SettingType::Integer &&
        s.type != SettingType::Number)
      return false;
    if (s.type == SettingType::Integer || s.type == SettingType::Epochs) {
      if (s.lo_open || s.hi_open || s.lo > s.hi || static_cast<double>(static_cast<int>(s.lo)) != s.lo ||
          static_cast<double>(static_cast<int>(s.hi)) != s.hi)
        return false;
    }
    if (s.type == SettingType::Number && !(s.lo < s.hi)) return false;
    if ((s.commands == SettingCommands::None) != s.option.empty()) return false;
  }
  return true;
}
static_assert(well_formed(), "a row of the training settings' table does not fit its member");

// The row of an entry of train_settings() (the same order).
const Row& row_of(const TrainSetting& setting) {
  const std::span<const TrainSetting> all = train_settings();
  if (&setting < all.data() || &setting >= all.data() + all.size())
    throw std::logic_error("not an entry of learn::train_settings()");
  return kRows[&setting - all.data()];
}

int& integer_at(TrainConfig& c, const Member& m) {
  if (const auto* p = std::get_if<int TrainConfig::*>(&m)) return c.**p;
  return c.network.*std::get<int NetworkConfig::*>(m);
}
bool& flag_at(TrainConfig& c, const Member& m) {
  if (const auto* p = std::get_if<bool TrainConfig::*>(&m)) return c.**p;
  return c.network.*std::get<bool NetworkConfig::*>(m);
}
// A setting added after files without it were written, at its default (off, 0): left out of the
// file, so that those files stay as they were.
template <class V>
V& at(TrainConfig& c, const Member& m) {
  return c.*std::get<V TrainConfig::*>(m);
}
bool is_default_zero(TrainConfig& c, const Row& r) {
  switch (r.setting.type) {
    case SettingType::Flag:
      return !flag_at(c, r.member);
    case SettingType::Number:
      return at<double>(c, r.member) == 0;
    default:
      return integer_at(c, r.member) == 0;
  }
}

std::string interval_text(const TrainSetting& s) {
  if (s.type == SettingType::Number)
    return fmt::format("{}{}, {}{}", s.lo_open ? "(" : "[", s.lo, s.hi, s.hi_open ? ")" : "]");
  return fmt::format("[{}, {}]", static_cast<long long>(s.lo), static_cast<long long>(s.hi));
}
bool in_range(const TrainSetting& s, double v) {
  return (s.lo_open ? v > s.lo : v >= s.lo) && (s.hi_open ? v < s.hi : v <= s.hi);
}

constexpr const char* kLayerNames[] = {"goal", "action", "classifier"};  // in the order of Layer

std::string expected_text(const TrainSetting& s) {
  switch (s.type) {
    case SettingType::Integer:
      return "expected an integer in " + interval_text(s);
    case SettingType::Number:
      return "expected a number in " + interval_text(s);
    case SettingType::Unsigned:
      return "expected an integer in [0, 18446744073709551615]";
    case SettingType::Epochs:
      return "expected three counts i,ii,iii (e.g. 2,2,2)";
    case SettingType::Frozen:
      return "expected a comma-separated list of goal, action, classifier";
    case SettingType::Classifier:
      return "expected one of " + agent::classifier_choices();
    case SettingType::Precision:
      return "expected one of auto, bf16, fp32";
    case SettingType::Flag:
      return "expected on or off";
    case SettingType::World:
    case SettingType::Folder:
      break;
  }
  return "expected a value";
}

// A plain decimal integer (no sign, no leading zero: CLI11 would read 010 as octal).
std::optional<long long> plain_integer(const std::string& text) {
  long long value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ptr != end || ec != std::errc() || (text.size() > 1 && text[0] == '0') || text[0] == '-')
    return std::nullopt;
  return value;
}

std::array<int, 3> parse_epochs(const TrainSetting& s, const std::string& text) {
  std::array<int, 3> epochs{};
  std::stringstream in(text);
  std::string part;
  int k = 0;
  while (std::getline(in, part, ',')) {
    const std::optional<long long> n = part.size() <= 6 ? plain_integer(part) : std::nullopt;
    if (k >= 3 || !n) throw std::invalid_argument("");
    epochs[k++] = static_cast<int>(*n);
  }
  if (k != 3 || text.back() == ',') throw std::invalid_argument("");
  for (int e : epochs)
    if (!in_range(s, e)) throw InputError(fmt::format("expected counts in {}, got '{}'", interval_text(s), text));
  return epochs;
}

std::array<bool, 3> parse_frozen(const std::string& text) {
  std::array<bool, 3> frozen{};
  if (text.empty() || text == "none") return frozen;
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    const auto* name = std::find(std::begin(kLayerNames), std::end(kLayerNames), part);
    if (name == std::end(kLayerNames)) throw std::invalid_argument("");
    frozen[name - std::begin(kLayerNames)] = true;
  }
  return frozen;
}

// The value as stored in JSON (the world: its YAML).
json value_json(const TrainConfig& config, const Row& r) {
  TrainConfig& c = const_cast<TrainConfig&>(config);  // read only
  switch (r.setting.type) {
    case SettingType::Integer:
      return integer_at(c, r.member);
    case SettingType::Number:
      return at<double>(c, r.member);
    case SettingType::Flag:
      return flag_at(c, r.member);
    case SettingType::Unsigned:
      return at<std::uint64_t>(c, r.member);
    case SettingType::Epochs:
      return at<std::array<int, 3>>(c, r.member);
    case SettingType::Frozen: {
      const std::array<bool, 3>& f = at<std::array<bool, 3>>(c, r.member);
      return {{kLayerNames[0], f[0]}, {kLayerNames[1], f[1]}, {kLayerNames[2], f[2]}};
    }
    case SettingType::Classifier:
      return agent::to_string(c.network.*std::get<agent::ClassifierKind NetworkConfig::*>(r.member));
    case SettingType::Precision:  // never "auto"
      return agent::to_string(resolve_precision(at<agent::Precision>(c, r.member)));
    case SettingType::World:
      return worlds::to_yaml(at<worlds::World>(c, r.member));
    case SettingType::Folder:
      return at<fs::path>(c, r.member).string();
  }
  return nullptr;
}

// Reads a row's value from its parent object; `at` names the key it reads (for messages).
template <class At>
void read_value(const json& parent, const Row& r, TrainConfig& c, At&& at_key) {
  const TrainSetting& s = r.setting;
  const char* key = s.key.data();  // the table's keys are literals
  switch (s.type) {
    case SettingType::Integer:
      integer_at(c, r.member) = at_key(parent, key).template get<int>();
      return;
    case SettingType::Number:
      at<double>(c, r.member) = at_key(parent, key).template get<double>();
      return;
    case SettingType::Flag:
      flag_at(c, r.member) = at_key(parent, key).template get<bool>();
      return;
    case SettingType::Unsigned:
      at<std::uint64_t>(c, r.member) = at_key(parent, key).template get<std::uint64_t>();
      return;
    case SettingType::Epochs:
      at<std::array<int, 3>>(c, r.member) = at_key(parent, key).template get<std::array<int, 3>>();
      return;
    case SettingType::Frozen: {
      const json& f = at_key(parent, key);
      auto& frozen = at<std::array<bool, 3>>(c, r.member);
      for (int l = 0; l < 3; ++l) frozen[l] = at_key(f, kLayerNames[l]).template get<bool>();
      return;
    }
    case SettingType::Classifier:
      c.network.*std::get<agent::ClassifierKind NetworkConfig::*>(r.member) =
          agent::parse_classifier_kind(at_key(parent, key).template get<std::string>());
      return;
    case SettingType::Precision: {
      // Absent from checkpoints written before bf16 existed: those ran in fp32 (not today's default).
      agent::Precision& precision = at<agent::Precision>(c, r.member);
      precision = agent::Precision::Float32;
      if (parent.contains(key)) precision = agent::parse_precision(at_key(parent, key).template get<std::string>());
      if (precision == agent::Precision::Auto)
        throw std::invalid_argument("expected the resolved fp32 or bf16, got auto");
      return;
    }
    case SettingType::World: {
      const std::string world_file = at_key(parent, "world_file").template get<std::string>();
      const std::string yaml = at_key(parent, key).template get<std::string>();
      at<worlds::World>(c, r.member) = worlds::parse_world(yaml, world_file);
      return;
    }
    case SettingType::Folder:
      at<fs::path>(c, r.member) = at_key(parent, key).template get<std::string>();
      return;
  }
}

void check_range(const TrainConfig& config, const Row& r, SettingName name) {
  const TrainSetting& s = r.setting;
  TrainConfig& c = const_cast<TrainConfig&>(config);  // read only
  auto refuse = [&](auto value) { throw InputError(fmt::format("{}: {}, got {}", name(s), expected_text(s), value)); };
  if (s.type == SettingType::Integer && !in_range(s, integer_at(c, r.member))) refuse(integer_at(c, r.member));
  if (s.type == SettingType::Number && !in_range(s, at<double>(c, r.member))) refuse(at<double>(c, r.member));
  if (s.type == SettingType::Epochs)
    for (int e : at<std::array<int, 3>>(c, r.member))
      if (!in_range(s, e))
        throw InputError(fmt::format("{}: expected counts in {}, got {}", name(s), interval_text(s), e));
}

}  // namespace

std::span<const TrainSetting> train_settings() {
  static const std::vector<TrainSetting> settings = [] {
    std::vector<TrainSetting> out;
    for (const Row& r : kRows) out.push_back(r.setting);
    return out;
  }();
  return settings;
}

const TrainSetting& train_setting(std::string_view key) {
  for (const TrainSetting& s : train_settings())
    if (setting_key(s) == key) return s;
  throw std::out_of_range("no training setting " + std::string(key));
}

std::string setting_key(const TrainSetting& s) {
  return s.section.empty() ? std::string(s.key) : std::string(s.section) + "." + std::string(s.key);
}

const char* to_string(Agreement part) {
  switch (part) {
    case Agreement::World:
      return "world";
    case Agreement::Networks:
      return "networks";
    case Agreement::Training:
      return "training settings";
    case Agreement::None:
      break;
  }
  return "";
}

std::string setting_help(const TrainSetting& s) {
  std::string help(s.help);
  if (s.type == SettingType::Classifier)  // "Classifier: paper: METHOD.md's dense blocks ... | strided: ..."
    for (const agent::ClassifierVariant& variant : agent::kClassifierVariants) {
      if (&variant != &agent::kClassifierVariants[0]) help += " | ";
      help += std::string(variant.name) + ": " + variant.help;
    }
  return help;
}

std::string setting_value_name(const TrainSetting& s) {
  if (!s.value_name.empty()) return std::string(s.value_name);
  return (s.type == SettingType::Number ? "FLOAT in " : "INT in ") + interval_text(s);
}

std::string setting_text(const TrainConfig& config, const TrainSetting& s) {
  const Row& r = row_of(s);
  TrainConfig& c = const_cast<TrainConfig&>(config);  // read only
  switch (s.type) {
    case SettingType::Number:
      return fmt::format("{}", at<double>(c, r.member));  // 0.001, 0 (JSON would write 0.0)
    case SettingType::Flag:
      return flag_at(c, r.member) ? "on" : "off";
    case SettingType::Epochs: {
      const std::array<int, 3>& e = at<std::array<int, 3>>(c, r.member);
      return fmt::format("{},{},{}", e[0], e[1], e[2]);
    }
    case SettingType::Frozen: {
      std::string text;
      for (int l = 0; l < 3; ++l)
        if (at<std::array<bool, 3>>(c, r.member)[l]) text += (text.empty() ? "" : ",") + std::string(kLayerNames[l]);
      return text.empty() ? "none" : text;
    }
    case SettingType::Precision:
      return agent::to_string(at<agent::Precision>(c, r.member));
    case SettingType::World:
      return at<worlds::World>(c, r.member).file.string();
    default:
      break;
  }
  const json value = value_json(config, r);
  return value.is_string() ? value.get<std::string>() : value.dump();
}

void set_setting(TrainConfig& config, const TrainSetting& s, const std::string& text) {
  const Row& r = row_of(s);
  const std::string refusal =
      fmt::format("{}{} got '{}'", expected_text(s), s.type == SettingType::Frozen ? ";" : ",", one_line(text));
  try {
    switch (s.type) {
      case SettingType::Integer: {
        const std::optional<long long> value = plain_integer(text);
        if (!value || !in_range(s, static_cast<double>(*value))) throw std::invalid_argument("");
        integer_at(config, r.member) = static_cast<int>(*value);
        return;
      }
      case SettingType::Number: {
        double value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        if (text.empty() || ptr != end || ec != std::errc() || !std::isfinite(value) || !in_range(s, value))
          throw std::invalid_argument("");
        at<double>(config, r.member) = value;
        return;
      }
      case SettingType::Flag:
        if (text != "on" && text != "off") throw std::invalid_argument("");
        flag_at(config, r.member) = text == "on";
        return;
      case SettingType::Unsigned: {
        std::uint64_t value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        if (text.empty() || ec != std::errc() || ptr != end) throw std::invalid_argument("");
        at<std::uint64_t>(config, r.member) = value;
        return;
      }
      case SettingType::Epochs:
        at<std::array<int, 3>>(config, r.member) = parse_epochs(s, text);
        return;
      case SettingType::Frozen:
        at<std::array<bool, 3>>(config, r.member) = parse_frozen(text);
        return;
      case SettingType::Classifier:
        config.network.*std::get<agent::ClassifierKind NetworkConfig::*>(r.member) = agent::parse_classifier_kind(text);
        return;
      case SettingType::Precision:
        at<agent::Precision>(config, r.member) = agent::parse_precision(text);
        return;
      case SettingType::World:
      case SettingType::Folder:
        break;
    }
  } catch (const std::invalid_argument&) {
    throw InputError(refusal);
  }
  throw std::logic_error("set_setting: " + setting_key(s) + " is not an option");
}

std::string agreement_text(const TrainConfig& config, Agreement part) {
  json values = json::object();
  for (const Row& r : kRows)
    if (r.setting.agreement == part) values[setting_key(r.setting)] = value_json(config, r);
  return values.dump();
}

void TrainConfig::validate(SettingName name) const {
  if (name == nullptr) name = setting_key;
  for (const Row& r : kRows) check_range(*this, r, name);
  // agent::NetworkConfig's own rules beyond the ranges ("classifier_width: expected ..."), named
  // as its row is.
  try {
    network.validate();
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    const std::string field = what.substr(0, what.find(':'));
    for (const TrainSetting& s : train_settings())
      if (s.section == "network" && s.key == field) throw InputError(name(s) + what.substr(field.size()));
    throw InputError("network." + what);
  }
  if (network.goals_only && epochs[2] > 0)
    throw InputError(
        fmt::format("{}: a goals-only agent ({}) has no action layer to train in mode iii: expected 0 "
                    "epochs of mode iii, got {} (give them to mode ii)",
                    name(train_setting("epochs")), name(train_setting("network.goals_only")), epochs[2]));
  const TrainSetting& batch = train_setting("batch_images");
  const TrainSetting& n = train_setting("rollouts");
  const int team = world.team.robots;  // a rollout is a team of K robots
  const long long robots = static_cast<long long>(batch_images) * rollouts * team;
  if (robots > env::kMaxRobots)
    throw InputError(team == 1
                         ? fmt::format("{} x {}: expected at most {} robots (what one camera draws), got {} x {} "
                                       "= {}",
                                       name(batch), name(n), env::kMaxRobots, batch_images, rollouts, robots)
                         : fmt::format("{} x {} x team.robots: expected at most {} robots (what one camera "
                                       "draws), got {} x {} x {} = {}",
                                       name(batch), name(n), env::kMaxRobots, batch_images, rollouts, team, robots));
  if (leave_one_out && rollouts < 2)
    throw InputError(
        fmt::format("{}: the leave-one-out baseline needs {} >= 2", name(train_setting("leave_one_out")), name(n)));
}

std::string TrainConfig::to_json() const {
  json j;
  for (const Row& r : kRows) {
    json& parent = r.setting.section.empty() ? j : j[std::string(r.setting.section)];
    // Off is the default of a flag added after files without it were written: those stay as they were.
    if (r.setting.stored_unless_default && is_default_zero(const_cast<TrainConfig&>(*this), r)) continue;
    parent[std::string(r.setting.key)] = value_json(*this, r);
    if (r.setting.type == SettingType::World) parent["world_file"] = world.file.string();
  }
  return j.dump(2);
}

TrainConfig TrainConfig::from_json(const std::string& text, const std::string& origin) {
  TrainConfig c;
  std::string field = "config";
  if (const std::optional<std::size_t> at = json_nested_beyond(text, kMaxJsonNesting))
    throw InputError(
        fmt::format("{}: config: arrays and objects nested more than {} deep (at byte {}; Scout's "
                    "writer nests 2)",
                    origin, kMaxJsonNesting, *at));
  try {
    const json j = json::parse(text);
    auto at_key = [&](const json& parent, const char* key) -> const json& {
      field = key;
      return parent.at(key);
    };
    for (const Row& r : kRows) {
      const json& parent = r.setting.section.empty() ? j : at_key(j, r.setting.section.data());
      if (r.setting.stored_unless_default && !parent.contains(r.setting.key.data())) continue;  // off
      read_value(parent, r, c, at_key);
    }
  } catch (const InputError& e) {
    throw InputError(origin + ": config: the stored world is invalid (" + one_line(e.what()) + ")");
  } catch (const std::exception& e) {
    throw InputError(origin + ": config: " + field + ": missing or of the wrong type (" + one_line(e.what()) + ")");
  }
  try {
    c.validate();
  } catch (const InputError& e) {
    throw InputError(origin + ": config: " + one_line(e.what()));
  }
  return c;
}

const char* to_string(Stage stage) {
  switch (stage) {
    case Stage::Pretrain:
      return "full";
    case Stage::ModeI:
      return "i";
    case Stage::ModeII:
      return "ii";
    case Stage::ModeIII:
      return "iii";
    case Stage::Done:
      return "done";
  }
  return "?";
}

std::uint64_t estimate_training_bytes(const TrainConfig& config, int width_px, int height_px, int world_size) {
  const agent::NetworkConfig& n = config.network;
  const double area = static_cast<double>(width_px) * height_px;
  const double element = config.precision == agent::Precision::Float32 ? 4 : 2;
  // A dense stack keeps each block's concatenated input and its ReLU output for backward.
  double planner = 0;
  const double planner_in = agent::planner_channels(n);
  for (int k = 0; k <= n.planner_depth; ++k) planner += planner_in + k * double(n.planner_width);
  planner += n.planner_depth * double(n.planner_width);
  // The goal context branch: its convolutions' inputs and outputs at 1/4 resolution (1/16 of the
  // area), its upsampled scores at full resolution.
  planner += 2.0 * (agent::kGoalContextBlocks + 3) * n.goal_context / 16 + 2;
  planner *= area * element;
  double classifier = 0;  // activations kept for one image
  const double w = n.classifier_width;
  switch (n.classifier) {
    case agent::ClassifierKind::Paper: {
      double channels = n.image_channels;
      for (int k = 0; k < n.classifier_depth; ++k) {
        const double width = w * double(1 << k);
        classifier += channels + 2 * width;  // the block's input, its convolution and its ReLU
        channels += width;
      }
      classifier = (classifier + channels + n.classes) * area;
      break;
    }
    case agent::ClassifierKind::PaperStrided:
    case agent::ClassifierKind::PaperStridedNorm: {
      const double per_width = n.classifier == agent::ClassifierKind::PaperStridedNorm ? 3 : 2;
      double channels = n.image_channels;
      double pixels = area;
      for (int k = 0; k < n.classifier_depth; ++k) {
        if (k > 0) pixels = std::ceil(std::sqrt(pixels) / 2) * std::ceil(std::sqrt(pixels) / 2);
        const double width = w * double(1 << k);
        classifier += (channels + per_width * width) * pixels;  // input (pooled), convolution, [norm,] ReLU
        channels += width;
      }
      classifier += (channels + n.classes) * pixels;
      break;
    }
    case agent::ClassifierKind::Strided: {
      double pixels = area;
      for (int k = 0; k < n.classifier_depth; ++k) {
        pixels /= 4;
        classifier += 7 * w * double(1 << k) * pixels;  // two convolutions, two norms, two ReLUs, an input
      }
      classifier += n.image_channels * area;
      break;
    }
    case agent::ClassifierKind::ResNet18: {
      double pixels = area;
      for (int stage = 0; stage < 4; ++stage) {
        if (stage > 0) pixels /= 4;
        classifier += 16 * w * double(1 << stage) * pixels;  // two blocks of conv, norm, ReLU, sum
      }
      classifier += 3 * w * area;  // the stem
      break;
    }
  }
  classifier *= element + 4;  // the activations and their fp32 normalisation or gradient copies
  // A rollout is a team of K robots (one robot without a team): its K robots make the one robot's
  // planner calls between them, and the classifier decides once.
  const double rollouts = std::ceil(double(config.batch_images) / world_size) * config.rollouts;
  const double team = config.world.team.robots;
  // The goal planner once an episode, then (with an action planner) once a move: mode iii's graph.
  const double calls = config.world.task.episodes * (1.0 + (n.goals_only ? 0.0 : config.world.task.steps));
  const double state = area * (n.image_channels + 4) * 4 * 2;  // observations, masks, the camera's floor
  // + Box2D's body and contacts per robot
  const double per_rollout = calls * planner + classifier + team * (state + 16 * 1024);
  const double weights = double(agent::parameter_count(n)) * (4 * 4 + 2);  // fp32 x 4, a bf16 copy
  constexpr double kBase = 600.0 * 1024 * 1024;  // LibTorch, OpenMP, Mesa's llvmpipe, the data
  return static_cast<std::uint64_t>(kBase + weights + rollouts * per_rollout);
}

}  // namespace scout::learn
