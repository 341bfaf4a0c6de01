#include "env/runs.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/seed_streams.hpp"
#include "sim/robots.hpp"

namespace scout::env {

namespace {

double robot_radius_px(const worlds::World& world, const grid::FloorFrame& frame) {
  return world.robot.radius_m / frame.pixel_size_m;
}

// An integer drawn uniformly from [lo, hi].
int uniform_between(core::Rng& rng, int lo, int hi) {
  return lo + static_cast<int>(core::uniform_below(rng, static_cast<std::uint64_t>(hi - lo + 1)));
}

}  // namespace

worlds::ObstacleSpec run_obstacles(const worlds::World& world, const grid::FloorFrame& frame,
                                   std::uint64_t motion_seed) {
  worlds::ObstacleSpec layout = world.obstacles;
  layout.random_boxes = 0;
  const worlds::ObstacleSpec& spec = world.obstacles;
  if (spec.random_boxes == 0) return layout;
  const int longest = std::min({spec.random_box_max_px, frame.width_px, frame.height_px});
  const int shortest = std::min(spec.random_box_min_px, longest);
  constexpr int kDraws = 1000;
  core::Rng rng(core::derive_seed(motion_seed, streams::kMotionObstacles));
  for (int draw = 0; draw < kDraws; ++draw) {
    layout.boxes.resize(world.obstacles.boxes.size());
    for (int k = 0; k < spec.random_boxes; ++k) {
      const int w = uniform_between(rng, shortest, longest), h = uniform_between(rng, shortest, longest);
      layout.boxes.push_back({.x = uniform_between(rng, 0, frame.width_px - w),
                              .y = uniform_between(rng, 0, frame.height_px - h),
                              .w = w,
                              .h = h});
    }
    // Room for the robot's disc: on the world's fixed start, or on some cell.
    const bool room = world.robot.start
                          ? layout.clearance_px(world.robot.start->first + 0.5, world.robot.start->second + 0.5) >=
                                robot_radius_px(world, frame)
                          : std::ranges::count(occupied_cells(world, frame, layout), 0) > 0;
    if (room) return layout;
  }
  throw InputError(field_location(world, "obstacles.random_boxes") +
                   fmt::format(": expected room for the robot's disc beside {} random boxes, got none in {} draws "
                               "(fewer or smaller boxes, or a smaller robot)",
                               spec.random_boxes, kDraws));
}

std::vector<std::uint8_t> occupied_cells(const worlds::World& world, const grid::FloorFrame& frame,
                                         const worlds::ObstacleSpec& layout) {
  std::vector<std::uint8_t> occupied(static_cast<std::size_t>(frame.area_px()), 0);
  const double r = robot_radius_px(world, frame);
  // clearance_px < r where some obstacle is nearer than r: each obstacle marks the cells of its
  // bounding box widened by r that are (a few hundred cells, not the floor times the obstacles:
  // every reset of a world with random boxes computes this for each robot).
  auto mark = [&](double x0, double y0, double x1, double y1, const auto& obstacle) {
    const int cx0 = std::max(0, static_cast<int>(std::floor(x0 - r - 0.5)));
    const int cx1 = std::min(frame.width_px - 1, static_cast<int>(std::ceil(x1 + r - 0.5)));
    const int cy0 = std::max(0, static_cast<int>(std::floor(y0 - r - 0.5)));
    const int cy1 = std::min(frame.height_px - 1, static_cast<int>(std::ceil(y1 + r - 0.5)));
    for (int y = cy0; y <= cy1; ++y)
      for (int x = cx0; x <= cx1; ++x)
        if (obstacle.distance_px(x + 0.5, y + 0.5) < r) occupied[static_cast<std::size_t>(y) * frame.width_px + x] = 1;
  };
  for (const worlds::BoxObstacle& b : layout.boxes) mark(b.x, b.y, b.x + b.w, b.y + b.h, b);
  for (const worlds::DiscObstacle& d : layout.discs) mark(d.x - d.r, d.y - d.r, d.x + d.r, d.y + d.r, d);
  return occupied;
}

grid::Cell draw_start(const worlds::World& world, const grid::FloorFrame& frame, const worlds::ObstacleSpec& layout,
                      core::Rng& rng) {
  if (world.robot.start) return {world.robot.start->first, world.robot.start->second};
  if (layout.no_fixed()) {
    const auto pixel = static_cast<int>(core::uniform_below(rng, static_cast<std::uint64_t>(frame.area_px())));
    return {pixel % frame.width_px, pixel / frame.width_px};
  }
  // Uniform over the cells where the robot's disc fits beside the obstacles.
  const std::vector<std::uint8_t> occupied = occupied_cells(world, frame, layout);
  std::vector<grid::Cell> clear;
  for (int y = 0; y < frame.height_px; ++y)
    for (int x = 0; x < frame.width_px; ++x)
      if (!occupied[static_cast<std::size_t>(y) * frame.width_px + x]) clear.emplace_back(x, y);
  if (clear.empty())
    throw InputError(field_location(world, "obstacles") +
                     ": expected room for the robot's disc beside the obstacles, got no cell at least " +
                     std::to_string(robot_radius_px(world, frame)) + " px from every obstacle");
  return clear[core::uniform_below(rng, clear.size())];
}

grid::Cell draw_start(const worlds::World& world, const grid::FloorFrame& frame, std::uint64_t motion_seed,
                      core::Rng& rng) {
  if (world.obstacles.random_boxes == 0) return draw_start(world, frame, world.obstacles, rng);
  return draw_start(world, frame, run_obstacles(world, frame, motion_seed), rng);
}

grid::Cell draw_start(const worlds::World& world, const grid::FloorFrame& frame, core::Rng& rng) {
  if (world.obstacles.random_boxes > 0)
    throw std::logic_error("env::draw_start: a world with random boxes draws each start beside its run's layout");
  return draw_start(world, frame, world.obstacles, rng);
}

std::uint64_t member_seed(std::uint64_t seed, int member) {
  return member == 0 ? seed : core::derive_seed(seed, streams::kTeamMember + static_cast<std::uint64_t>(member));
}

std::vector<grid::Cell> draw_team_starts(const worlds::World& world, const grid::FloorFrame& frame,
                                         std::uint64_t motion_seed, core::Rng& rng) {
  const worlds::ObstacleSpec layout =
      world.obstacles.random_boxes == 0 ? world.obstacles : run_obstacles(world, frame, motion_seed);
  std::vector<grid::Cell> starts{draw_start(world, frame, layout, rng)};
  // Apart by more than their bumpers' reach, so that no contact acts before the first move.
  const double spacing = 2.0 * sim::RobotBatch::bumper_radius_px(sim::RobotParams::from_world(world), frame);
  constexpr int kDraws = 1000;
  for (int draw = 0; static_cast<int>(starts.size()) < world.team.robots; ++draw) {
    if (draw == kDraws)
      throw InputError(field_location(world, "team.robots") +
                       fmt::format(": expected room for {} robots' discs on the floor, got {} placed in {} draws "
                                   "(fewer robots, or a smaller robot)",
                                   world.team.robots, starts.size(), kDraws));
    const grid::Cell c = draw_start(world, frame, layout, rng);
    const bool apart = std::ranges::all_of(
        starts, [&](const grid::Cell& s) { return static_cast<double>((c - s).squaredNorm()) > spacing * spacing; });
    if (apart) starts.push_back(c);
  }
  return starts;
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
  r.policy_seed = core::derive_seed(r.seed, streams::kRunPolicy);
  r.motion_seed = core::derive_seed(r.seed, streams::kRunMotion);
  r.floor_key = core::derive_seed(r.seed, streams::kRunFloor);
  r.obstacles = run_obstacles(world_, frame_, r.motion_seed);
  core::Rng start_rng(core::derive_seed(r.seed, streams::kRunStart));
  r.starts = draw_team_starts(world_, frame_, r.motion_seed, start_rng);
  r.start = r.starts.front();
  return r;
}

}  // namespace scout::env
