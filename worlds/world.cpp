// World files: YAML text -> validated World, and back (schema and error format in README.md).
//
// The loader is written for hostile input: every value is checked for kind (scalar, sequence,
// map), spelling (integers must be written as integers) and range, every key is checked against
// the schema, and every failure becomes one scout::InputError line
// "file:line: dotted.field: expected ..., got ...". yaml-cpp only ever sees text that has passed
// a size and nesting pre-scan, because its recursive-descent parser is the one part of the
// pipeline that could otherwise exhaust the stack.
#include "worlds/world.hpp"

#include <fmt/format.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <optional>
#include <set>
#include <span>
#include <sstream>
#include <string>
#include <system_error>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "worlds/dataset.hpp"
#include "worlds/floor_layout.hpp"

namespace scout::worlds {

const char* to_string(PoseSource source) {
  switch (source) {
    case PoseSource::Localised:
      return "localised";
    case PoseSource::Odometry:
      return "odometry";
  }
  return "?";
}

const char* to_string(FloorLayout layout) {
  switch (layout) {
    case FloorLayout::Centred:
      return "centred";
    case FloorLayout::Translated:
      return "translated";
    case FloorLayout::Cluttered:
      return "cluttered";
  }
  return "?";
}

const char* to_string(Split split) {
  switch (split) {
    case Split::Train:
      return "train";
    case Split::Validation:
      return "validation";
    case Split::Test:
      return "test";
  }
  return "train";  // unreachable for valid enumerators; keeps -Wreturn-type quiet
}

namespace {

namespace fs = std::filesystem;

/// World files are a few hundred bytes; anything near this is not a world file, and the cap
/// bounds the parser's time and memory.
constexpr std::size_t kMaxFileBytes = std::size_t{1} << 20;

/// yaml-cpp parses recursively (its own guard stops at 2000 levels, deep enough to matter on
/// small thread stacks); a world file needs 3 levels, so 64 refuses only nonsense.
constexpr int kMaxNesting = 64;

/// Scalars quoted back in messages are clipped so that one bad value cannot flood a terminal.
constexpr std::size_t kMaxQuoted = 40;
// The longest path a world may name (Linux's PATH_MAX).
constexpr std::size_t kMaxPathBytes = 4096;

constexpr std::string_view kYamlTagPrefix = "tag:yaml.org,2002:";

// ---------------------------------------------------------------------------------------------
// Messages

std::string clip(std::string_view text) {
  if (text.size() <= kMaxQuoted) return std::string(text);
  return std::string(text.substr(0, kMaxQuoted)) + "...";
}

/// The offset of the first byte of `text` that is not part of a character a YAML file can hold and
/// yaml-cpp's emitter writes back as it is: UTF-8 in its shortest form, no surrogate, nothing past
/// U+10FFFF, no noncharacter (U+FDD0..U+FDEF, U+xFFFE, U+xFFFF), which the emitter replaces with
/// U+FFFD. A name that failed this would be written into the manifest as another name.
std::optional<std::size_t> first_unwritable_byte(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    const auto lead = static_cast<unsigned char>(text[i]);
    if (lead < 0x80) {
      ++i;
      continue;
    }
    const std::size_t trailing = (lead & 0xE0) == 0xC0 ? 1 : (lead & 0xF0) == 0xE0 ? 2 : (lead & 0xF8) == 0xF0 ? 3 : 0;
    if (trailing == 0 || text.size() - i <= trailing) return i;
    char32_t code = lead & (0x3F >> trailing);
    for (std::size_t k = 1; k <= trailing; ++k) {
      const auto byte = static_cast<unsigned char>(text[i + k]);
      if ((byte & 0xC0) != 0x80) return i;
      code = (code << 6) | (byte & 0x3F);
    }
    constexpr char32_t kShortest[] = {0, 0x80, 0x800, 0x10000};
    const bool surrogate = code >= 0xD800 && code <= 0xDFFF;
    const bool noncharacter = (code >= 0xFDD0 && code <= 0xFDEF) || (code & 0xFFFE) == 0xFFFE;
    if (code < kShortest[trailing] || code > 0x10FFFF || surrogate || noncharacter) return i;
    i += trailing + 1;
  }
  return std::nullopt;
}

/// yaml-cpp marks are 0-based and may be the "null mark" (-1); messages are 1-based.
int line_of(const YAML::Mark& mark) { return mark.line >= 0 ? mark.line + 1 : 1; }
int line_of(const YAML::Node& node) { return line_of(node.Mark()); }

/// The tag as a user would write it ("!!str" rather than "tag:yaml.org,2002:str").
std::string short_tag(const std::string& tag) {
  if (tag.rfind(kYamlTagPrefix, 0) == 0) return "!!" + tag.substr(kYamlTagPrefix.size());
  return tag;
}

/// What a value is, for the "got ..." half of a message. Collections are described, never
/// printed: an alias can make them cyclic or huge.
std::string describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Undefined:
    case YAML::NodeType::Null:
      return "nothing";
    case YAML::NodeType::Sequence: {
      const std::size_t n = node.size();
      return "a sequence of " + std::to_string(n) + (n == 1 ? " element" : " elements");
    }
    case YAML::NodeType::Map:
      return "a map";
    case YAML::NodeType::Scalar:
      break;
  }
  const std::string& tag = node.Tag();
  if (tag == "!") return "the string \"" + clip(node.Scalar()) + "\"";
  if (tag != "?" && !tag.empty()) return "a value tagged " + clip(short_tag(tag)) + " (" + clip(node.Scalar()) + ")";
  return clip(node.Scalar());
}

std::string format_double(double v) {
  std::array<char, 64> buf{};
  const auto result = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), result.ptr);
}

// ---------------------------------------------------------------------------------------------
// The schema: one table per section, one row per field. The rows decide which keys a section
// takes, how each value is read and range-checked, what its messages say, how to_yaml writes it
// and what worlds/README.md lists (world_schema(); a test holds the README to it). A new integer
// or number field is one row here, its struct member and its README row.

/// How a field's value is written. The first three are the ordinary kinds, checked against the
/// row's range alone; each of the others is one special field with its own reader below.
enum class Type {
  Integer,        // int: a decimal integer in [lo, hi]
  Number,         // double: a finite decimal number in the row's interval
  Unsigned,       // std::uint64_t: any decimal integer in [0, 2^64 - 1]
  Dataset,        // floor.dataset: a name or a folder, resolved against the file
  SplitName,      // floor.split
  IndexOrRandom,  // floor.index: an integer in [lo, hi], or random
  PngPath,        // floor.image, resolved against the file
  StartOrRandom,  // robot.start: [x, y] or random
  PoseName,       // motion.pose: localised or odometry
  BoxList,        // obstacles.boxes: [[x, y, w, h], ...]
  DiscList,       // obstacles.discs: [[x, y, r], ...]
  SlipZoneList,   // motion.slip_zones: [[x, y, w, h, slip], ...]
  SizeOrImage,    // floor.size_px: [w, h], or image (the image's own size)
  LayoutName,     // floor.layout
};

/// The member a row reads and writes: its alternative is the one at the row's Type's position.
template <class Spec>
using Member = std::variant<int Spec::*, double Spec::*, std::uint64_t Spec::*, std::string Spec::*, Split Spec::*,
                            std::optional<int> Spec::*, fs::path Spec::*, std::optional<std::pair<int, int>> Spec::*,
                            PoseSource Spec::*, std::vector<BoxObstacle> Spec::*, std::vector<DiscObstacle> Spec::*,
                            std::vector<SlipZone> Spec::*, std::optional<FloorSize> Spec::*, FloorLayout Spec::*>;

/// The interval a value must lie in; integers take closed ones only.
struct Bounds {
  double lo = 0.0;
  double hi = 0.0;
  bool lo_open = false;
  bool hi_open = false;
};

/// [lo, hi]
constexpr Bounds closed(double lo, double hi) { return {lo, hi, false, false}; }
/// (lo, hi]
constexpr Bounds left_open(double lo, double hi) { return {lo, hi, true, false}; }
/// (lo, hi)
constexpr Bounds open_both(double lo, double hi) { return {lo, hi, true, true}; }

/// One field: `name : type = default (from the struct) in range, and rule # doc [unit]`.
template <class Spec>
struct Row {
  std::string_view name;
  Type type;
  Member<Spec> member;
  Bounds range;           // for Integer, Number and IndexOrRandom
  std::string_view rule;  // what else limits the value (checked by hand elsewhere), for the docs
  std::string_view unit;  // empty for counts, names and seeds
  std::string_view doc;
};

constexpr double kIntMax = std::numeric_limits<int>::max();

