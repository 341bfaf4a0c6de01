// World files: the shipped worlds, defaults, every kind of bad input and its exact message
// prefix, floor-size checks, path resolution and the to_yaml round trip.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "tests/support/temp_dir.hpp"
#include "tests/support/world_fields.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {
namespace {

namespace fs = std::filesystem;

const fs::path kSource = SCOUT_SOURCE_DIR;

using scout::testing::expect_same_world;  // every field but `file` and `lines`
using scout::testing::TempDir;

/// The message parse_world throws for `text`; fails the test if it accepts it.
std::string error_of(const std::string& text, const fs::path& origin = "w.yaml") {
  try {
    parse_world(text, origin);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "accepted:\n" << text;
  return {};
}

/// Asserts the exact "file:line: field:" prefix and the one-line rule.
void expect_error(const std::string& text, const std::string& prefix) {
  const std::string message = error_of(text);
  EXPECT_EQ(message.substr(0, prefix.size()), prefix) << "full message: " << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  EXPECT_EQ(message.find('\r'), std::string::npos) << message;
}

void expect_paper_preset(const World& w) {
  EXPECT_EQ(w.floor.split, Split::Test);
  EXPECT_FALSE(w.floor.index.has_value());
  EXPECT_TRUE(w.floor.image.empty());
  EXPECT_DOUBLE_EQ(w.floor.pixel_size_m, 0.1);
  EXPECT_DOUBLE_EQ(w.robot.radius_m, 0.25);
  EXPECT_DOUBLE_EQ(w.robot.mass_kg, 1.0);
  EXPECT_DOUBLE_EQ(w.robot.max_speed_mps, 2.0);
  EXPECT_FALSE(w.robot.start.has_value());
  EXPECT_DOUBLE_EQ(w.controller.kp_per_s, 60.0);
  EXPECT_DOUBLE_EQ(w.controller.tolerance_px, 0.05);
  EXPECT_EQ(w.camera.patch_px, 6);
  EXPECT_EQ(w.task.episodes, 4);
  EXPECT_EQ(w.task.steps, 5);
  EXPECT_EQ(w.task.step_px, 2);
  EXPECT_DOUBLE_EQ(w.physics.dt_s, 0.0166667);
  EXPECT_EQ(w.physics.velocity_iterations, 8);
  EXPECT_EQ(w.physics.position_iterations, 3);
  EXPECT_EQ(w.physics.max_ticks_per_move, 120);
  EXPECT_EQ(w.seed, 1u);
}

// --- The shipped worlds --------------------------------------------------------------------

TEST(WorldFile, ShippedMnistIsThePaperPreset) {
  const fs::path file = kSource / "worlds/mnist.yaml";
  const World w = load_world(file);
  EXPECT_EQ(w.file, file);
  EXPECT_EQ(w.floor.dataset, "mnist");
  expect_paper_preset(w);
  // Every section and field has its line, for later messages.
  for (const char* key : {"floor",
                          "floor.dataset",
                          "floor.split",
                          "floor.index",
                          "floor.pixel_size_m",
                          "robot",
                          "robot.radius_m",
                          "robot.mass_kg",
                          "robot.max_speed_mps",
                          "robot.start",
                          "controller",
                          "controller.kp_per_s",
                          "controller.tolerance_px",
                          "camera",
                          "camera.patch_px",
                          "task",
                          "task.episodes",
                          "task.steps",
                          "task.step_px",
                          "physics",
                          "physics.dt_s",
                          "physics.velocity_iterations",
                          "physics.position_iterations",
                          "physics.max_ticks_per_move",
                          "seed"}) {
    EXPECT_EQ(w.lines.count(key), 1u) << key;
  }
  EXPECT_EQ(w.lines.at("floor"), 2);
  EXPECT_EQ(w.lines.at("camera.patch_px"), 16);
  EXPECT_EQ(w.lines.at("seed"), 26);
}

TEST(WorldFile, ShippedFashionIsThePaperPresetOnFashionMnist) {
  const World w = load_world(kSource / "worlds/fashion.yaml");
  EXPECT_EQ(w.floor.dataset, "fashion-mnist");
  expect_paper_preset(w);
}

TEST(WorldFile, ShippedDigitFixedHasAFixedIndexAndStart) {
  const World w = load_world(kSource / "worlds/digit-fixed.yaml");
  EXPECT_EQ(w.floor.dataset, "mnist");
  EXPECT_EQ(w.floor.split, Split::Test);
  EXPECT_EQ(w.floor.index, 0);
  EXPECT_EQ(w.robot.start, std::make_pair(14, 14));
  EXPECT_EQ(w.seed, 7u);
  check_against_floor(w, 28, 28);  // the start and patch fit an MNIST floor
}

// --- Defaults ------------------------------------------------------------------------------

TEST(WorldFile, MissingSectionsTakeTheStructDefaults) {
  const World w = parse_world("seed: 3\n", "w.yaml");
  const World d;
  EXPECT_EQ(w.floor.dataset, "mnist");  // neither dataset nor image: the paper's floor
  EXPECT_EQ(w.floor.split, d.floor.split);
  EXPECT_EQ(w.floor.index, d.floor.index);
  EXPECT_TRUE(w.floor.image.empty());
  EXPECT_EQ(w.floor.pixel_size_m, d.floor.pixel_size_m);
  EXPECT_EQ(w.robot.radius_m, d.robot.radius_m);
  EXPECT_EQ(w.robot.start, d.robot.start);
  EXPECT_EQ(w.controller.kp_per_s, d.controller.kp_per_s);
  EXPECT_EQ(w.camera.patch_px, d.camera.patch_px);
  EXPECT_EQ(w.task.episodes, d.task.episodes);
  EXPECT_EQ(w.physics.dt_s, d.physics.dt_s);
  EXPECT_EQ(w.seed, 3u);
  EXPECT_EQ(w.lines.count("camera"), 0u);
}

TEST(WorldFile, MissingFieldsTakeTheDefaultsAndEmptySectionsAreAllowed) {
  const World w = parse_world("floor:\n  index: 12\ncamera:\ntask:\n  steps: 7\n", "w.yaml");
  const World d;
  EXPECT_EQ(w.floor.dataset, "mnist");
  EXPECT_EQ(w.floor.index, 12);
  EXPECT_EQ(w.camera.patch_px, d.camera.patch_px);
  EXPECT_EQ(w.task.steps, 7);
  EXPECT_EQ(w.task.episodes, d.task.episodes);
  EXPECT_EQ(w.seed, d.seed);
  EXPECT_EQ(w.lines.at("camera"), 3);
  EXPECT_EQ(w.lines.at("task.steps"), 5);
}

TEST(WorldFile, AcceptsBoundaryValuesAndFlowStyle) {
  const World w = parse_world(
      "floor: {pixel_size_m: 10, index: 2147483647, split: validation}\n"
      "robot: {radius_m: 10, mass_kg: 1e4, max_speed_mps: 1000, start: [0, 0]}\n"
      "controller: {kp_per_s: 1.99, tolerance_px: 0.499}\n"
      "camera: {patch_px: 64}\n"
      "task: {episodes: 1000, steps: 1, step_px: 512}\n"
      "physics: {dt_s: 1, velocity_iterations: 100, position_iterations: 1, max_ticks_per_move: 100000}\n"
      "seed: 18446744073709551615\n",
      "w.yaml");
  EXPECT_EQ(w.floor.split, Split::Validation);
  EXPECT_EQ(w.floor.index, std::numeric_limits<int>::max());
  EXPECT_EQ(w.robot.start, std::make_pair(0, 0));
  EXPECT_EQ(w.camera.patch_px, 64);
  EXPECT_EQ(w.task.episodes, 1000);
  EXPECT_EQ(w.physics.max_ticks_per_move, 100000);
  EXPECT_EQ(w.seed, std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(w.lines.at("camera.patch_px"), 4);
}

TEST(WorldFile, TheGainMayBeHighWhenTheTickIsShort) {
  const World w = parse_world("controller: {kp_per_s: 1e6}\nphysics: {dt_s: 1e-6}\n", "w.yaml");
  EXPECT_EQ(w.controller.kp_per_s, 1e6);
}

TEST(WorldFile, TheRobotMustBeHalfAPixelToAHundredPixelsInRadius) {
  EXPECT_EQ(parse_world("floor: {pixel_size_m: 0.002}\nrobot: {radius_m: 1e-3}\n", "w.yaml").robot.radius_m, 1e-3);
  expect_error("floor: {pixel_size_m: 0.1}\nrobot: {radius_m: 0.04}\n",
               "w.yaml:2: robot.radius_m: expected a radius of 0.5 to 100 pixels (0.05 to 10 m at pixel_size_m 0.1), "
               "got 0.04 m = 0.4 px");
  expect_error("floor:\n  pixel_size_m: 0.001\n", "w.yaml:2: robot.radius_m: expected a radius of 0.5 to 100 pixels");
}

TEST(WorldFile, ANulByteIsNamedWithItsLine) {
  expect_error(std::string("camera:\n  patch_px: 6\nseed: 1") + std::string(1, '\0') + "\n",
               "w.yaml:3: expected text, got a NUL byte");
}

// yaml-cpp's emitter would write such a name back as U+FFFD, so the manifest would name another
// folder: refused, with the byte's place and without quoting it.
TEST(WorldFile, ANameThatIsNotUtf8IsRefused) {
  expect_error("floor:\n  dataset: mnist\xE9\n",
               "w.yaml:2: floor.dataset: expected mnist, mnist-10k, fashion-mnist or a folder of IDX files in UTF-8 "
               "text, got a byte that is not a UTF-8 character at byte 6 of the value");
  expect_error("floor:\n  image: \xEF\xB7\x90.png\n",  // U+FDD0, a noncharacter
               "w.yaml:2: floor.image: expected a .png file in UTF-8 text, got a byte that is not a UTF-8 character at "
               "byte 1");
  // Characters beyond ASCII are names like any other.
  EXPECT_NE(parse_world("floor:\n  dataset: d\xC3\xADgitos\n", "w.yaml").floor.dataset.find("d\xC3\xADgitos"),
            std::string::npos);
}

TEST(WorldFile, AGainThatCannotSettleIsRefused) {
  // kp * dt = 2: the position error flips sign with the same size every tick.
  expect_error("controller: {kp_per_s: 120}\nphysics: {dt_s: 0.0166667}\n",
               "w.yaml:1: controller.kp_per_s: expected less than 2 / physics.dt_s");
  expect_error("physics:\n  dt_s: 0.1\n", "w.yaml:2: controller.kp_per_s: expected less than 2 / physics.dt_s");
}

TEST(WorldFile, SplitNames) {
  EXPECT_STREQ(to_string(Split::Train), "train");
  EXPECT_STREQ(to_string(Split::Validation), "validation");
  EXPECT_STREQ(to_string(Split::Test), "test");
}

// --- Bad input: one case each, with the exact "file:line: field:" prefix -------------------

struct BadCase {
  const char* name;
  const char* text;
  const char* prefix;
};

void PrintTo(const BadCase& bad, std::ostream* os) { *os << bad.name; }

class BadWorld : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadWorld, IsRefusedWithOneLineNamingFileLineAndField) { expect_error(GetParam().text, GetParam().prefix); }

const BadCase kBadCases[] = {
    {"UnknownTopLevelKey", "floor: {}\nrobott: {}\n",
     "w.yaml:2: robott: expected a section among floor, robot, controller, camera, task, physics, motion, pushes, "
     "obstacles, team, seed, got unknown key"},
    {"UnknownNestedKey", "robot:\n  radius_m: 1\n  radius: 1\n",
     "w.yaml:3: robot.radius: expected a key among radius_m, mass_kg, max_speed_mps, start, got unknown key "
     "\"radius\""},
    {"UnknownKeyInFlowMap", "task: {episodes: 4, goals: 2}\n", "w.yaml:1: task.goals: expected a key among episodes"},
    {"NonScalarKey", "camera:\n  [1, 2]: 3\n",
     "w.yaml:2: camera: expected keys among patch_px, wide_px, wide_scale, got a sequence"},
    {"DuplicateKey", "camera:\n  patch_px: 6\n  patch_px: 7\n",
     "w.yaml:3: camera.patch_px: expected each key once, got a second one (the first is on line 2)"},
    {"DuplicateSection", "seed: 1\ncamera: {}\nseed: 2\n", "w.yaml:3: seed: expected each section once"},
    {"StringForNumber", "robot:\n  mass_kg: heavy\n",
     "w.yaml:2: robot.mass_kg: expected a number in (0, 10000], got heavy"},
    {"QuotedNumber", "camera:\n  patch_px: \"6\"\n",
     "w.yaml:2: camera.patch_px: expected an integer in [1, 64], got the string \"6\""},
    {"TaggedNumber", "camera:\n  patch_px: !!str 6\n",
     "w.yaml:2: camera.patch_px: expected an integer in [1, 64], got a value tagged !!str"},
    {"MapForScalar", "camera:\n  patch_px: {a: 1}\n",
     "w.yaml:2: camera.patch_px: expected an integer in [1, 64], got a map"},
    {"SequenceForScalar", "physics:\n  dt_s: [0.1]\n",
     "w.yaml:2: physics.dt_s: expected a number in (0, 1], got a sequence of 1 element"},
    {"NothingForScalar", "physics:\n  dt_s:\n", "w.yaml:2: physics.dt_s: expected a number in (0, 1], got nothing"},
    {"ScalarForSection", "robot: fast\n",
     "w.yaml:1: robot: expected a map of radius_m, mass_kg, max_speed_mps, start, got fast"},
    {"FloatForInteger", "seed: 1\ncamera:\n  patch_px: 6.5\n",
     "w.yaml:3: camera.patch_px: expected an integer in [1, 64], got 6.5"},
    {"FloatWithZeroFractionForInteger", "task:\n  steps: 5.0\n",
     "w.yaml:2: task.steps: expected an integer in [1, 1000], got 5.0"},
    {"ExponentForInteger", "physics:\n  max_ticks_per_move: 1e3\n",
     "w.yaml:2: physics.max_ticks_per_move: expected an integer in [1, 100000], got 1e3"},
    {"HexForInteger", "camera:\n  patch_px: 0x10\n",
     "w.yaml:2: camera.patch_px: expected an integer in [1, 64], got 0x10"},
    {"PatchBelowRange", "camera:\n  patch_px: 0\n", "w.yaml:2: camera.patch_px: expected an integer in [1, 64], got 0"},
    {"PatchAboveRange", "camera:\n  patch_px: 65\n",
     "w.yaml:2: camera.patch_px: expected an integer in [1, 64], got 65"},
    {"EpisodesZero", "task:\n  episodes: 0\n", "w.yaml:2: task.episodes: expected an integer in [1, 1000], got 0"},
    {"EpisodesAboveRange", "task:\n  episodes: 1001\n",
     "w.yaml:2: task.episodes: expected an integer in [1, 1000], got 1001"},
    {"StepsZero", "task:\n  steps: 0\n", "w.yaml:2: task.steps: expected an integer in [1, 1000], got 0"},
    {"StepPxAboveRange", "task:\n  step_px: 513\n", "w.yaml:2: task.step_px: expected an integer in [1, 512], got 513"},
    {"NegativePatch", "camera:\n  patch_px: -6\n", "w.yaml:2: camera.patch_px: expected an integer in [1, 64], got -6"},
    {"NegativeRadius", "robot:\n  radius_m: -0.25\n",
     "w.yaml:2: robot.radius_m: expected a number in (0, 10], got -0.25"},
    {"NegativeZeroRadius", "robot:\n  radius_m: -0\n",
     "w.yaml:2: robot.radius_m: expected a number in (0, 10], got -0"},
    {"RadiusAboveRange", "robot:\n  radius_m: 10.5\n",
     "w.yaml:2: robot.radius_m: expected a number in (0, 10], got 10.5"},
    {"MassZero", "robot:\n  mass_kg: 0\n", "w.yaml:2: robot.mass_kg: expected a number in (0, 10000], got 0"},
    {"MassAboveRange", "robot:\n  mass_kg: 10001\n",
     "w.yaml:2: robot.mass_kg: expected a number in (0, 10000], got 10001"},
    {"SpeedAboveRange", "robot:\n  max_speed_mps: 1000.5\n",
     "w.yaml:2: robot.max_speed_mps: expected a number in (0, 1000], got 1000.5"},
    {"PixelSizeZero", "floor:\n  pixel_size_m: 0\n",
     "w.yaml:2: floor.pixel_size_m: expected a number in (0, 10], got 0"},
    {"PixelSizeAboveRange", "floor:\n  pixel_size_m: 11\n",
     "w.yaml:2: floor.pixel_size_m: expected a number in (0, 10], got 11"},
    {"GainZero", "controller:\n  kp_per_s: 0\n",
     "w.yaml:2: controller.kp_per_s: expected a number in (0, 1e+06], got 0"},
    {"GainAboveRange", "controller:\n  kp_per_s: 2e6\n",
     "w.yaml:2: controller.kp_per_s: expected a number in (0, 1e+06], got 2e6"},
    {"ToleranceZero", "controller:\n  tolerance_px: 0\n",
     "w.yaml:2: controller.tolerance_px: expected a number in (0, 0.5), got 0"},
    {"ToleranceHalfPixel", "controller:\n  tolerance_px: 0.5\n",
     "w.yaml:2: controller.tolerance_px: expected a number in (0, 0.5), got 0.5"},
    {"DtZero", "physics:\n  dt_s: 0\n", "w.yaml:2: physics.dt_s: expected a number in (0, 1], got 0"},
    {"DtAboveRange", "physics:\n  dt_s: 1.5\n", "w.yaml:2: physics.dt_s: expected a number in (0, 1], got 1.5"},
    {"DtInfinite", "physics:\n  dt_s: .inf\n", "w.yaml:2: physics.dt_s: expected a number in (0, 1], got .inf"},
    {"DtNan", "physics:\n  dt_s: .nan\n", "w.yaml:2: physics.dt_s: expected a number in (0, 1], got .nan"},
    {"DtOverflows", "physics:\n  dt_s: 1e400\n", "w.yaml:2: physics.dt_s: expected a number in (0, 1], got 1e400"},
    {"VelocityIterationsZero", "physics:\n  velocity_iterations: 0\n",
     "w.yaml:2: physics.velocity_iterations: expected an integer in [1, 100], got 0"},
    {"PositionIterationsAboveRange", "physics:\n  position_iterations: 101\n",
     "w.yaml:2: physics.position_iterations: expected an integer in [1, 100], got 101"},
    {"TicksZero", "physics:\n  max_ticks_per_move: 0\n",
     "w.yaml:2: physics.max_ticks_per_move: expected an integer in [1, 100000], got 0"},
    {"TicksAboveRange", "physics:\n  max_ticks_per_move: 100001\n",
     "w.yaml:2: physics.max_ticks_per_move: expected an integer in [1, 100000], got 100001"},
    {"NegativeSeed", "seed: -1\n", "w.yaml:1: seed: expected an unsigned integer in [0, 18446744073709551615], got -1"},
    {"SeedBeyond64Bits", "seed: 18446744073709551616\n",
     "w.yaml:1: seed: expected an unsigned integer in [0, 18446744073709551615], got 18446744073709551616"},
    {"FloatSeed", "seed: 1.5\n", "w.yaml:1: seed: expected an unsigned integer in [0, 18446744073709551615], got 1.5"},
    {"NegativeIndex", "floor:\n  index: -1\n",
     "w.yaml:2: floor.index: expected an integer in [0, 2147483647] or random, got -1"},
    {"IndexBeyondInt", "floor:\n  index: 2147483648\n",
     "w.yaml:2: floor.index: expected an integer in [0, 2147483647] or random, got 2147483648"},
    {"IndexWord", "floor:\n  index: any\n",
     "w.yaml:2: floor.index: expected an integer in [0, 2147483647] or random, got any"},
    {"BadSplit", "floor:\n  split: val\n", "w.yaml:2: floor.split: expected train, validation or test, got val"},
    {"EmptyDataset", "floor:\n  dataset: \"\"\n",
     "w.yaml:2: floor.dataset: expected mnist, mnist-10k, fashion-mnist or a folder of IDX files, got the string \"\""},
    {"StartWithThreeElements", "robot:\n  start: [1, 2, 3]\n",
     "w.yaml:2: robot.start: expected [x, y] (two non-negative integers, pixels) or random, got a sequence of 3 "
     "elements"},
    {"StartWithOneElement", "robot:\n  start: [1]\n",
     "w.yaml:2: robot.start: expected [x, y] (two non-negative integers, pixels) or random, got a sequence of 1 "
     "element"},
    {"StartNegative", "robot:\n  start:\n    - 3\n    - -1\n",
     "w.yaml:2: robot.start: expected [x, y] (two non-negative integers, pixels) or random, got y = -1"},
    {"StartFloat", "robot:\n  start: [1.5, 2]\n",
     "w.yaml:2: robot.start: expected [x, y] (two non-negative integers, pixels) or random, got x = 1.5"},
    {"StartScalar", "robot:\n  start: middle\n",
     "w.yaml:2: robot.start: expected [x, y] (two non-negative integers, pixels) or random, got middle"},
    {"DatasetAndImage", "floor:\n  dataset: mnist\n  image: floor.png\n",
     "w.yaml:3: floor.image: expected either floor.dataset or floor.image, got both"},
    {"ImageAndDataset", "floor:\n  image: floor.png\n  dataset: mnist\n",
     "w.yaml:3: floor.dataset: expected either floor.dataset or floor.image, got both"},
    {"SplitWithImage", "floor:\n  image: floor.png\n  split: test\n",
     "w.yaml:3: floor.split: expected no split with floor.image, got test"},
    {"IndexWithImage", "floor:\n  index: 3\n  image: floor.png\n",
     "w.yaml:2: floor.index: expected no index with floor.image, got 3"},
    {"ImageNotPng", "floor:\n  image: floor.jpg\n", "w.yaml:2: floor.image: expected a .png file, got floor.jpg"},
    {"ImageOnlyExtension", "floor:\n  image: .png\n", "w.yaml:2: floor.image: expected a .png file, got .png"},
    {"MotionPoseIsANameOfTwo", "motion:\n  pose: true\n",
     "w.yaml:2: motion.pose: expected localised or odometry, got true"},
    {"MotionScaleAboveAThird", "motion: {scale_sd: 0.35}\n",
     "w.yaml:1: motion.scale_sd: expected a number in [0, 0.3], got 0.35"},
    {"PushAfterTheMovesLastTick", "physics: {max_ticks_per_move: 8}\npushes: {probability: 0.5}\n",
     "w.yaml:1: pushes.within_ticks: expected at most physics.max_ticks_per_move = 8 (a push must come while the move "
     "lasts), got 10 (the default)"},
    {"PushProbabilityAboveOne", "pushes:\n  probability: 1.5\n",
     "w.yaml:2: pushes.probability: expected a number in [0, 1], got 1.5"},
    {"ObstacleBoxOfThree", "obstacles:\n  boxes: [[1, 2, 3]]\n",
     "w.yaml:2: obstacles.boxes: expected a list of at most 64 boxes [x, y, w, h] (integers, pixels: x, y >= 0, w, h "
     ">= 1), got box 1 = "},
    {"ObstacleBoxOfWidthZero", "obstacles:\n  boxes: [[1, 2, 0, 3]]\n",
     "w.yaml:2: obstacles.boxes: expected a list of at most 64 boxes [x, y, w, h] (integers, pixels: x, y >= 0, w, h "
     ">= 1), got box 1 w = 0"},
    {"ObstacleDiscNegativeRadius", "obstacles: {discs: [[4, 4, -1]]}\n",
     "w.yaml:1: obstacles.discs: expected a list of at most 64 discs [x, y, r] (numbers, pixels: x, y >= 0, r in (0, "
     "1000]), got disc 1 r = -1"},
    {"ObstacleBoxesNotAList", "obstacles: {boxes: 3}\n", "w.yaml:1: obstacles.boxes: expected a list of at most 64"},
    {"RandomBoxesShortestAboveLongest", "obstacles:\n  random_boxes: 2\n  random_box_min_px: 5\n",
     "w.yaml:3: obstacles.random_box_min_px: expected at most obstacles.random_box_max_px = 4, got 5"},
    {"SlipAboveNineTenths", "motion:\n  slip_zones: [[0, 0, 4, 4, 0.95]]\n",
     "w.yaml:2: motion.slip_zones: expected a list of at most 64 zones [x, y, w, h, slip] (pixels: integers x, y >= "
     "0, w, h >= 1; slip in [0, 0.9]), got zone 1 slip = 0.95"},
    {"TeamNotDividingTheEpisodes", "task: {episodes: 4}\nteam:\n  robots: 3\n",
     "w.yaml:3: team.robots: expected a divisor of task.episodes = 4 (each robot drives episodes / robots of the "
     "rollout's episodes), got 3"},
    {"TeamWithAFixedStart", "robot: {start: [3, 4]}\nteam: {robots: 2}\n",
     "w.yaml:1: robot.start: expected random when team.robots > 1 (each robot of the team draws its own start), got "
     "[3, 4]"},
    {"TeamTooLarge", "team: {robots: 9}\n", "w.yaml:1: team.robots: expected an integer in [1, 8], got 9"},
    {"RandomBoxesTooMany", "obstacles: {random_boxes: 65}\n",
     "w.yaml:1: obstacles.random_boxes: expected an integer in [0, 64], got 65"},
    {"PushWithinZeroTicks", "pushes:\n  within_ticks: 0\n",
     "w.yaml:2: pushes.within_ticks: expected an integer in [1, 100000], got 0"},
    {"SyntaxError", "floor:\n  dataset: mnist\nrobot: [1, 2\n", "w.yaml:4: YAML syntax error: "},
    {"SyntaxErrorBadIndent", "floor:\n  dataset: mnist\n    split: test\n", "w.yaml:3: YAML syntax error: "},
    {"EmptyText", "", "w.yaml:1: expected a map of sections (floor, robot, ...)"},
    {"OnlyComments", "# nothing here\n\n", "w.yaml:1: expected a map of sections (floor, robot, ...)"},
    {"SequenceTopLevel", "- floor\n- robot\n", "w.yaml:1: expected a map of sections (floor, robot, ...)"},
    {"ScalarTopLevel", "42\n", "w.yaml:1: expected a map of sections (floor, robot, ...)"},
    {"TwoDocuments", "seed: 1\n---\nseed: 2\n", "w.yaml:2: expected one YAML document, got more"},
    {"StrayCommaAfterTheMap", "seed: 1\n---\n,\n", "w.yaml:2: expected one YAML document, got more"},
    {"StrayCommaFirst", ",\nseed: 1\n", "w.yaml:1: expected a map of sections (floor, robot, ...)"},
    {"DeepFlowNesting", "seed: [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[\n",
     "w.yaml:1: expected nesting at most 64 levels deep, got deeper"},
    {"DeepCompactNesting",
     "seed:\n- - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - - "
     "- - - - - - - - - - - - - - - - - x\n",
     "w.yaml:2: expected nesting at most 64 levels deep, got deeper"},
    {"AliasOfAWrongKind", "a: &a [1, 2]\n", "w.yaml:1: a: expected a section among"},
    {"AliasedSectionWithWrongKeys", "robot: &r {radius_m: 1}\ncontroller: *r\n",
     // The shared node's keys are written on line 1: that is the line named.
     "w.yaml:1: controller.radius_m: expected a key among kp_per_s, tolerance_px"},
    {"CyclicAlias", "seed: &a [*a]\n",
     "w.yaml:1: seed: expected an unsigned integer in [0, 18446744073709551615], got a sequence of 1 element"},
    {"NewlineInValueIsEscaped", "floor:\n  split: \"te\\nst\"\n",
     "w.yaml:2: floor.split: expected train, validation or test, got the string \"te\\nst\""},
};

INSTANTIATE_TEST_SUITE_P(WorldFile, BadWorld, ::testing::ValuesIn(kBadCases),
                         [](const ::testing::TestParamInfo<BadCase>& bad) { return std::string(bad.param.name); });

TEST(WorldFile, DeepIndentationNestingIsRefused) {
  std::string text;
  for (int i = 0; i < 100; ++i) text += std::string(static_cast<std::size_t>(i), ' ') + "k" + std::to_string(i) + ":\n";
  expect_error(text, "w.yaml:65: expected nesting at most 64 levels deep, got deeper");
}

// A "billion laughs": nine levels of nine aliases name 9^9 (387 million) strings in a few hundred
// bytes. yaml-cpp shares aliased nodes and Scout describes a sequence by its length, never by
// walking it, so the refusal is immediate and small.
TEST(WorldFile, AliasBombIsRefusedWithoutExpanding) {
  std::string bomb = "seed: [&a [x, x, x, x, x, x, x, x, x]";
  for (char level = 'b'; level <= 'i'; ++level) {
    bomb += std::string(", &") + level + " [";
    for (int k = 0; k < 9; ++k) bomb += std::string(k ? ", *" : "*") + static_cast<char>(level - 1);
    bomb += "]";
  }
  bomb += "]\n";
  expect_error(
      bomb, "w.yaml:1: seed: expected an unsigned integer in [0, 18446744073709551615], got a sequence of 9 elements");
}

// A scalar of a megabyte less a little (the file limit) is refused and quoted clipped, not whole.
TEST(WorldFile, HugeScalarsAreRefusedWithAClippedQuote) {
  for (const std::string& scalar :
       {std::string(1000000, '9'), std::string(1000000, 'x'), "\"" + std::string(1000000, 'y') + "\""}) {
    const std::string message = error_of("seed: " + scalar + "\n");
    EXPECT_EQ(message.rfind("w.yaml:1: seed: expected an unsigned integer", 0), 0u) << message.substr(0, 200);
    EXPECT_LT(message.size(), 300u) << message.substr(0, 300);
  }
}

TEST(WorldFile, VeryDeepNestingIsRefusedWithoutCrashing) {
  expect_error("seed: " + std::string(200000, '['), "w.yaml:1: expected nesting at most 64 levels deep");
  expect_error("seed: " + std::string(200000, '{'), "w.yaml:1: expected nesting at most 64 levels deep");
}

TEST(WorldFile, TooLargeTextIsRefused) {
  const std::string text = "seed: 1\n" + std::string(std::size_t{1} << 20, '#');
  expect_error(text, "w.yaml: expected a world file of at most 1 MiB (1048576 bytes), got 1048584 bytes");
}

TEST(WorldFile, TooLargeFileIsRefusedWithoutReadingItAll) {
  try {
    load_world("/dev/zero");  // endless: the loader must stop reading past the cap
    FAIL() << "accepted /dev/zero";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/zero: expected a world file of at most 1 MiB (1048576 bytes), got more");
  }
}

TEST(WorldFile, BracketsInsideQuotesAndCommentsAreNotNesting) {
  const std::string many(100, '[');
  const World w =
      parse_world("floor:\n  dataset: \"" + many + "\"  # " + many + "\nrobot: {start: random}  # ]]]\n", "w.yaml");
  EXPECT_EQ(w.floor.dataset, fs::absolute(many).lexically_normal().string());
}

TEST(WorldFile, ErrorNamesThePathAsGiven) {
  const std::string message = error_of("camera: {patch_px: 0}\n", "some/dir/../x.yaml");
  EXPECT_EQ(message.rfind("some/dir/../x.yaml:1: camera.patch_px:", 0), 0u) << message;
}

TEST(WorldFile, NewlinesInThePathDoNotBreakTheLine) {
  const std::string message = error_of("seed: -1\n", "a\nb.yaml");
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  EXPECT_EQ(message.rfind("a\\nb.yaml:1: seed:", 0), 0u) << message;
}

// --- Files: missing, empty, directory --------------------------------------------------------

TEST(WorldFile, MissingFileIsRefused) {
  const TempDir dir;
  const fs::path file = dir.path() / "absent.yaml";
  try {
    load_world(file);
    FAIL() << "accepted a missing file";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), file.string() + ": cannot open world file");
  }
}

