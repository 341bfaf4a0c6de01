// Deterministic fuzzing of parse_world: random bytes, YAML-ish token soup, deep nesting and
// mutations of the shipped world. Every input must give a World that satisfies every range, or a
// one-line scout::InputError; any other exception (or a crash) is a bug. An accepted world must
// survive the manifest round trip (to_yaml, then parse_world) equal in every field of the schema
// (tests/support/world_fields.hpp lists them, held to the structs and to world_schema()), with a
// line for each field to_yaml writes.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"
#include "tests/support/world_fields.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {
namespace {

using scout::testing::expect_same_world;

constexpr std::uint64_t kSeed = 0x5c0057;  // fixed: a failure reproduces on every run
constexpr int kCasesPerKind = 5000;        // four kinds, 20,000 inputs in all

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// The invariants the loader promises for an accepted world, checked independently of it.
void expect_valid(const World& w, const std::string& text) {
  SCOPED_TRACE("input:\n" + text);
  EXPECT_NE(w.floor.dataset.empty(), w.floor.image.empty()) << "exactly one of dataset and image";
  if (!w.floor.image.empty()) {
    EXPECT_TRUE(w.floor.image.is_absolute());
    EXPECT_FALSE(w.floor.index.has_value());
  }
  if (w.floor.index) {
    EXPECT_GE(*w.floor.index, 0);
  }
  EXPECT_GT(w.floor.pixel_size_m, 0.0);
  EXPECT_LE(w.floor.pixel_size_m, 10.0);
  EXPECT_GT(w.robot.radius_m, 0.0);
  EXPECT_LE(w.robot.radius_m, 10.0);
  EXPECT_GT(w.robot.mass_kg, 0.0);
  EXPECT_LE(w.robot.mass_kg, 1e4);
  EXPECT_GT(w.robot.max_speed_mps, 0.0);
  EXPECT_LE(w.robot.max_speed_mps, 1000.0);
  if (w.robot.start) {
    EXPECT_GE(w.robot.start->first, 0);
    EXPECT_GE(w.robot.start->second, 0);
  }
  EXPECT_GT(w.controller.kp_per_s, 0.0);
  EXPECT_LE(w.controller.kp_per_s, 1e6);
  EXPECT_GT(w.controller.tolerance_px, 0.0);
  EXPECT_LT(w.controller.tolerance_px, 0.5);
  EXPECT_GE(w.camera.patch_px, 1);
  EXPECT_LE(w.camera.patch_px, 512);
  EXPECT_GE(w.task.episodes, 1);
  EXPECT_LE(w.task.episodes, 1000);
  EXPECT_GE(w.task.steps, 1);
  EXPECT_LE(w.task.steps, 1000);
  EXPECT_GE(w.task.step_px, 1);
  EXPECT_LE(w.task.step_px, 512);
  EXPECT_GT(w.physics.dt_s, 0.0);
  EXPECT_LE(w.physics.dt_s, 1.0);
  EXPECT_GE(w.physics.velocity_iterations, 1);
  EXPECT_LE(w.physics.velocity_iterations, 100);
  EXPECT_GE(w.physics.position_iterations, 1);
  EXPECT_LE(w.physics.position_iterations, 100);
  EXPECT_GE(w.physics.max_ticks_per_move, 1);
  EXPECT_LE(w.physics.max_ticks_per_move, 100000);
  for (const auto& [field, line] : w.lines) {
    EXPECT_GE(line, 1) << field;
  }
}

/// The dotted keys to_yaml writes for `w`, with the sections: every field of the schema but the
/// floor's other kind (a PNG floor has no dataset, split or index; a data set floor no image).
std::set<std::string> written_keys(const World& w) {
  std::set<std::string> keys;
  const bool png = !w.floor.image.empty();
  // A scenario section is written only when a field of it differs from its default.
  std::set<std::string> varied_scenarios;
  const World defaults;
  scout::testing::for_each_world_field(w, defaults, [&](const char* name, const auto& x, const auto& y) {
    const std::string dotted(name);
    const std::string section = dotted.substr(0, dotted.find('.'));
    if ((section == "motion" || section == "pushes" || section == "obstacles" || section == "team") && !(x == y))
      varied_scenarios.insert(section);
  });
  for (const FieldInfo& f : world_schema()) {
    const std::string section(f.section), name(f.name);
    if (section.empty()) {
      keys.insert(name);
      continue;
    }
    const bool scenario = section == "motion" || section == "pushes" || section == "obstacles" || section == "team";
    if (scenario && varied_scenarios.count(section) == 0) continue;
    keys.insert(section);
    if (section == "floor" && (png ? name == "dataset" || name == "split" || name == "index" : name == "image"))
      continue;
    // The layout's fields are written only for a composed floor (every earlier world's text stays).
    const bool layout_field = name == "size_px" || name == "layout" || name == "digits";
    if (section == "floor" && layout_field && !w.floor.composed()) continue;
    const bool cluttered = w.floor.layout == FloorLayout::Cluttered;
    if (section == "floor" && name == "clutter" && !cluttered) continue;
    const bool wide_written = w.camera.wide() || w.camera.wide_scale != CameraSpec{}.wide_scale;
    if (section == "camera" && (name == "wide_px" || name == "wide_scale") && !wide_written) continue;
    if (section == "floor" && name == "clutter_px" && !cluttered && w.floor.clutter_px == FloorSpec{}.clutter_px)
      continue;
    keys.insert(section + "." + name);
  }
  return keys;
}

/// What the accepted worlds exercised.
struct Tally {
  /// Per field, how many accepted worlds held a value other than the default: the round trip's
  /// comparison of that field met a value a dropped or mangled field would not give back.
  std::map<std::string, int> varied;
  /// Accepted worlds naming a data set or PNG that to_yaml cannot write back (the loader refuses
  /// such names, so none may be accepted).
  int unwritable_names = 0;
};

/// Whether yaml-cpp's emitter, which to_yaml writes through, gives `s` back byte for byte: UTF-8
/// in shortest form, no surrogates, nothing past U+10FFFF, and none of the noncharacters it
/// replaces (U+FDD0..U+FDEF, U+xFFFE, U+xFFFF). Anything else it writes with U+FFFD instead.
bool emitter_keeps(std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const auto lead = static_cast<unsigned char>(s[i]);
    if (lead < 0x80) {
      ++i;
      continue;
    }
    const std::size_t trailing = (lead & 0xE0) == 0xC0 ? 1 : (lead & 0xF0) == 0xE0 ? 2 : (lead & 0xF8) == 0xF0 ? 3 : 0;
    if (trailing == 0 || s.size() - i <= trailing) return false;
    char32_t cp = lead & (0x3F >> trailing);
    for (std::size_t k = 1; k <= trailing; ++k) {
      const auto byte = static_cast<unsigned char>(s[i + k]);
      if ((byte & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (byte & 0x3F);
    }
    constexpr char32_t kShortest[] = {0, 0x80, 0x800, 0x10000};
    if (cp < kShortest[trailing] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF) || (cp >= 0xFDD0 && cp <= 0xFDEF) ||
        (cp & 0xFFFE) == 0xFFFE)
      return false;
    i += trailing + 1;
  }
  return true;
}

/// The manifest round trip: to_yaml's text, read back from the same origin, is the same world in
/// every field; and it gives every field a line of its own (a field the writer dropped would
/// read back as its default, which a world holding the default would not show).
///
/// The loader refuses a floor.dataset or floor.image whose bytes the emitter would not write back
/// (a stray byte in `dataset: mnist` once came back as U+FFFD, and the manifest named another
/// folder): an accepted world never holds one.
void expect_round_trip(const World& w, const std::string& text, Tally& tally) {
  const std::string yaml = to_yaml(w);
  SCOPED_TRACE("input:\n" + text + "\nto_yaml:\n" + yaml);
  const World back = parse_world(yaml, "fuzz.yaml");
  for (const std::string& name : {w.floor.dataset, w.floor.image.string()})
    if (!emitter_keeps(name)) ++tally.unwritable_names;
  expect_same_world(back, w);
  EXPECT_EQ(back.file, w.file);
  const std::set<std::string> want = written_keys(w);
  std::string missing, extra;
  for (const std::string& key : want)
    if (back.lines.count(key) == 0) missing += " " + key;
  for (const auto& [key, line] : back.lines)
    if (want.count(key) == 0) extra += " " + key;
  EXPECT_EQ(missing, "") << "keys to_yaml did not write";
  EXPECT_EQ(extra, "") << "keys to_yaml wrote beyond the schema's";
}

/// Feeds one input; returns whether it was accepted. Anything but World or InputError fails.
bool feed(const std::string& text, Tally& tally) {
  static const World defaults = parse_world("seed: 0\n", "fuzz.yaml");
  try {
    const World w = parse_world(text, "fuzz.yaml");
    expect_valid(w, text);
    // What was accepted must also survive the manifest round trip and the floor check.
    expect_round_trip(w, text, tally);
    scout::testing::for_each_world_field(w, defaults, [&tally](const char* name, const auto& x, const auto& y) {
      tally.varied[name] += x == y ? 0 : 1;
    });
    try {
      check_against_floor(w, 28, 28);
    } catch (const InputError&) {
      // a floor-size refusal is a valid outcome
    }
    return true;
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_EQ(message.rfind("fuzz.yaml", 0), 0u) << message;
    return false;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "unexpected exception: " << e.what() << "\ninput:\n" << text;
  } catch (...) {
    ADD_FAILURE() << "unexpected non-standard exception\ninput:\n" << text;
  }
  return false;
}

class Fuzzer {
 public:
  explicit Fuzzer(std::uint64_t seed) : rng_(seed) {}