// Columns: name, type, member (its initializer is the default), range, rule beyond the range
// (checked by hand, here for the docs), unit, doc. Rows are in the order to_yaml writes them.
// clang-format off
constexpr Row<FloorSpec> kFloorRows[] = {
    {"dataset", Type::Dataset, &FloorSpec::dataset, {}, "non-empty", "",
     "`mnist`, `mnist-10k`, `fashion-mnist`, or a folder of IDX files (relative to the world file)"},
    {"split", Type::SplitName, &FloorSpec::split, {}, "", "",
     "which split of `dataset` the floor comes from"},
    {"index", Type::IndexOrRandom, &FloorSpec::index, closed(0, kIntMax), "and below the split's size", "",
     "which image of the split; `random` draws it from the seed"},
    {"image", Type::PngPath, &FloorSpec::image, {}, "ends in `.png` (any case)", "",
     "a grayscale PNG used as the floor instead of a data set (relative to the world file)"},
    {"pixel_size_m", Type::Number, &FloorSpec::pixel_size_m, left_open(0, 10), "", "m per pixel",
     "floor scale"},
    // Floors larger than the digit (worlds/floor_layout.hpp); written only when one of them is set.
    {"size_px", Type::SizeOrImage, &FloorSpec::size_px, {}, "each side in [1, 512], at least the image's", "pixels",
     "`[w, h]`: the floor's size, with the digits composed on it by `layout`; `image`: the image's own size"},
    {"layout", Type::LayoutName, &FloorSpec::layout, {}, "needs `dataset`", "",
     "`centred` (the digit at the centre), `translated` (at a random place) or `cluttered` (translated, plus "
     "`clutter` pieces of other digits); drawn from the seed"},
    {"clutter", Type::Integer, &FloorSpec::clutter, closed(0, 1000), "at least 1 with `cluttered`, else 0", "",
     "pieces of other digits of the same split pasted at random places (the brighter pixel wins)"},
    {"clutter_px", Type::Integer, &FloorSpec::clutter_px, closed(1, 512), "at most the image's smaller side",
     "pixels", "the side of a clutter piece, cut at a random place of its digit"},
    {"digits", Type::Integer, &FloorSpec::digits, closed(1, kMaxFloorDigits),
     "and at most the floor's cells of the image's size", "",
     "digits on one floor, each in its own cell of the floor; the label is their sum"},
};

constexpr Row<RobotSpec> kRobotRows[] = {
    {"radius_m", Type::Number, &RobotSpec::radius_m, left_open(0, 10),
     "and 0.5 to 100 pixels (`radius_m` / `pixel_size_m`)", "m",
     "disc radius; it sets where the walls stand, and with the mass the body Box2D simulates"},
    {"mass_kg", Type::Number, &RobotSpec::mass_kg, left_open(0, 1e4), "", "kg",
     "body mass"},
    {"max_speed_mps", Type::Number, &RobotSpec::max_speed_mps, left_open(0, 1000), "", "m/s",
     "controller speed limit"},
    {"start", Type::StartOrRandom, &RobotSpec::start, {}, "non-negative integers, on the floor", "pixels",
     "start cell (x right, y down); `random` draws it from the seed"},
};

constexpr Row<ControllerSpec> kControllerRows[] = {
    {"kp_per_s", Type::Number, &ControllerSpec::kp_per_s, left_open(0, 1e6), "and `kp_per_s` × `dt_s` < 2", "1/s",
     "proportional gain: velocity = kp × position error, capped at `max_speed_mps`; kp × dt = 1 lands in one tick "
     "once within reach, 2 or more never settles"},
    // Below half a pixel, so that a settled robot is always inside its target cell.
    {"tolerance_px", Type::Number, &ControllerSpec::tolerance_px, open_both(0, 0.5), "", "pixels",
     "a move has settled when the centre is this close to the cell centre"},
};

constexpr Row<CameraSpec> kCameraRows[] = {
    {"patch_px", Type::Integer, &CameraSpec::patch_px, closed(1, kMaxPatchPx),
     "and at most the floor's smaller side", "pixels",
     "m: the camera sees an m × m window; the upper bound is the renderer's limit"},
    // The wider view; written only when it is on (every earlier world's text stays).
    {"wide_px", Type::Integer, &CameraSpec::wide_px, closed(0, kMaxPatchPx),
     "and `wide_px` × `wide_scale` at most twice the floor's larger side", "pixels",
     "the wider view: a second window of `wide_px` × `wide_px` coarse pixels taken with the patch, each the mean "
     "of `wide_scale` × `wide_scale` floor pixels; 0: none"},
    {"wide_scale", Type::Integer, &CameraSpec::wide_scale, closed(1, 16), "", "pixels",
     "floor pixels per wide-view pixel, per side"},
};

constexpr Row<TaskSpec> kTaskRows[] = {
    {"episodes", Type::Integer, &TaskSpec::episodes, closed(1, 1000), "", "", "E: goals per rollout"},
    {"steps", Type::Integer, &TaskSpec::steps, closed(1, 1000), "", "", "T: moves per episode"},
    {"step_px", Type::Integer, &TaskSpec::step_px, closed(1, 512), "", "pixels", "s: the longest move"},
};

constexpr Row<PhysicsSpec> kPhysicsRows[] = {
    {"dt_s", Type::Number, &PhysicsSpec::dt_s, left_open(0, 1), "", "s", "one Box2D tick (1/60 s by default)"},
    {"velocity_iterations", Type::Integer, &PhysicsSpec::velocity_iterations, closed(1, 100), "", "",
     "Box2D velocity solver iterations per tick"},
    {"position_iterations", Type::Integer, &PhysicsSpec::position_iterations, closed(1, 100), "", "",
     "Box2D position solver iterations per tick"},
    {"max_ticks_per_move", Type::Integer, &PhysicsSpec::max_ticks_per_move, closed(1, 100000), "", "ticks",
     "a move not settled after this many ticks ends where the robot is"},
};

// The scenario sections: their defaults are the paper's exact world, and to_yaml writes a
// section only when it differs from them, so that the text of every world without it is unchanged.
constexpr Row<MotionSpec> kMotionRows[] = {
    {"scale_sd", Type::Number, &MotionSpec::scale_sd, closed(0, 0.3), "", "",
     "each move's displacement is scaled by 1 + N(0, scale_sd²) (at least 0.05), unsensed (wheel slip, wheel radius)"},
    {"heading_sd_deg", Type::Number, &MotionSpec::heading_sd_deg, closed(0, 45), "", "degrees",
     "each move's displacement is rotated by N(0, heading_sd_deg²), unsensed"},
    {"pose", Type::PoseName, &MotionSpec::pose, {}, "", "",
     "the agent's pose l: `localised` (the cell it is in: the paper's) or `odometry` (the commanded cells)"},
    {"slip_zones", Type::SlipZoneList, &MotionSpec::slip_zones, {}, "at most 64, each on the floor, slip in [0, 0.9]",
     "pixels", "floor regions of lower friction `[x, y, w, h, slip]`: while the robot's centre is in one, its wheels "
     "lose the share `slip` of their travel, unsensed"},
};

constexpr Row<PushSpec> kPushRows[] = {
    {"probability", Type::Number, &PushSpec::probability, closed(0, 1), "", "",
     "chance that a move is pushed"},
    {"impulse_ns", Type::Number, &PushSpec::impulse_ns, left_open(0, 100), "", "N·s",
     "the push: a velocity change of impulse / mass in a uniformly drawn direction"},
    {"within_ticks", Type::Integer, &PushSpec::within_ticks, closed(1, 100000),
     "and at most `physics.max_ticks_per_move` when `probability` > 0", "ticks",
     "the push comes at a tick drawn uniformly from the move's first `within_ticks`; the move lasts until then"},
    {"traction_s", Type::Number, &PushSpec::traction_s, left_open(0, 100), "", "s",
     "time constant of the push's velocity, which the wheels' traction absorbs"},
};

constexpr Row<ObstacleSpec> kObstacleRows[] = {
    {"boxes", Type::BoxList, &ObstacleSpec::boxes, {}, "at most 64, each on the floor, w and h at least 1", "pixels",
     "box obstacles `[x, y, w, h]`: the floor pixels [x, x + w) × [y, y + h)"},
    {"discs", Type::DiscList, &ObstacleSpec::discs, {}, "at most 64, centres on the floor, r in (0, 1000]", "pixels",
     "disc obstacles `[x, y, r]`: centre (continuous: a cell's centre is x + 0.5) and radius"},
    {"shade", Type::Integer, &ObstacleSpec::shade, closed(0, 255), "", "",
     "the grey level the camera sees on an obstacle"},
    {"random_boxes", Type::Integer, &ObstacleSpec::random_boxes, closed(0, kMaxObstacles), "", "",
     "boxes drawn anew for every run, uniformly over the floor, beside `boxes` and `discs` (redrawn until the "
     "robot's start is clear)"},
    {"random_box_min_px", Type::Integer, &ObstacleSpec::random_box_min_px, closed(1, 512),
     "and at most `random_box_max_px`", "pixels", "the shortest side of a random box"},
    {"random_box_max_px", Type::Integer, &ObstacleSpec::random_box_max_px, closed(1, 512),
     "and at most the floor's smaller side", "pixels",
     "the longest side of a random box: each side is drawn uniformly from the integers in [min, max]"},
};

constexpr Row<TeamSpec> kTeamRows[] = {
    {"robots", Type::Integer, &TeamSpec::robots, closed(1, kMaxTeamRobots), "and dividing `task.episodes`", "",
     "K robots on one floor: they move in the same ticks, collide, and share what the team has seen; each drives "
     "E / K episodes"},
};

/// Fields at the top level, beside the sections.
constexpr Row<World> kTopRows[] = {
    {"seed", Type::Unsigned, &World::seed, {}, "", "", "run seed; the command line's `--seed` overrides it"},
};
// clang-format on

