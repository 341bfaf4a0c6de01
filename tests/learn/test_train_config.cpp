// The training settings' schema table (learn/train_config.cpp): it drives the JSON a checkpoint
// stores (keys unchanged, so older checkpoints still read), the ranges and their messages (named
// by JSON key, never by a command-line flag), the options' texts, and what ranks compare.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "core/error.hpp"
#include "env/batch_env.hpp"
#include "learn/train_config.hpp"
#include "render/camera.hpp"
#include "worlds/world.hpp"

namespace scout::learn {
namespace {

worlds::World preset_world() { return worlds::load_world(std::string(SCOUT_SOURCE_DIR) + "/worlds/mnist.yaml"); }

TrainConfig valid_config() {
  TrainConfig c;
  c.world = preset_world();
  c.data_folder = "/data/mnist";
  c.precision = agent::Precision::Float32;
  return c;
}

// The one-line InputError that from_json throws for `text` (empty if none).
std::string refusal(const std::string& text) {
  try {
    TrainConfig::from_json(text, "RUN/checkpoint.safetensors");
  } catch (const InputError& e) {
    return e.what();
  }
  return {};
}

// A config text whose `key` (a top-level integer) holds `value`.
std::string with_value(std::string text, const std::string& key, const std::string& value) {
  const std::size_t at = text.find("\"" + key + "\": ");
  EXPECT_NE(at, std::string::npos) << key;
  const std::size_t begin = at + key.size() + 4;
  text.replace(begin, text.find_first_of(",\n", begin) - begin, value);
  return text;
}

// The keys every checkpoint written so far holds, in the order they are written: a checkpoint
// written before this table must still read, and one written now must read in an older build.
TEST(TrainSettings, TheJsonKeysAreThoseCheckpointsHaveAlwaysHeld) {
  const nlohmann::ordered_json j = nlohmann::ordered_json::parse(valid_config().to_json());
  std::vector<std::string> keys;
  for (const auto& [key, value] : j.items()) keys.push_back(key);
  EXPECT_EQ(keys,
            (std::vector<std::string>{"world_yaml", "world_file", "data_folder", "network", "pretrain_epochs", "epochs",
                                      "rollouts", "batch_images", "learning_rate", "leave_one_out", "entropy_bonus",
                                      "precision", "frozen", "seed", "train_limit", "validation_limit"}));
  std::vector<std::string> network;
  for (const auto& [key, value] : j["network"].items()) network.push_back(key);
  EXPECT_EQ(network, (std::vector<std::string>{"image_channels", "classes", "planner_width", "planner_depth",
                                               "classifier", "classifier_width", "classifier_depth"}));
  EXPECT_EQ(j["frozen"].dump(), R"({"goal":false,"action":false,"classifier":false})");
}

// Every setting changed from its default survives to_json and from_json, and writes again the
// same text.
TEST(TrainSettings, EveryChangedSettingRoundTrips) {
  TrainConfig c = valid_config();
  c.network.planner_width = 8;
  c.network.planner_depth = 2;
  c.network.classifier = agent::ClassifierKind::Strided;
  c.network.classifier_width = 4;
  c.network.classifier_depth = 2;
  c.network.classes = 7;
  c.network.occupancy = true;
  c.network.goal_context = 24;
  c.pretrain_epochs = 3;
  c.epochs = {1, 0, 5};
  c.rollouts = 3;
  c.batch_images = 10;
  c.learning_rate = 0.0025;
  c.leave_one_out = true;
  c.entropy_bonus = 0.5;
  c.distillation = 0.25;
  c.precision = agent::Precision::BFloat16;
  c.frozen = {true, false, true};
  c.seed = 18446744073709551615ull;
  c.train_limit = 100;
  c.validation_limit = 20;
  const std::string text = c.to_json();
  const TrainConfig back = TrainConfig::from_json(text, "run");
  EXPECT_EQ(back.to_json(), text);
  for (const TrainSetting& s : train_settings()) EXPECT_EQ(setting_text(back, s), setting_text(c, s)) << setting_key(s);
  EXPECT_EQ(setting_text(back, train_setting("frozen")), "goal,classifier");
  EXPECT_EQ(setting_text(back, train_setting("leave_one_out")), "on");
  EXPECT_EQ(setting_text(back, train_setting("network.classifier")), "strided");
}

// The occupancy channel came after checkpoints without it: off, it is not written (every file
// written before stays byte for byte what it was, and reads off); on, it is, and reads back on.
TEST(TrainSettings, TheOccupancyFlagIsStoredOnlyWhenOn) {
  TrainConfig c = valid_config();
  const std::string off = c.to_json();
  EXPECT_EQ(off.find("occupancy"), std::string::npos);
  EXPECT_FALSE(TrainConfig::from_json(off, "run").network.occupancy);
  c.network.occupancy = true;
  const nlohmann::ordered_json on = nlohmann::ordered_json::parse(c.to_json());
  EXPECT_EQ(on["network"]["occupancy"], true);
  EXPECT_TRUE(TrainConfig::from_json(c.to_json(), "run").network.occupancy);
  EXPECT_EQ(setting_text(c, train_setting("network.occupancy")), "on");
  EXPECT_EQ(train_setting("network.occupancy").agreement, Agreement::Networks);
  // A stored value of the wrong type is refused like any other.
  std::string bad = c.to_json();
  bad.replace(bad.find("\"occupancy\": true"), std::string("\"occupancy\": true").size(), "\"occupancy\": 3");
  EXPECT_NE(refusal(bad).find("occupancy"), std::string::npos) << refusal(bad);
}

// The goal context branch and the full-image teacher came later still: 0 (none) is not written and
// an absent key reads 0; a value is written, reads back, and one out of range is refused naming the
// field.
TEST(TrainSettings, TheGoalContextAndTheTeachersWeightAreStoredOnlyWhenSet) {
  TrainConfig c = valid_config();
  EXPECT_EQ(c.to_json().find("goal_context"), std::string::npos);
  EXPECT_EQ(TrainConfig::from_json(c.to_json(), "run").network.goal_context, 0);
  c.network.goal_context = 32;
  EXPECT_EQ(nlohmann::ordered_json::parse(c.to_json())["network"]["goal_context"], 32);
  EXPECT_EQ(TrainConfig::from_json(c.to_json(), "run").network.goal_context, 32);
  std::string bad = c.to_json();
  bad.replace(bad.find("\"goal_context\": 32"), std::string("\"goal_context\": 32").size(), "\"goal_context\": 100000");
  EXPECT_NE(refusal(bad).find("goal_context"), std::string::npos) << refusal(bad);
  // The full-image teacher's weight alike: 0 unwritten (absent reads 0), any other value written.
  EXPECT_EQ(c.to_json().find("distillation"), std::string::npos);
  c.distillation = 0.5;
  EXPECT_EQ(nlohmann::ordered_json::parse(c.to_json())["distillation"], 0.5);
  EXPECT_EQ(TrainConfig::from_json(c.to_json(), "run").distillation, 0.5);
}

// An option's text sets its setting and reads back the same; a bad one is refused with the row's
// "expected ..." (the caller names the option or key).
TEST(TrainSettings, OptionTextsRoundTripAndBadOnesAreRefused) {
  for (const TrainSetting& s : train_settings()) {
    if (s.option.empty()) continue;
    TrainConfig c = valid_config();
    const std::string text = setting_text(c, s);
    TrainConfig again = valid_config();
    set_setting(again, s, text);
    EXPECT_EQ(setting_text(again, s), text) << setting_key(s);
    try {
      set_setting(again, s, "x,y");
      ADD_FAILURE() << setting_key(s) << " took x,y";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind("expected ", 0), 0u) << what;
      EXPECT_NE(what.find("'x,y'"), std::string::npos) << what;
    }
  }
  TrainConfig c = valid_config();
  EXPECT_THROW(set_setting(c, train_setting("rollouts"), "65"), InputError);
  EXPECT_THROW(set_setting(c, train_setting("rollouts"), "04"), InputError);  // not octal
  EXPECT_THROW(set_setting(c, train_setting("learning_rate"), "0"), InputError);
  EXPECT_THROW(set_setting(c, train_setting("epochs"), "1,2"), InputError);
  set_setting(c, train_setting("epochs"), "3,0,1");
  EXPECT_EQ(c.epochs, (std::array<int, 3>{3, 0, 1}));
  set_setting(c, train_setting("learning_rate"), "1e-4");
  EXPECT_EQ(c.learning_rate, 1e-4);
}

// A checkpoint's config out of range is refused naming the key, never a command-line flag
// (issue 23: "config: --rollouts: ..." read as if the user had typed it).
TEST(TrainSettings, ACheckpointsBadValueIsNamedByItsKey) {
  const std::string text = valid_config().to_json();
  const std::string rollouts = refusal(with_value(text, "rollouts", "0"));
  EXPECT_EQ(rollouts, "RUN/checkpoint.safetensors: config: rollouts: expected an integer in [1, 64], got 0");
  const std::string lr = refusal(with_value(text, "learning_rate", "10"));
  EXPECT_EQ(lr, "RUN/checkpoint.safetensors: config: learning_rate: expected a number in (0, 10), got 10");
  const std::string width = refusal(with_value(text, "planner_width", "0"));
  EXPECT_EQ(width, "RUN/checkpoint.safetensors: config: network.planner_width: expected an integer in [1, 512], got 0");
  const std::string baseline = refusal(with_value(with_value(text, "rollouts", "1"), "leave_one_out", "true"));
  EXPECT_EQ(baseline,
            "RUN/checkpoint.safetensors: config: leave_one_out: the leave-one-out baseline needs rollouts >= 2");
  for (const std::string& what : {rollouts, lr, width, baseline}) EXPECT_EQ(what.find("--"), std::string::npos) << what;
}

// The camera draws at most render::kMaxCameraRobots robots: a batch of more is refused up front
// with one line, by key in a checkpoint and by option on the command line.
TEST(TrainSettings, ABatchTheCameraCannotDrawIsRefusedUpFront) {
  static_assert(env::kMaxRobots == render::kMaxCameraRobots);
  TrainConfig c = valid_config();
  c.batch_images = 64;
  c.rollouts = render::kMaxCameraRobots / 64;
  EXPECT_NO_THROW(c.validate());
  c.batch_images = 65;
  try {
    c.validate();
    FAIL() << "65 x 64 robots were accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "batch_images x rollouts: expected at most 4096 robots (what one camera draws), got 65 x 64 = 4160");
  }
  try {
    c.validate([](const TrainSetting& s) { return std::string(s.option); });
    FAIL() << "65 x 64 robots were accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("--batch x --rollouts: expected at most 4096 robots", 0), 0u) << e.what();
  }
}

// The table's columns: every option is one setting's, the ranks compare what a run's numbers
// depend on (not paths, not what comes from the data), and a resume may change only the schedule,
// the rate, the full-image teacher's weight, the arithmetic and where the data is.
TEST(TrainSettings, TheTableSaysWhatEachCommandResumeAndRankDoes) {
  std::set<std::string_view> options;
  std::set<std::string> changes;
  for (const TrainSetting& s : train_settings()) {
    if (!s.option.empty()) {
      EXPECT_TRUE(options.insert(s.option).second) << s.option;
    }
    if (s.on_resume == OnResume::Changes) changes.insert(setting_key(s));
  }
  EXPECT_EQ(changes, (std::set<std::string>{"data_folder", "distillation", "epochs", "learning_rate", "precision"}));
  EXPECT_EQ(train_setting("rollouts").commands, SettingCommands::TrainAndBench);
  EXPECT_EQ(train_setting("seed").commands, SettingCommands::Train);

  const TrainConfig a = valid_config();
  TrainConfig moved = a;
  moved.data_folder = "/elsewhere";
  moved.network.classes = 5;  // from the data, compared by SHA-256
  TrainConfig other = a;
  other.entropy_bonus = 0.1;
  TrainConfig wider = a;
  wider.network.planner_width = 8;
  for (Agreement part : {Agreement::World, Agreement::Networks, Agreement::Training}) {
    EXPECT_EQ(agreement_text(moved, part), agreement_text(a, part)) << to_string(part);
    EXPECT_EQ(agreement_text(other, part) == agreement_text(a, part), part != Agreement::Training) << to_string(part);
    EXPECT_EQ(agreement_text(wider, part) == agreement_text(a, part), part != Agreement::Networks) << to_string(part);
  }
}

}  // namespace
}  // namespace scout::learn
