// Deterministic fuzzing of parse_world: random bytes, YAML-ish token soup, deep nesting and
// mutations of the shipped world. Every input must give a World that satisfies every range, or a
// one-line scout::InputError; any other exception (or a crash) is a bug.
#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {
namespace {

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

/// Feeds one input; returns whether it was accepted. Anything but World or InputError fails.
bool feed(const std::string& text) {
  try {
    const World w = parse_world(text, "fuzz.yaml");
    expect_valid(w, text);
    // What was accepted must also survive the manifest round trip and the floor check.
    const World back = parse_world(to_yaml(w), "fuzz.yaml");
    EXPECT_EQ(back.camera.patch_px, w.camera.patch_px);
    EXPECT_EQ(back.physics.dt_s, w.physics.dt_s);
    EXPECT_EQ(back.seed, w.seed);
    EXPECT_EQ(back.robot.start, w.robot.start);
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
      {"seed", {}}};
  const std::vector<char> kInterestingChars = {'[', ']', '{',  '}',  ':', '-', '#', '"', '\'', '&', '*', '!',
                                               '|', '>', '\t', '\n', ' ', '0', '9', '.', 'e',  '%', '@', '`'};
};

TEST(WorldFuzz, EveryInputGivesAWorldOrAnInputError) {
  const std::string preset = read_text(std::string(SCOUT_SOURCE_DIR) + "/worlds/mnist.yaml");
  ASSERT_FALSE(preset.empty());
  ASSERT_TRUE(feed(preset));

  Fuzzer fuzz(kSeed);
  int accepted_structured = 0;
  int accepted_mutants = 0;
  for (int i = 0; i < kCasesPerKind; ++i) {
    feed(fuzz.random_bytes());
    // Token soup and world-shaped maps share one kind: half each.
    if (i % 2 == 0) {
      feed(fuzz.token_soup());
    } else {
      accepted_structured += feed(fuzz.structured()) ? 1 : 0;
    }
    feed(fuzz.deep_nesting());
    accepted_mutants += feed(fuzz.mutate(preset)) ? 1 : 0;
    if (::testing::Test::HasFailure()) break;  // one input's report is enough to act on
  }
  // Mild mutations (a truncated comment, a swapped line) keep a file valid: the accept path
  // must be exercised as well as the refusals.
  EXPECT_GT(accepted_mutants, kCasesPerKind / 50);
  EXPECT_LT(accepted_mutants, kCasesPerKind);
  EXPECT_GT(accepted_structured, kCasesPerKind / 200);
  RecordProperty("accepted_mutants", accepted_mutants);
  RecordProperty("accepted_structured", accepted_structured);
}

}  // namespace
}  // namespace scout::worlds