/// A row's member matches its type, and integers have closed, integral, non-negative ranges
/// (read_int compares magnitudes): checked at compile time, so that a mistyped new row does not
/// build.
template <class Spec, std::size_t N>
constexpr bool well_formed(const Row<Spec> (&rows)[N]) {
  for (const Row<Spec>& row : rows) {
    if (row.member.index() != static_cast<std::size_t>(row.type)) return false;
    const Bounds& b = row.range;
    if (row.type == Type::Integer || row.type == Type::IndexOrRandom) {
      if (b.lo_open || b.hi_open || b.lo > b.hi || b.lo < 0 || b.hi > kIntMax) return false;
      if (static_cast<double>(static_cast<int>(b.lo)) != b.lo || static_cast<double>(static_cast<int>(b.hi)) != b.hi)
        return false;
    }
    if (row.type == Type::Number && !(b.lo < b.hi)) return false;
  }
  return true;
}
static_assert(well_formed(kFloorRows) && well_formed(kRobotRows) && well_formed(kControllerRows) &&
              well_formed(kCameraRows) && well_formed(kTaskRows) && well_formed(kPhysicsRows) &&
              well_formed(kMotionRows) && well_formed(kPushRows) && well_formed(kObstacleRows) &&
              well_formed(kTeamRows) && well_formed(kTopRows));

/// A table as a span, the one shape the code that walks every section takes.
template <class Spec, std::size_t N>
std::span<const Row<Spec>> rows_of(const Row<Spec> (&rows)[N]) {
  return rows;
}

/// Calls f(section, rows, spec) for each section in file order, then f("", top-level rows, world).
/// `W` is World or const World.
template <class W, class F>
void for_each_section(W& world, F&& f) {
  f(std::string_view("floor"), rows_of(kFloorRows), world.floor);
  f(std::string_view("robot"), rows_of(kRobotRows), world.robot);
  f(std::string_view("controller"), rows_of(kControllerRows), world.controller);
  f(std::string_view("camera"), rows_of(kCameraRows), world.camera);
  f(std::string_view("task"), rows_of(kTaskRows), world.task);
  f(std::string_view("physics"), rows_of(kPhysicsRows), world.physics);
  f(std::string_view("motion"), rows_of(kMotionRows), world.motion);
  f(std::string_view("pushes"), rows_of(kPushRows), world.pushes);
  f(std::string_view("obstacles"), rows_of(kObstacleRows), world.obstacles);
  f(std::string_view("team"), rows_of(kTeamRows), world.team);
  f(std::string_view(), rows_of(kTopRows), world);
}

/// The keys allowed at the top level: the sections, then the top-level fields.
const std::vector<std::string_view>& top_level_keys() {
  static const std::vector<std::string_view> keys = [] {
    std::vector<std::string_view> out;
    const World world;
    for_each_section(world, [&out](std::string_view section, auto rows, const auto&) {
      if (!section.empty()) {
        out.push_back(section);
      } else {
        for (const auto& row : rows) out.push_back(row.name);
      }
    });
    return out;
  }();
  return keys;
}

template <class Spec>
std::vector<std::string_view> names_of(std::span<const Row<Spec>> rows) {
  std::vector<std::string_view> names;
  for (const Row<Spec>& row : rows) names.push_back(row.name);
  return names;
}

template <class Spec>
const Row<Spec>& row_named(std::span<const Row<Spec>> rows, std::string_view name) {
  const auto it = std::find_if(rows.begin(), rows.end(), [name](const Row<Spec>& row) { return row.name == name; });
  return *it;  // callers pass keys that fields_of has checked against the same rows
}

/// The interval in messages and docs: "[1, 64]", "(0, 10]"; empty for the special fields but the
/// index.
std::string interval_text(Type type, const Bounds& b) {
  switch (type) {
    case Type::Integer:
    case Type::IndexOrRandom:
      return "[" + std::to_string(static_cast<int>(b.lo)) + ", " + std::to_string(static_cast<int>(b.hi)) + "]";
    case Type::Number:
      return (b.lo_open ? "(" : "[") + format_double(b.lo) + ", " + format_double(b.hi) + (b.hi_open ? ")" : "]");
    case Type::Unsigned:
      return "[0, " + std::to_string(std::numeric_limits<std::uint64_t>::max()) + "]";
    case Type::Dataset:
    case Type::SplitName:
    case Type::PngPath:
    case Type::StartOrRandom:
    case Type::PoseName:
    case Type::BoxList:
    case Type::DiscList:
    case Type::SlipZoneList:
    case Type::SizeOrImage:
    case Type::LayoutName:
      break;
  }
  return {};
}

/// What a row's type is called in the docs.
std::string_view type_text(Type type) {
  switch (type) {
    case Type::Integer:
      return "integer";
    case Type::Number:
      return "number";
    case Type::Unsigned:
      return "unsigned integer";
    case Type::Dataset:
    case Type::PngPath:
      return "string";
    case Type::SplitName:
      return "`train`, `validation` or `test`";
    case Type::IndexOrRandom:
      return "integer or `random`";
    case Type::StartOrRandom:
      return "`[x, y]` or `random`";
    case Type::PoseName:
      return "`localised` or `odometry`";
    case Type::BoxList:
      return "list of `[x, y, w, h]` integers";
    case Type::DiscList:
      return "list of `[x, y, r]` numbers";
    case Type::SlipZoneList:
      return "list of `[x, y, w, h, slip]` numbers";
    case Type::SizeOrImage:
      return "`[w, h]` or `image`";
    case Type::LayoutName:
      return "`centred`, `translated` or `cluttered`";
  }
  return {};
}

/// Data sets known by name (dataset_folder resolves them); any other `dataset` is a folder.
bool named_dataset(std::string_view dataset) {
  const auto names = named_datasets();
  return std::find(names.begin(), names.end(), dataset) != names.end();
}

/// A field's value as plain text, as to_yaml writes it (without its quotes): the docs' defaults.
template <class Spec>
std::string value_text(const Row<Spec>& row, const Spec& spec) {
  switch (row.type) {
    case Type::Integer:
      return std::to_string(spec.*std::get<int Spec::*>(row.member));
    case Type::Number:
      return format_double(spec.*std::get<double Spec::*>(row.member));
    case Type::Unsigned:
      return std::to_string(spec.*std::get<std::uint64_t Spec::*>(row.member));
    case Type::Dataset: {
      const std::string& dataset = spec.*std::get<std::string Spec::*>(row.member);
      return dataset.empty() ? std::string("mnist") : dataset;  // neither dataset nor image: the paper's floor
    }
    case Type::SplitName:
      return to_string(spec.*std::get<Split Spec::*>(row.member));
    case Type::IndexOrRandom: {
      const std::optional<int>& index = spec.*std::get<std::optional<int> Spec::*>(row.member);
      return index ? std::to_string(*index) : std::string("random");
    }
    case Type::PngPath:
      return (spec.*std::get<fs::path Spec::*>(row.member)).string();
    case Type::StartOrRandom: {
      const auto& start = spec.*std::get<std::optional<std::pair<int, int>> Spec::*>(row.member);
      return start ? "[" + std::to_string(start->first) + ", " + std::to_string(start->second) + "]"
                   : std::string("random");
    }
    case Type::PoseName:
      return to_string(spec.*std::get<PoseSource Spec::*>(row.member));
    case Type::BoxList:
    case Type::DiscList:
    case Type::SlipZoneList:
      return "[]";  // the docs' default: none
    case Type::SizeOrImage: {
      const auto& size = spec.*std::get<std::optional<FloorSize> Spec::*>(row.member);
      return size ? "[" + std::to_string(size->width_px) + ", " + std::to_string(size->height_px) + "]"
                  : std::string("image");
    }
    case Type::LayoutName:
      return to_string(spec.*std::get<FloorLayout Spec::*>(row.member));
  }
  return {};
}

/// Everything that reads one world text: its origin (for messages and relative paths) and the
/// World being filled in.
class Loader {
 public:
  Loader(const fs::path& origin, World& world) : origin_(origin), world_(world) {}

  /// Throws "origin:line: message" as one line.
  [[noreturn]] void fail(int line, std::string_view message) const {
    throw InputError(one_line(origin_.string() + ":" + std::to_string(line) + ": " + std::string(message)));
  }

  [[noreturn]] void fail_field(int line, std::string_view field, std::string_view expected,
                               std::string_view got) const {
    fail(line, std::string(field) + ": expected " + std::string(expected) + ", got " + std::string(got));
  }

  void check_text(std::string_view text) const;
  void check_size_and_bytes(std::string_view text) const;
  void read(const YAML::Node& root);

 private:
  // One key of a section, with everything a field reader needs for its messages.
  struct Field {
    std::string key;     // as written
    std::string dotted;  // "camera.patch_px"
    int line = 1;        // the key's line
    YAML::Node value;
  };

  std::vector<Field> fields_of(const YAML::Node& section, const std::string& section_name,
                               const std::vector<std::string_view>& allowed);

