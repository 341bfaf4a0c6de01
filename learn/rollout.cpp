#include "learn/rollout.hpp"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "core/random.hpp"
#include "core/timing.hpp"
#include "env/protocol.hpp"

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

void RandomPolicy::choose_axes(const BatchState& /*state*/, std::span<std::uint8_t> need, std::span<grid::Axis> axes) {
  if (need.size() > rngs_.size() || axes.size() < need.size())
    throw std::invalid_argument("RandomPolicy: more robots than seeds or axes");
  for (std::size_t i = 0; i < need.size(); ++i)
    if (need[i]) axes[i] = (rngs_[i]() >> 63) ? grid::Axis::Vertical : grid::Axis::Horizontal;
}

RolloutEngine::RolloutEngine(const worlds::World& world, const grid::FloorFrame& frame, int max_robots)
    : task_(world.task), team_size_(world.team.robots) {
  if (max_robots <= 0) throw std::invalid_argument("RolloutEngine: max_robots must be positive");
  if (team_size_ < 1 || task_.episodes % team_size_ != 0)
    throw std::invalid_argument("RolloutEngine: " + std::to_string(task_.episodes) + " episodes do not divide among " +
                                std::to_string(team_size_) + " robots");
  env_ = std::make_unique<env::BatchEnv>(world, frame, max_robots);
  state_.frame = frame;
  state_.patch_px = world.camera.patch_px;
  state_.step_px = world.task.step_px;
  goals_.resize(max_robots);
}

RolloutEngine::~RolloutEngine() = default;

std::string RolloutEngine::camera_description() const { return env_->camera_description(); }
int RolloutEngine::max_robots() const { return env_->max_robots(); }

RolloutTiming RolloutEngine::timing() const { return {.env = env_->timing(), .other_s = other_s_}; }

void RolloutEngine::reset_timing() {
  env_->reset_timing();
  other_s_ = 0;
}

// The policy's view of the environment's arrays and the goals.
void RolloutEngine::refresh_state() {
  state_.count = env_->count();
  state_.team = team_size_;
  state_.pose = env_->poses();
  state_.seen = env_->seen();
  state_.revealed = env_->revealed();
  state_.occupied = env_->occupied();
  state_.wide_revealed = env_->wide_revealed();
  state_.wide_seen = env_->wide_seen();
  state_.wide_grid = env_->wide_grid();
  state_.goal = std::span<const grid::Cell>(goals_.data(), static_cast<std::size_t>(state_.count));
}

void RolloutEngine::check_inputs(std::span<const std::uint8_t> floors, std::span<const grid::Cell> starts) const {
  const auto count = starts.size();
  const std::size_t area = static_cast<std::size_t>(state_.frame.area_px());
  if (count == 0 || count > static_cast<std::size_t>(env_->max_robots()))
    throw std::invalid_argument("RolloutEngine::run: " + std::to_string(count) + " robots, at most " +
                                std::to_string(env_->max_robots()));
  if (floors.size() != area * count)
    throw std::invalid_argument("RolloutEngine::run: floors hold " + std::to_string(floors.size()) +
                                " bytes, expected " + std::to_string(area * count));
  for (const grid::Cell& s : starts)
    if (!state_.frame.contains(s)) throw std::invalid_argument("RolloutEngine::run: a start cell is off the floor");
}

// Each robot's record opens with its start; every physics tick of every move goes into it
// (animations) through the environment's tick hook, which run() clears on every way out.
void RolloutEngine::open_records(std::vector<RolloutRecord>& records, std::span<const grid::Cell> starts) {
  const std::size_t moves = static_cast<std::size_t>(task_.episodes / team_size_) * task_.steps;
  for (std::size_t i = 0; i < records.size(); ++i) {
    records[i].start = starts[i];
    records[i].steps.reserve(moves);
    records[i].path.reserve(moves + 1);
    records[i].path.push_back(state_.pose[i]);
    records[i].tick_path_px.push_back(env_->position_px(static_cast<int>(i)));
  }
  env_->set_tick_hook([&records](int robot, std::span<const Eigen::Vector2d> ticks) {
    std::vector<Eigen::Vector2d>& path = records[robot].tick_path_px;
    path.insert(path.end(), ticks.begin(), ticks.end());
  });
}

// The state a trajectory image shows, at the start of `episode` (E: the end).
void RolloutEngine::record_snapshots(std::vector<RolloutRecord>& records, int episode, bool with_goal) const {
  for (std::size_t i = 0; i < records.size(); ++i) {
    SnapshotRecord s;
    s.episode = episode;
    s.robot = state_.pose[i];
    if (with_goal) s.goal = state_.goal[i];
    s.seen = state_.seen[i].data();
    if (const std::uint8_t* map = state_.wide_revealed_image(static_cast<int>(i))) {
      const std::size_t area = static_cast<std::size_t>(state_.frame.area_px());
      s.wide_revealed.resize(area);
      s.wide_seen.resize(area);
      grid::expand_blocks(state_.wide_grid, state_.frame, map, s.wide_revealed.data());
      grid::expand_blocks(state_.wide_grid, state_.frame, state_.wide_seen_cells(static_cast<int>(i)),
                          s.wide_seen.data());
    }
    s.path_length = records[i].path.size();
    records[i].snapshots.push_back(std::move(s));
  }
}

