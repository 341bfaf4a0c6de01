#include "learn/rollout.hpp"

#include <chrono>
#include <stdexcept>
#include <string>

#include "core/random.hpp"
#include "core/timing.hpp"
#include "render/camera.hpp"

namespace scout::learn {

namespace {

using core::Clock;
using core::seconds_since;

}  // namespace

RandomPolicy::RandomPolicy(std::span<const std::uint64_t> seeds) {
  rngs_.reserve(seeds.size());
  for (std::uint64_t s : seeds) rngs_.emplace_back(s);
}

void RandomPolicy::choose_goals(const BatchState& state, int /*episode*/, std::span<grid::Cell> goals) {
  if (goals.size() > rngs_.size()) throw std::invalid_argument("RandomPolicy: more robots than seeds");
  const auto area = static_cast<std::uint64_t>(state.frame.area_px());
  for (std::size_t i = 0; i < goals.size(); ++i) {
    const auto pixel = static_cast<int>(core::uniform_below(rngs_[i], area));
    goals[i] = {pixel % state.frame.width_px, pixel / state.frame.width_px};
  }
}

void RandomPolicy::choose_axes(const BatchState& /*state*/, std::span<const std::uint8_t> need,
                               std::span<grid::Axis> axes) {
  if (need.size() > rngs_.size() || axes.size() < need.size())
    throw std::invalid_argument("RandomPolicy: more robots than seeds or axes");
  for (std::size_t i = 0; i < need.size(); ++i)
    if (need[i]) axes[i] = (rngs_[i]() >> 63) ? grid::Axis::Vertical : grid::Axis::Horizontal;
}

grid::Cell draw_start(const worlds::World& world, const grid::FloorFrame& frame, core::Rng& rng) {
  if (world.robot.start) return {world.robot.start->first, world.robot.start->second};
  const auto pixel = static_cast<int>(core::uniform_below(rng, static_cast<std::uint64_t>(frame.area_px())));
  return {pixel % frame.width_px, pixel / frame.width_px};
}

RolloutEngine::RolloutEngine(const worlds::World& world, const grid::FloorFrame& frame, int max_robots)
    : task_(world.task), max_robots_(max_robots) {
  if (max_robots <= 0) throw std::invalid_argument("RolloutEngine: max_robots must be positive");
  state_.frame = frame;
  state_.patch_px = world.camera.patch_px;
  state_.pose.resize(max_robots);
  state_.goal.resize(max_robots);
  state_.seen.assign(max_robots, grid::RevealMask(frame));
  state_.observed.resize(static_cast<std::size_t>(max_robots) * frame.area_px());
  robots_ = std::make_unique<sim::RobotBatch>(frame, sim::RobotParams::from_world(world), max_robots);
  camera_ = std::make_unique<render::PatchCamera>(frame.width_px, frame.height_px, world.camera.patch_px, max_robots);
  pixel_poses_.resize(max_robots);
  patches_.resize(static_cast<std::size_t>(max_robots) * world.camera.patch_px * world.camera.patch_px);
}

RolloutEngine::~RolloutEngine() = default;

std::string RolloutEngine::camera_description() const { return camera_->gl_description(); }

// Reads the camera at every robot's grid pose and writes the patches into y and h.
void RolloutEngine::observe(int count) {
  auto t0 = Clock::now();
  static_assert(sizeof(render::PixelPose) == 2 * sizeof(int));
  std::vector<render::PixelPose>& poses = pixel_poses_;
  for (int i = 0; i < count; ++i) poses[i] = {state_.pose[i].x(), state_.pose[i].y()};
  const std::size_t patch_bytes = static_cast<std::size_t>(state_.patch_px) * state_.patch_px;
  camera_->capture(std::span(poses.data(), count), std::span(patches_.data(), patch_bytes * count));
  timing_.render_s += seconds_since(t0);

  t0 = Clock::now();
  const int m = state_.patch_px;
  const int width = state_.frame.width_px;
  const int half = m / 2;
  for (int i = 0; i < count; ++i) {
    const grid::Window w = grid::camera_window(state_.pose[i], m, state_.frame);
    state_.seen[i].reveal(w);
    std::uint8_t* y = state_.observed.data() + static_cast<std::size_t>(i) * state_.frame.area_px();
    const std::uint8_t* patch = patches_.data() + static_cast<std::size_t>(i) * m * m;
    // The patch's (0, 0) is the window's unclipped corner (pose - m/2).
    const int px0 = state_.pose[i].x() - half, py0 = state_.pose[i].y() - half;
    for (int yy = w.y0; yy < w.y1; ++yy)
      for (int xx = w.x0; xx < w.x1; ++xx)
        y[static_cast<std::size_t>(yy) * width + xx] = patch[(yy - py0) * m + (xx - px0)];
  }
  timing_.other_s += seconds_since(t0);
}

std::vector<RolloutRecord> RolloutEngine::run(std::span<const std::uint8_t> floors, std::span<const grid::Cell> starts,
                                              Policy& policy, bool record) {
  const int count = static_cast<int>(starts.size());
  const std::size_t area = static_cast<std::size_t>(state_.frame.area_px());
  if (count <= 0 || count > max_robots_)
    throw std::invalid_argument("RolloutEngine::run: " + std::to_string(count) + " robots, at most " +
                                std::to_string(max_robots_));
  if (floors.size() != area * count)
    throw std::invalid_argument("RolloutEngine::run: floors hold " + std::to_string(floors.size()) +
                                " bytes, expected " + std::to_string(area * count));
  for (const grid::Cell& s : starts)
    if (!state_.frame.contains(s)) throw std::invalid_argument("RolloutEngine::run: a start cell is off the floor");

  auto t0 = Clock::now();
  state_.count = count;
  camera_->load_floors(floors, count);
  std::fill(state_.observed.begin(), state_.observed.begin() + static_cast<std::ptrdiff_t>(area * count), 0);
  for (int i = 0; i < count; ++i) {
    robots_->place(i, starts[i]);
    state_.pose[i] = robots_->grid_pose(i);
    state_.seen[i].clear();
  }
  commands_.assign(count, grid::Cell::Zero());
  results_.assign(count, sim::MoveResult{});
  need_.assign(count, 0);
  axes_.assign(count, grid::Axis::None);
  timing_.other_s += seconds_since(t0);
  observe(count);

  std::vector<RolloutRecord> records(record ? count : 0);
  const int E = task_.episodes, T = task_.steps;
  auto snapshot = [&](int episode, bool with_goal) {
    for (int i = 0; i < count; ++i) {
      SnapshotRecord s;
      s.episode = episode;
      s.robot = state_.pose[i];
      if (with_goal) s.goal = state_.goal[i];
      s.seen = state_.seen[i].data();
      s.path_length = records[i].path.size();
      records[i].snapshots.push_back(std::move(s));
    }
  };
  if (record) {
    for (int i = 0; i < count; ++i) {
      records[i].start = starts[i];
      records[i].steps.reserve(static_cast<std::size_t>(E) * T);
      records[i].path.reserve(static_cast<std::size_t>(E) * T + 1);
      records[i].path.push_back(state_.pose[i]);
      records[i].tick_path_px.push_back(robots_->position_px(i));
    }
    tick_positions_.resize(static_cast<std::size_t>(count));
  }

  for (int e = 0; e < E; ++e) {
    t0 = Clock::now();
    policy.choose_goals(state_, e, std::span(state_.goal.data(), count));
    timing_.other_s += seconds_since(t0);
    if (record) snapshot(e, true);
    for (int t = 0; t < T; ++t) {
      t0 = Clock::now();
      // The action protocol: forced axes where the goal is in line, the policy elsewhere.
      for (int i = 0; i < count; ++i) {
        const grid::Decision d = grid::decide(state_.pose[i], state_.goal[i]);
        need_[i] = d == grid::Decision::Choose;
        axes_[i] = d == grid::Decision::Vertical     ? grid::Axis::Vertical
                   : d == grid::Decision::Horizontal ? grid::Axis::Horizontal
                                                     : grid::Axis::None;
      }
      policy.choose_axes(state_, need_, std::span(axes_.data(), count));
      for (int i = 0; i < count; ++i)
        commands_[i] = grid::move_command(state_.pose[i], state_.goal[i], axes_[i], task_.step_px);
      timing_.other_s += seconds_since(t0);

      t0 = Clock::now();
      if (record)
        for (int i = 0; i < count; ++i) tick_positions_[i].clear();
      robots_->move(commands_, results_,
                    record ? std::span(tick_positions_.data(), static_cast<std::size_t>(count))
                           : std::span<std::vector<Eigen::Vector2d>>());
      for (int i = 0; i < count; ++i) state_.pose[i] = robots_->grid_pose(i);
      timing_.physics_s += seconds_since(t0);
      observe(count);

      t0 = Clock::now();
      for (int i = 0; i < count; ++i) {
        timing_.ticks += results_[i].ticks;
        timing_.peak_speed_mps = std::max(timing_.peak_speed_mps, results_[i].peak_speed_mps);
      }
      timing_.moves += count;
      if (record) {
        for (int i = 0; i < count; ++i) {
          StepRecord s;
          s.episode = e;
          s.step = t;
          s.goal = state_.goal[i];
          s.axis = axes_[i];
          s.sampled = need_[i] != 0;
          s.command = commands_[i];
          s.result = results_[i];
          s.pose_m = robots_->position_m(i);
          s.grid_pose = state_.pose[i];
          s.revealed_px = state_.seen[i].count();
          records[i].steps.push_back(s);
          records[i].path.push_back(state_.pose[i]);
          records[i].tick_path_px.insert(records[i].tick_path_px.end(), tick_positions_[i].begin(),
                                         tick_positions_[i].end());
        }
      }
      timing_.other_s += seconds_since(t0);
    }
  }
  if (record) snapshot(E, false);
  return records;
}

}  // namespace scout::learn