  std::size_t below(std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng_); }
  template <class T>
  const T& pick(const std::vector<T>& items) {
    return items[below(items.size())];
  }

  std::string random_bytes() {
    std::string s(below(200), '\0');
    for (char& c : s) c = static_cast<char>(below(256));
    return s;
  }

  std::string token_soup() {
    std::string s;
    const std::size_t n = 1 + below(60);
    for (std::size_t i = 0; i < n; ++i) {
      s += pick(kTokens);
      s += pick(kSeparators);
    }
    return s;
  }

  /// A world-shaped map: known (and a few unknown) sections and fields, block or flow style,
  /// with values drawn from the edge cases, so that the accept path meets odd values too.
  std::string structured() {
    std::string s;
    const std::size_t sections = 1 + below(5);
    for (std::size_t i = 0; i < sections; ++i) {
      const auto& [section, fields] = kSchema[below(kSchema.size())];
      if (section == "seed") {
        s += "seed: " + pick(kNumbers) + "\n";
        continue;
      }
      const bool flow = below(2) == 0;
      s += section + (flow ? ": {" : ":\n");
      const std::size_t n = below(4);
      for (std::size_t j = 0; j < n; ++j) {
        const std::string field = below(20) == 0 ? pick(kTokens) : fields[below(fields.size())];
        const std::string value = below(2) == 0 ? pick(kNumbers) : pick(kValues);
        s += flow ? (j ? ", " : "") + field + ": " + value : "  " + field + ": " + value + "\n";
      }
      if (flow) s += "}\n";
    }
    return s;
  }