// Move t of episode e, as every robot made it.
void RolloutEngine::record_moves(std::vector<RolloutRecord>& records, int e, int t) const {
  const std::span<const env::MoveResult> results = env_->last_results();
  for (std::size_t i = 0; i < records.size(); ++i) {
    StepRecord s;
    s.episode = e;
    s.step = t;
    s.goal = state_.goal[i];
    s.axis = axes_[i];
    s.sampled = need_[i] != 0;
    s.command = commands_[i];
    s.result = results[i];
    s.pose_m = env_->pose_m(static_cast<int>(i));
    s.grid_pose = state_.pose[i];
    s.revealed_px = state_.seen[i].count();
    records[i].steps.push_back(s);
    records[i].path.push_back(state_.pose[i]);
  }
}

void RolloutEngine::tally_axis_decisions(int count) {
  const int step = task_.step_px, patch = state_.patch_px;
  auto new_px = [&](int robot, grid::Axis axis) {
    const grid::Cell& pose = state_.pose[robot];
    const grid::Cell to = pose + grid::move_command(pose, state_.goal[robot], axis, step);
    const grid::Window w = grid::camera_window(to, patch, state_.frame);
    const grid::RevealMask& seen = state_.seen[robot];
    int fresh = 0;
    for (int y = w.y0; y < w.y1; ++y)
      for (int x = w.x0; x < w.x1; ++x) fresh += seen.seen(x, y) ? 0 : 1;
    return fresh;
  };
  for (int i = 0; i < count; ++i) {
    if (!need_[i]) continue;
    const int h = new_px(i, grid::Axis::Horizontal), v = new_px(i, grid::Axis::Vertical);
    ++axis_tally_.decisions;
    if (h == v) continue;
    ++axis_tally_.differing;
    axis_tally_.gap_px += std::abs(h - v);
    axis_tally_.chose_more += (axes_[i] == grid::Axis::Horizontal) == (h > v) ? 1 : 0;
  }
}

std::vector<RolloutRecord> RolloutEngine::run(std::span<const std::uint8_t> floors, std::span<const grid::Cell> starts,
                                              std::span<const std::uint64_t> motion_seeds, Policy& policy,
                                              bool record) {
  check_inputs(floors, starts);
  const int count = static_cast<int>(starts.size());
  env_->reset(floors, starts, motion_seeds);
  auto t0 = Clock::now();
  std::fill(goals_.begin(), goals_.begin() + count, grid::Cell::Zero());
  refresh_state();
  commands_.assign(count, grid::Cell::Zero());
  need_.assign(count, 0);
  axes_.assign(count, grid::Axis::None);
  stalled_.assign(count, 0);

  std::vector<RolloutRecord> records(record ? count : 0);
  if (record) open_records(records, starts);
  // The hook points into this call's records: cleared on every way out.
  struct ClearHook {
    env::BatchEnv& env;
    ~ClearHook() { env.set_tick_hook({}); }
  } clear_hook{*env_};
  other_s_ += seconds_since(t0);

  // A team's robots drive E / K episodes each, all at once: the team's moves are the lone robot's E * T.
  const int E = task_.episodes / team_size_, T = task_.steps;
  for (int e = 0; e < E; ++e) {
    t0 = Clock::now();
    policy.choose_goals(state_, e, std::span(goals_.data(), count));
    other_s_ += seconds_since(t0);
    if (record) record_snapshots(records, e, true);
    for (int t = 0; t < T; ++t) {
      t0 = Clock::now();
      env::forced_axes(state_.pose, state_.goal, need_, axes_);
      policy.choose_axes(state_, need_, std::span(axes_.data(), count));
      tally_axis_decisions(count);
      env::move_commands(state_.pose, state_.goal, axes_, task_.step_px, commands_);
      other_s_ += seconds_since(t0);

      env_->step(commands_);
      refresh_state();
      const std::span<const env::MoveResult> results = env_->last_results();
      for (int i = 0; i < count; ++i)
        stalled_[i] += results[i].blocked || (results[i].ticks > 0 && !results[i].settled) ? 1 : 0;

      t0 = Clock::now();
      if (record) record_moves(records, e, t);
      other_s_ += seconds_since(t0);
    }
  }
  if (record) record_snapshots(records, E, false);
  return records;
}

}  // namespace scout::learn