TEST(WorldFile, DirectoryIsRefusedAsUnopenable) {
  const TempDir dir;
  try {
    load_world(dir.path());
    FAIL() << "accepted a directory";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir.path().string() + ": cannot open world file");
  }
}

TEST(WorldFile, EmptyFileIsRefused) {
  const TempDir dir;
  const fs::path file = dir.write("empty.yaml", "");
  try {
    load_world(file);
    FAIL() << "accepted an empty file";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), file.string() + ":1: expected a map of sections (floor, robot, ...)");
  }
}

TEST(WorldFile, LoadReportsTheLineInTheFile) {
  const TempDir dir;
  const fs::path file = dir.write("bad.yaml", "# a comment\nfloor:\n  dataset: mnist\ncamera:\n  patch_px: 6.5\n");
  try {
    load_world(file);
    FAIL() << "accepted patch_px 6.5";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), file.string() + ":5: camera.patch_px: expected an integer in [1, 64], got 6.5");
  }
}

// --- Checks against the floor's size ---------------------------------------------------------

TEST(WorldFile, PatchLargerThanTheFloorNamesItsLine) {
  const World w = parse_world("seed: 1\ncamera:\n  patch_px: 40\n", "w.yaml");
  try {
    check_against_floor(w, 28, 28);
    FAIL() << "accepted a 40 px patch on a 28 px floor";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "w.yaml:3: camera.patch_px: expected an integer in [1, 28] (the floor is 28x28 pixels), got 40");
  }
  EXPECT_NO_THROW(check_against_floor(w, 40, 64));
}

