#include "sim/robots.hpp"

#include <box2d/box2d.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/random.hpp"
#include "core/worker_pool.hpp"

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

// How far a polygon's faces stand inside the edge they stand for: Box2D's skin less its slop, so
// that a disc comes to rest against the polygon where it would touch the bare edge.
constexpr float kSkinInset_u = b2_polygonRadius - b2_linearSlop;

float wall_offset_u(double radius_u) {
  return static_cast<float>(radius_u) + b2_polygonRadius - b2_linearSlop + kWallClearance_u;
}

// One static body holding every obstacle of the world as a fixture, in Box2D units. A box's
// polygon is inset by kSkinInset_u: with Box2D's skin around it, the disc rests against the box
// where the box is drawn, so a cell whose disc just reaches a box (o = 0 there, and the route
// rule's routes go through it: at integer corners and a 2.5 px radius, many cells) is reached
// like any other instead of about 0.05 px short (the skin less the slop), held there as blocked.
b2Body* add_obstacles(b2World& world, const worlds::ObstacleSpec& spec) {
  b2BodyDef def;
  b2Body* body = world.CreateBody(&def);
  const float u = static_cast<float>(kUnitsPerPx);
  for (const worlds::BoxObstacle& b : spec.boxes) {
    b2PolygonShape box;
    box.SetAsBox(0.5f * b.w * u - kSkinInset_u, 0.5f * b.h * u - kSkinInset_u,
                 b2Vec2((b.x + 0.5f * b.w) * u, (b.y + 0.5f * b.h) * u), 0.0f);
    body->CreateFixture(&box, 0.0f);
  }
  for (const worlds::DiscObstacle& d : spec.discs) {
    b2CircleShape disc;
    disc.m_p.Set(static_cast<float>(d.x) * u, static_cast<float>(d.y) * u);
    disc.m_radius = static_cast<float>(d.r) * u;
    body->CreateFixture(&disc, 0.0f);
  }
  return body;
}

// Collision filters in a team's world: the robots' discs meet the walls and the obstacles (Box2D's
// default category) and not each other; their bumpers meet only each other.
b2Filter filter(std::uint16_t category, std::uint16_t mask) {
  b2Filter f;
  f.categoryBits = category;
  f.maskBits = mask;
  return f;
}
const b2Filter kDiscFilter = filter(0x0004, 0x0001);
const b2Filter kBumperFilter = filter(0x0002, 0x0002);

// The walls: one static loop through `corners`. A chain collides on one side only, the right of
// each edge, so the corners wind with the right side facing the floor.
b2Body* add_walls(b2World& world, const b2Vec2 (&corners)[4]) {
  b2BodyDef def;
  b2Body* walls = world.CreateBody(&def);
  b2ChainShape loop;
  loop.CreateLoop(corners, 4);
  walls->CreateFixture(&loop, 0.0f);
  return walls;
}

// A robot: a frictionless disc with fixed rotation at `position` (Box2D units). With a bumper radius
// (teams), a massless bumper as well, which only the teammates' bumpers touch: Box2D's discs have
// no contact skin, so two robots closing in at full speed would overlap by up to two ticks' travel
// before their contact acts, and a robot blocked there would keep the overlap. A bumper one tick's
// travel wider than the disc keeps the discs themselves apart.
b2Body* add_robot(b2World& world, b2Vec2 position, float radius_u, float density, float bumper_radius_u) {
  b2BodyDef def;
  def.type = b2_dynamicBody;
  def.fixedRotation = true;
  def.allowSleep = false;
  def.position = position;
  b2Body* body = world.CreateBody(&def);
  const bool bumper = bumper_radius_u > 0.0f;
  b2CircleShape disc;
  disc.m_radius = radius_u;
  b2FixtureDef fixture;
  fixture.shape = &disc;
  fixture.density = density;
  fixture.friction = 0.0f;
  fixture.restitution = 0.0f;
  if (bumper) fixture.filter = kDiscFilter;  // the bumper meets the teammates
  body->CreateFixture(&fixture);
  if (bumper) {
    b2CircleShape ring;
    ring.m_radius = bumper_radius_u;
    b2FixtureDef ring_def;
    ring_def.shape = &ring;
    ring_def.density = 0.0f;
    ring_def.friction = 0.0f;
    ring_def.restitution = 0.0f;
    ring_def.filter = kBumperFilter;
    body->CreateFixture(&ring_def);
  }
  return body;
}

