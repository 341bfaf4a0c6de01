#pragma once
/// World files: the YAML description of a scenario (schema in worlds/README.md).
/// Loading validates every field and never aborts: bad input throws scout::InputError with
/// "file:line: field: expected ..." and nothing else.
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"

namespace scout::worlds {

/// Which part of a data set a floor comes from (METHOD.md § Data).
enum class Split { Train, Validation, Test };
const char* to_string(Split split);

/// How a floor is made from a data set's images (worlds/floor_layout.hpp, worlds/README.md § Floors
/// larger than the digit): the image itself (today's floors), or composed on a larger black floor.
enum class FloorLayout {
  Centred,     ///< the digit at the floor's centre (the image itself when the floor has the image's size)
  Translated,  ///< the digit at a random place on the floor
  Cluttered,   ///< translated, plus pieces of other digits of the same split at random places
};
const char* to_string(FloorLayout layout);

/// A floor's size, pixels.
struct FloorSize {
  int width_px = 0;
  int height_px = 0;
  bool operator==(const FloorSize&) const = default;
};

/// The most digits one floor holds.
inline constexpr int kMaxFloorDigits = 16;

/// The floor: a data set image or a PNG file, and its physical scale.
struct FloorSpec {
  std::string dataset;  ///< "mnist", "fashion-mnist" or a folder path (absolute once loaded); empty when `image` is set
  Split split = Split::Train;        ///< split of `dataset`
  std::optional<int> index;          ///< image index within the split; nullopt means "random"
  std::filesystem::path image;       ///< PNG file read as grayscale (absolute once loaded); empty when `dataset` is set
  double pixel_size_m = 0.1;         ///< metres per floor pixel
  std::optional<FloorSize> size_px;  ///< the floor's size; nullopt: the image's own (today's floors)
  FloorLayout layout = FloorLayout::Centred;  ///< where the digits go on a floor of size_px
  int clutter = 0;                            ///< Cluttered: pieces of other digits pasted on each floor
  int clutter_px = 8;                         ///< the side of a clutter piece, pixels
  int digits = 1;  ///< digits on one floor; with several the label is their sum (worlds/floor_layout.hpp)
  /// True when floors are composed from the images rather than being them (any field above set).
  bool composed() const { return size_px.has_value() || layout != FloorLayout::Centred || digits != 1; }
};

/// The robot body.
struct RobotSpec {
  double radius_m = 0.25;                    ///< disc radius, metres
  double mass_kg = 1.0;                      ///< body mass, kilograms
  double max_speed_mps = 2.0;                ///< controller speed limit, metres per second
  std::optional<std::pair<int, int>> start;  ///< start cell [x, y] in pixels; nullopt means "random"
};

/// The move controller: a saturated proportional velocity controller (sim/README in code).
struct ControllerSpec {
  double kp_per_s = 60.0;      ///< proportional gain on the position error, 1/s
  double tolerance_px = 0.05;  ///< a move has settled when the centre is this close to the cell centre, pixels
};

/// The largest camera patch the renderer draws (render::PatchCamera's limit), pixels.
inline constexpr int kMaxPatchPx = 64;

/// The downward camera.
struct CameraSpec {
  int patch_px = 6;  ///< m: the camera sees an m x m pixel window, 1 .. kMaxPatchPx
  /// The wider view (off at 0): a second, coarser window of wide_px x wide_px pixels, each the
  /// mean of a block of wide_scale x wide_scale floor pixels of the floor's block grid (the blocks
  /// around the robot's block), taken with the patch (render::WideView). It covers
  /// (wide_px * wide_scale)^2 floor pixels.
  int wide_px = 0;
  int wide_scale = 4;  ///< floor pixels per wide-view pixel, per side
  bool wide() const { return wide_px > 0; }
};

/// The active-perception task.
struct TaskSpec {
  int episodes = 4;  ///< E: goals per rollout
  int steps = 5;     ///< T: moves per episode
  int step_px = 2;   ///< s: the longest move, pixels
};

/// Box2D stepping.
struct PhysicsSpec {
  double dt_s = 1.0 / 60.0;      ///< one tick, seconds
  int velocity_iterations = 8;   ///< Box2D velocity solver iterations per tick
  int position_iterations = 3;   ///< Box2D position solver iterations per tick
  int max_ticks_per_move = 120;  ///< a move that has not settled after this many ticks ends where the robot is
};

/// What the agent reads as its own pose when moves do not land exactly (docs/SCENARIOS.md § Imperfect
/// motion).
enum class PoseSource {
  Localised,  ///< the cell the robot is really in (a localised robot; the paper's l)
  Odometry,   ///< the cell dead reckoning believes it is in: the chain of commanded cells
};
const char* to_string(PoseSource source);

/// Imperfect motion: each move is executed with a scale and a heading error the robot does not
/// sense (wheel slip, miscalibrated wheels). The defaults are exact moves: today's worlds.
/// A floor region of lower friction: the pixels [x, x + w) x [y, y + h), where the wheels lose the
/// share `slip` of their travel.
struct SlipZone {
  int x = 0;
  int y = 0;
  int w = 1;
  int h = 1;
  double slip = 0.5;
  bool operator==(const SlipZone&) const = default;
};

struct MotionSpec {
  double scale_sd = 0.0;        ///< standard deviation of the per-move scale error of the displacement
  double heading_sd_deg = 0.0;  ///< standard deviation of the per-move heading error, degrees
  PoseSource pose = PoseSource::Localised;
  std::vector<SlipZone> slip_zones;  ///< regions of lower friction (docs/SCENARIOS.md § Slip zones)
  /// True when every move lands on its commanded cell's centre (within the controller's tolerance).
  bool exact() const { return scale_sd == 0.0 && heading_sd_deg == 0.0 && slip_zones.empty(); }
  /// The slip at the floor point (x, y) (continuous pixels): the largest of the zones that hold it, 0 outside.
  double slip_at(double x, double y) const;
};

/// Random pushes: an impulse on the robot during a move, which the controller corrects (it feels
/// the push through its wheels) until the move settles or runs out of ticks.
struct PushSpec {
  double probability = 0.0;  ///< chance that a move is pushed
  double impulse_ns = 1.0;   ///< the push's impulse, newton-seconds (a velocity change of impulse / mass)
  int within_ticks = 10;     ///< the push comes at a tick drawn uniformly from the move's first `within_ticks`
  double traction_s = 0.1;   ///< time constant with which the wheels' traction absorbs the push's velocity
  bool none() const { return probability == 0.0; }
};

/// A box obstacle: the floor pixels [x, x + w) x [y, y + h).
struct BoxObstacle {
  int x = 0;
  int y = 0;
  int w = 1;
  int h = 1;
  /// The distance from the floor point (x, y) to the box, pixels (0 inside it).
  double distance_px(double px, double py) const;
  bool operator==(const BoxObstacle&) const = default;
};

/// A disc obstacle: centre (x, y) in continuous floor pixels (a cell's centre is (x + 0.5, y + 0.5)),
/// radius r pixels.
struct DiscObstacle {
  double x = 0.5;
  double y = 0.5;
  double r = 1.0;
  /// The distance from the floor point (x, y) to the disc's edge, pixels (0 inside it).
  double distance_px(double px, double py) const;
  bool operator==(const DiscObstacle&) const = default;
};

/// The most obstacles of each kind a world holds.
inline constexpr int kMaxObstacles = 64;

/// Static obstacles on the floor (docs/SCENARIOS.md § Obstacles): bodies that stop the robot, and
/// that the downward camera sees instead of the floor. The default is none: today's worlds.
struct ObstacleSpec {
  std::vector<BoxObstacle> boxes;
  std::vector<DiscObstacle> discs;
  int shade = 128;            ///< the grey level the camera sees on an obstacle
  int random_boxes = 0;       ///< boxes drawn anew for every run (env::run_obstacles), beside the fixed ones
  int random_box_min_px = 2;  ///< a random box's sides are drawn uniformly from [min, max] pixels
  int random_box_max_px = 4;
  /// No obstacle at all, fixed or random: today's worlds.
  bool none() const { return boxes.empty() && discs.empty() && random_boxes == 0; }
  /// No fixed obstacle (a world with random boxes only, or a run's layout without any).
  bool no_fixed() const { return boxes.empty() && discs.empty(); }
  /// True when the floor point (x, y) (continuous pixels) lies on an obstacle.
  bool covers(double x, double y) const;
  /// The distance from (x, y) to the nearest obstacle's edge, pixels (0 inside one; +infinity
  /// without obstacles).
  double clearance_px(double x, double y) const;
};

/// The most robots of one team (docs/SCENARIOS.md § Several robots).
inline constexpr int kMaxTeamRobots = 8;

/// Several robots on one floor (docs/SCENARIOS.md § Several robots): K robots share one Box2D
/// world, move in the same ticks, collide, and share what the team has seen; each drives E / K
/// of the rollout's E episodes. The default, one robot, is today's worlds.
struct TeamSpec {
  int robots = 1;  ///< K
  bool single() const { return robots == 1; }
};

/// A loaded, validated world file.
struct World {
  std::filesystem::path file;  ///< the file it was read from (as given)
  FloorSpec floor;
  RobotSpec robot;
  ControllerSpec controller;
  CameraSpec camera;
  TaskSpec task;
  PhysicsSpec physics;
  MotionSpec motion;
  PushSpec pushes;
  ObstacleSpec obstacles;
  TeamSpec team;
  std::uint64_t seed = 0;            ///< run seed; the command line's --seed overrides it
  std::map<std::string, int> lines;  ///< dotted field name -> 1-based line in `file`, for later errors