TEST(WorldFile, DefaultPatchLargerThanATinyFloorIsRefused) {
  const World w = parse_world("seed: 1\n", "w.yaml");
  try {
    check_against_floor(w, 4, 4);
    FAIL() << "accepted a 6 px patch on a 4 px floor";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("w.yaml:1: camera.patch_px: expected an integer in [1, 4]", 0), 0u) << message;
    EXPECT_NE(message.find("(the default)"), std::string::npos) << message;
  }
}

TEST(WorldFile, StartOffTheFloorNamesItsLine) {
  const World w = parse_world("floor: {dataset: mnist}\nrobot:\n  radius_m: 0.25\n  start: [28, 3]\n", "w.yaml");
  try {
    check_against_floor(w, 28, 28);
    FAIL() << "accepted start x = 28 on a 28 px floor";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "w.yaml:4: robot.start: expected [x, y] with x in [0, 27] and y in [0, 27] (the floor is 28x28 pixels), "
              "got [28, 3]");
  }
  EXPECT_NO_THROW(check_against_floor(w, 29, 28));
  const World below = parse_world("robot:\n  start: [3, 40]\n", "w.yaml");
  EXPECT_THROW(check_against_floor(below, 28, 28), InputError);
  const World random = parse_world("robot: {start: random}\n", "w.yaml");
  EXPECT_NO_THROW(check_against_floor(random, 6, 6));
}

