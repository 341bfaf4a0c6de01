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
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

namespace scout::worlds {

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

constexpr std::string_view kYamlTagPrefix = "tag:yaml.org,2002:";

// ---------------------------------------------------------------------------------------------
// Messages

std::string clip(std::string_view text) {
  if (text.size() <= kMaxQuoted) return std::string(text);
  return std::string(text.substr(0, kMaxQuoted)) + "...";
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
                               std::initializer_list<std::string_view> allowed);

  int read_int(const Field& f, int lo, int hi) const;
  std::uint64_t read_u64(const Field& f) const;
  double read_number(const Field& f, double lo, double hi, bool hi_open) const;
  std::string read_string(const Field& f, std::string_view expected) const;

  void read_floor(const YAML::Node& section);
  void read_robot(const YAML::Node& section);
  void read_controller(const YAML::Node& section);
  void read_camera(const YAML::Node& section);
  void read_task(const YAML::Node& section);
  void read_physics(const YAML::Node& section);

  fs::path resolve(const fs::path& relative, const Field& f) const;

  const fs::path& origin_;
  World& world_;
};

// ---------------------------------------------------------------------------------------------
// Pre-scan: size and nesting, before yaml-cpp sees the text.

void Loader::check_text(std::string_view text) const {
  if (text.size() > kMaxFileBytes) {
    throw InputError(one_line(origin_.string() + ": expected a world file of at most 1 MiB (" +
                              std::to_string(kMaxFileBytes) + " bytes), got " + std::to_string(text.size()) +
                              " bytes"));
  }
  // yaml-cpp reports a NUL byte as a confusing escape error on the wrong line: name it here.
  if (const auto nul = text.find('\0'); nul != std::string_view::npos) {
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(nul), '\n');
    throw InputError(one_line(origin_.string() + ":" + std::to_string(line) + ": expected text, got a NUL byte"));
  }
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

int Loader::read_int(const Field& f, int lo, int hi) const {
  const auto t = integer_text(f.value);
  const bool ok = t && !t->too_large && (!t->negative || t->magnitude == 0) &&
                  t->magnitude >= static_cast<std::uint64_t>(lo) && t->magnitude <= static_cast<std::uint64_t>(hi);
  if (!ok) fail_field(f.line, f.dotted, int_range(lo, hi), describe(f.value));
  return static_cast<int>(t->magnitude);
}

std::uint64_t Loader::read_u64(const Field& f) const {
  const auto t = integer_text(f.value);
  if (!t || t->too_large || (t->negative && t->magnitude != 0)) {
    fail_field(f.line, f.dotted,
               "an unsigned integer in [0, " + std::to_string(std::numeric_limits<std::uint64_t>::max()) + "]",
               describe(f.value));
  }
  return t->magnitude;
}

double Loader::read_number(const Field& f, double lo, double hi, bool hi_open) const {
  bool out_of_range = false;
  const auto v = number_text(f.value, out_of_range);
  // Written as !(in range) so that a NaN could never slip through.
  const bool ok = v && *v > lo && (hi_open ? *v < hi : *v <= hi);
  if (!ok) {
    fail_field(f.line, f.dotted, "a number in (" + format_double(lo) + ", " + format_double(hi) + (hi_open ? ")" : "]"),
               describe(f.value));
  }
  return *v;
}

