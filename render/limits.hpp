#pragma once
/// The camera's limits, GL-free, for the layers above that size their batches by them.

namespace scout::render {

/// The most robots one camera draws (its `max_robots`): the one limit that env::BatchEnv,
/// env::VectorEnv's num_envs, `scout bench sim --robots` and a training batch (B x N, checked by
/// learn::TrainConfig::validate) derive from.
inline constexpr int kMaxCameraRobots = 4096;

}  // namespace scout::render