  std::string deep_nesting() {
    const std::size_t depth = 30 + below(3000);
    std::string s = pick(std::vector<std::string>{"seed: ", "floor:\n  dataset: ", "", "robot:\n  start: "});
    switch (below(5)) {
      case 0:
        s += std::string(depth, '[');
        break;
      case 1:
        s += std::string(depth, '{');
        break;
      case 2:
        for (std::size_t i = 0; i < depth; ++i) s += "- ";
        s += "x";
        break;
      case 3:
        for (std::size_t i = 0; i < depth; ++i) s += std::string(i, ' ') + "k:\n";
        break;
      default:
        for (std::size_t i = 0; i < depth; ++i)
          s += pick(std::vector<std::string>{"[", "{a: ", "[\"]\", ", "'", "\"", "#", "\n", "- ", "? "});
    }
    return s;
  }

  std::string mutate(const std::string& base) {
    std::vector<std::string> lines;
    std::istringstream in(base);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    const std::size_t mutations = 1 + below(4);
    for (std::size_t m = 0; m < mutations && !lines.empty(); ++m) {
      const std::size_t i = below(lines.size());
      std::string& line = lines[i];
      switch (below(8)) {
        case 0:
          lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(i));
          break;
        case 1:
          lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(i), line);
          break;
        case 2:
          std::swap(line, lines[below(lines.size())]);
          break;
        case 3:
          if (!line.empty()) line[below(line.size())] = static_cast<char>(below(256));
          break;
        case 4:
          if (!line.empty()) line[below(line.size())] = pick(kInterestingChars);
          break;
        case 5:
          line.resize(below(line.size() + 1));
          break;
        case 6: {
          // Replace the value after the colon with an interesting one.
          const auto colon = line.find(':');
          if (colon != std::string::npos) line = line.substr(0, colon + 1) + " " + pick(kValues);
          break;
        }
        default:
          line.insert(below(line.size() + 1), pick(kTokens));
          break;
      }
    }
    std::string out;
    for (const std::string& line : lines) out += line + "\n";
    if (below(4) == 0) out.resize(below(out.size() + 1));  // truncated mid-file
    return out;
  }

 private:
  std::mt19937_64 rng_;

  const std::vector<std::string> kTokens = {"[",
                                            "]",
                                            "{",
                                            "}",
                                            ":",
                                            ": ",
                                            "-",
                                            "- ",
                                            ",",
                                            "?",
                                            "? ",
                                            "\"",
                                            "'",
                                            "#",
                                            "|",
                                            ">",
                                            "&a",
                                            "*a",
                                            "&b ",
                                            "*b",
                                            "!!str",
                                            "!!int",
                                            "!!map",
                                            "!!seq",
                                            "!foo",
                                            "<<",
                                            "---",
                                            "...",
                                            "%YAML 1.2",
                                            "\t",
                                            "\\",
                                            "~",
                                            "null",
                                            "floor",
                                            "robot",
                                            "controller",
                                            "camera",
                                            "task",
                                            "physics",
                                            "motion",
                                            "pushes",
                                            "obstacles",
                                            "seed",
                                            "perturbation",
                                            "dataset",
                                            "split",
                                            "index",
                                            "image",
                                            "pixel_size_m",
                                            "radius_m",
                                            "mass_kg",
                                            "max_speed_mps",
                                            "start",
                                            "kp_per_s",
                                            "tolerance_px",
                                            "patch_px",
                                            "episodes",
                                            "steps",
                                            "step_px",
                                            "dt_s",
                                            "velocity_iterations",
                                            "position_iterations",
                                            "max_ticks_per_move",
                                            "random",
                                            "mnist",
                                            "fashion-mnist",
                                            "test",
                                            "train",
                                            "validation",
                                            "a.png",
                                            "0",
                                            "1",
                                            "6",
                                            "-1",
                                            "-0",
                                            "0.5",
                                            "6.5",
                                            "1e400",
                                            "-1e400",
                                            "1e-400",
                                            "nan",
                                            ".nan",
                                            ".inf",
                                            "-.inf",
                                            "0x10",
                                            "0o7",
                                            "007",
                                            "1_000",
                                            "18446744073709551615",
                                            "18446744073709551616",
                                            "99999999999999999999999999",
                                            "2147483647",
                                            "2147483648",
                                            "+5",
                                            "1.",
                                            ".5",
                                            "e5",
                                            "1e",
                                            "\xff",
                                            "\xef\xbb\xbf",
                                            std::string(1, '\0')};
  const std::vector<std::string> kSeparators = {" ", "", "\n", "\n  ", "\n    ", ", ", "\r\n"};
  const std::vector<std::string> kValues = {"random",
                                            "odometry",
                                            "[[1, 2, 3, 4]]",
                                            "[[20, 20, 2.5], [3, 4, 0.5]]",
                                            "[[0, 0, 0, 1]]",
                                            "localised",
                                            "[1, 2]",
                                            "[1, 2, 3]",
                                            "{}",
                                            "[]",
                                            "~",
                                            "",
                                            "\"6\"",
                                            "6.0",
                                            "0",
                                            "-3",
                                            "1e400",
                                            ".inf",
                                            ".nan",
                                            "-0",
                                            "0x10",
                                            "18446744073709551615",
                                            "18446744073709551616",
                                            "&x 5",
                                            "*x",
                                            "!!str 6",
                                            "|\n  6",
                                            "[[[[",
                                            "a.png",
                                            "fashion-mnist",
                                            "../x",
                                            "512",
                                            "513",
                                            "1000",
                                            "0.4999",
                                            "1e-300"};
  const std::vector<std::string> kNumbers = {"0",
                                             "1",
                                             "2",
                                             "3",
                                             "6",
                                             "28",
                                             "100",
                                             "512",
                                             "1000",
                                             "0.05",
                                             "0.1",
                                             "0.25",
                                             "0.4999",
                                             "0.5",
                                             "1.0",
                                             "2.0",
                                             "10",
                                             "60",
                                             "1e4",
                                             "1e6",
                                             "1e-3",
                                             "-1",
                                             "-0",
                                             "-0.0",
                                             "6.5",
                                             "1e400",
                                             "1e-400",
                                             ".5",
                                             "5.",
                                             "+3",
                                             "007",
                                             "2147483647",
                                             "2147483648",
                                             "18446744073709551615",
                                             "18446744073709551616",
                                             "[3, 4]",
                                             "[0, 0]",
                                             "random"};
  const std::vector<std::pair<std::string, std::vector<std::string>>> kSchema = {
      {"floor", {"dataset", "split", "index", "image", "pixel_size_m"}},
      {"robot", {"radius_m", "mass_kg", "max_speed_mps", "start"}},
      {"controller", {"kp_per_s", "tolerance_px"}},
      {"camera", {"patch_px"}},
      {"task", {"episodes", "steps", "step_px"}},
      {"physics", {"dt_s", "velocity_iterations", "position_iterations", "max_ticks_per_move"}},
      {"motion", {"scale_sd", "heading_sd_deg", "pose", "slip_zones"}},
      {"pushes", {"probability", "impulse_ns", "within_ticks", "traction_s"}},
      {"obstacles", {"boxes", "discs", "shade", "random_boxes", "random_box_min_px", "random_box_max_px"}},
      {"team", {"robots"}},
      {"seed", {}}};
  const std::vector<char> kInterestingChars = {'[', ']', '{',  '}',  ':', '-', '#', '"', '\'', '&', '*', '!',
                                               '|', '>', '\t', '\n', ' ', '0', '9', '.', 'e',  '%', '@', '`'};
};

