#include "learn/internal/agent_policy.hpp"

#include <algorithm>
#include <chrono>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>

#include "agent/state.hpp"
#include "core/error.hpp"
#include "core/timing.hpp"
#include "learn/internal/precision.hpp"
#include "worlds/idx.hpp"

namespace scout::learn {

namespace {

using core::Clock;
using core::seconds_since;

// A uniform double in [0, 1) from the top 53 bits.
double unit_interval(core::Rng& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

}  // namespace

AgentPolicy::AgentPolicy(agent::AgentImpl& agent, const grid::FloorFrame& frame, int patch_px, int max_robots)
    : agent_(agent), frame_(frame), patch_px_(patch_px), max_robots_(max_robots) {
  if (agent.config().image_channels != worlds::ImageSet::channels)
    throw std::invalid_argument("AgentPolicy: floors have " + std::to_string(worlds::ImageSet::channels) +
                                " channel(s), the agent expects " + std::to_string(agent.config().image_channels));
  rows_.reserve(max_robots);
}

void AgentPolicy::begin(std::span<const std::uint64_t> seeds, const Sampling& sampling) {
  const int count = static_cast<int>(seeds.size());
  if (count <= 0 || count > max_robots_) throw std::invalid_argument("AgentPolicy::begin: bad robot count");
  sampling_ = sampling;
  // Without an action planner every axis is i.i.d., whatever the mode asks for.
  if (!agent_.action) sampling_.learned_actions = false;
  count_ = count;
  rngs_.clear();
  rngs_.reserve(count);
  for (std::uint64_t s : seeds) rngs_.emplace_back(s);
  log_pi_ = torch::zeros({count});
  entropy_ = torch::zeros({count});
  action_decisions_ = 0;
  goal_maps_.assign(sampling.record_goal_maps ? count : 0, {});
}

int AgentPolicy::sample(core::Rng& rng, const float* probabilities, int n) const {
  if (sampling_.greedy) {
    int best = 0;
    for (int k = 1; k < n; ++k)
      if (probabilities[k] > probabilities[best]) best = k;
    return best;
  }
  // Inverse CDF; rounding can leave u above the float sum, then the last possible outcome wins.
  const double u = unit_interval(rng);
  double cumulative = 0;
  int last = 0;
  for (int k = 0; k < n; ++k) {
    if (probabilities[k] <= 0) continue;
    cumulative += probabilities[k];
    last = k;
    if (u < cumulative) return k;
  }
  return last;
}

void AgentPolicy::choose_goals(const BatchState& state, int episode, std::span<grid::Cell> goals) {
  const int count = static_cast<int>(goals.size());
  if (count != count_) throw std::invalid_argument("AgentPolicy::choose_goals: robot count differs from begin()");
  const int width = frame_.width_px, area = frame_.area_px();
  if (!sampling_.learned_goals) {
    if (routes_free(state)) {  // uniform over the cells the route rule allows
      rows_.resize(count);
      std::iota(rows_.begin(), rows_.end(), std::int64_t{0});
      reachable_goals(state, rows_);
    }
    for (int i = 0; i < count; ++i) {
      if (!routes_free(state)) {
        const auto pixel = static_cast<int>(core::uniform_below(rngs_[i], static_cast<std::uint64_t>(area)));
        goals[i] = {pixel % width, pixel / width};
        continue;
      }
      const std::uint8_t* allowed = reachable_.data() + static_cast<std::size_t>(i) * area;
      const auto cells = static_cast<std::uint64_t>(std::count(allowed, allowed + area, 1));
      auto nth = static_cast<std::int64_t>(core::uniform_below(rngs_[i], cells));  // cells >= 1: the robot's own
      int pixel = 0;
      while (allowed[pixel] == 0 || nth-- > 0) ++pixel;
      goals[i] = {pixel % width, pixel / width};
    }
    return;
  }
  // The goals the robots hold while they choose: none before the first episode, then the last
  // ones, replaced as the new ones are drawn.
  goals_now_.assign(state.goal.begin(), state.goal.begin() + count);
  has_goal_.assign(count, episode > 0 ? 1 : 0);
  const int team = agent_.config().team_channels ? std::max(1, state.team) : 1;
  if (team == 1) {
    rows_.resize(count);
    std::iota(rows_.begin(), rows_.end(), std::int64_t{0});
    sample_goals(state, rows_, goals);
    return;
  }
  // With the teammates' channels a team's robots choose one after the other, member 0 first, each
  // seeing the goals just chosen by those before it: a joint proposal of the team's goals as a
  // product of conditionals, whose log-probability is the sum of theirs.
  for (int member = 0; member < team; ++member) {
    rows_.clear();
    for (int i = member; i < count; i += team) rows_.push_back(i);
    sample_goals(state, rows_, goals);
  }
}

agent::RobotView AgentPolicy::view_of(const BatchState& state, int i, const grid::Cell* goal,
                                      std::span<const grid::Cell> team_goals, std::span<const std::uint8_t> has_goal) {
  agent::RobotView view{state.revealed_image(i), state.seen[i].data().data(), state.pose[i], goal,
                        state.occupied_cells(i)};
  if (agent_.config().wide_view) {
    if (state.wide_seen.empty())
      throw InputError(
          "the model's planners read the wider view (--wide-view), but this world has none: set camera.wide_px");
    view.wide_revealed = state.wide_revealed_image(i);
    view.wide_seen = state.wide_seen_cells(i);
    view.wide_grid = state.wide_grid;
  }
  if (!agent_.config().team_channels || state.team <= 1) return view;
  teammate_poses_.clear();
  teammate_goals_.clear();
  const int first = i - i % state.team;
  for (int j = first; j < first + state.team; ++j) {
    if (j == i) continue;
    teammate_poses_.push_back(state.pose[j]);
    if (has_goal[j]) teammate_goals_.push_back(team_goals[j]);
  }
  view.teammate_poses = teammate_poses_;
  view.teammate_goals = teammate_goals_;
  return view;
}

void AgentPolicy::sample_goals(const BatchState& state, std::span<const std::int64_t> rows,
                               std::span<grid::Cell> goals) {
  const int k = static_cast<int>(rows.size()), width = frame_.width_px, area = frame_.area_px();
  const bool whole_batch = k == count_;
  std::optional<torch::NoGradGuard> no_grad;
  if (!sampling_.with_grad) no_grad.emplace();
  const ComputePrecision precision(sampling_.precision);
  auto t0 = Clock::now();
  // Fresh storage each call: autograd keeps the input of the first convolution for backward.
  const agent::NetworkConfig& config = agent_.config();
  const int channels = agent::planner_channels(config);
  torch::Tensor input = torch::empty({k, channels, frame_.height_px, width});
  float* data = input.data_ptr<float>();
  for (int r = 0; r < k; ++r) {
    const auto i = static_cast<int>(rows[r]);
    const agent::RobotView view = view_of(state, i, has_goal_[i] ? &goals_now_[i] : nullptr, goals_now_, has_goal_);
    agent::write_planner_input(frame_, patch_px_, view, data + static_cast<std::size_t>(r) * channels * area,
                               config.occupancy, config.team_channels, config.wide_view);
  }
  input = network_input(input, sampling_.precision);
  timing_.state_s += seconds_since(t0);
  t0 = Clock::now();
  torch::Tensor logits = agent_.goal->forward(input).to(torch::kFloat);  // [k, H*W]
  if (routes_free(state)) {
    // The route rule: pi_g renormalised over the reachable cells. A large finite negative rather
    // than -inf keeps p log p at 0 (not NaN) in the entropy.
    reachable_goals(state, rows);
    const torch::Tensor reachable = torch::from_blob(reachable_.data(), {k, area}, torch::kUInt8).to(torch::kBool);
    logits = logits.masked_fill(reachable.logical_not(), -1e30f);
  }
  torch::Tensor log_p = torch::log_softmax(logits, 1);  // [k, H*W]
  torch::Tensor p = log_p.detach().exp().contiguous();
  const float* probabilities = p.data_ptr<float>();
  std::vector<std::int64_t> chosen(k);
  for (int r = 0; r < k; ++r) {
    const auto i = static_cast<std::size_t>(rows[r]);
    const float* row = probabilities + static_cast<std::size_t>(r) * area;
    const int pixel = sample(rngs_[i], row, area);
    chosen[r] = pixel;
    goals[i] = {pixel % width, pixel / width};
    goals_now_[i] = goals[i];
    has_goal_[i] = 1;
    if (sampling_.record_goal_maps) goal_maps_[i].emplace_back(row, row + area);
  }
  torch::Tensor index = torch::from_blob(chosen.data(), {k, 1}, torch::kLong).clone();
  const torch::Tensor chosen_log_p = log_p.gather(1, index).squeeze(1);
  const torch::Tensor entropy = -(log_p.exp() * log_p).sum(1);
  if (whole_batch) {  // every robot in order: a plain sum (what a batch without teams has always done)
    log_pi_ = log_pi_ + chosen_log_p;
    entropy_ = entropy_ + entropy;
  } else {
    const torch::Tensor where = torch::from_blob(const_cast<std::int64_t*>(rows.data()), {k}, torch::kLong).clone();
    log_pi_ = log_pi_.index_add(0, where, chosen_log_p);
    entropy_ = entropy_.index_add(0, where, entropy);
  }
  timing_.forward_s += seconds_since(t0);
}

void AgentPolicy::choose_axes(const BatchState& state, std::span<std::uint8_t> need, std::span<grid::Axis> axes) {
  const int count = static_cast<int>(need.size());
  if (count != count_ || axes.size() < need.size())
    throw std::invalid_argument("AgentPolicy::choose_axes: robot count differs from begin()");
  if (routes_free(state)) route_axes(state, need, axes);
  if (!sampling_.learned_actions) {
    for (int i = 0; i < count; ++i)
      if (need[i]) axes[i] = (rngs_[i]() >> 63) ? grid::Axis::Vertical : grid::Axis::Horizontal;
    return;
  }
  std::optional<torch::NoGradGuard> no_grad;
  if (!sampling_.with_grad) no_grad.emplace();
  const ComputePrecision precision(sampling_.precision);
  auto t0 = Clock::now();
  // Only the robots with chi = 1 go through the action planner.
  rows_.clear();
  for (int i = 0; i < count; ++i)
    if (need[i]) rows_.push_back(i);
  if (rows_.empty()) {
    timing_.state_s += seconds_since(t0);
    return;
  }
  const int k = static_cast<int>(rows_.size()), area = frame_.area_px();
  const int channels = agent::planner_channels(agent_.config());
  all_goals_.assign(count, 1);
  torch::Tensor input = torch::empty({k, channels, frame_.height_px, frame_.width_px});
  float* data = input.data_ptr<float>();
  for (int r = 0; r < k; ++r) {
    const auto i = static_cast<std::size_t>(rows_[r]);
    // Every robot holds a goal while it moves: the teammates' are theirs now.
    const agent::RobotView view = view_of(state, static_cast<int>(i), &state.goal[i], state.goal, all_goals_);
    agent::write_planner_input(frame_, patch_px_, view, data + static_cast<std::size_t>(r) * channels * area,
                               agent_.config().occupancy, agent_.config().team_channels, agent_.config().wide_view);
  }
  input = network_input(input, sampling_.precision);
  timing_.state_s += seconds_since(t0);
  t0 = Clock::now();
  torch::Tensor log_p = torch::log_softmax(agent_.action->forward(input).to(torch::kFloat), 1);  // [k, 2]
  torch::Tensor p = log_p.detach().exp().contiguous();
  const float* probabilities = p.data_ptr<float>();
  std::vector<std::int64_t> chosen(k);
  for (int r = 0; r < k; ++r) {
    const auto i = static_cast<std::size_t>(rows_[r]);
    chosen[r] = sample(rngs_[i], probabilities + 2 * r, 2);
    axes[i] = chosen[r] == 1 ? grid::Axis::Vertical : grid::Axis::Horizontal;
  }
  action_decisions_ += k;
  torch::Tensor rows = torch::from_blob(rows_.data(), {k}, torch::kLong).clone();
  torch::Tensor index = torch::from_blob(chosen.data(), {k, 1}, torch::kLong).clone();
  log_pi_ = log_pi_.index_add(0, rows, log_p.gather(1, index).squeeze(1));
  entropy_ = entropy_.index_add(0, rows, -(log_p.exp() * log_p).sum(1));
  timing_.forward_s += seconds_since(t0);
}

bool AgentPolicy::routes_free(const BatchState& state) const {
  return agent_.config().free_routes && !state.occupied.empty();
}

void AgentPolicy::reachable_goals(const BatchState& state, std::span<const std::int64_t> rows) {
  const auto area = static_cast<std::size_t>(frame_.area_px());
  reachable_.resize(rows.size() * area);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const auto i = static_cast<int>(rows[r]);
    grid::monotone_reach(std::span(state.occupied_cells(i), area), frame_, state.pose[i],
                         std::span(reachable_.data() + r * area, area));
  }
}

void AgentPolicy::route_axes(const BatchState& state, std::span<std::uint8_t> need, std::span<grid::Axis> axes) {
  if (state.step_px <= 0) throw std::invalid_argument("AgentPolicy: the route rule needs the state's step_px");
  const auto area = static_cast<std::size_t>(frame_.area_px());
  constexpr grid::Axis kAxes[2] = {grid::Axis::Horizontal, grid::Axis::Vertical};
  for (std::size_t i = 0; i < need.size(); ++i) {
    if (need[i] == 0) continue;
    const std::span<const std::uint8_t> blocked(state.occupied_cells(static_cast<int>(i)), area);
    const grid::Cell& pose = state.pose[i];
    const grid::Cell& goal = state.goal[i];
    bool keeps_route[2];
    for (int a = 0; a < 2; ++a) {
      const grid::Cell to = pose + grid::move_command(pose, goal, kAxes[a], state.step_px);
      keeps_route[a] = grid::monotone_route_free(blocked, frame_, pose, to, route_scratch_) &&
                       grid::monotone_route_free(blocked, frame_, to, goal, route_scratch_);
    }
    if (keeps_route[0] == keeps_route[1]) continue;  // both or neither: the layer chooses as before
    need[i] = 0;
    axes[i] = keeps_route[0] ? kAxes[0] : kAxes[1];
  }
}

const std::vector<float>& AgentPolicy::goal_map(int robot, int episode) const {
  if (robot < 0 || robot >= static_cast<int>(goal_maps_.size()) || episode < 0 ||
      episode >= static_cast<int>(goal_maps_[robot].size()))
    throw std::out_of_range("AgentPolicy::goal_map: no map recorded for this robot and episode");
  return goal_maps_[robot][episode];
}

torch::Tensor revealed_images(const BatchState& state, int count) {
  const grid::FloorFrame& frame = state.frame;
  torch::Tensor y = torch::empty({count, worlds::ImageSet::channels, frame.height_px, frame.width_px});
  float* data = y.data_ptr<float>();
  for (int i = 0; i < count; ++i) {
    agent::RobotView view{state.revealed_image(i), state.seen[i].data().data(), state.pose[i], nullptr};
    agent::write_revealed_image(frame, view, data + static_cast<std::size_t>(i) * frame.area_px());
  }
  return y;
}

torch::Tensor full_images(std::span<const std::uint8_t> floors, int count, const grid::FloorFrame& frame) {
  const auto area = static_cast<std::size_t>(frame.area_px());
  if (floors.size() < area * count) throw std::invalid_argument("full_images: too few floor bytes");
  torch::Tensor x = torch::empty({count, worlds::ImageSet::channels, frame.height_px, frame.width_px});
  float* data = x.data_ptr<float>();
  for (std::size_t k = 0; k < area * count; ++k) data[k] = agent::pixel_value(floors[k]);
  return x;
}

}  // namespace scout::learn
