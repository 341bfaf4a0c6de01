#pragma once
/// The training step's speed (scout bench train): images per second of full training steps in
/// each mode, with the physics and the camera in the loop, and where the time goes. Torch-free:
/// the CLI includes this header.
#include <filesystem>
#include <functional>
#include <vector>

#include "learn/trainer.hpp"

namespace scout::learn {

struct TrainBenchConfig {
  TrainConfig train;          ///< world, data, networks, N, B, lr, baseline, precision, seed
  std::vector<Stage> modes;   ///< which stages to time (ModeI..ModeIII, Pretrain)
  int batches = 5;            ///< timed batches per mode (after the warm-up)
  int warmup = 1;             ///< untimed batches per mode first (allocator, oneDNN kernels)
  int threads = 0;            ///< LibTorch threads (0: one per core)
  bool force_memory = false;  ///< run even when estimate_training_bytes exceeds the available memory
};

/// Where one training step's time went, seconds (medians over the timed batches for `step_s`,
/// sums over them for the parts, so that the parts add up to the total).
struct StepTimes {
  double physics_s = 0;     ///< Box2D: moves of every robot
  double render_s = 0;      ///< the OSMesa camera: patches rendered and read back
  double state_s = 0;       ///< y, l, h, g_l written into tensors, revealed-pixel bookkeeping
  double forward_s = 0;     ///< planners and classifier forward, sampling, log pi, J-hat
  double backward_s = 0;    ///< autograd through every decision and the classifier
  double optimizer_s = 0;   ///< Adam's step
  double all_reduce_s = 0;  ///< data-parallel: flattening, summing over the processes and writing back the gradients
  double total_s = 0;       ///< the whole step (the parts plus what falls between them)
};

struct ModeBench {
  Stage mode = Stage::ModeI;
  int batches = 0;
  double images_per_s = 0;         ///< B / median step time
  double median_step_s = 0;        ///< median over the timed batches
  StepTimes sum;                   ///< over the timed batches
  double action_decisions = 0;     ///< per batch: robots x moves that went through the action planner
  double simulation_share() const  ///< physics + camera, of the whole step
  {
    return sum.total_s > 0 ? (sum.physics_s + sum.render_s) / sum.total_s : 0;
  }
};

struct TrainBenchReport {
  std::vector<ModeBench> modes;
  int threads = 0;                                ///< per process
  int world_size = 1;                             ///< processes sharing each batch
  double all_reduce_bytes = 0;                    ///< gradient bytes summed per step (fp32)
  int robots = 0;                                 ///< B x N per batch, over all processes
  std::vector<std::filesystem::path> data_files;  ///< the IDX files read (for manifests)
  std::uint64_t estimated_bytes = 0;              ///< estimate_training_bytes for this process's share
  std::uint64_t peak_bytes = 0;                   ///< this process's peak resident size at the end (VmHWM)
};

class ProcessGroup;  // learn/distributed.hpp

/// Times training steps exactly as Trainer runs them (fresh weights from the config's seed, Adam,
/// the same batches and estimator), nothing written. `stop` is polled between batches; a stop
/// throws core::Stopped. With a `group` every rank calls this: each drives its share of every
/// batch and the gradients are summed over the ranks, as in data-parallel training.
TrainBenchReport bench_training(const TrainBenchConfig& config, const core::StopToken& stop = {},
                                ProcessGroup* group = nullptr);

}  // namespace scout::learn
