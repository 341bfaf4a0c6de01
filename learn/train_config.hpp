#pragma once
/// The configuration of a training run (METHOD.md § Training modes): the stages of the schedule,
/// the layers, and everything that determines a run, as stored in every checkpoint. Torch-free.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>

#include "agent/config.hpp"
#include "worlds/world.hpp"

namespace scout::learn {

/// A stage of the schedule. Pretrain trains the classifier on full images (u_c = x), the
/// transfer variant's first step; modes (i) - (iii) are METHOD.md's.
enum class Stage { Pretrain = 0, ModeI = 1, ModeII = 2, ModeIII = 3 };
const char* to_string(Stage stage);  ///< "full", "i", "ii", "iii"

/// The layers, in the order of TrainConfig::frozen.
enum class Layer { Goal = 0, Action = 1, Classifier = 2 };

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
  /// The networks' arithmetic (weights stay fp32). A new run resolves Auto for its CPU
  /// (agent::resolve_precision); checkpoints and manifests hold the resolved fp32 or bf16.
  agent::Precision precision = agent::Precision::Auto;
  std::array<bool, 3> frozen = {false, false, false};  ///< per Layer: not updated in modes (i)-(iii)
  std::uint64_t seed = 1;                              ///< initialisation, data order, starts and sampling
  int train_limit = 0;                                 ///< train on the first K training digits only (0: all)
  int validation_limit = 0;                            ///< validate on the first K validation digits only (0: all)

  /// Throws InputError naming the option when a value is out of range.
  void validate() const;
  /// The config as JSON text (the world as YAML inside) and back; `origin` names the source in errors.
  std::string to_json() const;
  static TrainConfig from_json(const std::string& text, const std::string& origin);
};

/// About how much memory training `config` on floors of width x height takes at its peak (mode
/// (iii), where both planners keep their activations for the backward pass of every robot), with
/// each of `world_size` processes driving its share of a batch: the weights, their gradients and
/// Adam's moments, the planners' and the classifier's saved activations per robot, the physics
/// and camera per robot, and the process's own base (LibTorch, Mesa). An estimate for refusing
/// requests that cannot fit (`scout train` refuses them unless --force), not an exact figure:
/// learn/README.md compares it with measured peaks.
std::uint64_t estimate_training_bytes(const TrainConfig& config, int width_px, int height_px, int world_size = 1);

}  // namespace scout::learn