  /// True when every move lands where it was commanded: no motion error, no pushes (the paper's
  /// world; the camera then sees exact crops at grid poses).
  bool ideal_motion() const { return motion.exact() && pushes.none(); }
};

/// One field of the world file, as the schema table in worlds/README.md lists it. The loader's
/// checks, its messages and to_yaml are driven by the same table (worlds/world.cpp, "The schema").
/// Texts may hold Markdown code spans (`random`), as the README shows them.
struct FieldInfo {
  std::string_view section;  ///< "floor", "robot", ...; empty for a top-level field (seed)
  std::string_view name;     ///< the YAML key
  std::string_view type;     ///< "integer", "number", "unsigned integer", or a special field's form
  std::string default_text;  ///< a default World's value as to_yaml writes it; empty where there is none
  std::string range_text;    ///< the accepted values ("[1, 64]", "(0, 10]"), then any rule beyond them
  std::string_view doc;      ///< one line: what the field means
  std::string_view unit;     ///< empty for counts, names and seeds
};

/// Every field of the world file, in the order to_yaml writes them.
std::span<const FieldInfo> world_schema();

/// Reads and validates a world file. Relative `dataset` folders and `image` paths are resolved
/// against the file's directory. Throws InputError.
World load_world(const std::filesystem::path& file);

/// Parses world-file text; `origin` names it in error messages and is the base for relative paths.
World parse_world(std::string_view text, const std::filesystem::path& origin);

/// "file:line: field" for a field of the world (its line if the file gave it, else its
/// section's, else none), the start of every error message about that field.
std::string field_location(const World& world, const std::string& field);

/// Checks the fields that depend on the floor's size (patch larger than the floor, start off
/// the floor). Throws InputError naming the field's line.
void check_against_floor(const World& world, int floor_width_px, int floor_height_px);

/// The world as YAML text with every field resolved (for manifests); parse_world reads it back.
std::string to_yaml(const World& world);

}  // namespace scout::worlds