// The fastest a robot may go: a scale error can speed the drive up (four standard deviations are
// counted), and a push adds its velocity change.
double fastest_speed_mps(const RobotParams& params) {
  return params.body.max_speed_mps * (1.0 + 4.0 * params.motion.scale_sd) +
         (params.pushes.none() ? 0.0 : params.pushes.impulse_ns / params.body.mass_kg);
}

// A robot whose move is over holds its place while its teammates finish theirs: a teammate
// pushing it must not shove it along. It stays a dynamic body (making it static would drop its
// contacts for a tick, and let a teammate into its disc), but a million times heavier, and at rest
// before every tick: a push at full speed moves it a millionth of a tick's travel.
constexpr float kHeldMassFactor = 1e6f;

void hold(b2Body* body) {
  b2MassData mass;
  body->GetMassData(&mass);
  mass.mass *= kHeldMassFactor;
  body->SetMassData(&mass);
  body->SetLinearVelocity(b2Vec2(0.0f, 0.0f));
}

// A tick that moved the centre less than this while touching an obstacle means the obstacle
// holds it: the move ends there (pixels).
constexpr double kBlockedTravel_px = 0.02;

// The smallest scale a move's displacement takes (motion.scale_sd's normal is clamped there).
constexpr double kMinScale = 0.05;

}  // namespace

// One floor: a Box2D world with walls, the floor's obstacles and a team of robots.
struct RobotBatch::Team {
  std::unique_ptr<b2World> world;
  b2Body* walls = nullptr;
  b2Body* obstacles = nullptr;  // null in a world without obstacles
};

struct RobotBatch::Robot {
  b2Body* body = nullptr;
  Team* team = nullptr;
  // Imperfect motion only: the robot's stream of motion errors and pushes, and the part of its
  // displacement the odometry has not sensed (true position minus believed one, Box2D units).
  core::Rng motion_rng{0};
  Eigen::Vector2d unsensed_u = Eigen::Vector2d::Zero();
};

RobotParams RobotParams::from_world(const worlds::World& world) {
  return {world.robot, world.controller, world.physics, world.motion, world.pushes, world.obstacles, world.team};
}

double RobotBatch::wall_margin_px() { return kWallClearance_u / kUnitsPerPx; }

double RobotBatch::bumper_radius_px(const RobotParams& params, const grid::FloorFrame& frame) {
  return (params.body.radius_m + fastest_speed_mps(params) * params.physics.dt_s) / frame.pixel_size_m;
}

RobotBatch::RobotBatch(const grid::FloorFrame& frame, const RobotParams& params, int count, int threads)
    : RobotBatch(frame, params, count, std::make_shared<core::WorkerPool>(threads)) {}

RobotBatch::RobotBatch(const grid::FloorFrame& frame, const RobotParams& params, int count,
                       std::shared_ptr<core::WorkerPool> pool)
    : frame_(frame),
      params_(params),
      robots_(new Robot[count > 0 ? count : 0]),
      count_(count),
      team_size_(params.team.robots),
      pool_(std::move(pool)) {
  if (!pool_) throw std::invalid_argument("RobotBatch: no worker pool");
  if (count <= 0) throw std::invalid_argument("RobotBatch: count must be positive, got " + std::to_string(count));
  if (team_size_ < 1 || team_size_ > worlds::kMaxTeamRobots || count % team_size_ != 0)
    throw std::invalid_argument("RobotBatch: " + std::to_string(count) + " robots do not make teams of " +
                                std::to_string(team_size_));
  teams_.reset(new Team[count / team_size_]);
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
  const b2Vec2 corners[4] = {
      {min_x - off, min_y - off}, {min_x - off, max_y + off}, {max_x + off, max_y + off}, {max_x + off, min_y - off}};
  const float density = static_cast<float>(params.body.mass_kg / (M_PI * radius_u * radius_u));

  // Continuous collision (time of impact) costs about half of a tick here. It is needed only when
  // one tick can carry the centre across a wall, i.e. when the speed limit allows moving a
  // sizeable part of the radius per tick; the paper preset moves 1/3 px = 0.033 m per tick
  // against a 0.25 m radius, and a discrete contact then always stops the disc.
  const double fastest_mps = fastest_speed_mps(params);
  const bool continuous = fastest_mps * params.physics.dt_s > 0.25 * params.body.radius_m;  // same ratio in units
  const float bumper_radius_u =
      team_size_ > 1 ? static_cast<float>(bumper_radius_px(params, frame) * kUnitsPerPx) : 0.0f;
  for (int k = 0; k < count / team_size_; ++k) {
    Team& t = teams_[k];
    t.world = std::make_unique<b2World>(b2Vec2(0.0f, 0.0f));
    t.world->SetAllowSleeping(false);
    t.world->SetContinuousPhysics(continuous);
    t.walls = add_walls(*t.world, corners);
    if (!params.obstacles.no_fixed()) t.obstacles = add_obstacles(*t.world, params.obstacles);
    for (int i = k * team_size_; i < (k + 1) * team_size_; ++i) {
      Robot& r = robots_[i];
      r.team = &t;
      // Apart until place() puts them on their starts (members never overlap at creation).
      const b2Vec2 parked(min_x + static_cast<float>(i - k * team_size_) * 3.0f * static_cast<float>(radius_u), min_y);
      r.body = add_robot(*t.world, parked, static_cast<float>(radius_u), density, bumper_radius_u);
    }
  }
}