TEST(WorldFile, ObstaclesOffTheFloorOrOnTheStartNameTheirLine) {
  const World box = parse_world("obstacles:\n  boxes: [[2, 2, 3, 3], [25, 0, 4, 2]]\n", "w.yaml");
  try {
    check_against_floor(box, 28, 28);
    FAIL() << "accepted a box reaching x = 29 on a 28 px floor";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "w.yaml:2: obstacles.boxes: expected boxes within the floor (28x28 pixels: x + w <= 28, y + h <= 28), "
              "got box 2 = [25, 0, 4, 2]");
  }
  EXPECT_NO_THROW(check_against_floor(box, 29, 28));
  const World disc = parse_world("obstacles: {discs: [[14, 30.5, 1]]}\n", "w.yaml");
  EXPECT_THROW(check_against_floor(disc, 28, 28), InputError);
  // The default robot's radius is 2.5 px: a start 2 px from a box overlaps it.
  const World start = parse_world("robot: {start: [10, 10]}\nobstacles: {boxes: [[12, 10, 2, 2]]}\n", "w.yaml");
  try {
    check_against_floor(start, 28, 28);
    FAIL() << "accepted a start 1.5 px from a box";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "w.yaml:1: robot.start: expected a cell whose centre is at least the robot's radius (2.5 px) from every "
              "obstacle, got [10, 10], 1.5 px from one");
  }
  // Random boxes must fit on the floor.
  const World random = parse_world("obstacles:\n  random_boxes: 1\n  random_box_max_px: 8\n", "w.yaml");
  EXPECT_NO_THROW(check_against_floor(random, 8, 9));
  try {
    check_against_floor(random, 9, 7);
    FAIL() << "accepted 8 px boxes on a 7 px high floor";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "w.yaml:3: obstacles.random_box_max_px: expected at most the floor's smaller side, 7 (the floor is 9x7 "
              "pixels), got 8");
  }
  const World clear = parse_world("robot: {start: [5, 10]}\nobstacles: {boxes: [[12, 10, 2, 2]]}\n", "w.yaml");
  EXPECT_NO_THROW(check_against_floor(clear, 28, 28));
  EXPECT_DOUBLE_EQ(clear.obstacles.clearance_px(5.5, 10.5), 6.5);
  EXPECT_TRUE(clear.obstacles.covers(13.9, 11.9));
  EXPECT_FALSE(clear.obstacles.covers(14.1, 11.9));
}