  /// `alternative` names what else the field takes (" or random").
  int read_int(const Field& f, int lo, int hi, std::string_view alternative = "") const;
  std::uint64_t read_u64(const Field& f) const;
  double read_number(const Field& f, const Bounds& range) const;
  std::string read_string(const Field& f, std::string_view expected) const;
  Split read_split(const Field& f) const;
  std::optional<int> read_index(const Field& f, const Bounds& range) const;
  fs::path read_png(const Field& f) const;
  std::optional<std::pair<int, int>> read_start(const Field& f) const;
  PoseSource read_pose(const Field& f) const;
  std::vector<BoxObstacle> read_boxes(const Field& f) const;
  std::vector<DiscObstacle> read_discs(const Field& f) const;
  std::vector<SlipZone> read_slip_zones(const Field& f) const;
  std::optional<FloorSize> read_floor_size(const Field& f) const;
  FloorLayout read_layout(const Field& f) const;

  /// Reads one field into its member, as its row says.
  template <class Spec>
  void read_field(const Row<Spec>& row, const Field& f, Spec& spec) const;

  /// Reads a section's fields into `spec`; returns them (keys, lines, values) for checks across
  /// fields.
  template <class Spec>
  std::vector<Field> read_section(const YAML::Node& section, const std::string& section_name,
                                  std::span<const Row<Spec>> rows, Spec& spec);

  /// The floor's rules across fields: a data set or an image, and paths resolved.
  void finish_floor(const std::vector<Field>& fields);

  /// The rules across sections (the robot's size in pixels, pushes within a move, a controller
  /// that settles), once every section is read.
  void check_across_fields() const;

  /// The line of the first of `fields` the file gave, else 1: where a message about them points.
  int first_line(std::initializer_list<const char*> fields) const;

  fs::path resolve(const fs::path& relative, const Field& f) const;

  const fs::path& origin_;
  World& world_;
};

// ---------------------------------------------------------------------------------------------
// Pre-scan: size and nesting, before yaml-cpp sees the text.

// The file's size, and no NUL byte (yaml-cpp reports one as a confusing escape error on the
// wrong line: it is named here).
void Loader::check_size_and_bytes(std::string_view text) const {
  if (text.size() > kMaxFileBytes) {
    throw InputError(one_line(origin_.string() + ": expected a world file of at most 1 MiB (" +
                              std::to_string(kMaxFileBytes) + " bytes), got " + std::to_string(text.size()) +
                              " bytes"));
  }
  if (const auto nul = text.find('\0'); nul != std::string_view::npos) {
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(nul), '\n');
    throw InputError(one_line(origin_.string() + ":" + std::to_string(line) + ": expected text, got a NUL byte"));
  }
}

void Loader::check_text(std::string_view text) const {
  check_size_and_bytes(text);
  // Over-estimates depth where unsure (brackets in plain scalars, lines of a block scalar count
  // as nesting), which only refuses odd files; the quote rules are strict enough that text can
  // hide real brackets from the scan only where yaml-cpp's own depth guard still applies.
  std::vector<std::size_t> indents;  // indentation of the open block levels
  int block_depth = 0;
  int flow_depth = 0;
  bool in_double = false;
  bool in_single = false;
  int line = 1;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view row = text.substr(start, end - start);

    std::size_t pos = 0;
    if (!in_double && !in_single && flow_depth == 0) {
      std::size_t indent = 0;
      while (indent < row.size() && row[indent] == ' ') ++indent;
      const bool blank = indent == row.size() || row[indent] == '#' || row[indent] == '\r';
      if (!blank) {
        while (!indents.empty() && indents.back() > indent) indents.pop_back();
        if (indents.empty() || indents.back() < indent) indents.push_back(indent);
        // "- - - x" and "? ? x" open one level per indicator on a single line.
        int compact = 0;
        pos = indent;
        while (pos + 1 < row.size() && (row[pos] == '-' || row[pos] == '?') &&
               (row[pos + 1] == ' ' || row[pos + 1] == '\t')) {
          ++compact;
          pos += 2;
          while (pos < row.size() && (row[pos] == ' ' || row[pos] == '\t')) ++pos;
        }
        block_depth = static_cast<int>(indents.size()) + compact;
        if (block_depth > kMaxNesting) {
          fail(line, "expected nesting at most " + std::to_string(kMaxNesting) + " levels deep, got deeper");
        }
      }
    }

    char prev = ' ';         // the previous character on this row; a row starts like after a space
    char prev_solid = '\0';  // the previous non-blank character on this row
    for (; pos < row.size(); ++pos) {
      const char c = row[pos];
      if (in_double) {
        if (c == '\\') {
          ++pos;  // the escaped character cannot close the string
        } else if (c == '"') {
          in_double = false;
        }
      } else if (in_single) {
        if (c == '\'') {
          if (pos + 1 < row.size() && row[pos + 1] == '\'') {
            ++pos;  // '' is an escaped quote
          } else {
            in_single = false;
          }
        }
      } else if (c == '#' && (prev == ' ' || prev == '\t')) {
        break;  // a comment runs to the end of the row
      } else if ((c == '"' || c == '\'') &&
                 (prev_solid == '\0' || std::string_view("[{,:-?").find(prev_solid) != std::string_view::npos)) {
        // Only where a scalar can begin; "don't" inside a plain scalar opens nothing.
        (c == '"' ? in_double : in_single) = true;
      } else if (c == '[' || c == '{') {
        ++flow_depth;
        if (block_depth + flow_depth > kMaxNesting) {
          fail(line, "expected nesting at most " + std::to_string(kMaxNesting) + " levels deep, got deeper");
        }
      } else if (c == ']' || c == '}') {
        flow_depth = std::max(0, flow_depth - 1);
      }
      prev = c;
      if (c != ' ' && c != '\t') prev_solid = c;
    }
    ++line;
    start = end + 1;
  }
}

// ---------------------------------------------------------------------------------------------
// Scalars

/// A decimal integer as written: optional sign, digits only (no 0x, no 1e3, no 6.0).
struct IntegerText {
  bool negative = false;
  bool too_large = false;  // magnitude beyond 2^64 - 1
  std::uint64_t magnitude = 0;
};

std::optional<IntegerText> integer_text(const YAML::Node& node) {
  // Only plain, untagged scalars are numbers: "6" in quotes is a string the user meant as such.
  if (!node.IsScalar() || node.Tag() != "?") return std::nullopt;
  const std::string& s = node.Scalar();
  IntegerText out;
  std::size_t i = 0;
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) {
    out.negative = s[i] == '-';
    ++i;
  }
  if (i == s.size()) return std::nullopt;
  for (; i < s.size(); ++i) {
    if (s[i] < '0' || s[i] > '9') return std::nullopt;
    const auto digit = static_cast<std::uint64_t>(s[i] - '0');
    if (out.magnitude > (std::numeric_limits<std::uint64_t>::max() - digit) / 10) {
      out.too_large = true;
    } else if (!out.too_large) {
      out.magnitude = out.magnitude * 10 + digit;
    }
  }
  return out;
}

/// A decimal number: sign, digits with an optional point, optional exponent. Excludes .inf,
/// .nan and hex, which are never a sensible physical quantity here.
std::optional<double> number_text(const YAML::Node& node, bool& out_of_range) {
  out_of_range = false;
  if (!node.IsScalar() || node.Tag() != "?") return std::nullopt;
  const std::string& s = node.Scalar();
  const auto is_digit = [&s](std::size_t i) { return i < s.size() && s[i] >= '0' && s[i] <= '9'; };
  std::size_t i = 0;
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
  std::size_t digits = 0;
  for (; is_digit(i); ++i) ++digits;
  if (i < s.size() && s[i] == '.') {
    for (++i; is_digit(i); ++i) ++digits;
  }
  if (digits == 0) return std::nullopt;
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
    if (!is_digit(i)) return std::nullopt;
    while (is_digit(i)) ++i;
  }
  if (i != s.size()) return std::nullopt;
  double value = 0.0;
  // from_chars takes no leading '+'; the grammar above has already been checked.
  const char* first = s.data() + (s[0] == '+' ? 1 : 0);
  const auto result = std::from_chars(first, s.data() + s.size(), value);
  if (result.ec == std::errc::result_out_of_range) {
    out_of_range = true;
    return std::nullopt;
  }
  if (result.ec != std::errc() || result.ptr != s.data() + s.size()) return std::nullopt;
  return value;
}

std::string int_range(long long lo, long long hi) {
  return "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
}

int Loader::read_int(const Field& f, int lo, int hi, std::string_view alternative) const {
  const auto t = integer_text(f.value);
  const bool ok = t && !t->too_large && (!t->negative || t->magnitude == 0) &&
                  t->magnitude >= static_cast<std::uint64_t>(lo) && t->magnitude <= static_cast<std::uint64_t>(hi);
  if (!ok) fail_field(f.line, f.dotted, int_range(lo, hi) + std::string(alternative), describe(f.value));
  return static_cast<int>(t->magnitude);
}

std::uint64_t Loader::read_u64(const Field& f) const {
  const auto t = integer_text(f.value);
  if (!t || t->too_large || (t->negative && t->magnitude != 0)) {
    fail_field(f.line, f.dotted, "an unsigned integer in " + interval_text(Type::Unsigned, {}), describe(f.value));
  }
  return t->magnitude;
}

