#include "env/runs.hpp"

#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/seed_streams.hpp"

namespace scout::env {

grid::Cell draw_start(const worlds::World& world, const grid::FloorFrame& frame, core::Rng& rng) {
  if (world.robot.start) return {world.robot.start->first, world.robot.start->second};
  if (world.obstacles.none()) {
    const auto pixel = static_cast<int>(core::uniform_below(rng, static_cast<std::uint64_t>(frame.area_px())));
    return {pixel % frame.width_px, pixel / frame.width_px};
  }
  // Uniform over the cells where the robot's disc fits beside the obstacles.
  const double radius_px = world.robot.radius_m / frame.pixel_size_m;
  std::vector<grid::Cell> clear;
  for (int y = 0; y < frame.height_px; ++y)
    for (int x = 0; x < frame.width_px; ++x)
      if (world.obstacles.clearance_px(x + 0.5, y + 0.5) >= radius_px) clear.emplace_back(x, y);
  if (clear.empty())
    throw InputError(field_location(world, "obstacles") +
                     ": expected room for the robot's disc beside the obstacles, got no cell at least " +
                     std::to_string(radius_px) + " px from every obstacle");
  return clear[core::uniform_below(rng, clear.size())];
}

RunSequence::RunSequence(const worlds::World& world, const grid::FloorFrame& frame, int split_size, std::uint64_t seed)
    : world_(world), frame_(frame), seed_(seed) {
  if (split_size <= 0) throw std::invalid_argument("RunSequence: the split has no digit");
  if (!world.floor.index) {
    digit_order_.resize(static_cast<std::size_t>(split_size));
    for (int i = 0; i < split_size; ++i) digit_order_[i] = i;
    core::Rng order_rng(core::derive_seed(seed, streams::kRunDigitOrder));
    core::shuffle(digit_order_, order_rng);
  }
}

PlannedRun RunSequence::run(std::uint64_t k) const {
  PlannedRun r;
  r.seed = core::derive_seed(seed_, k);
  r.index = world_.floor.index ? *world_.floor.index : digit_order_[k % digit_order_.size()];
  core::Rng start_rng(core::derive_seed(r.seed, streams::kRunStart));
  r.start = draw_start(world_, frame_, start_rng);
  r.policy_seed = core::derive_seed(r.seed, streams::kRunPolicy);
  r.motion_seed = core::derive_seed(r.seed, streams::kRunMotion);
  return r;
}

}  // namespace scout::env