// --- Paths -----------------------------------------------------------------------------------

TEST(WorldFile, RelativeDatasetAndImageResolveAgainstTheFile) {
  const TempDir dir;
  const fs::path a = dir.write("worlds/a.yaml", "floor:\n  dataset: ../data/digits\n");
  const fs::path b = dir.write("worlds/sub/b.yaml", "floor:\n  image: ./floors/../floor.PNG\n");
  const World wa = load_world(a);
  EXPECT_EQ(fs::path(wa.floor.dataset), (dir.path() / "data/digits").lexically_normal());
  EXPECT_TRUE(fs::path(wa.floor.dataset).is_absolute());
  const World wb = load_world(b);
  EXPECT_EQ(wb.floor.image, (dir.path() / "worlds/sub/floor.PNG").lexically_normal());
  EXPECT_TRUE(wb.floor.dataset.empty());
}

TEST(WorldFile, NamedDatasetsAndAbsolutePathsStayAsTheyAre) {
  EXPECT_EQ(parse_world("floor: {dataset: mnist}\n", "x/w.yaml").floor.dataset, "mnist");
  EXPECT_EQ(parse_world("floor: {dataset: fashion-mnist}\n", "x/w.yaml").floor.dataset, "fashion-mnist");
  EXPECT_EQ(parse_world("floor: {dataset: /srv/idx/}\n", "x/w.yaml").floor.dataset, "/srv/idx/");
  EXPECT_EQ(parse_world("floor: {image: /srv/a/../f.png}\n", "x/w.yaml").floor.image, fs::path("/srv/f.png"));
}