double Loader::read_number(const Field& f, const Bounds& range) const {
  bool out_of_range = false;
  const auto v = number_text(f.value, out_of_range);
  // Written as !(in range) so that a NaN could never slip through.
  const bool ok =
      v && (range.lo_open ? *v > range.lo : *v >= range.lo) && (range.hi_open ? *v < range.hi : *v <= range.hi);
  if (!ok) fail_field(f.line, f.dotted, "a number in " + interval_text(Type::Number, range), describe(f.value));
  return *v;
}

std::string Loader::read_string(const Field& f, std::string_view expected) const {
  if (!f.value.IsScalar() || f.value.Scalar().empty()) fail_field(f.line, f.dotted, expected, describe(f.value));
  // A name or a path: longer than any path the system opens, it is refused here, quoted clipped,
  // rather than repeated whole in a later message ("FOLDER: no such folder").
  const std::string& s = f.value.Scalar();
  if (s.size() > kMaxPathBytes)
    fail_field(f.line, f.dotted, fmt::format("{} (at most {} bytes)", expected, kMaxPathBytes),
               fmt::format("{} bytes (\"{}\")", s.size(), clip(s)));
  if (const std::optional<std::size_t> at = first_unwritable_byte(s))
    fail_field(f.line, f.dotted, fmt::format("{} in UTF-8 text", expected),
               fmt::format("a byte that is not a UTF-8 character at byte {} of the value", *at + 1));
  return s;
}

// ---------------------------------------------------------------------------------------------
// Sections

std::string join(const auto& names) {
  std::string out;
  for (std::string_view n : names) {
    if (!out.empty()) out += ", ";
    out += n;
  }
  return out;
}

Split Loader::read_split(const Field& f) const {
  const std::string s = f.value.IsScalar() ? f.value.Scalar() : std::string();
  for (const Split split : {Split::Train, Split::Validation, Split::Test}) {
    if (s == to_string(split)) return split;
  }
  fail_field(f.line, f.dotted, "train, validation or test", describe(f.value));
}

std::optional<int> Loader::read_index(const Field& f, const Bounds& range) const {
  if (f.value.IsScalar() && f.value.Scalar() == "random") return std::nullopt;
  return read_int(f, static_cast<int>(range.lo), static_cast<int>(range.hi), " or random");
}

fs::path Loader::read_png(const Field& f) const {
  const std::string s = read_string(f, "a .png file");
  std::string ext = s.size() >= 4 ? s.substr(s.size() - 4) : std::string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; });
  if (ext != ".png" || s.size() == 4) fail_field(f.line, f.dotted, "a .png file", describe(f.value));
  return s;
}

std::optional<std::pair<int, int>> Loader::read_start(const Field& f) const {
  const std::string expected = "[x, y] (two non-negative integers, pixels) or random";
  if (f.value.IsScalar() && f.value.Scalar() == "random") return std::nullopt;
  if (!f.value.IsSequence() || f.value.size() != 2) fail_field(f.line, f.dotted, expected, describe(f.value));
  std::array<int, 2> xy{};
  for (std::size_t i = 0; i < 2; ++i) {
    const YAML::Node element = f.value[i];
    const auto t = integer_text(element);
    const auto hi = static_cast<std::uint64_t>(std::numeric_limits<int>::max());
    if (!t || t->too_large || (t->negative && t->magnitude != 0) || t->magnitude > hi) {
      fail_field(f.line, f.dotted, expected, std::string(i == 0 ? "x = " : "y = ") + describe(element));
    }
    xy[i] = static_cast<int>(t->magnitude);
  }
  return std::make_pair(xy[0], xy[1]);
}

std::optional<FloorSize> Loader::read_floor_size(const Field& f) const {
  const std::string expected = "[w, h] (two integers in [1, 512], pixels) or image";
  if (f.value.IsScalar() && f.value.Scalar() == "image") return std::nullopt;
  if (!f.value.IsSequence() || f.value.size() != 2) fail_field(f.line, f.dotted, expected, describe(f.value));
  std::array<int, 2> wh{};
  for (std::size_t i = 0; i < 2; ++i) {
    const YAML::Node element = f.value[i];
    const auto t = integer_text(element);
    if (!t || t->too_large || t->negative || t->magnitude < 1 || t->magnitude > 512)
      fail_field(f.line, f.dotted, expected, std::string(i == 0 ? "w = " : "h = ") + describe(element));
    wh[i] = static_cast<int>(t->magnitude);
  }
  return FloorSize{wh[0], wh[1]};
}

FloorLayout Loader::read_layout(const Field& f) const {
  const std::string s = f.value.IsScalar() ? f.value.Scalar() : std::string();
  for (const FloorLayout layout : {FloorLayout::Centred, FloorLayout::Translated, FloorLayout::Cluttered}) {
    if (s == to_string(layout)) return layout;
  }
  fail_field(f.line, f.dotted, "centred, translated or cluttered", describe(f.value));
}

PoseSource Loader::read_pose(const Field& f) const {
  const std::string s = f.value.IsScalar() ? f.value.Scalar() : std::string();
  for (const PoseSource source : {PoseSource::Localised, PoseSource::Odometry}) {
    if (s == to_string(source)) return source;
  }
  fail_field(f.line, f.dotted, "localised or odometry", describe(f.value));
}

std::vector<BoxObstacle> Loader::read_boxes(const Field& f) const {
  const std::string expected = "a list of at most 64 boxes [x, y, w, h] (integers, pixels: x, y >= 0, w, h >= 1)";
  if (!f.value.IsSequence() || f.value.size() > static_cast<std::size_t>(kMaxObstacles))
    fail_field(f.line, f.dotted, expected, describe(f.value));
  std::vector<BoxObstacle> boxes;
  for (std::size_t i = 0; i < f.value.size(); ++i) {
    const YAML::Node box = f.value[i];
    if (!box.IsSequence() || box.size() != 4)
      fail_field(f.line, f.dotted, expected, "box " + std::to_string(i + 1) + " = " + describe(box));
    std::array<int, 4> v{};
    for (std::size_t k = 0; k < 4; ++k) {
      const auto t = integer_text(box[k]);
      const std::uint64_t lo = k < 2 ? 0 : 1;
      if (!t || t->too_large || (t->negative && t->magnitude != 0) || t->magnitude < lo || t->magnitude > 100000)
        fail_field(f.line, f.dotted, expected,
                   "box " + std::to_string(i + 1) + " " + "xywh"[k] + " = " + describe(box[k]));
      v[k] = static_cast<int>(t->magnitude);
    }
    boxes.push_back({v[0], v[1], v[2], v[3]});
  }
  return boxes;
}

std::vector<DiscObstacle> Loader::read_discs(const Field& f) const {
  const std::string expected = "a list of at most 64 discs [x, y, r] (numbers, pixels: x, y >= 0, r in (0, 1000])";
  if (!f.value.IsSequence() || f.value.size() > static_cast<std::size_t>(kMaxObstacles))
    fail_field(f.line, f.dotted, expected, describe(f.value));
  std::vector<DiscObstacle> discs;
  for (std::size_t i = 0; i < f.value.size(); ++i) {
    const YAML::Node disc = f.value[i];
    if (!disc.IsSequence() || disc.size() != 3)
      fail_field(f.line, f.dotted, expected, "disc " + std::to_string(i + 1) + " = " + describe(disc));
    std::array<double, 3> v{};
    for (std::size_t k = 0; k < 3; ++k) {
      bool out_of_range = false;
      const auto n = number_text(disc[k], out_of_range);
      const bool ok = n && (k < 2 ? *n >= 0.0 && *n <= 100000.0 : *n > 0.0 && *n <= 1000.0);
      if (!ok)
        fail_field(f.line, f.dotted, expected,
                   "disc " + std::to_string(i + 1) + " " + "xyr"[k] + " = " + describe(disc[k]));
      v[k] = *n;
    }
    discs.push_back({v[0], v[1], v[2]});
  }
  return discs;
}

std::vector<SlipZone> Loader::read_slip_zones(const Field& f) const {
  const std::string expected =
      "a list of at most 64 zones [x, y, w, h, slip] (pixels: integers x, y >= 0, w, h >= 1; slip in [0, 0.9])";
  if (!f.value.IsSequence() || f.value.size() > static_cast<std::size_t>(kMaxObstacles))
    fail_field(f.line, f.dotted, expected, describe(f.value));
  std::vector<SlipZone> zones;
  for (std::size_t i = 0; i < f.value.size(); ++i) {
    const YAML::Node zone = f.value[i];
    if (!zone.IsSequence() || zone.size() != 5)
      fail_field(f.line, f.dotted, expected, "zone " + std::to_string(i + 1) + " = " + describe(zone));
    std::array<int, 4> v{};
    for (std::size_t k = 0; k < 4; ++k) {
      const auto t = integer_text(zone[k]);
      const std::uint64_t lo = k < 2 ? 0 : 1;
      if (!t || t->too_large || (t->negative && t->magnitude != 0) || t->magnitude < lo || t->magnitude > 100000)
        fail_field(f.line, f.dotted, expected,
                   "zone " + std::to_string(i + 1) + " " + "xywh"[k] + " = " + describe(zone[k]));
      v[k] = static_cast<int>(t->magnitude);
    }
    bool out_of_range = false;
    const auto slip = number_text(zone[4], out_of_range);
    if (!slip || !(*slip >= 0.0 && *slip <= 0.9))
      fail_field(f.line, f.dotted, expected, "zone " + std::to_string(i + 1) + " slip = " + describe(zone[4]));
    zones.push_back({v[0], v[1], v[2], v[3], *slip});
  }
  return zones;
}

