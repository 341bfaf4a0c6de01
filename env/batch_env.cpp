#include "env/batch_env.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "core/timing.hpp"
#include "core/worker_pool.hpp"
#include "env/runs.hpp"
#include "render/camera.hpp"
#include "sim/robots.hpp"

namespace scout::env {

// Robots a worker takes at a time from the pool: few enough to spread 240 over two threads evenly,
// enough that taking them costs little beside the work.
constexpr int kRobotsPerChunk = 8;

using core::Clock;
using core::seconds_since;

BatchEnv::BatchEnv(const worlds::World& world, const grid::FloorFrame& frame, int max_robots)
    : frame_(frame),
      patch_px_(world.camera.patch_px),
      max_robots_(max_robots),
      team_size_(world.team.robots),
      world_(world) {
  if (max_robots <= 0) throw std::invalid_argument("BatchEnv: max_robots must be positive");
  if (max_robots % team_size_ != 0)
    throw std::invalid_argument("BatchEnv: max_robots " + std::to_string(max_robots) + " is not a multiple of " +
                                std::to_string(team_size_) + " robots per team");
  pool_ = std::make_shared<core::WorkerPool>();
  robots_ = std::make_unique<sim::RobotBatch>(frame, sim::RobotParams::from_world(world), max_robots, pool_);
  exact_motion_ = robots_->params().exact();
  wide_px_ = world.camera.wide_px;
  wide_scale_ = world.camera.wide_scale;
  camera_ = std::make_unique<render::PatchCamera>(frame.width_px, frame.height_px, patch_px_, max_robots,
                                                  render::WideView{wide_px_, wide_scale_});
  const std::size_t area = static_cast<std::size_t>(frame.area_px());
  if (wide_px_ > 0) {
    wide_grid_ = grid::BlockGrid::over(frame, wide_scale_);
    const std::size_t blocks = static_cast<std::size_t>(wide_grid_.area());
    wide_patches_.resize(static_cast<std::size_t>(max_robots) * wide_px_ * wide_px_);
    wide_revealed_.resize(blocks * max_robots);
    wide_seen_.resize(blocks * max_robots);
  }
  poses_.resize(max_robots);
  seen_.assign(max_robots, grid::RevealMask(frame));
  revealed_.resize(area * max_robots);
  if (!world.obstacles.none()) floors_.resize(area * max_robots);
  patches_.resize(static_cast<std::size_t>(max_robots) * patch_px_ * patch_px_);
  pixel_poses_.resize(max_robots);
  centres_.resize(max_robots);
  moves_.resize(max_robots);
  sim_results_.resize(max_robots);
  results_.resize(max_robots);
  ticks_.resize(max_robots);
  for (int y = 0; y < frame.height_px; ++y)
    for (int x = 0; x < frame.width_px; ++x)
      if (world.obstacles.covers(x + 0.5, y + 0.5))
        obstacle_pixels_.push_back(static_cast<std::size_t>(y) * frame.width_px + x);
  obstacle_shade_ = static_cast<std::uint8_t>(world.obstacles.shade);
  if (!world.obstacles.none()) occupied_.resize(area * max_robots);
  if (!world.obstacles.none() && world.obstacles.random_boxes == 0)
    fixed_occupied_ = occupied_cells(world, frame, world.obstacles);
}

BatchEnv::~BatchEnv() = default;

std::string BatchEnv::camera_description() const { return camera_->gl_description(); }

std::span<const std::uint8_t> BatchEnv::patches() const {
  return {patches_.data(), static_cast<std::size_t>(count_) * patch_px_ * patch_px_};
}
std::span<const grid::Cell> BatchEnv::poses() const { return {poses_.data(), static_cast<std::size_t>(count_)}; }
std::span<const std::uint8_t> BatchEnv::revealed() const {
  return {revealed_.data(), static_cast<std::size_t>(count_) * frame_.area_px()};
}
std::span<const std::uint8_t> BatchEnv::wide_patches() const {
  return {wide_patches_.data(), wide_patches_.empty() ? 0 : static_cast<std::size_t>(count_) * wide_px_ * wide_px_};
}
std::span<const std::uint8_t> BatchEnv::wide_revealed() const {
  return {wide_revealed_.data(), static_cast<std::size_t>(count_) * wide_grid_.area()};
}
std::span<const std::uint8_t> BatchEnv::wide_seen() const {
  return {wide_seen_.data(), static_cast<std::size_t>(count_) * wide_grid_.area()};
}
std::span<const std::uint8_t> BatchEnv::occupied() const {
  if (occupied_.empty()) return {};
  return {occupied_.data(), static_cast<std::size_t>(count_) * frame_.area_px()};
}
std::span<const grid::RevealMask> BatchEnv::seen() const { return {seen_.data(), static_cast<std::size_t>(count_)}; }
std::span<const int> BatchEnv::moves() const { return {moves_.data(), static_cast<std::size_t>(count_)}; }
std::span<const MoveResult> BatchEnv::last_results() const {
  return {results_.data(), static_cast<std::size_t>(count_)};
}
Eigen::Vector2d BatchEnv::pose_m(int robot) const { return robots_->position_m(robot); }
Eigen::Vector2d BatchEnv::position_px(int robot) const { return robots_->position_px(robot); }

void BatchEnv::set_tick_hook(TickHook hook) { tick_hook_ = std::move(hook); }

// Robot i's memory as a run starts: in a world with obstacles its floor copied in and the fixed
// obstacles painted over it, and nothing seen yet. Touches robot i's arrays only, so the robots of a reset share the
// pool. On a 100 x 100 floor: y and the mask cleared where the last run saw (a few hundred bytes, not 10 kB each), and
// the coarse map's two arrays of 289 bytes.
void BatchEnv::start_buffers(int robot, std::span<const std::uint8_t> floor) {
  const std::size_t area = static_cast<std::size_t>(frame_.area_px());
  if (!floors_.empty()) {
    std::copy(floor.begin(), floor.end(), floors_.begin() + static_cast<std::ptrdiff_t>(area * robot));
    for (const std::size_t pixel : obstacle_pixels_) floors_[area * robot + pixel] = obstacle_shade_;
  }
  // y holds bytes only where the robot's team revealed them, which its mask's bounds hold.
  const grid::Window& written = seen_[robot].bounds();
  for (int y = written.y0; y < written.y1; ++y)
    std::fill_n(revealed_.begin() + static_cast<std::ptrdiff_t>(area * robot + y * frame_.width_px + written.x0),
                written.x1 - written.x0, 0);
  if (wide_px_ > 0) {
    const std::size_t blocks = static_cast<std::size_t>(wide_grid_.area());
    std::fill_n(wide_revealed_.begin() + static_cast<std::ptrdiff_t>(blocks * robot), blocks, 0);
    std::fill_n(wide_seen_.begin() + static_cast<std::ptrdiff_t>(blocks * robot), blocks, 0);
  }
  seen_[robot].clear();
}

// Puts robot i at rest on its start, after start_buffers. A team's floor holds the random boxes
// drawn from its first robot's motion seed, `layout_seed`.
void BatchEnv::place(int robot, const grid::Cell& start, std::uint64_t motion_seed, std::uint64_t layout_seed) {
  const std::size_t area = static_cast<std::size_t>(frame_.area_px());
  if (world_.obstacles.random_boxes > 0) {
    // The run's own layout, drawn from its motion seed as every caller that drew its start did.
    const worlds::ObstacleSpec layout = run_obstacles(world_, frame_, layout_seed);
    if (robot % team_size_ == 0) robots_->set_obstacles(robot, layout);  // the team's floor
    for (const worlds::BoxObstacle& b : layout.boxes)
      for (int y = b.y; y < b.y + b.h; ++y)
        std::fill_n(floors_.begin() + static_cast<std::ptrdiff_t>(area * robot + y * frame_.width_px + b.x), b.w,
                    obstacle_shade_);
    const std::vector<std::uint8_t> occupied = occupied_cells(world_, frame_, layout);
    std::copy(occupied.begin(), occupied.end(), occupied_.begin() + static_cast<std::ptrdiff_t>(area * robot));
  } else if (!fixed_occupied_.empty()) {
    std::copy(fixed_occupied_.begin(), fixed_occupied_.end(),
              occupied_.begin() + static_cast<std::ptrdiff_t>(area * robot));
  }
  robots_->place(robot, start, motion_seed);
  poses_[robot] = robots_->agent_pose(robot);
  moves_[robot] = 0;
  sim_results_[robot] = sim::MoveResult{};
  results_[robot] = MoveResult{};
}

void BatchEnv::reset(std::span<const std::uint8_t> floors, std::span<const grid::Cell> starts,
                     std::span<const std::uint64_t> motion_seeds) {
  const int count = static_cast<int>(starts.size());
  const std::size_t area = static_cast<std::size_t>(frame_.area_px());
  if (count <= 0 || count > max_robots_)
    throw std::invalid_argument("BatchEnv::reset: " + std::to_string(count) + " robots, at most " +
                                std::to_string(max_robots_));
  if (floors.size() != area * count)
    throw std::invalid_argument("BatchEnv::reset: floors hold " + std::to_string(floors.size()) + " bytes, expected " +
                                std::to_string(area * count));
  if (motion_seeds.size() != starts.size())
    throw std::invalid_argument("BatchEnv::reset: " + std::to_string(motion_seeds.size()) + " motion seeds for " +
                                std::to_string(count) + " robots");
  if (count % team_size_ != 0)
    throw std::invalid_argument("BatchEnv::reset: " + std::to_string(count) + " robots do not make teams of " +
                                std::to_string(team_size_));
  for (const grid::Cell& s : starts)
    if (!frame_.contains(s)) throw std::invalid_argument("BatchEnv::reset: a start cell is off the floor");
  const auto t0 = Clock::now();
  count_ = count;
  pool_->parallel_for(count, kRobotsPerChunk, [&](int i) { start_buffers(i, floors.subspan(area * i, area)); });
  for (int i = 0; i < count; ++i) place(i, starts[i], motion_seeds[i], motion_seeds[i - i % team_size_]);
  camera_->load_floors(floors_.empty() ? floors : std::span<const std::uint8_t>(floors_.data(), area * count), count,
                       pool_.get());
  timing_.observe_s += seconds_since(t0);
  observe();
}

void BatchEnv::reset_robots(std::span<const int> robots, std::span<const std::uint8_t> floors,
                            std::span<const grid::Cell> starts, std::span<const std::uint64_t> motion_seeds) {
  const std::size_t area = static_cast<std::size_t>(frame_.area_px());
  if (starts.size() != robots.size() || motion_seeds.size() != robots.size() || floors.size() != area * robots.size())
    throw std::invalid_argument("BatchEnv::reset_robots: " + std::to_string(robots.size()) + " robots, " +
                                std::to_string(starts.size()) + " starts, " + std::to_string(motion_seeds.size()) +
                                " motion seeds and " + std::to_string(floors.size()) + " floor bytes");
  for (std::size_t k = 0; k < robots.size(); ++k) {
    if (robots[k] < 0 || robots[k] >= count_)
      throw std::invalid_argument("BatchEnv::reset_robots: robot " + std::to_string(robots[k]) + " of " +
                                  std::to_string(count_));
    if (!frame_.contains(starts[k]))
      throw std::invalid_argument("BatchEnv::reset_robots: a start cell is off the floor");
  }
  if (robots.empty()) return;
  // Each robot once: their buffers are started in parallel.
  std::vector<bool> listed(count_, false);
  for (const int robot : robots) {
    if (listed[robot])
      throw std::invalid_argument("BatchEnv::reset_robots: robot " + std::to_string(robot) + " is listed twice");
    listed[robot] = true;
  }
  // A team starts again as a whole, its robots listed together, its first robot first: they share
  // a floor (and its random boxes, drawn from the first one's motion seed).
  for (std::size_t k = 0; k < robots.size(); k += team_size_) {
    bool whole = robots[k] % team_size_ == 0 && k + team_size_ <= robots.size();
    for (int j = 1; whole && j < team_size_; ++j) whole = robots[k + j] == robots[k] + j;
    if (!whole)
      throw std::invalid_argument("BatchEnv::reset_robots: robot " + std::to_string(robots[k]) +
                                  " does not begin a whole team of " + std::to_string(team_size_) + " in order");
  }
  const auto t0 = Clock::now();
  pool_->parallel_for(static_cast<int>(robots.size()), kRobotsPerChunk,
                      [&](int k) { start_buffers(robots[k], floors.subspan(area * k, area)); });
  for (std::size_t k = 0; k < robots.size(); ++k)
    place(robots[k], starts[k], motion_seeds[k], motion_seeds[k - k % team_size_]);
  // Without obstacles the camera takes the reset robots' floors alone; with them, the painted
  // floors of the whole batch in one upload.
  if (floors_.empty())
    camera_->replace_floors(robots, floors, pool_.get());
  else
    camera_->load_floors(std::span(floors_.data(), area * count_), count_, pool_.get());
  timing_.observe_s += seconds_since(t0);
  // Looking again from an unchanged pose reveals nothing new and writes the same y.
  observe();
}

void BatchEnv::step(std::span<const grid::Cell> commands) {
  if (static_cast<int>(commands.size()) != count_)
    throw std::invalid_argument("BatchEnv::step: " + std::to_string(commands.size()) + " commands for " +
                                std::to_string(count_) + " robots");
  auto t0 = Clock::now();
  if (tick_hook_) {
    for (int i = 0; i < count_; ++i) ticks_[i].clear();
    robots_->move(commands, std::span(sim_results_.data(), commands.size()), std::span(ticks_.data(), commands.size()));
  } else {
    robots_->move(commands, std::span(sim_results_.data(), commands.size()));
  }
  for (int i = 0; i < count_; ++i) {
    const sim::MoveResult& r = sim_results_[i];
    results_[i] = {.ticks = r.ticks,
                   .settled = r.settled,
                   .touched_wall = r.touched_wall,
                   .peak_speed_mps = r.peak_speed_mps,
                   .beyond_border_px = r.beyond_border_px,
                   .pushed = r.pushed,
                   .blocked = r.blocked};
    poses_[i] = robots_->agent_pose(i);
    ++moves_[i];
    timing_.ticks += results_[i].ticks;
    timing_.peak_speed_mps = std::max(timing_.peak_speed_mps, results_[i].peak_speed_mps);
  }
  timing_.moves += count_;
  timing_.physics_s += seconds_since(t0);
  observe();
  if (tick_hook_)
    for (int i = 0; i < count_; ++i) tick_hook_(i, ticks_[i]);
}

// The camera looks from every robot (at its grid pose in an exact world, where the robot really
// is otherwise); what it sees is revealed and written into y at the pose the agent reads: into
// the y and h of every robot of its team (what one has seen, the team has).
void BatchEnv::observe() {
  auto t0 = Clock::now();
  const std::size_t patch_bytes = static_cast<std::size_t>(patch_px_) * patch_px_;
  const std::span<std::uint8_t> patches(patches_.data(), patch_bytes * count_);
  const std::span<std::uint8_t> wide(
      wide_patches_.data(), wide_patches_.empty() ? 0 : static_cast<std::size_t>(count_) * wide_px_ * wide_px_);
  if (exact_motion_) {
    static_assert(sizeof(render::PixelPose) == 2 * sizeof(int));
    for (int i = 0; i < count_; ++i) pixel_poses_[i] = {poses_[i].x(), poses_[i].y()};
    camera_->capture(std::span(pixel_poses_.data(), count_), patches, wide);
  } else {
    for (int i = 0; i < count_; ++i) {
      const Eigen::Vector2d p = robots_->position_px(i);
      centres_[i] = {static_cast<float>(p.x()), static_cast<float>(p.y())};
    }
    camera_->capture_at(std::span(centres_.data(), count_), patches, wide);
  }
  timing_.render_s += seconds_since(t0);

  t0 = Clock::now();
  // A team's robots write only the team's arrays: the teams share the pool.
  pool_->parallel_for(count_ / team_size_, std::max(1, kRobotsPerChunk / team_size_), [this](int team) {
    for (int i = team * team_size_; i < (team + 1) * team_size_; ++i) {
      reveal_patch(i);
      if (wide_px_ > 0) reveal_wide(i);
    }
  });
  timing_.observe_s += seconds_since(t0);
}

// Robot i's patch into its team's y and h.
void BatchEnv::reveal_patch(int i) {
  const int m = patch_px_;
  const int width = frame_.width_px;
  const grid::Window w = grid::camera_window(poses_[i], m, frame_);
  const std::uint8_t* patch = patches_.data() + static_cast<std::size_t>(i) * m * m;
  // The patch's (0, 0) is the window's unclipped corner (pose - m/2).
  const int px0 = poses_[i].x() - m / 2, py0 = poses_[i].y() - m / 2;
  const int team_first = i - i % team_size_;
  for (int j = team_first; j < team_first + team_size_; ++j) {
    seen_[j].reveal(w);
    std::uint8_t* y = revealed_.data() + static_cast<std::size_t>(j) * frame_.area_px();
    for (int yy = w.y0; yy < w.y1; ++yy)
      std::copy_n(patch + (yy - py0) * m + (w.x0 - px0), w.x1 - w.x0, y + static_cast<std::size_t>(yy) * width + w.x0);
  }
}

// Robot i's wider view into its team's coarse map: each block the look covers takes its mean (the
// latest look wins) and is marked seen, at the pose the agent reads, as the patch. (With odometry
// the camera looked from the true cell's block; where the believed cell lies in another block, the
// look lands a block off, as the patch lands by the odometry's error.)
void BatchEnv::reveal_wide(int i) {
  const int px = wide_px_;
  const grid::BlockGrid& grid = wide_grid_;
  const std::size_t blocks = static_cast<std::size_t>(grid.area());
  const std::uint8_t* look = wide_patches_.data() + static_cast<std::size_t>(i) * px * px;
  // The look's first block, and the part of the window on the floor's blocks.
  const int u0 = grid.block_of(poses_[i].x()) - px / 2, v0 = grid.block_of(poses_[i].y()) - px / 2;
  const int ua = std::max(u0, 0), ub = std::min(u0 + px, grid.columns);
  const int va = std::max(v0, 0), vb = std::min(v0 + px, grid.rows);
  if (ua >= ub || va >= vb) return;
  const int team_first = i - i % team_size_;
  for (int j = team_first; j < team_first + team_size_; ++j) {
    std::uint8_t* coarse = wide_revealed_.data() + blocks * j;
    std::uint8_t* seen = wide_seen_.data() + blocks * j;
    for (int v = va; v < vb; ++v) {
      const std::size_t row = static_cast<std::size_t>(v) * grid.columns;
      const std::uint8_t* look_row = look + static_cast<std::size_t>(v - v0) * px;
      std::copy(look_row + (ua - u0), look_row + (ub - u0), coarse + row + ua);
      std::fill(seen + row + ua, seen + row + ub, std::uint8_t{1});
    }
  }
}

}  // namespace scout::env