TEST(WorldFile, RelativeOriginResolvesAgainstTheWorkingDirectory) {
  const World w = parse_world("floor: {dataset: idx}\n", "x/w.yaml");
  EXPECT_EQ(fs::path(w.floor.dataset), (fs::current_path() / "x/idx").lexically_normal());
}

// --- to_yaml ---------------------------------------------------------------------------------

TEST(WorldFile, ToYamlRoundTripsTheShippedWorld) {
  const World w = load_world(kSource / "worlds/mnist.yaml");
  const std::string text = to_yaml(w);
  EXPECT_NE(text.find("index: random"), std::string::npos) << text;
  EXPECT_NE(text.find("start: random"), std::string::npos) << text;
  expect_same_world(parse_world(text, "elsewhere/round.yaml"), w);
}

TEST(WorldFile, ToYamlRoundTripsEveryFieldExactly) {
  const TempDir dir;
  const fs::path file =
      dir.write("w.yaml",
                "floor: {dataset: \"odd ~ name: #x\", split: validation, index: 17, pixel_size_m: 0.3}\n"
                "robot: {radius_m: 0.7, mass_kg: 3.7, max_speed_mps: 1e-3, start: [5, 9]}\n"
                "controller: {kp_per_s: 12.5, tolerance_px: 0.1}\n"
                "camera: {patch_px: 9}\n"
                "task: {episodes: 7, steps: 3, step_px: 4}\n"
                "physics: {dt_s: 0.001, velocity_iterations: 6, position_iterations: 2,"
                " max_ticks_per_move: 999}\n"
                "seed: 18446744073709551615\n");
  const World w = load_world(file);
  expect_same_world(parse_world(to_yaml(w), file), w);

  World exact = parse_world("floor: {image: f.png}\n", dir.path() / "w.yaml");
  exact.physics.dt_s = 1.0 / 60.0;  // not a short decimal: the text must carry every bit
  exact.controller.kp_per_s = 1.0 / 3.0;
  const World back = parse_world(to_yaml(exact), "anywhere.yaml");
  expect_same_world(back, exact);
  EXPECT_EQ(back.floor.image, dir.path() / "f.png");
}

// --- to_yaml's exact text: pinned, so that a change in how worlds are written is deliberate ---

// clang-format off
const char* const kMnistYaml = R"(floor:
  dataset: mnist
  split: test
  index: random
  pixel_size_m: 0.1