template <class Spec>
void Loader::read_field(const Row<Spec>& row, const Field& f, Spec& spec) const {
  const Bounds& range = row.range;
  switch (row.type) {
    case Type::Integer:
      spec.*std::get<int Spec::*>(row.member) = read_int(f, static_cast<int>(range.lo), static_cast<int>(range.hi));
      return;
    case Type::Number:
      spec.*std::get<double Spec::*>(row.member) = read_number(f, range);
      return;
    case Type::Unsigned:
      spec.*std::get<std::uint64_t Spec::*>(row.member) = read_u64(f);
      return;
    case Type::Dataset:
      spec.*std::get<std::string Spec::*>(row.member) =
          read_string(f, "mnist, mnist-10k, fashion-mnist or a folder of IDX files");
      return;
    case Type::SplitName:
      spec.*std::get<Split Spec::*>(row.member) = read_split(f);
      return;
    case Type::IndexOrRandom:
      spec.*std::get<std::optional<int> Spec::*>(row.member) = read_index(f, range);
      return;
    case Type::PngPath:
      spec.*std::get<fs::path Spec::*>(row.member) = read_png(f);
      return;
    case Type::StartOrRandom:
      spec.*std::get<std::optional<std::pair<int, int>> Spec::*>(row.member) = read_start(f);
      return;
    case Type::PoseName:
      spec.*std::get<PoseSource Spec::*>(row.member) = read_pose(f);
      return;
    case Type::BoxList:
      spec.*std::get<std::vector<BoxObstacle> Spec::*>(row.member) = read_boxes(f);
      return;
    case Type::DiscList:
      spec.*std::get<std::vector<DiscObstacle> Spec::*>(row.member) = read_discs(f);
      return;
    case Type::SlipZoneList:
      spec.*std::get<std::vector<SlipZone> Spec::*>(row.member) = read_slip_zones(f);
      return;
    case Type::SizeOrImage:
      spec.*std::get<std::optional<FloorSize> Spec::*>(row.member) = read_floor_size(f);
      return;
    case Type::LayoutName:
      spec.*std::get<FloorLayout Spec::*>(row.member) = read_layout(f);
      return;
  }
}

// ---------------------------------------------------------------------------------------------
// Sections

std::vector<Loader::Field> Loader::fields_of(const YAML::Node& section, const std::string& section_name,
                                             const std::vector<std::string_view>& allowed) {
  std::vector<Field> fields;
  if (section.IsNull()) return fields;  // "camera:" with every line commented out: all defaults
  if (!section.IsMap()) {
    fail_field(world_.lines.at(section_name), section_name, "a map of " + join(allowed), describe(section));
  }
  std::set<std::string> seen;
  // By value: yaml-cpp's iterators hand out temporaries, so a reference into it->first dangles.
  for (const auto& entry : section) {
    const YAML::Node key = entry.first;
    const int line = line_of(key);
    if (!key.IsScalar()) {
      fail_field(line, section_name, "keys among " + join(allowed), describe(key) + " as a key");
    }
    Field f;
    f.key = key.Scalar();
    f.dotted = section_name + "." + clip(f.key);
    f.line = line;
    f.value = entry.second;
    if (std::find(allowed.begin(), allowed.end(), f.key) == allowed.end()) {
      fail_field(line, f.dotted, "a key among " + join(allowed), "unknown key \"" + clip(f.key) + "\"");
    }
    if (!seen.insert(f.key).second) {
      fail_field(line, f.dotted, "each key once",
                 "a second one (the first is on line " + std::to_string(world_.lines.at(f.dotted)) + ")");
    }
    world_.lines[f.dotted] = line;
    fields.push_back(std::move(f));
  }
  return fields;
}

fs::path Loader::resolve(const fs::path& relative, const Field& f) const {
  try {
    return fs::absolute(origin_.parent_path() / relative).lexically_normal();
  } catch (const fs::filesystem_error& e) {
    fail_field(f.line, f.dotted, "a path that can be made absolute", std::string(e.what()));
  }
}

template <class Spec>
std::vector<Loader::Field> Loader::read_section(const YAML::Node& section, const std::string& section_name,
                                                std::span<const Row<Spec>> rows, Spec& spec) {
  std::vector<Field> fields = fields_of(section, section_name, names_of(rows));
  for (const Field& f : fields) read_field(row_named(rows, f.key), f, spec);
  return fields;
}

void Loader::finish_floor(const std::vector<Field>& fields) {
  const auto given = [&fields](std::string_view key) -> const Field* {
    const auto it = std::find_if(fields.begin(), fields.end(), [key](const Field& f) { return f.key == key; });
    return it != fields.end() ? &*it : nullptr;
  };
  const Field* dataset = given("dataset");
  const Field* image = given("image");
  const Field* split = given("split");
  const Field* index = given("index");
  FloorSpec& floor = world_.floor;
  if (image != nullptr) {
    if (dataset != nullptr) {
      const Field& later = dataset->line > image->line ? *dataset : *image;
      fail_field(later.line, later.dotted, "either floor.dataset or floor.image", "both");
    }
    // A PNG is a single floor: a split or an index would silently mean nothing.
    if (split != nullptr) fail_field(split->line, split->dotted, "no split with floor.image", describe(split->value));
    if (index != nullptr) fail_field(index->line, index->dotted, "no index with floor.image", describe(index->value));
    floor.dataset.clear();
    floor.image = resolve(floor.image, *image);
    return;
  }
  // Neither given: the paper's floor.
  if (dataset == nullptr) floor.dataset = "mnist";
  if (!named_dataset(floor.dataset)) floor.dataset = resolve(floor.dataset, *dataset).string();
}

void Loader::read(const YAML::Node& root) {
  if (!root.IsMap()) fail(1, "expected a map of sections (floor, robot, ...)");
  const std::vector<std::string_view>& keys = top_level_keys();
  std::set<std::string> seen;
  bool floor_seen = false;
  for (const auto& entry : root) {
    const YAML::Node key = entry.first;
    const int line = line_of(key);
    if (!key.IsScalar()) fail(line, "expected section names (" + join(keys) + "), got " + describe(key) + " as a key");
    const std::string name = key.Scalar();
    if (std::find(keys.begin(), keys.end(), name) == keys.end()) {
      fail_field(line, clip(name), "a section among " + join(keys), "unknown key \"" + clip(name) + "\"");
    }
    if (!seen.insert(name).second) {
      fail_field(line, name, "each section once",
                 "a second one (the first is on line " + std::to_string(world_.lines.at(name)) + ")");
    }
    world_.lines[name] = line;
    const YAML::Node value = entry.second;
    std::vector<Field> fields;
    for_each_section(world_, [&](std::string_view section, auto rows, auto& spec) {
      if (section == name) {
        fields = read_section(value, name, rows, spec);
      } else if (section.empty()) {
        for (const auto& row : rows) {
          if (row.name == name) read_field(row, Field{name, name, line, value}, spec);
        }
      }
    });
    if (name == "floor") {
      finish_floor(fields);
      floor_seen = true;
    }
  }
  if (!floor_seen) world_.floor.dataset = "mnist";  // no floor section: the paper's floor
  check_across_fields();
}

int Loader::first_line(std::initializer_list<const char*> fields) const {
  for (const char* field : fields)
    if (const auto it = world_.lines.find(field); it != world_.lines.end()) return it->second;
  return 1;
}