std::string Loader::read_string(const Field& f, std::string_view expected) const {
  if (!f.value.IsScalar() || f.value.Scalar().empty()) fail_field(f.line, f.dotted, expected, describe(f.value));
  return f.value.Scalar();
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

std::vector<Loader::Field> Loader::fields_of(const YAML::Node& section, const std::string& section_name,
                                             std::initializer_list<std::string_view> allowed) {
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

void Loader::read_floor(const YAML::Node& section) {
  const Field* dataset = nullptr;
  const Field* image = nullptr;
  const Field* split = nullptr;
  const Field* index = nullptr;
  const auto fields = fields_of(section, "floor", {"dataset", "split", "index", "image", "pixel_size_m"});
  FloorSpec& floor = world_.floor;
  for (const Field& f : fields) {
    if (f.key == "dataset") {
      floor.dataset = read_string(f, "mnist, fashion-mnist or a folder of IDX files");
      dataset = &f;
    } else if (f.key == "split") {
      const std::string s = f.value.IsScalar() ? f.value.Scalar() : std::string();
      if (s == "train") {
        floor.split = Split::Train;
      } else if (s == "validation") {
        floor.split = Split::Validation;
      } else if (s == "test") {
        floor.split = Split::Test;
      } else {
        fail_field(f.line, f.dotted, "train, validation or test", describe(f.value));
      }
      split = &f;
    } else if (f.key == "index") {
      if (f.value.IsScalar() && f.value.Scalar() == "random") {
        floor.index.reset();
      } else {
        const auto t = integer_text(f.value);
        const auto hi = static_cast<std::uint64_t>(std::numeric_limits<int>::max());
        if (!t || t->too_large || (t->negative && t->magnitude != 0) || t->magnitude > hi) {
          fail_field(f.line, f.dotted, int_range(0, std::numeric_limits<int>::max()) + " or random", describe(f.value));
        }
        floor.index = static_cast<int>(t->magnitude);
      }
      index = &f;
    } else if (f.key == "image") {
      const std::string s = read_string(f, "a .png file");
      std::string ext = s.size() >= 4 ? s.substr(s.size() - 4) : std::string();
      std::transform(ext.begin(), ext.end(), ext.begin(),
                     [](char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; });
      if (ext != ".png" || s.size() == 4) fail_field(f.line, f.dotted, "a .png file", describe(f.value));
      floor.image = s;
      image = &f;
    } else {  // pixel_size_m
      floor.pixel_size_m = read_number(f, 0.0, 10.0, false);
    }
  }
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
  if (floor.dataset != "mnist" && floor.dataset != "fashion-mnist") {
    floor.dataset = resolve(floor.dataset, *dataset).string();
  }
}

void Loader::read_robot(const YAML::Node& section) {
  RobotSpec& robot = world_.robot;
  for (const Field& f : fields_of(section, "robot", {"radius_m", "mass_kg", "max_speed_mps", "start"})) {
    if (f.key == "radius_m") {
      robot.radius_m = read_number(f, 0.0, 10.0, false);
    } else if (f.key == "mass_kg") {
      robot.mass_kg = read_number(f, 0.0, 1e4, false);
    } else if (f.key == "max_speed_mps") {
      robot.max_speed_mps = read_number(f, 0.0, 1000.0, false);
    } else {  // start
      const std::string expected = "[x, y] (two non-negative integers, pixels) or random";
      if (f.value.IsScalar() && f.value.Scalar() == "random") {
        robot.start.reset();
        continue;
      }
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
      robot.start = std::make_pair(xy[0], xy[1]);
    }
  }
}

void Loader::read_controller(const YAML::Node& section) {
  for (const Field& f : fields_of(section, "controller", {"kp_per_s", "tolerance_px"})) {
    if (f.key == "kp_per_s") {
      world_.controller.kp_per_s = read_number(f, 0.0, 1e6, false);
    } else {
      // Below half a pixel, so that a settled robot is always inside its target cell.
      world_.controller.tolerance_px = read_number(f, 0.0, 0.5, true);
    }
  }
}

void Loader::read_camera(const YAML::Node& section) {
  for (const Field& f : fields_of(section, "camera", {"patch_px"})) {
    world_.camera.patch_px = read_int(f, 1, kMaxPatchPx);
  }
}

void Loader::read_task(const YAML::Node& section) {
  for (const Field& f : fields_of(section, "task", {"episodes", "steps", "step_px"})) {
    if (f.key == "episodes") {
      world_.task.episodes = read_int(f, 1, 1000);
    } else if (f.key == "steps") {
      world_.task.steps = read_int(f, 1, 1000);
    } else {
      world_.task.step_px = read_int(f, 1, 512);
    }
  }
}

void Loader::read_physics(const YAML::Node& section) {
  PhysicsSpec& physics = world_.physics;
  for (const Field& f :
       fields_of(section, "physics", {"dt_s", "velocity_iterations", "position_iterations", "max_ticks_per_move"})) {
    if (f.key == "dt_s") {
      physics.dt_s = read_number(f, 0.0, 1.0, false);
    } else if (f.key == "velocity_iterations") {
      physics.velocity_iterations = read_int(f, 1, 100);
    } else if (f.key == "position_iterations") {
      physics.position_iterations = read_int(f, 1, 100);
    } else {
      physics.max_ticks_per_move = read_int(f, 1, 100000);
    }
  }
}

void Loader::read(const YAML::Node& root) {
  if (!root.IsMap()) fail(1, "expected a map of sections (floor, robot, ...)");
  static constexpr std::array<std::string_view, 7> kSections = {"floor", "robot",   "controller", "camera",
                                                                "task",  "physics", "seed"};
  std::set<std::string> seen;
  bool floor_seen = false;
  for (const auto& entry : root) {
    const YAML::Node key = entry.first;
    const int line = line_of(key);
    if (!key.IsScalar())
      fail(line, "expected section names (" + join(kSections) + "), got " + describe(key) + " as a key");
    const std::string name = key.Scalar();
    if (name == "perturbation") fail(line, "perturbation: not yet supported (slip and push are future work)");
    if (std::find(kSections.begin(), kSections.end(), name) == kSections.end()) {
      fail_field(line, clip(name), "a section among " + join(kSections), "unknown key \"" + clip(name) + "\"");
    }
    if (!seen.insert(name).second) {
      fail_field(line, name, "each section once",
                 "a second one (the first is on line " + std::to_string(world_.lines.at(name)) + ")");
    }
    world_.lines[name] = line;
    const YAML::Node value = entry.second;
    if (name == "floor") {
      read_floor(value);
      floor_seen = true;
    } else if (name == "robot") {
      read_robot(value);
    } else if (name == "controller") {
      read_controller(value);
    } else if (name == "camera") {
      read_camera(value);
    } else if (name == "task") {
      read_task(value);
    } else if (name == "physics") {
      read_physics(value);
    } else {  // seed
      Field f;
      f.key = name;
      f.dotted = name;
      f.line = line;
      f.value = value;
      world_.seed = read_u64(f);
    }
  }
  if (!floor_seen) world_.floor.dataset = "mnist";  // no floor section: the paper's floor

  // The robot's size in pixels: Box2D runs in tenths of a pixel and is tuned for bodies of 0.1 to
  // 10 of its units, so a radius of 0.5 to 100 pixels.
  const double radius_px = world_.robot.radius_m / world_.floor.pixel_size_m;
  if (radius_px < 0.5 || radius_px > 100.0) {
    const auto it = world_.lines.find("robot.radius_m");
    const int line = it != world_.lines.end()                   ? it->second
                     : world_.lines.count("floor.pixel_size_m") ? world_.lines.at("floor.pixel_size_m")
                                                                : 1;
    fail_field(line, "robot.radius_m",
               "a radius of 0.5 to 100 pixels (" + format_double(0.5 * world_.floor.pixel_size_m) + " to " +
                   format_double(100.0 * world_.floor.pixel_size_m) + " m at pixel_size_m " +
                   format_double(world_.floor.pixel_size_m) + ")",
               format_double(world_.robot.radius_m) + " m = " + fmt::format("{:.3g}", radius_px) + " px" +
                   (it == world_.lines.end() ? " (the default)" : ""));
  }

  // The controller sets velocity = kp * error each tick, so the error shrinks by |1 - kp dt| per
  // tick once under the speed limit: at kp dt >= 2 it never shrinks and a move never settles.
  const double gain_per_tick = world_.controller.kp_per_s * world_.physics.dt_s;
  if (gain_per_tick >= 2.0) {
    const auto it = world_.lines.find("controller.kp_per_s");
    const int line = it != world_.lines.end()             ? it->second
                     : world_.lines.count("physics.dt_s") ? world_.lines.at("physics.dt_s")
                                                          : 1;
    fail_field(line, "controller.kp_per_s",
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
  if (world.camera.patch_px > smallest) {
    const int line = field_line(world, "camera.patch_px", "camera");
    const bool given = world.lines.count("camera.patch_px") != 0;
    throw InputError(one_line(origin + ":" + std::to_string(line) + ": camera.patch_px: expected " +
                              int_range(1, std::max(smallest, 1)) + " (the floor is " + size + " pixels), got " +
                              std::to_string(world.camera.patch_px) + (given ? "" : " (the default)")));
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
  }
}

std::string to_yaml(const World& world) {
  // Numbers go out as their shortest round-trip text, so parse_world(to_yaml(w)) == w exactly.
  const auto number = [](double v) { return format_double(v); };
  YAML::Emitter out;
  out << YAML::BeginMap;

  out << YAML::Key << "floor" << YAML::Value << YAML::BeginMap;
  if (!world.floor.image.empty()) {
    out << YAML::Key << "image" << YAML::Value << YAML::DoubleQuoted << world.floor.image.string();
  } else {
    const std::string dataset = world.floor.dataset.empty() ? std::string("mnist") : world.floor.dataset;
    out << YAML::Key << "dataset" << YAML::Value;
    if (dataset == "mnist" || dataset == "fashion-mnist") {
      out << dataset;
    } else {
      // Quoted so that no folder name ("~", "null", "123") is read back as anything but a string.
      out << YAML::DoubleQuoted << dataset;
    }
    out << YAML::Key << "split" << YAML::Value << to_string(world.floor.split);
    out << YAML::Key << "index" << YAML::Value;
    if (world.floor.index) {
      out << *world.floor.index;
    } else {
      out << "random";
    }
  }
  out << YAML::Key << "pixel_size_m" << YAML::Value << number(world.floor.pixel_size_m);
  out << YAML::EndMap;

  out << YAML::Key << "robot" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "radius_m" << YAML::Value << number(world.robot.radius_m);
  out << YAML::Key << "mass_kg" << YAML::Value << number(world.robot.mass_kg);
  out << YAML::Key << "max_speed_mps" << YAML::Value << number(world.robot.max_speed_mps);
  out << YAML::Key << "start" << YAML::Value;
  if (world.robot.start) {
    out << YAML::Flow << YAML::BeginSeq << world.robot.start->first << world.robot.start->second << YAML::EndSeq;
  } else {
    out << "random";
  }
  out << YAML::EndMap;

  out << YAML::Key << "controller" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "kp_per_s" << YAML::Value << number(world.controller.kp_per_s);
  out << YAML::Key << "tolerance_px" << YAML::Value << number(world.controller.tolerance_px);
  out << YAML::EndMap;

  out << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "patch_px" << YAML::Value << world.camera.patch_px;
  out << YAML::EndMap;

  out << YAML::Key << "task" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "episodes" << YAML::Value << world.task.episodes;
  out << YAML::Key << "steps" << YAML::Value << world.task.steps;
  out << YAML::Key << "step_px" << YAML::Value << world.task.step_px;
  out << YAML::EndMap;

  out << YAML::Key << "physics" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "dt_s" << YAML::Value << number(world.physics.dt_s);
  out << YAML::Key << "velocity_iterations" << YAML::Value << world.physics.velocity_iterations;
  out << YAML::Key << "position_iterations" << YAML::Value << world.physics.position_iterations;
  out << YAML::Key << "max_ticks_per_move" << YAML::Value << world.physics.max_ticks_per_move;
  out << YAML::EndMap;

  out << YAML::Key << "seed" << YAML::Value << world.seed;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace scout::worlds