// The round trip below compares the fields tests/support/world_fields.hpp lists: they must be
// the schema's, all of them, in its order (the header holds them to the structs' members).
TEST(WorldFuzz, TheComparisonCoversEverySchemaField) {
  std::vector<std::string> schema;
  for (const FieldInfo& f : world_schema())
    schema.push_back(f.section.empty() ? std::string(f.name) : std::string(f.section) + "." + std::string(f.name));
  EXPECT_EQ(scout::testing::listed_world_fields(), schema);
}

TEST(WorldFuzz, EveryInputGivesAWorldOrAnInputError) {
  const std::string preset = read_text(std::string(SCOUT_SOURCE_DIR) + "/worlds/mnist.yaml");
  ASSERT_FALSE(preset.empty());
  Tally tally;
  ASSERT_TRUE(feed(preset, tally));
  // Every field away from its default at least once, for both kinds of floor, so that the round
  // trip meets each field with a value of its own whatever the fuzz below draws.
  ASSERT_TRUE(
      feed("floor: {dataset: \"odd ~ name: #x\", split: validation, index: 17, pixel_size_m: 0.3}\n"
           "robot: {radius_m: 0.7, mass_kg: 3.7, max_speed_mps: 1e-3, start: [5, 9]}\n"
           "controller: {kp_per_s: 12.5, tolerance_px: 0.1}\n"
           "camera: {patch_px: 9}\n"
           "task: {episodes: 7, steps: 3, step_px: 4}\n"
           "physics: {dt_s: 0.001, velocity_iterations: 6, position_iterations: 2, max_ticks_per_move: 999}\n"
           "motion: {scale_sd: 0.15, heading_sd_deg: 7.5, pose: odometry, slip_zones: [[0, 1, 2, 3, 0.25]]}\n"
           "pushes: {probability: 0.25, impulse_ns: 2.5, within_ticks: 4, traction_s: 0.3}\n"
           "obstacles: {boxes: [[1, 2, 3, 4], [20, 0, 1, 1]], discs: [[10.5, 7.25, 2]], shade: 200, random_boxes: 2,\n"
           "            random_box_min_px: 3, random_box_max_px: 5}\n"
           "seed: 18446744073709551615\n",
           tally));
  // A team needs random starts and a divisor of the episodes: beside the file above.
  ASSERT_TRUE(feed("task: {episodes: 6}\nteam: {robots: 3}\n", tally));
  // A composed floor writes its layout's fields.
  ASSERT_TRUE(
      feed("floor: {size_px: [100, 61], layout: cluttered, clutter: 7, clutter_px: 5, digits: 3}\n"
           "camera: {patch_px: 8, wide_px: 12, wide_scale: 3}\n",
           tally));
  ASSERT_TRUE(
      feed("floor: {image: a.png, pixel_size_m: 0.30000000000000004}\nphysics: {dt_s: 0.1}\n"
           "controller: {kp_per_s: 0.3333333333333333}\n",
           tally));

  Fuzzer fuzz(kSeed);
  int accepted_structured = 0;
  int accepted_mutants = 0;
  for (int i = 0; i < kCasesPerKind; ++i) {
    feed(fuzz.random_bytes(), tally);
    // Token soup and world-shaped maps share one kind: half each.
    if (i % 2 == 0) {
      feed(fuzz.token_soup(), tally);
    } else {
      accepted_structured += feed(fuzz.structured(), tally) ? 1 : 0;
    }
    feed(fuzz.deep_nesting(), tally);
    accepted_mutants += feed(fuzz.mutate(preset), tally) ? 1 : 0;
    if (::testing::Test::HasFailure()) break;  // one input's report is enough to act on
  }
  // Mild mutations (a truncated comment, a swapped line) keep a file valid: the accept path
  // must be exercised as well as the refusals.
  EXPECT_GT(accepted_mutants, kCasesPerKind / 50);
  EXPECT_LT(accepted_mutants, kCasesPerKind);
  EXPECT_GT(accepted_structured, kCasesPerKind / 200);
  std::string varied;
  for (const std::string& name : scout::testing::listed_world_fields()) {
    EXPECT_GT(tally.varied[name], 0) << name << " never differed from its default in an accepted world";
    varied += " " + name + "=" + std::to_string(tally.varied[name]);
  }
  std::printf("[ measured ] accepted worlds with a field away from its default:%s\n", varied.c_str());
  EXPECT_EQ(tally.unwritable_names, 0) << "accepted worlds naming a data set or PNG to_yaml cannot write back";
  RecordProperty("accepted_mutants", accepted_mutants);
  RecordProperty("accepted_structured", accepted_structured);
}

}  // namespace
}  // namespace scout::worlds
