#include "sim/robots.hpp"

#include <box2d/box2d.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "sim/worker_pool.hpp"

namespace scout::sim {

namespace {

// Box2D's tolerances (slop, skin, largest step) are fixed lengths, tuned for bodies of 0.1 to 10
// of its units. So Box2D does not run in metres but in units of a tenth of a floor pixel,
// whatever pixel_size_m is: a robot behaves the same in pixels at any floor scale, and contact
// tolerances stay a small fraction of a pixel. (With the paper's 0.1 m per pixel, one unit is
// one metre.) Speeds and sizes are converted on the way in, poses on the way out.
constexpr double kUnitsPerPx = 0.1;

// Where the walls stand. Box2D keeps a disc at rest against an edge at a centre distance of
// radius + polygon skin - slop, within a few slops. We put the edge so that this resting
// distance falls two slops *beyond* the border pixel's centre: a normal move onto a border cell
// then settles without touching the wall, and a push into the wall stops the centre at most
// ~0.1 px past the border centre: on the border pixel, never off the floor.
constexpr float kWallClearance_u = 2.0f * b2_linearSlop;

float wall_offset_u(double radius_u) {
  return static_cast<float>(radius_u) + b2_polygonRadius - b2_linearSlop + kWallClearance_u;
}

}  // namespace

struct RobotBatch::Robot {
  std::unique_ptr<b2World> world;
  b2Body* body = nullptr;
};

RobotParams RobotParams::from_world(const worlds::World& world) {
  return {world.robot, world.controller, world.physics};
}

double RobotBatch::wall_margin_px() { return kWallClearance_u / kUnitsPerPx; }

RobotBatch::RobotBatch(const grid::FloorFrame& frame, const RobotParams& params, int count, int threads)
    : frame_(frame),
      params_(params),
      robots_(new Robot[count > 0 ? count : 0]),
      count_(count),
      pool_(std::make_unique<WorkerPool>(threads)) {
  if (count <= 0) throw std::invalid_argument("RobotBatch: count must be positive, got " + std::to_string(count));
  if (frame.width_px <= 0 || frame.height_px <= 0 || frame.pixel_size_m <= 0)
    throw std::invalid_argument("RobotBatch: the floor must have a positive size");

  // The rectangle the centre may reach: border pixels' centres, in Box2D units (floor frame, y down;
  // Box2D does not care about handedness without gravity or rotation).
  const float px = static_cast<float>(kUnitsPerPx);
  const double units_per_m = kUnitsPerPx / frame.pixel_size_m;
  const double radius_u = params.body.radius_m * units_per_m;
  const float min_x = 0.5f * px, max_x = (frame.width_px - 0.5f) * px;
  const float min_y = 0.5f * px, max_y = (frame.height_px - 0.5f) * px;
  const float off = wall_offset_u(radius_u);
  // A chain collides on one side only, the right of each edge: wind it so that the right
  // side faces the floor.
  const b2Vec2 corners[4] = {
      {min_x - off, min_y - off}, {min_x - off, max_y + off}, {max_x + off, max_y + off}, {max_x + off, min_y - off}};
  const float density = static_cast<float>(params.body.mass_kg / (M_PI * radius_u * radius_u));

  // Continuous collision (time of impact) costs about half of a tick here. It is needed only when
  // one tick can carry the centre across a wall, i.e. when the speed limit allows moving a
  // sizeable part of the radius per tick; the paper preset moves 1/3 px = 0.033 m per tick
  // against a 0.25 m radius, and a discrete contact then always stops the disc.
  const bool continuous =
      params.body.max_speed_mps * params.physics.dt_s > 0.25 * params.body.radius_m;  // same ratio in units
  for (int i = 0; i < count; ++i) {
    Robot& r = robots_[i];
    r.world = std::make_unique<b2World>(b2Vec2(0.0f, 0.0f));
    r.world->SetAllowSleeping(false);
    r.world->SetContinuousPhysics(continuous);

    b2BodyDef wall_def;
    b2Body* walls = r.world->CreateBody(&wall_def);
    b2ChainShape loop;
    loop.CreateLoop(corners, 4);
    walls->CreateFixture(&loop, 0.0f);

    b2BodyDef body_def;
    body_def.type = b2_dynamicBody;
    body_def.fixedRotation = true;
    body_def.allowSleep = false;
    body_def.position.Set(min_x, min_y);
    r.body = r.world->CreateBody(&body_def);
    b2CircleShape disc;
    disc.m_radius = static_cast<float>(radius_u);
    b2FixtureDef fixture;
    fixture.shape = &disc;
    fixture.density = density;
    fixture.friction = 0.0f;
    fixture.restitution = 0.0f;
    r.body->CreateFixture(&fixture);
  }
}

RobotBatch::~RobotBatch() = default;

int RobotBatch::size() const { return count_; }
int RobotBatch::threads() const { return pool_->threads(); }
const grid::FloorFrame& RobotBatch::frame() const { return frame_; }
const RobotParams& RobotBatch::params() const { return params_; }

void RobotBatch::place(int robot, const grid::Cell& cell) {
  Robot& r = robots_[robot];
  const Eigen::Vector2d u = frame_.cell_centre_px(cell) * kUnitsPerPx;
  r.body->SetTransform(b2Vec2(static_cast<float>(u.x()), static_cast<float>(u.y())), 0.0f);
  r.body->SetLinearVelocity(b2Vec2(0.0f, 0.0f));
}

Eigen::Vector2d RobotBatch::position_px(int robot) const {
  const b2Vec2 p = robots_[robot].body->GetPosition();
  return Eigen::Vector2d(p.x, p.y) / kUnitsPerPx;
}

Eigen::Vector2d RobotBatch::position_m(int robot) const {
  // One multiplication by metres per unit (exactly 1 at 0.1 m per pixel), not two conversions.
  const b2Vec2 p = robots_[robot].body->GetPosition();
  return Eigen::Vector2d(p.x, p.y) * (frame_.pixel_size_m / kUnitsPerPx);
}

grid::Cell RobotBatch::grid_pose(int robot) const { return frame_.grid_pose(position_px(robot)); }

bool RobotBatch::touching_wall(int robot) const {
  for (const b2ContactEdge* e = robots_[robot].body->GetContactList(); e != nullptr; e = e->next)
    if (e->contact->IsTouching()) return true;
  return false;
}

void RobotBatch::move(std::span<const grid::Cell> commands, std::span<MoveResult> results,
                      std::span<std::vector<Eigen::Vector2d>> tick_positions_px) {
  if (commands.size() > static_cast<std::size_t>(count_) || results.size() < commands.size())
    throw std::invalid_argument("RobotBatch::move: " + std::to_string(commands.size()) + " commands for " +
                                std::to_string(count_) + " robots and " + std::to_string(results.size()) + " results");
  if (!tick_positions_px.empty() && tick_positions_px.size() < commands.size())
    throw std::invalid_argument("RobotBatch::move: " + std::to_string(tick_positions_px.size()) + " tick traces for " +
                                std::to_string(commands.size()) + " commands");
  const float dt = static_cast<float>(params_.physics.dt_s);
  const double units_per_m = kUnitsPerPx / frame_.pixel_size_m;
  const double tolerance_u = params_.controller.tolerance_px * kUnitsPerPx;
  const double max_speed_u = params_.body.max_speed_mps * units_per_m;
  const double kp = params_.controller.kp_per_s;
  const int n = static_cast<int>(commands.size());

  // Each robot lives in its own world, so robots are independent work items: no
  // synchronisation per tick, and the result does not depend on the thread count.
  pool_->parallel_for(n, 8, [&](int i) {
    Robot& r = robots_[i];
    MoveResult& out = results[i];
    out = MoveResult{};
    const grid::Cell target_cell = grid_pose(i) + commands[i];
    const Eigen::Vector2d target = frame_.cell_centre_px(target_cell) * kUnitsPerPx;
    double peak_speed_u = 0.0;
    for (;;) {
      const b2Vec2 p = r.body->GetPosition();
      const Eigen::Vector2d error(target.x() - p.x, target.y() - p.y);
      const double distance = error.norm();
      if (distance <= tolerance_u) {
        out.settled = true;
        break;
      }
      if (out.ticks >= params_.physics.max_ticks_per_move) break;
      // Saturated P-control of velocity: the body still collides, so a wall stops it.
      const double speed = std::min(max_speed_u, kp * distance);
      const Eigen::Vector2d v = error * (speed / distance);
      r.body->SetLinearVelocity(b2Vec2(static_cast<float>(v.x()), static_cast<float>(v.y())));
      r.world->Step(dt, params_.physics.velocity_iterations, params_.physics.position_iterations);
      ++out.ticks;
      // The speed reached is the distance actually travelled in the tick (a contact that stops
      // the body mid-tick leaves zero velocity behind, but not zero travel), or the velocity
      // left, whichever is larger.
      const b2Vec2 now = r.body->GetPosition();
      const double travelled = Eigen::Vector2d(now.x - p.x, now.y - p.y).norm() / dt;
      peak_speed_u = std::max({peak_speed_u, travelled, static_cast<double>(r.body->GetLinearVelocity().Length())});
      const double x = now.x / kUnitsPerPx, y = now.y / kUnitsPerPx;
      if (!tick_positions_px.empty()) tick_positions_px[i].emplace_back(x, y);
      out.beyond_border_px =
          std::max({out.beyond_border_px, 0.5 - x, x - (frame_.width_px - 0.5), 0.5 - y, y - (frame_.height_px - 0.5)});
      if (!out.touched_wall) out.touched_wall = touching_wall(i);
    }
    out.peak_speed_mps = peak_speed_u / units_per_m;
    // The robot comes to rest on its cell (or where the wall stopped it) before the next move.
    r.body->SetLinearVelocity(b2Vec2(0.0f, 0.0f));
  });
}

}  // namespace scout::sim

// Box2D 2.4 times every phase of every b2World::Step, and of every island it solves, with a
// b2Timer (a gettimeofday call at each start and each reading) to fill b2World::GetProfile().
// Scout never reads that profile, yet those 15 clock reads per tick, 25-50 ns each on our cloud
// machines, were half to two thirds of a robot's tick. libbox2d calls b2Timer through its
// procedure linkage table, so these definitions, linked into every program that drives robots,
// take the place of the library's (ELF symbol interposition; a static Box2D would not pull its
// own in either): the timers cost nothing and the profile reads zero. tests/sim checks that
// Box2D's steps use them.
b2Timer::b2Timer() = default;
void b2Timer::Reset() {}
float b2Timer::GetMilliseconds() const { return 0.0f; }