void Loader::check_across_fields() const {
  check_layout(world_);  // the floor's layout: its rules in worlds/floor_layout.cpp
  // The robot's size in pixels: Box2D runs in tenths of a pixel and is tuned for bodies of 0.1 to
  // 10 of its units, so a radius of 0.5 to 100 pixels.
  const double radius_px = world_.robot.radius_m / world_.floor.pixel_size_m;
  if (radius_px < 0.5 || radius_px > 100.0) {
    fail_field(first_line({"robot.radius_m", "floor.pixel_size_m"}), "robot.radius_m",
               "a radius of 0.5 to 100 pixels (" + format_double(0.5 * world_.floor.pixel_size_m) + " to " +
                   format_double(100.0 * world_.floor.pixel_size_m) + " m at pixel_size_m " +
                   format_double(world_.floor.pixel_size_m) + ")",
               format_double(world_.robot.radius_m) + " m = " + fmt::format("{:.3g}", radius_px) + " px" +
                   (world_.lines.count("robot.radius_m") ? "" : " (the default)"));
  }

  // A push drawn after the move's last tick would never land: the stated rate would be a lie.
  if (world_.pushes.probability > 0.0 && world_.pushes.within_ticks > world_.physics.max_ticks_per_move) {
    fail_field(first_line({"pushes.within_ticks", "physics.max_ticks_per_move", "pushes"}), "pushes.within_ticks",
               "at most physics.max_ticks_per_move = " + std::to_string(world_.physics.max_ticks_per_move) +
                   " (a push must come while the move lasts)",
               std::to_string(world_.pushes.within_ticks) +
                   (world_.lines.count("pushes.within_ticks") ? "" : " (the default)"));
  }

  if (world_.obstacles.random_box_min_px > world_.obstacles.random_box_max_px) {
    fail_field(first_line({"obstacles.random_box_min_px", "obstacles.random_box_max_px", "obstacles"}),
               "obstacles.random_box_min_px",
               "at most obstacles.random_box_max_px = " + std::to_string(world_.obstacles.random_box_max_px),
               std::to_string(world_.obstacles.random_box_min_px) +
                   (world_.lines.count("obstacles.random_box_min_px") ? "" : " (the default)"));
  }

  // Each member of a team drives E / K of the rollout's E episodes: the budget of moves is the
  // one robot's.
  if (world_.task.episodes % world_.team.robots != 0) {
    fail_field(first_line({"team.robots", "task.episodes", "team"}), "team.robots",
               "a divisor of task.episodes = " + std::to_string(world_.task.episodes) +
                   " (each robot drives episodes / robots of the rollout's episodes)",
               std::to_string(world_.team.robots));
  }
  // Members start on distinct cells at least a diameter apart: one fixed start cannot hold them.
  if (!world_.team.single() && world_.robot.start) {
    fail_field(
        first_line({"robot.start", "team.robots"}), "robot.start",
        "random when team.robots > 1 (each robot of the team draws its own start)",
        "[" + std::to_string(world_.robot.start->first) + ", " + std::to_string(world_.robot.start->second) + "]");
  }

  // The controller sets velocity = kp * error each tick, so the error shrinks by |1 - kp dt| per
  // tick once under the speed limit: at kp dt >= 2 it never shrinks and a move never settles.
  const double gain_per_tick = world_.controller.kp_per_s * world_.physics.dt_s;
  if (gain_per_tick >= 2.0) {
    fail_field(first_line({"controller.kp_per_s", "physics.dt_s"}), "controller.kp_per_s",
               "less than 2 / physics.dt_s = " + format_double(2.0 / world_.physics.dt_s) +
                   " (kp_per_s * dt_s = 1 lands in one tick; 2 or more never settles)",
               format_double(world_.controller.kp_per_s) +
                   (world_.lines.count("controller.kp_per_s") ? "" : " (the default)"));
  }
}

/// Parser events are ignored except where each document starts (to name a second document).
class DocumentStarts final : public YAML::EventHandler {
 public:
  YAML::Mark last = YAML::Mark::null_mark();

  void OnDocumentStart(const YAML::Mark& mark) override { last = mark; }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t, const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

/// The line a field was given on, else its section's, else the first: defaults have no line.
int field_line(const World& world, const std::string& field, const std::string& section) {
  if (const auto it = world.lines.find(field); it != world.lines.end()) return it->second;
  if (const auto it = world.lines.find(section); it != world.lines.end()) return it->second;
  return 1;
}

/// A floor is written with either its image or its data-set fields, whichever it uses, with its
/// layout's fields only when it is composed (so that every earlier world's text is unchanged), and
/// with the clutter's when it is cluttered (or a piece size was set all the same).
template <class Spec>
bool written(const Row<Spec>& row, const Spec& spec) {
  if constexpr (std::is_same_v<Spec, FloorSpec>) {
    const bool png = !spec.image.empty();
    if (row.type == Type::PngPath) return png;
    if (row.type == Type::Dataset || row.type == Type::SplitName || row.type == Type::IndexOrRandom) return !png;
    if (row.name == "clutter") return spec.layout == FloorLayout::Cluttered;
    if (row.name == "clutter_px")
      return spec.layout == FloorLayout::Cluttered || spec.clutter_px != FloorSpec{}.clutter_px;
    if (row.type == Type::SizeOrImage || row.type == Type::LayoutName || row.name == "digits") return spec.composed();
  }
  if constexpr (std::is_same_v<Spec, CameraSpec>) {
    if (row.name == "wide_px" || row.name == "wide_scale")
      return spec.wide() || spec.wide_scale != CameraSpec{}.wide_scale;
  }
  return true;
}

/// One value in to_yaml's text, which parse_world reads back to the same value.
template <class Spec>
void emit_value(YAML::Emitter& out, const Row<Spec>& row, const Spec& spec) {
  switch (row.type) {
    case Type::Integer:
      out << spec.*std::get<int Spec::*>(row.member);
      return;
    case Type::Number:
      // The shortest round-trip text, so that parse_world(to_yaml(w)) == w exactly.
      out << format_double(spec.*std::get<double Spec::*>(row.member));
      return;
    case Type::Unsigned:
      out << spec.*std::get<std::uint64_t Spec::*>(row.member);
      return;
    case Type::Dataset: {
      const std::string dataset = value_text(row, spec);
      if (named_dataset(dataset)) {
        out << dataset;
      } else {
        // Quoted so that no folder name ("~", "null", "123") is read back as anything but a string.
        out << YAML::DoubleQuoted << dataset;
      }
      return;
    }
    case Type::SplitName:
      out << to_string(spec.*std::get<Split Spec::*>(row.member));
      return;
    case Type::IndexOrRandom:
      if (const std::optional<int>& index = spec.*std::get<std::optional<int> Spec::*>(row.member)) {
        out << *index;
      } else {
        out << "random";
      }
      return;
    case Type::PngPath:
      out << YAML::DoubleQuoted << (spec.*std::get<fs::path Spec::*>(row.member)).string();
      return;
    case Type::StartOrRandom:
      if (const auto& start = spec.*std::get<std::optional<std::pair<int, int>> Spec::*>(row.member)) {
        out << YAML::Flow << YAML::BeginSeq << start->first << start->second << YAML::EndSeq;
      } else {
        out << "random";
      }
      return;
    case Type::PoseName:
      out << to_string(spec.*std::get<PoseSource Spec::*>(row.member));
      return;
    case Type::BoxList:
      out << YAML::Flow << YAML::BeginSeq;
      for (const BoxObstacle& b : spec.*std::get<std::vector<BoxObstacle> Spec::*>(row.member))
        out << YAML::Flow << YAML::BeginSeq << b.x << b.y << b.w << b.h << YAML::EndSeq;
      out << YAML::EndSeq;
      return;
    case Type::DiscList:
      out << YAML::Flow << YAML::BeginSeq;
      for (const DiscObstacle& d : spec.*std::get<std::vector<DiscObstacle> Spec::*>(row.member))
        out << YAML::Flow << YAML::BeginSeq << format_double(d.x) << format_double(d.y) << format_double(d.r)
            << YAML::EndSeq;
      out << YAML::EndSeq;
      return;
    case Type::SlipZoneList:
      out << YAML::Flow << YAML::BeginSeq;
      for (const SlipZone& z : spec.*std::get<std::vector<SlipZone> Spec::*>(row.member))
        out << YAML::Flow << YAML::BeginSeq << z.x << z.y << z.w << z.h << format_double(z.slip) << YAML::EndSeq;
      out << YAML::EndSeq;
      return;
    case Type::SizeOrImage:
      if (const auto& size = spec.*std::get<std::optional<FloorSize> Spec::*>(row.member)) {
        out << YAML::Flow << YAML::BeginSeq << size->width_px << size->height_px << YAML::EndSeq;
      } else {
        out << "image";
      }
      return;
    case Type::LayoutName:
      out << to_string(spec.*std::get<FloorLayout Spec::*>(row.member));
      return;
  }
}

/// The scenario sections are written only when they differ from the exact world (their defaults).
template <class Spec>
bool section_written(const Spec& spec) {
  if constexpr (std::is_same_v<Spec, MotionSpec>) {
    const MotionSpec defaults;
    return spec.scale_sd != defaults.scale_sd || spec.heading_sd_deg != defaults.heading_sd_deg ||
           spec.pose != defaults.pose || !spec.slip_zones.empty();
  } else if constexpr (std::is_same_v<Spec, ObstacleSpec>) {
    const ObstacleSpec defaults;
    return !spec.none() || spec.shade != defaults.shade || spec.random_box_min_px != defaults.random_box_min_px ||
           spec.random_box_max_px != defaults.random_box_max_px;
  } else if constexpr (std::is_same_v<Spec, TeamSpec>) {
    return !spec.single();
  } else if constexpr (std::is_same_v<Spec, PushSpec>) {
    const PushSpec defaults;
    return spec.probability != defaults.probability || spec.impulse_ns != defaults.impulse_ns ||
           spec.within_ticks != defaults.within_ticks || spec.traction_s != defaults.traction_s;
  } else {
    return true;
  }
}

}  // namespace

std::string field_location(const World& world, const std::string& field) {
  const std::string section = field.substr(0, field.find('.'));
  const bool known = world.lines.count(field) != 0 || world.lines.count(section) != 0;
  const std::string where = known ? ":" + std::to_string(field_line(world, field, section)) : "";
  return one_line(world.file.string()) + where + ": " + field;
}

