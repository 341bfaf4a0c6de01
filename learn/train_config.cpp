// TrainConfig: validation and its JSON form (stored in checkpoints and manifests).
#include "learn/train_config.hpp"

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "core/error.hpp"

namespace scout::learn {

using json = nlohmann::ordered_json;

namespace {

// Upper bounds that catch typos before hours are spent, not research limits.
constexpr int kMaxEpochs = 100000;
constexpr int kMaxRollouts = 64;
constexpr int kMaxBatchImages = 4096;

void check_range(const char* option, long long value, long long lo, long long hi) {
  if (value < lo || value > hi)
    throw InputError(fmt::format("{}: expected an integer in [{}, {}], got {}", option, lo, hi, value));
}

}  // namespace

void TrainConfig::validate() const {
  try {
    network.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--") + e.what());
  }
  check_range("--pretrain-epochs", pretrain_epochs, 0, kMaxEpochs);
  for (int e : epochs) check_range("--epochs", e, 0, kMaxEpochs);
  check_range("--rollouts", rollouts, 1, kMaxRollouts);
  check_range("--batch", batch_images, 1, kMaxBatchImages);
  check_range("--batch x --rollouts", static_cast<long long>(batch_images) * rollouts, 1, 16384);
  if (!(learning_rate > 0 && learning_rate < 10))
    throw InputError(fmt::format("--lr: expected a number in (0, 10), got {}", learning_rate));
  if (leave_one_out && rollouts < 2) throw InputError("--baseline: the leave-one-out baseline needs --rollouts >= 2");
  if (!(entropy_bonus >= 0 && entropy_bonus < 100))
    throw InputError(fmt::format("--entropy-bonus: expected a number in [0, 100), got {}", entropy_bonus));
  check_range("--train-limit", train_limit, 0, 100000000);
  check_range("--validation-limit", validation_limit, 0, 100000000);
}

std::string TrainConfig::to_json() const {
  json j;
  j["world_yaml"] = worlds::to_yaml(world);
  j["world_file"] = world.file.string();
  j["data_folder"] = data_folder.string();
  j["network"] = {{"image_channels", network.image_channels},
                  {"classes", network.classes},
                  {"planner_width", network.planner_width},
                  {"planner_depth", network.planner_depth},
                  {"classifier", agent::to_string(network.classifier)},
                  {"classifier_width", network.classifier_width},
                  {"classifier_depth", network.classifier_depth}};
  j["pretrain_epochs"] = pretrain_epochs;
  j["epochs"] = epochs;
  j["rollouts"] = rollouts;
  j["batch_images"] = batch_images;
  j["learning_rate"] = learning_rate;
  j["leave_one_out"] = leave_one_out;
  j["entropy_bonus"] = entropy_bonus;
  j["precision"] = agent::to_string(agent::resolve_precision(precision));  // never "auto"
  j["frozen"] = {{"goal", frozen[0]}, {"action", frozen[1]}, {"classifier", frozen[2]}};
  j["seed"] = seed;
  j["train_limit"] = train_limit;
  j["validation_limit"] = validation_limit;
  return j.dump(2);
}

TrainConfig TrainConfig::from_json(const std::string& text, const std::string& origin) {
  TrainConfig c;
  std::string field = "config";
  try {
    const json j = json::parse(text);
    auto at = [&](const json& parent, const char* key) -> const json& {
      field = key;
      return parent.at(key);
    };
    const std::string world_file = at(j, "world_file").get<std::string>();
    c.world = worlds::parse_world(at(j, "world_yaml").get<std::string>(), world_file);
    c.data_folder = at(j, "data_folder").get<std::string>();
    const json& n = at(j, "network");
    c.network.image_channels = at(n, "image_channels").get<int>();
    c.network.classes = at(n, "classes").get<int>();
    c.network.planner_width = at(n, "planner_width").get<int>();
    c.network.planner_depth = at(n, "planner_depth").get<int>();
    c.network.classifier = agent::parse_classifier_kind(at(n, "classifier").get<std::string>());
    c.network.classifier_width = at(n, "classifier_width").get<int>();
    c.network.classifier_depth = at(n, "classifier_depth").get<int>();
    c.pretrain_epochs = at(j, "pretrain_epochs").get<int>();
    c.epochs = at(j, "epochs").get<std::array<int, 3>>();
    c.rollouts = at(j, "rollouts").get<int>();
    c.batch_images = at(j, "batch_images").get<int>();
    c.learning_rate = at(j, "learning_rate").get<double>();
    c.leave_one_out = at(j, "leave_one_out").get<bool>();
    c.entropy_bonus = at(j, "entropy_bonus").get<double>();
    // Absent from checkpoints written before bf16 existed: those ran in fp32 (not today's default).
    c.precision = agent::Precision::Float32;
    if (j.contains("precision")) c.precision = agent::parse_precision(at(j, "precision").get<std::string>());
    if (c.precision == agent::Precision::Auto) {
      field = "precision";
      throw std::invalid_argument("expected the resolved fp32 or bf16, got auto");
    }
    const json& f = at(j, "frozen");
    c.frozen = {at(f, "goal").get<bool>(), at(f, "action").get<bool>(), at(f, "classifier").get<bool>()};
    c.seed = at(j, "seed").get<std::uint64_t>();
    c.train_limit = at(j, "train_limit").get<int>();
    c.validation_limit = at(j, "validation_limit").get<int>();
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
  }
  return "?";
}

std::uint64_t estimate_training_bytes(const TrainConfig& config, int width_px, int height_px, int world_size) {
  const agent::NetworkConfig& n = config.network;
  const double area = static_cast<double>(width_px) * height_px;
  const double element = config.precision == agent::Precision::Float32 ? 4 : 2;
  // A dense stack keeps each block's concatenated input and its ReLU output for backward.
  double planner = 0;
  const double planner_in = n.image_channels + 3.0;
  for (int k = 0; k <= n.planner_depth; ++k) planner += planner_in + k * double(n.planner_width);
  planner += n.planner_depth * double(n.planner_width);
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
  const double robots = std::ceil(double(config.batch_images) / world_size) * config.rollouts;
  const double calls = config.world.task.episodes * (1.0 + config.world.task.steps);  // goals, then each move
  const double state = area * (n.image_channels + 4) * 4 * 2;                 // observations, masks, the camera's floor
  const double per_robot = calls * planner + classifier + state + 16 * 1024;  // + Box2D's body and contacts
  const double weights = double(agent::parameter_count(n)) * (4 * 4 + 2);     // fp32 x 4, a bf16 copy
  constexpr double kBase = 600.0 * 1024 * 1024;  // LibTorch, OpenMP, Mesa's llvmpipe, the data
  return static_cast<std::uint64_t>(kBase + weights + robots * per_robot);
}

}  // namespace scout::learn