robot:
  radius_m: 0.25
  mass_kg: 1
  max_speed_mps: 2
  start: random
controller:
  kp_per_s: 60
  tolerance_px: 0.05
camera:
  patch_px: 6
task:
  episodes: 4
  steps: 5
  step_px: 2
physics:
  dt_s: 0.0166667
  velocity_iterations: 8
  position_iterations: 3
  max_ticks_per_move: 120
seed: 1
)";

const char* const kFashionYaml = R"(floor:
  dataset: fashion-mnist
  split: test
  index: random
  pixel_size_m: 0.1
robot:
  radius_m: 0.25
  mass_kg: 1
  max_speed_mps: 2
  start: random
controller:
  kp_per_s: 60
  tolerance_px: 0.05
camera:
  patch_px: 6
task:
  episodes: 4
  steps: 5
  step_px: 2
physics:
  dt_s: 0.0166667
  velocity_iterations: 8
  position_iterations: 3
  max_ticks_per_move: 120
seed: 1
)";

const char* const kDigitFixedYaml = R"(floor:
  dataset: mnist
  split: test
  index: 0
  pixel_size_m: 0.1
robot:
  radius_m: 0.25
  mass_kg: 1
  max_speed_mps: 2
  start: [14, 14]
controller:
  kp_per_s: 60
  tolerance_px: 0.05
camera:
  patch_px: 6
task:
  episodes: 4
  steps: 5
  step_px: 2
physics:
  dt_s: 0.016666666666666666
  velocity_iterations: 8
  position_iterations: 3
  max_ticks_per_move: 120
seed: 7
)";

const char* const kEveryFieldYaml = R"(floor:
  dataset: "/data/worlds/odd ~ name: #x"
  split: validation
  index: 17
  pixel_size_m: 0.3
robot:
  radius_m: 0.7
  mass_kg: 3.7
  max_speed_mps: 0.001
  start: [5, 9]
controller:
  kp_per_s: 12.5
  tolerance_px: 0.1
camera:
  patch_px: 9
task:
  episodes: 7
  steps: 3
  step_px: 4
physics:
  dt_s: 0.001
  velocity_iterations: 6
  position_iterations: 2
  max_ticks_per_move: 999
seed: 18446744073709551615
)";

const char* const kImageYaml = R"(floor:
  image: "/data/worlds/f.PNG"
  pixel_size_m: 0.02
robot:
  radius_m: 0.05
  mass_kg: 1
  max_speed_mps: 2
  start: random
controller:
  kp_per_s: 0.3333333333333333
  tolerance_px: 0.05
camera:
  patch_px: 6
task:
  episodes: 4
  steps: 5
  step_px: 2
physics:
  dt_s: 0.016666666666666666
  velocity_iterations: 8
  position_iterations: 3
  max_ticks_per_move: 120
seed: 0
)";

const char* const kDefaultYaml = R"(floor:
  dataset: mnist
  split: train
  index: random
  pixel_size_m: 0.1
robot:
  radius_m: 0.25
  mass_kg: 1
  max_speed_mps: 2
  start: random
controller:
  kp_per_s: 60
  tolerance_px: 0.05
camera:
  patch_px: 6
task:
  episodes: 4
  steps: 5
  step_px: 2
physics:
  dt_s: 0.016666666666666666
  velocity_iterations: 8
  position_iterations: 3
  max_ticks_per_move: 120
seed: 0
)";
// clang-format on

TEST(WorldFile, ToYamlTextOfTheShippedWorldsIsPinned) {
  EXPECT_EQ(to_yaml(load_world(kSource / "worlds/mnist.yaml")), kMnistYaml);
  EXPECT_EQ(to_yaml(load_world(kSource / "worlds/fashion.yaml")), kFashionYaml);
  EXPECT_EQ(to_yaml(load_world(kSource / "worlds/digit-fixed.yaml")), kDigitFixedYaml);
}

TEST(WorldFile, ToYamlTextOfEveryFieldSetIsPinned) {
  // An absolute origin: relative folders resolve without touching the disk, so the text is fixed.
  const World every = parse_world(
      "floor: {dataset: \"odd ~ name: #x\", split: validation, index: 17, pixel_size_m: 0.3}\n"
      "robot: {radius_m: 0.7, mass_kg: 3.7, max_speed_mps: 1e-3, start: [5, 9]}\n"
      "controller: {kp_per_s: 12.5, tolerance_px: 0.1}\n"
      "camera: {patch_px: 9}\n"
      "task: {episodes: 7, steps: 3, step_px: 4}\n"
      "physics: {dt_s: 0.001, velocity_iterations: 6, position_iterations: 2, max_ticks_per_move: 999}\n"
      "seed: 18446744073709551615\n",
      "/data/worlds/w.yaml");
  EXPECT_EQ(to_yaml(every), kEveryFieldYaml);
  expect_same_world(parse_world(kEveryFieldYaml, "/elsewhere/w.yaml"), every);

  World image =
      parse_world("floor: {image: f.PNG, pixel_size_m: 0.02}\nrobot: {radius_m: 0.05}\n", "/data/worlds/w.yaml");
  image.physics.dt_s = 1.0 / 60.0;  // not short decimals: every digit goes out
  image.controller.kp_per_s = 1.0 / 3.0;
  EXPECT_EQ(to_yaml(image), kImageYaml);
  expect_same_world(parse_world(kImageYaml, "/elsewhere/w.yaml"), image);

  EXPECT_EQ(to_yaml(World{}), kDefaultYaml);
}

// The scenario sections: written after physics when they differ from their defaults (a world
// that does not use them keeps the text above), every field of the section then.
TEST(WorldFile, ToYamlWritesAScenarioSectionOnlyWhenItIsUsed) {
  const World motion = parse_world("motion: {heading_sd_deg: 7.5}\n", "/data/worlds/w.yaml");
  const std::string text = to_yaml(motion);
  EXPECT_NE(text.find("physics:"), std::string::npos);
  EXPECT_NE(
      text.find("\nmotion:\n  scale_sd: 0\n  heading_sd_deg: 7.5\n  pose: localised\n  slip_zones: []\nseed: 0\n"),
      std::string::npos)
      << text;
  EXPECT_EQ(text.find("pushes:"), std::string::npos) << text;
  expect_same_world(parse_world(text, "/elsewhere/w.yaml"), motion);

  const World pushes = parse_world("pushes: {within_ticks: 3}\nmotion: {pose: localised}\n", "/data/worlds/w.yaml");
  const std::string pushed = to_yaml(pushes);
  EXPECT_EQ(pushed.find("motion:"), std::string::npos) << "motion at its defaults is not written";
  EXPECT_NE(pushed.find("\npushes:\n  probability: 0\n  impulse_ns: 1\n  within_ticks: 3\n  traction_s: 0.1\n"),
            std::string::npos)
      << pushed;
  expect_same_world(parse_world(pushed, "/elsewhere/w.yaml"), pushes);
}