RobotBatch::~RobotBatch() = default;

int RobotBatch::size() const { return count_; }
int RobotBatch::team_size() const { return team_size_; }
int RobotBatch::threads() const { return pool_->threads(); }
const grid::FloorFrame& RobotBatch::frame() const { return frame_; }
const RobotParams& RobotBatch::params() const { return params_; }

void RobotBatch::place(int robot, const grid::Cell& cell, std::uint64_t motion_seed) {
  Robot& r = robots_[robot];
  r.motion_rng = core::Rng(motion_seed);
  r.unsensed_u.setZero();
  const Eigen::Vector2d u = frame_.cell_centre_px(cell) * kUnitsPerPx;
  r.body->SetTransform(b2Vec2(static_cast<float>(u.x()), static_cast<float>(u.y())), 0.0f);
  r.body->SetLinearVelocity(b2Vec2(0.0f, 0.0f));
}

void RobotBatch::set_obstacles(int robot, const worlds::ObstacleSpec& layout) {
  Team& t = *robots_[robot].team;
  if (t.obstacles != nullptr) t.world->DestroyBody(t.obstacles);  // and its contacts
  t.obstacles = layout.no_fixed() ? nullptr : add_obstacles(*t.world, layout);
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

grid::Cell RobotBatch::odometry_pose(int robot) const {
  return frame_.grid_pose(position_px(robot) - robots_[robot].unsensed_u / kUnitsPerPx);
}

grid::Cell RobotBatch::agent_pose(int robot) const {
  return params_.motion.pose == worlds::PoseSource::Odometry ? odometry_pose(robot) : grid_pose(robot);
}

bool RobotBatch::touching_wall(int robot) const {
  const Robot& r = robots_[robot];
  for (const b2ContactEdge* e = r.body->GetContactList(); e != nullptr; e = e->next)
    if (e->other == r.team->walls && e->contact->IsTouching()) return true;
  return false;
}

bool RobotBatch::touching_obstacle(int robot) const {
  const Robot& r = robots_[robot];
  if (r.team->obstacles == nullptr) return false;
  for (const b2ContactEdge* e = r.body->GetContactList(); e != nullptr; e = e->next)
    if (e->other == r.team->obstacles && e->contact->IsTouching()) return true;
  return false;
}

bool RobotBatch::touching_teammate(int robot) const {
  const Robot& r = robots_[robot];
  if (team_size_ == 1) return false;
  for (const b2ContactEdge* e = r.body->GetContactList(); e != nullptr; e = e->next)
    if (e->other != r.team->walls && e->other != r.team->obstacles && e->contact->IsTouching()) return true;
  return false;
}

// What every move of a batch shares: the world's constants in Box2D units, and the bookkeeping
// after each tick.
struct RobotBatch::MoveContext {
  const RobotBatch& batch;
  float dt;
  double units_per_m;
  double tolerance_u;
  double max_speed_u;
  double kp;
  double push_speed_u;       // a push's velocity change (impulse / mass), Box2D units per second
  double traction_per_tick;  // the share of a push's velocity left after a tick

  explicit MoveContext(const RobotBatch& b)
      : batch(b),
        dt(static_cast<float>(b.params_.physics.dt_s)),
        units_per_m(kUnitsPerPx / b.frame_.pixel_size_m),
        tolerance_u(b.params_.controller.tolerance_px * kUnitsPerPx),
        max_speed_u(b.params_.body.max_speed_mps * units_per_m),
        kp(b.params_.controller.kp_per_s),
        push_speed_u(b.params_.pushes.impulse_ns / b.params_.body.mass_kg * units_per_m),
        traction_per_tick(std::exp(-b.params_.physics.dt_s / b.params_.pushes.traction_s)) {}

  // The saturated P-control law: velocity toward `error` (units), kp x distance capped at the
  // speed limit.
  Eigen::Vector2d command(const Eigen::Vector2d& error, double distance) const {
    const double speed = std::min(max_speed_u, kp * distance);
    return error * (speed / distance);
  }

  // After a tick that started at `p`: the speed reached, the tick trace, the border and the walls.
  void after_tick(int robot, const b2Vec2& p, double& peak_speed_u, MoveResult& out,
                  std::vector<Eigen::Vector2d>* trace) const {
    const b2Body* body = batch.robots_[robot].body;
    // The speed reached is the distance actually travelled in the tick (a contact that stops
    // the body mid-tick leaves zero velocity behind, but not zero travel), or the velocity
    // left, whichever is larger.
    const b2Vec2 now = body->GetPosition();
    const double travelled = Eigen::Vector2d(now.x - p.x, now.y - p.y).norm() / dt;
    peak_speed_u = std::max({peak_speed_u, travelled, static_cast<double>(body->GetLinearVelocity().Length())});
    const double x = now.x / kUnitsPerPx, y = now.y / kUnitsPerPx;
    if (trace != nullptr) trace->emplace_back(x, y);
    const grid::FloorFrame& frame = batch.frame_;
    out.beyond_border_px =
        std::max({out.beyond_border_px, 0.5 - x, x - (frame.width_px - 0.5), 0.5 - y, y - (frame.height_px - 0.5)});
    if (!out.touched_wall) out.touched_wall = batch.touching_wall(robot);
    // Held by an obstacle or a teammate: the move ends at contact rather than pushing until the
    // tick bound.
    const bool can_be_held = batch.robots_[robot].team->obstacles != nullptr || batch.team_size_ > 1;
    if (can_be_held && travelled * dt < kBlockedTravel_px * kUnitsPerPx &&
        (batch.touching_obstacle(robot) || batch.touching_teammate(robot)))
      out.blocked = true;
  }
};

// One robot's move in progress: what begin_move() drew and computed, and what each tick carries
// over to the next.
struct RobotBatch::MemberMove {
  MoveResult* out = nullptr;
  std::vector<Eigen::Vector2d>* trace = nullptr;
  bool done = false;
  Eigen::Vector2d target_u = Eigen::Vector2d::Zero();  // the commanded cell's centre (believed, with odometry)
  double peak_speed_u = 0.0;
  b2Vec2 tick_start;  // the position at the start of the current tick
  // Imperfect motion only (docs/SCENARIOS.md § Imperfect motion).
  double scale = 1.0, cos_h = 1.0, sin_h = 0.0;
  bool push_drawn = false;
  int push_tick = 0;
  double push_angle = 0.0;
  double carried = 1.0;  // the share of the wheels' travel that reaches the floor this tick
  Eigen::Vector2d push_velocity_u = Eigen::Vector2d::Zero();
};

// The start of a move. The paper's robot (an exact world): the controller closes its loop on the
// true position, so every move settles on its commanded cell (a wall or the tick bound
// permitting). Imperfect motion (docs/SCENARIOS.md § Imperfect motion): the controller closes its
// loop on odometry, the true position minus what the wheels did not sense. Each move draws a
// scale s and a heading error theta, and the wheels' motion reaches the floor as s R(theta) times
// the commanded velocity; the difference is unsensed, so the move settles where odometry says the
// target is and lands off it. A push is felt (the wheels turn with it): the controller corrects
// it, and traction absorbs the push's velocity with time constant traction_s.
// Returns false when the move is over before its first tick (a zero command with imperfect motion).
bool RobotBatch::begin_move(const MoveContext& /*c*/, int i, const grid::Cell& command, MemberMove& m) {
  if (params_.exact()) {
    m.target_u = frame_.cell_centre_px(grid_pose(i) + command) * kUnitsPerPx;
    return true;
  }
  Robot& r = robots_[i];
  const worlds::MotionSpec& motion = params_.motion;
  const worlds::PushSpec& pushes = params_.pushes;
  // Seven draws in a fixed order for every move, zero ones included, so that a robot's k-th
  // move always uses the same part of its stream.
  // The scale is kept above 0.05: a move never runs backwards (scale_sd <= 0.3 makes a clamp rarer than 1 in 1000).
  m.scale = std::max(kMinScale, 1.0 + motion.scale_sd * core::standard_normal(r.motion_rng));
  const double heading = motion.heading_sd_deg * (M_PI / 180.0) * core::standard_normal(r.motion_rng);
  m.push_drawn = core::uniform01(r.motion_rng) < pushes.probability;
  m.push_tick =
      static_cast<int>(core::uniform_below(r.motion_rng, static_cast<std::uint64_t>(std::max(pushes.within_ticks, 1))));
  m.push_angle = 2.0 * M_PI * core::uniform01(r.motion_rng);
  if (motion.pose == worlds::PoseSource::Localised) r.unsensed_u.setZero();  // re-localised before each move
  if (command == grid::Cell::Zero()) return false;                           // no move: it stays, no tick, no push
  m.cos_h = std::cos(heading);
  m.sin_h = std::sin(heading);
  m.target_u = frame_.cell_centre_px(odometry_pose(i) + command) * kUnitsPerPx;
  return true;
}

// Before a tick: the move is over (settled, or out of ticks), or the controller sets the velocity.
// Returns false when the move is over.
bool RobotBatch::before_tick(const MoveContext& c, int i, MemberMove& m) {
  Robot& r = robots_[i];
  MoveResult& out = *m.out;
  const b2Vec2 p = r.body->GetPosition();
  m.tick_start = p;
  if (params_.exact()) {
    const Eigen::Vector2d error(m.target_u.x() - p.x, m.target_u.y() - p.y);
    const double distance = error.norm();
    if (distance <= c.tolerance_u) {
      out.settled = true;
      return false;
    }
    if (out.ticks >= params_.physics.max_ticks_per_move) return false;
    // Saturated P-control of velocity: the body still collides, so a wall stops it.
    const Eigen::Vector2d v = c.command(error, distance);
    r.body->SetLinearVelocity(b2Vec2(static_cast<float>(v.x()), static_cast<float>(v.y())));
    return true;
  }
  const Eigen::Vector2d believed = Eigen::Vector2d(p.x, p.y) - r.unsensed_u;
  const Eigen::Vector2d error = m.target_u - believed;
  const double distance = error.norm();
  const bool push_pending = m.push_drawn && out.ticks <= m.push_tick;
  if (distance <= c.tolerance_u && !push_pending) {
    out.settled = true;
    return false;
  }
  if (out.ticks >= params_.physics.max_ticks_per_move) return false;
  const Eigen::Vector2d commanded = distance > 0.0 ? c.command(error, distance) : Eigen::Vector2d::Zero();
  // On a slip zone the wheels turn as commanded but carry the body only (1 - slip) of the way.
  const double traction = 1.0 - params_.motion.slip_at(p.x / kUnitsPerPx, p.y / kUnitsPerPx);
  m.carried = m.scale * traction;
  const Eigen::Vector2d wheels(m.carried * (m.cos_h * commanded.x() - m.sin_h * commanded.y()),
                               m.carried * (m.sin_h * commanded.x() + m.cos_h * commanded.y()));
  if (m.push_drawn && out.ticks == m.push_tick) {
    m.push_velocity_u = c.push_speed_u * Eigen::Vector2d(std::cos(m.push_angle), std::sin(m.push_angle));
    out.pushed = true;
  }
  const Eigen::Vector2d v = wheels + m.push_velocity_u;
  r.body->SetLinearVelocity(b2Vec2(static_cast<float>(v.x()), static_cast<float>(v.y())));
  return true;
}

// After a tick: the odometry's unsensed part, the bookkeeping; the move is over when held.
void RobotBatch::after_tick(const MoveContext& c, int i, MemberMove& m) {
  Robot& r = robots_[i];
  MoveResult& out = *m.out;
  ++out.ticks;
  if (!params_.exact()) {
    // The unsensed part of what the drive really did: the wheels believe they moved
    // (s (1 - slip) R(theta))^-1 times the drive's displacement. Measured from the displacement, so that a
    // wall, an obstacle or a teammate that stops the body stops the odometry too (it is sensed).
    const b2Vec2 now = r.body->GetPosition();
    const b2Vec2& p = m.tick_start;
    const Eigen::Vector2d drive =
        Eigen::Vector2d(now.x - p.x, now.y - p.y) - m.push_velocity_u * static_cast<double>(c.dt);
    const Eigen::Vector2d believed_drive((m.cos_h * drive.x() + m.sin_h * drive.y()) / m.carried,
                                         (-m.sin_h * drive.x() + m.cos_h * drive.y()) / m.carried);
    r.unsensed_u += drive - believed_drive;
    m.push_velocity_u *= c.traction_per_tick;
  }
  c.after_tick(i, m.tick_start, m.peak_speed_u, out, m.trace);
  if (out.blocked) m.done = true;
}

void RobotBatch::end_move(const MoveContext& c, int i, MemberMove& m) {
  m.done = true;
  m.out->peak_speed_mps = m.peak_speed_u / c.units_per_m;
  if (!params_.exact() && params_.motion.pose == worlds::PoseSource::Localised)
    robots_[i].unsensed_u.setZero();  // where it is, it knows
  if (team_size_ > 1) hold(robots_[i].body);
}

// The robots of team `team` tick together: before each tick every robot still moving sets its
// velocity, the team's world steps once, and each looks at where it got. A robot whose move is
// over holds its place while the others finish; with one robot this is the paper's loop.
void RobotBatch::move_team(const MoveContext& c, int team, std::span<const grid::Cell> commands,
                           std::span<MoveResult> results, std::span<std::vector<Eigen::Vector2d>> traces) {
  const int first = team * team_size_;
  MemberMove moves[worlds::kMaxTeamRobots];
  for (int k = 0; k < team_size_; ++k) {
    const int i = first + k;
    MemberMove& m = moves[k];
    results[i] = MoveResult{};
    m.out = &results[i];
    m.trace = traces.empty() ? nullptr : &traces[i];
    if (!begin_move(c, i, commands[i], m)) {  // it stays: no tick, nothing to end
      m.done = true;
      if (team_size_ > 1) hold(robots_[i].body);
    }
  }
  b2World& world = *teams_[team].world;
  for (;;) {
    bool moving = false;
    for (int k = 0; k < team_size_; ++k) {
      if (moves[k].done) continue;
      if (before_tick(c, first + k, moves[k])) {
        moving = true;
      } else {
        end_move(c, first + k, moves[k]);
      }
    }
    if (!moving) break;
    if (team_size_ > 1)
      for (int k = 0; k < team_size_; ++k)
        if (moves[k].done) robots_[first + k].body->SetLinearVelocity(b2Vec2(0.0f, 0.0f));
    world.Step(c.dt, params_.physics.velocity_iterations, params_.physics.position_iterations);
    for (int k = 0; k < team_size_; ++k) {
      if (moves[k].done) continue;
      after_tick(c, first + k, moves[k]);
      if (moves[k].done) end_move(c, first + k, moves[k]);
    }
  }
  for (int k = 0; k < team_size_; ++k) {
    b2Body* body = robots_[first + k].body;
    // The robot comes to rest on its cell (or where a wall stopped it) before the next move.
    if (team_size_ > 1) body->ResetMassData();  // its own mass again
    body->SetLinearVelocity(b2Vec2(0.0f, 0.0f));
  }
}

void RobotBatch::move(std::span<const grid::Cell> commands, std::span<MoveResult> results,
                      std::span<std::vector<Eigen::Vector2d>> tick_positions_px) {
  if (commands.size() > static_cast<std::size_t>(count_) || results.size() < commands.size() ||
      commands.size() % team_size_ != 0)
    throw std::invalid_argument("RobotBatch::move: " + std::to_string(commands.size()) + " commands for " +
                                std::to_string(count_) + " robots in teams of " + std::to_string(team_size_) + " and " +
                                std::to_string(results.size()) + " results");
  if (!tick_positions_px.empty() && tick_positions_px.size() < commands.size())
    throw std::invalid_argument("RobotBatch::move: " + std::to_string(tick_positions_px.size()) + " tick traces for " +
                                std::to_string(commands.size()) + " commands");
  const MoveContext context(*this);
  const int teams = static_cast<int>(commands.size()) / team_size_;

  // Each team lives in its own world, so teams are independent work items: no synchronisation
  // per tick, and the result does not depend on the thread count.
  pool_->parallel_for(teams, std::max(1, 8 / team_size_),
                      [&](int team) { move_team(context, team, commands, results, tick_positions_px); });
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
