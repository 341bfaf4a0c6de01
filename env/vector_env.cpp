#include "env/vector_env.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.hpp"
#include "core/memory.hpp"
#include "worlds/dataset.hpp"

namespace scout::env {

namespace fs = std::filesystem;

VectorEnv::VectorEnv(const VectorEnvConfig& config)
    : num_envs_(static_cast<int>(config.num_envs)), reward_(config.reward), autoreset_(config.autoreset) {
  if (config.num_envs < 1 || config.num_envs > kMaxEnvs)
    throw InputError(
        fmt::format("num_envs: expected an integer in 1..{} (the camera's batch), got {}", kMaxEnvs, config.num_envs));
  world_ = worlds::load_world(config.world_file);
  if (config.split) {
    if (!world_.floor.image.empty())
      throw InputError(
          fmt::format("split: {} has a PNG floor, not a data set with splits", config.world_file.string()));
    world_.floor.split = *config.split;
  }
  const fs::path data_root = config.data_root.empty() ? worlds::default_data_root() : config.data_root;
  floors_ = worlds::load_floors(world_, data_root);
  frame_ = {
      .width_px = floors_.width_px(), .height_px = floors_.height_px(), .pixel_size_m = world_.floor.pixel_size_m};
  // D: the images' classes, or the sums of a floor of several digits (FloorComposer::classes).
  for (int label : floors_.labels) classes_ = std::max(classes_, label + 1);
  if (classes_ > 0) classes_ = floors_.composer.classes(classes_);
  team_ = world_.team.robots;
  if (static_cast<std::int64_t>(num_envs_) * team_ > kMaxEnvs)
    throw InputError(fmt::format("num_envs: expected at most {} teams of {} robots (the camera's batch of {}), got {}",
                                 kMaxEnvs / team_, team_, kMaxEnvs, num_envs_));
  moves_ = world_.task.episodes / team_ * world_.task.steps;  // each robot of a team drives E / K episodes
  seed_ = config.seed.value_or(world_.seed);
  // Per robot: its floor twice (the camera's texture and the batch's copy), what it has seen and
  // revealed (here and in the caller's float arrays), its patch, and its Box2D body.
  const std::uint64_t area = static_cast<std::uint64_t>(frame_.area_px());
  const std::uint64_t patch = static_cast<std::uint64_t>(world_.camera.patch_px) * world_.camera.patch_px;
  const std::uint64_t per_robot = area * (1 + 1 + 1 + 1 + 4 + 1) + patch * 5 + 16 * 1024;
  core::check_memory(
      (std::uint64_t{256} << 20) + per_robot * static_cast<std::uint64_t>(num_envs_) * team_,
      team_ == 1 ? fmt::format("num_envs = {} robots on {} x {} floors", num_envs_, frame_.width_px, frame_.height_px)
                 : fmt::format("num_envs = {} teams of {} robots on {} x {} floors", num_envs_, team_, frame_.width_px,
                               frame_.height_px),
      config.force, "pass force=True");
  try {
    env_ = std::make_unique<BatchEnv>(world_, frame_, num_envs_ * team_);
  } catch (const std::runtime_error& e) {
    throw InputError(std::string("the camera cannot start: ") + one_line(e.what()));
  }
  sequence_.assign(num_envs_, nullptr);
  stride_.assign(num_envs_, static_cast<std::uint64_t>(num_envs_));
  run_.resize(num_envs_);
  planned_.resize(num_envs_);
  label_.assign(num_envs_, -1);
  done_.assign(num_envs_, 0);
  reset_now_.assign(num_envs_, 0);
  time_step_.assign(num_envs_, 0);
  commands_.resize(num_envs_ * team_);
  floor_bytes_.resize(static_cast<std::size_t>(frame_.area_px()) * num_envs_ * team_);
  starts_.resize(num_envs_ * team_);
  motion_seeds_.resize(num_envs_ * team_);
}

VectorEnv::~VectorEnv() = default;

std::vector<std::uint8_t> VectorEnv::floor_image(int env_index) const {
  std::vector<std::uint8_t> floor(static_cast<std::size_t>(frame_.area_px()));
  floors_.floor(planned_[env_index].index, planned_[env_index].floor_key, floor);
  return floor;
}

// Plans envs[k]'s run run_[envs[k]]: the floor, start and motion seed of its robot m (of K) into
// row k * K + m of floor_bytes_, starts_ and motion_seeds_, and the batch's robot numbers into
// robots_.
void VectorEnv::plan(std::span<const int> envs) {
  const std::size_t area = static_cast<std::size_t>(frame_.area_px());
  robots_.clear();
  for (std::size_t k = 0; k < envs.size(); ++k) {
    const int i = envs[k];
    planned_[i] = sequence_[i]->run(run_[i]);
    for (int m = 0; m < team_; ++m) {
      const std::size_t row = k * team_ + m;
      label_[i] =
          floors_.floor(planned_[i].index, planned_[i].floor_key, std::span(floor_bytes_.data() + area * row, area));
      starts_[row] = planned_[i].starts[m];
      motion_seeds_[row] = member_seed(planned_[i].motion_seed, m);
      robots_.push_back(i * team_ + m);
    }
    done_[i] = 0;
    time_step_[i] = 0;
  }
}

// Starts the robots plan() planned: the whole batch, or those of the envs it names.
void VectorEnv::start_planned() {
  const std::size_t area = static_cast<std::size_t>(frame_.area_px());
  const std::size_t n = robots_.size();
  if (static_cast<int>(n) == env_->max_robots()) {
    env_->reset(std::span(floor_bytes_.data(), area * n), std::span(starts_.data(), n),
                std::span(motion_seeds_.data(), n));
  } else {
    env_->reset_robots(robots_, std::span(floor_bytes_.data(), area * n), std::span(starts_.data(), n),
                       std::span(motion_seeds_.data(), n));
  }
}

// The run sequence of `seed`, shared by the robots that use it (a sequence is a function of its seed).
const RunSequence* VectorEnv::sequence(std::uint64_t seed) {
  std::unique_ptr<RunSequence>& s = sequences_[seed];
  if (!s) s = std::make_unique<RunSequence>(world_, frame_, floors_.size(), seed);
  return s.get();
}

void VectorEnv::reset(std::optional<std::uint64_t> seed, const VectorOutputs& out) {
  reset(VectorReset{.seed = seed}, out);
}

void VectorEnv::reset(const VectorReset& which, const VectorOutputs& out) {
  const auto n = static_cast<std::size_t>(num_envs_);
  if (!which.mask.empty() && which.mask.size() != n)
    throw InputError(fmt::format("reset_mask: expected {} flags (one per {}), got {}", n, team_ == 1 ? "robot" : "team",
                                 which.mask.size()));
  if (!which.robot_seeds.empty() && which.robot_seeds.size() != n)
    throw InputError(fmt::format("seed: expected one seed or a list of {} (one per {}), got a list of {}", n,
                                 team_ == 1 ? "robot" : "team", which.robot_seeds.size()));
  if (which.seed && !which.robot_seeds.empty()) throw InputError("seed: expected one seed or a list, not both");
  std::vector<int> robots;
  for (int i = 0; i < num_envs_; ++i)
    if (which.mask.empty() || which.mask[i]) robots.push_back(i);
  if (robots.empty()) throw InputError("reset_mask: expected at least one robot to reset");
  const bool first = sequence_[0] == nullptr;
  if (first && robots.size() != n) throw InputError("reset_mask: the first reset starts every robot");
  if (which.seed) seed_ = *which.seed;
  for (const int i : robots) {
    const std::optional<std::uint64_t> own = which.robot_seeds.empty() ? std::nullopt : which.robot_seeds[i];
    if (own) {  // its own sequence, from its first run
      sequence_[i] = sequence(*own);
      stride_[i] = 1;
      run_[i] = 0;
    } else if (which.seed || !sequence_[i]) {  // the batch's sequence, dealt out
      sequence_[i] = sequence(seed_);
      stride_[i] = n;
      run_[i] = static_cast<std::uint64_t>(i);
    } else {  // its next run
      run_[i] += stride_[i];
    }
  }
  std::vector<const RunSequence*> used(sequence_);  // drop the sequences no robot runs any more
  std::sort(used.begin(), used.end());
  std::erase_if(sequences_,
                [&](const auto& entry) { return !std::binary_search(used.begin(), used.end(), entry.second.get()); });
  plan(robots);
  start_planned();
  if (out.reward) std::fill_n(out.reward, num_envs_, 0.0f);
  if (out.terminated) std::fill_n(out.terminated, num_envs_, 0);
  if (out.truncated) std::fill_n(out.truncated, num_envs_, 0);
  write(out);
}

// Copies the action (so that what is checked is what is used, whoever owns the caller's
// buffers) and checks the copy.
void VectorEnv::take(const VectorAction& action) {
  if (!sequence_[0]) throw InputError("step: call reset first");
  const int robots = num_envs_ * team_;
  if (static_cast<int>(action.move.size()) != robots)
    throw InputError(team_ == 1 ? fmt::format("action['move']: expected {} moves (one per robot), got {}", num_envs_,
                                              action.move.size())
                                : fmt::format("action['move']: expected {} x {} moves (one per robot of each team), "
                                              "got {} values",
                                              num_envs_, team_, action.move.size()));
  move_.assign(action.move.begin(), action.move.end());
  prediction_.assign(action.prediction.begin(), action.prediction.end());
  goal_.assign(action.goal.begin(), action.goal.end());
  // Where entry r of a flat per-robot array stands in the caller's array: [i] or, in teams, [i][m].
  const auto at = [this](int r) {
    return team_ == 1 ? fmt::format("[{}]", r) : fmt::format("[{}][{}]", r / team_, r % team_);
  };
  for (int r = 0; r < robots; ++r)
    if (move_[r] < 0 || move_[r] > 3)
      throw InputError(
          fmt::format("action['move']{}: expected 0, 1, 2 or 3 (+x, -x, +y, -y), got {}", at(r), move_[r]));
  if (!prediction_.empty()) {
    if (classes_ == 0) throw InputError("action['prediction']: the floors have no labels to predict");
    if (prediction_.size() != static_cast<std::size_t>(num_envs_) * classes_)
      throw InputError(fmt::format("action['prediction']: expected {} x {} logits, got {} values", num_envs_, classes_,
                                   prediction_.size()));
    for (std::size_t k = 0; k < prediction_.size(); ++k)
      if (!std::isfinite(prediction_[k]))
        throw InputError(fmt::format("action['prediction'][{}][{}]: expected a finite logit, got {}", k / classes_,
                                     k % classes_, prediction_[k]));
  }
  if (!goal_.empty()) {
    if (goal_.size() != static_cast<std::size_t>(robots) * 2)
      throw InputError(
          team_ == 1 ? fmt::format("action['goal']: expected {} x 2 cells, got {} values", num_envs_, goal_.size())
                     : fmt::format("action['goal']: expected {} x {} x 2 cells, got {} values", num_envs_, team_,
                                   goal_.size()));
    for (int r = 0; r < robots; ++r)
      if (!frame_.contains({goal_[2 * r], goal_[2 * r + 1]}))
        throw InputError(fmt::format("action['goal']{}: expected a cell of the {} x {} floor, got ({}, {})", at(r),
                                     frame_.width_px, frame_.height_px, goal_[2 * r], goal_[2 * r + 1]));
  }
  if (!autoreset_)
    for (int i = 0; i < num_envs_; ++i)
      if (done_[i])
        throw InputError(fmt::format("step: robot {}'s run has ended: reset it first (autoreset is off)", i));
}

void VectorEnv::step(const VectorAction& action, const VectorOutputs& out) {
  take(action);
  // NEXT_STEP autoreset: who finished last step starts their next run now, their action ignored.
  finished_.clear();
  std::fill(reset_now_.begin(), reset_now_.end(), 0);
  for (int i = 0; i < num_envs_; ++i)
    if (done_[i]) {
      reset_now_[i] = 1;
      run_[i] += stride_[i];
      finished_.push_back(i);
    }
  const int s = world_.task.step_px;
  const std::span<const grid::Cell> poses = env_->poses();
  for (int r = 0; r < num_envs_ * team_; ++r) {
    if (done_[r / team_]) {
      commands_[r] = grid::Cell::Zero();
      continue;
    }
    static const grid::Cell kDirections[4] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    const grid::Cell d = kDirections[move_[r]];
    if (!goal_.empty()) {  // the protocol's move: along the move's axis toward the goal, never past it
      const grid::Cell goal(goal_[2 * r], goal_[2 * r + 1]);
      commands_[r] = grid::move_command(poses[r], goal, d.x() != 0 ? grid::Axis::Horizontal : grid::Axis::Vertical, s);
      continue;
    }
    // A move past the floor's edge stops on the border pixel, where the wall would stop it, without
    // the controller pushing against the wall until its tick limit.
    const grid::Cell target(std::clamp(poses[r].x() + d.x() * s, 0, frame_.width_px - 1),
                            std::clamp(poses[r].y() + d.y() * s, 0, frame_.height_px - 1));
    commands_[r] = target - poses[r];
  }
  if (!finished_.empty()) {
    plan(finished_);
    start_planned();
  }
  env_->step(commands_);

  const std::size_t D = static_cast<std::size_t>(classes_);
  for (int i = 0; i < num_envs_; ++i) {
    const bool reset_now = reset_now_[i] != 0;
    if (!reset_now) ++time_step_[i];
    const bool last = !reset_now && time_step_[i] >= moves_;
    float r = 0.0f;
    const int label = label_[i];
    if (!reset_now && !prediction_.empty() && label >= 0 && (reward_ == Reward::Dense || last)) {
      // log softmax(logits)[label], in double for a stable log-sum-exp.
      const float* logits = prediction_.data() + D * i;
      const double top = *std::max_element(logits, logits + D);
      double sum = 0;
      for (std::size_t c = 0; c < D; ++c) sum += std::exp(static_cast<double>(logits[c]) - top);
      r = static_cast<float>(logits[label] - top - std::log(sum));
    }
    if (out.reward) out.reward[i] = r;
    if (out.terminated) out.terminated[i] = last ? 1 : 0;
    if (out.truncated) out.truncated[i] = 0;
    done_[i] = last ? 1 : 0;
  }
  write(out);
}

void VectorEnv::write(const VectorOutputs& out) const {
  const std::size_t area = static_cast<std::size_t>(frame_.area_px());
  const std::span<const std::uint8_t> patches = env_->patches();
  const std::span<const std::uint8_t> revealed = env_->revealed();
  const std::span<const std::uint8_t> occupied = env_->occupied();
  constexpr float kScale = 1.0f / 255.0f;
  if (out.patch)
    for (std::size_t k = 0; k < patches.size(); ++k) out.patch[k] = patches[k] * kScale;
  const std::span<const std::uint8_t> wide_patches = env_->wide_patches();
  const bool wide = !wide_patches.empty();
  if (out.wide_patch && wide)
    for (std::size_t k = 0; k < wide_patches.size(); ++k) out.wide_patch[k] = wide_patches[k] * kScale;
  // Per robot: the pose and the centre.
  for (int r = 0; r < num_envs_ * team_; ++r) {
    const grid::Cell pose = env_->poses()[r];
    if (out.pose) {
      out.pose[2 * r] = pose.x();
      out.pose[2 * r + 1] = pose.y();
    }
    if (out.pose_m) {
      const Eigen::Vector2d p = env_->pose_m(r);
      out.pose_m[2 * r] = p.x();
      out.pose_m[2 * r + 1] = p.y();
    }
  }
  // Per env: y, h and o are a team's (its first robot holds them), and the run's facts.
  for (int i = 0; i < num_envs_; ++i) {
    const std::size_t first = static_cast<std::size_t>(i) * team_;
    if (out.revealed)
      for (std::size_t k = 0; k < area; ++k) out.revealed[area * i + k] = revealed[area * first + k] * kScale;
    if (out.occupied && !occupied.empty())
      std::copy_n(occupied.begin() + static_cast<std::ptrdiff_t>(area * first), area, out.occupied + area * i);
    if (out.seen) std::copy_n(env_->seen()[first].data().data(), area, out.seen + area * i);
    // The coarse map per floor pixel: each takes its block's byte.
    const grid::BlockGrid& blocks = env_->wide_grid();
    const std::size_t block_bytes = static_cast<std::size_t>(blocks.area());
    if (out.wide_revealed && wide) {
      const std::uint8_t* map = env_->wide_revealed().data() + block_bytes * first;
      float* to = out.wide_revealed + area * i;
      for (int y = 0; y < frame_.height_px; ++y) {
        const std::uint8_t* block_row = map + static_cast<std::size_t>(y / blocks.scale) * blocks.columns;
        for (int x = 0; x < frame_.width_px; ++x) *to++ = block_row[x / blocks.scale] * kScale;
      }
    }
    if (out.wide_seen && wide)
      grid::expand_blocks(blocks, frame_, env_->wide_seen().data() + block_bytes * first, out.wide_seen + area * i);
    if (out.time_step) out.time_step[i] = time_step_[i];
    if (out.label) out.label[i] = label_[i];
    if (out.index) out.index[i] = planned_[i].index;
    if (out.policy_seed) out.policy_seed[i] = planned_[i].policy_seed;
  }
}

}  // namespace scout::env