// --- The schema: the code's table, its messages and worlds/README.md agree ------------------

/// The cells of a Markdown table row, trimmed ("\|" is a '|' inside a cell).
std::vector<std::string> cells_of(const std::string& row) {
  std::vector<std::string> cells;
  std::string cell;
  for (std::size_t i = 1; i < row.size(); ++i) {  // past the leading '|'
    if (row[i] == '\\' && i + 1 < row.size() && row[i + 1] == '|') {
      cell += '|';
      ++i;
    } else if (row[i] == '|') {
      const auto first = cell.find_first_not_of(' ');
      const auto last = cell.find_last_not_of(' ');
      cells.push_back(first == std::string::npos ? std::string() : cell.substr(first, last - first + 1));
      cell.clear();
    } else {
      cell += row[i];
    }
  }
  return cells;
}

/// A schema row as the README writes it: names and defaults as code, "—" for nothing.
std::vector<std::string> readme_cells(const FieldInfo& f) {
  const auto text = [](std::string_view s) { return s.empty() ? std::string("—") : std::string(s); };
  const auto code = [](std::string_view s) { return s.empty() ? std::string("—") : "`" + std::string(s) + "`"; };
  return {text(f.section),    code(f.name), text(f.type), code(f.default_text),
          text(f.range_text), text(f.doc),  text(f.unit)};
}

/// The body rows of the first table under "## Schema" in worlds/README.md.
std::vector<std::string> readme_schema_rows() {
  std::ifstream in(kSource / "worlds/README.md");
  EXPECT_TRUE(in) << "cannot read worlds/README.md";
  std::vector<std::string> rows;
  bool in_schema = false;
  bool in_table = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("## ", 0) == 0) {
      if (in_schema) break;
      in_schema = line == "## Schema";
    } else if (in_schema && line.rfind("|", 0) == 0) {
      if (!in_table) {
        in_table = true;  // the header row; the rule follows
        std::getline(in, line);
      } else {
        rows.push_back(line);
      }
    } else if (in_table) {
      break;
    }
  }
  return rows;
}

TEST(WorldFile, TheReadmeSchemaTableIsTheCodesTable) {
  const std::vector<std::string> columns = {"section", "field", "type", "default", "range", "meaning", "unit"};
  std::string table = "| section | field | type | default | range | meaning | unit |\n|---|---|---|---|---|---|---|\n";
  for (const FieldInfo& f : world_schema()) {
    table += "|";
    for (const std::string& cell : readme_cells(f)) table += " " + cell + " |";
    table += "\n";
  }
  const std::vector<std::string> rows = readme_schema_rows();
  EXPECT_EQ(rows.size(), world_schema().size());
  for (std::size_t i = 0; i < std::min(rows.size(), world_schema().size()); ++i) {
    const FieldInfo& f = world_schema()[i];
    const std::vector<std::string> expected = readme_cells(f);
    const std::vector<std::string> actual = cells_of(rows[i]);
    ASSERT_EQ(actual.size(), expected.size()) << "README row " << i + 1 << ": " << rows[i];
    for (std::size_t c = 0; c < expected.size(); ++c) {
      EXPECT_EQ(actual[c], expected[c]) << "README row " << i + 1 << " (" << f.section << " " << f.name << "), column "
                                        << columns[c];
    }
  }
  if (HasFailure()) ADD_FAILURE() << "worlds/README.md's schema table should read:\n" << table;
}

TEST(WorldFile, TheSchemaListsTheKeysTheLoaderTakesInFileOrder) {
  std::map<std::string, std::string> keys;  // section -> "a, b, c"
  std::vector<std::string> top;             // sections, then top-level fields
  for (const FieldInfo& f : world_schema()) {
    const std::string section(f.section);
    if (section.empty()) {
      top.emplace_back(f.name);
      continue;
    }
    if (keys.count(section) == 0) top.push_back(section);
    keys[section] += (keys[section].empty() ? "" : ", ") + std::string(f.name);
  }
  for (const auto& [section, names] : keys) {
    expect_error(section + ":\n  no_such_key: 1\n",
                 "w.yaml:2: " + section + ".no_such_key: expected a key among " + names + ", got unknown key");
  }
  std::string sections;
  for (const std::string& name : top) sections += (sections.empty() ? "" : ", ") + name;
  expect_error("no_such_key: 1\n", "w.yaml:1: no_such_key: expected a section among " + sections + ", got");

  // to_yaml writes the fields in the schema's order (a default world has no image; the scenario
  // sections are written when they differ from their defaults, and the floor's layout when the
  // floor is composed, as here).
  std::string order;
  for (const FieldInfo& f : world_schema()) {
    if (f.name != "image") order += std::string(f.section.empty() ? "" : "  ") + std::string(f.name) + ":";
  }
  World scenario;
  scenario.floor.size_px = FloorSize{40, 40};
  scenario.floor.layout = FloorLayout::Cluttered;
  scenario.floor.clutter = 3;
  scenario.camera.wide_px = 5;
  scenario.motion.pose = PoseSource::Odometry;
  scenario.pushes.probability = 0.5;
  scenario.obstacles.shade = 7;
  scenario.team.robots = 2;
  std::string written;
  std::istringstream yaml(to_yaml(scenario));
  for (std::string line; std::getline(yaml, line);) {
    if (line.find(": ") != std::string::npos) written += line.substr(0, line.find(':') + 1);
  }
  EXPECT_EQ(written, order);
}

TEST(WorldFile, EachSchemaDefaultReadsBackAsTheDefault) {
  const World defaults = parse_world("seed: 0\n", "w.yaml");
  for (const FieldInfo& f : world_schema()) {
    if (f.default_text.empty()) continue;  // floor.image: no default
    const std::string text =
        f.section.empty() ? std::string(f.name) + ": " + f.default_text + "\n"
                          : std::string(f.section) + ":\n  " + std::string(f.name) + ": " + f.default_text + "\n";
    SCOPED_TRACE(text);
    expect_same_world(parse_world(text, "w.yaml"), defaults);
  }
}

TEST(WorldFile, RangeMessagesQuoteTheSchemasRanges) {
  for (const FieldInfo& f : world_schema()) {
    const std::string article = f.type == "integer"            ? "an integer in "
                                : f.type == "number"           ? "a number in "
                                : f.type == "unsigned integer" ? "an unsigned integer in "
                                                               : "";
    if (article.empty()) continue;  // the special fields word their own messages
    const std::string interval = f.range_text.substr(0, f.range_text.find_first_of(")]") + 1);
    const bool top = f.section.empty();
    const std::string dotted = top ? std::string(f.name) : std::string(f.section) + "." + std::string(f.name);
    const std::string text =
        top ? std::string(f.name) + ": word\n" : std::string(f.section) + ":\n  " + std::string(f.name) + ": word\n";
    expect_error(text, "w.yaml:" + std::string(top ? "1" : "2") + ": " + dotted + ": expected " + article + interval +
                           ", got word");
  }
}

}  // namespace
}  // namespace scout::worlds