World parse_world(std::string_view text, const std::filesystem::path& origin) {
  World world;
  world.file = origin;
  Loader loader(origin, world);
  loader.check_text(text);
  // YAML::LoadAll is not used: in yaml-cpp 0.7 it loops forever, allocating, on a stray "," at
  // document level (yaml-cpp issue #1040). Load reads the first document only, and a parser that
  // is asked for at most two documents tells whether there is more.
  YAML::Node root;
  try {
    root = YAML::Load(std::string(text));
    if (!root.IsMap()) loader.fail(1, "expected a map of sections (floor, robot, ...)");
    std::istringstream stream{std::string(text)};
    YAML::Parser parser(stream);
    DocumentStarts starts;
    if (parser.HandleNextDocument(starts) && parser.HandleNextDocument(starts)) {
      loader.fail(line_of(starts.last), "expected one YAML document, got more");
    }
  } catch (const YAML::Exception& e) {
    // e.msg is yaml-cpp's message without its own "line X, column Y" prefix.
    loader.fail(line_of(e.mark), "YAML syntax error: " + e.msg);
  }
  try {
    loader.read(root);
  } catch (const YAML::Exception& e) {
    // Validation checks every node's kind before using it, so this is a safety net only.
    loader.fail(line_of(e.mark), "YAML error: " + e.msg);
  }
  return world;
}

World load_world(const std::filesystem::path& file) {
  std::error_code ec;
  if (fs::is_directory(file, ec)) throw InputError(one_line(file.string() + ": cannot open world file"));
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(one_line(file.string() + ": cannot open world file"));
  // Read at most one byte past the cap, so that /dev/zero or a huge file costs nothing.
  std::string text;
  std::array<char, 65536> buf{};
  while (text.size() <= kMaxFileBytes && in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    text.append(buf.data(), static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) throw InputError(one_line(file.string() + ": cannot open world file"));
  if (text.size() > kMaxFileBytes) {
    // Only the first bytes were read, so the true size is unknown here.
    throw InputError(one_line(file.string() + ": expected a world file of at most 1 MiB (" +
                              std::to_string(kMaxFileBytes) + " bytes), got more"));
  }
  return parse_world(text, file);
}

void check_against_floor(const World& world, int floor_width_px, int floor_height_px) {
  const std::string origin = world.file.string();
  const std::string size = std::to_string(floor_width_px) + "x" + std::to_string(floor_height_px);
  const int smallest = std::min(floor_width_px, floor_height_px);
  const int span = world.camera.wide_px * world.camera.wide_scale;
  // Twice the side sees the whole floor from any cell (a corner included); a wider window would
  // only add black.
  if (span > 2 * std::max(floor_width_px, floor_height_px)) {
    const int line = field_line(world, "camera.wide_px", "camera");
    throw InputError(one_line(fmt::format(
        "{}:{}: camera.wide_px: expected wide_px x wide_scale at most twice the floor's larger side, {} (the floor is "
        "{} pixels), got {} x {} = {}",
        origin, line, 2 * std::max(floor_width_px, floor_height_px), size, world.camera.wide_px,
        world.camera.wide_scale, span)));
  }
  if (world.camera.patch_px > smallest) {
    const int line = field_line(world, "camera.patch_px", "camera");
    const bool given = world.lines.count("camera.patch_px") != 0;
    throw InputError(one_line(origin + ":" + std::to_string(line) + ": camera.patch_px: expected " +
                              int_range(1, std::max(smallest, 1)) + " (the floor is " + size + " pixels), got " +
                              std::to_string(world.camera.patch_px) + (given ? "" : " (the default)")));
  }
  for (std::size_t i = 0; i < world.obstacles.boxes.size(); ++i) {
    const BoxObstacle& b = world.obstacles.boxes[i];
    if (b.x + b.w > floor_width_px || b.y + b.h > floor_height_px) {
      const int line = field_line(world, "obstacles.boxes", "obstacles");
      throw InputError(one_line(fmt::format(
          "{}:{}: obstacles.boxes: expected boxes within the floor ({} pixels: x + w <= {}, y + h <= {}), got box {} "
          "= [{}, {}, {}, {}]",
          origin, line, size, floor_width_px, floor_height_px, i + 1, b.x, b.y, b.w, b.h)));
    }
  }
  if (world.obstacles.random_boxes > 0 && world.obstacles.random_box_max_px > smallest) {
    const int line = field_line(world, "obstacles.random_box_max_px", "obstacles");
    throw InputError(one_line(fmt::format(
        "{}:{}: obstacles.random_box_max_px: expected at most the floor's smaller side, {} (the floor is {} pixels), "
        "got {}",
        origin, line, smallest, size, world.obstacles.random_box_max_px)));
  }
  for (std::size_t i = 0; i < world.motion.slip_zones.size(); ++i) {
    const SlipZone& z = world.motion.slip_zones[i];
    if (z.x + z.w > floor_width_px || z.y + z.h > floor_height_px) {
      const int line = field_line(world, "motion.slip_zones", "motion");
      throw InputError(one_line(fmt::format(
          "{}:{}: motion.slip_zones: expected zones within the floor ({} pixels: x + w <= {}, y + h <= {}), got zone "
          "{} = [{}, {}, {}, {}, {}]",
          origin, line, size, floor_width_px, floor_height_px, i + 1, z.x, z.y, z.w, z.h, format_double(z.slip))));
    }
  }
  for (std::size_t i = 0; i < world.obstacles.discs.size(); ++i) {
    const DiscObstacle& d = world.obstacles.discs[i];
    if (d.x > floor_width_px || d.y > floor_height_px) {
      const int line = field_line(world, "obstacles.discs", "obstacles");
      throw InputError(one_line(
          fmt::format("{}:{}: obstacles.discs: expected centres on the floor ({} pixels), got disc {} = [{}, {}, {}]",
                      origin, line, size, i + 1, format_double(d.x), format_double(d.y), format_double(d.r))));
    }
  }
  if (world.robot.start) {
    const auto [x, y] = *world.robot.start;
    if (x < 0 || y < 0 || x >= floor_width_px || y >= floor_height_px) {
      const int line = field_line(world, "robot.start", "robot");
      throw InputError(one_line(origin + ":" + std::to_string(line) + ": robot.start: expected [x, y] with x in [0, " +
                                std::to_string(floor_width_px - 1) + "] and y in [0, " +
                                std::to_string(floor_height_px - 1) + "] (the floor is " + size + " pixels), got [" +
                                std::to_string(x) + ", " + std::to_string(y) + "]"));
    }
    // The robot's disc must fit there: a start on or beside an obstacle would overlap its body.
    const double radius_px = world.robot.radius_m / world.floor.pixel_size_m;
    const double clearance = world.obstacles.clearance_px(x + 0.5, y + 0.5);
    if (clearance < radius_px) {
      const int line = field_line(world, "robot.start", "robot");
      throw InputError(one_line(fmt::format(
          "{}:{}: robot.start: expected a cell whose centre is at least the robot's radius ({} px) from every "
          "obstacle, got [{}, {}], {} px from one",
          origin, line, format_double(radius_px), x, y, fmt::format("{:.3g}", clearance))));
    }
  }
}

double MotionSpec::slip_at(double x, double y) const {
  double slip = 0.0;
  for (const SlipZone& z : slip_zones)
    if (x >= z.x && x < z.x + z.w && y >= z.y && y < z.y + z.h) slip = std::max(slip, z.slip);
  return slip;
}

bool ObstacleSpec::covers(double x, double y) const { return clearance_px(x, y) == 0.0; }

double BoxObstacle::distance_px(double px, double py) const {
  const double dx = std::max({x - px, 0.0, px - (x + w)});
  const double dy = std::max({y - py, 0.0, py - (y + h)});
  return std::hypot(dx, dy);
}

double DiscObstacle::distance_px(double px, double py) const { return std::max(0.0, std::hypot(px - x, py - y) - r); }

double ObstacleSpec::clearance_px(double x, double y) const {
  double nearest = std::numeric_limits<double>::infinity();
  for (const BoxObstacle& b : boxes) nearest = std::min(nearest, b.distance_px(x, y));
  for (const DiscObstacle& d : discs) nearest = std::min(nearest, d.distance_px(x, y));
  return nearest;
}

std::string to_yaml(const World& world) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  for_each_section(world, [&out](std::string_view section, auto rows, const auto& spec) {
    if (!section_written(spec)) return;
    if (!section.empty()) out << YAML::Key << std::string(section) << YAML::Value << YAML::BeginMap;
    for (const auto& row : rows) {
      if (!written(row, spec)) continue;
      out << YAML::Key << std::string(row.name) << YAML::Value;
      emit_value(out, row, spec);
    }
    if (!section.empty()) out << YAML::EndMap;
  });
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

std::span<const FieldInfo> world_schema() {
  static const std::vector<FieldInfo> schema = [] {
    std::vector<FieldInfo> out;
    const World defaults{};
    for_each_section(defaults, [&out](std::string_view section, auto rows, const auto& spec) {
      for (const auto& row : rows) {
        std::string range = interval_text(row.type, row.range);
        if (!row.rule.empty()) range += (range.empty() ? "" : ", ") + std::string(row.rule);
        out.push_back({section, row.name, type_text(row.type), value_text(row, spec), range, row.doc, row.unit});
      }
    });
    return out;
  }();
  return schema;
}

}  // namespace scout::worlds
