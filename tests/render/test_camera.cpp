// The GL patch camera against the CPU crop, bit for bit, and its sub-pixel capture_at against the
// bilinear CPU reference, on real Mesa: ctest runs these once per back end this build has
// (SCOUT_CAMERA_BACKEND=osmesa, then egl; tests/render/CMakeLists.txt).
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/worker_pool.hpp"
#include "render/camera.hpp"

namespace scout::render {
namespace {

struct Floors {
  int width = 0;
  int height = 0;
  int count = 0;
  std::vector<std::uint8_t> bytes;  // count images, each width * height, row-major
  const std::uint8_t* image(int i) const { return bytes.data() + static_cast<std::size_t>(i) * width * height; }
};

// Random bytes over the whole 0..255 range, a different floor per robot.
Floors random_floors(int width, int height, int count, unsigned seed) {
  Floors floors{width, height, count, {}};
  floors.bytes.resize(static_cast<std::size_t>(width) * height * count);
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  for (std::uint8_t& value : floors.bytes) value = static_cast<std::uint8_t>(byte(random));
  return floors;
}

// The CPU reference's patches, robot i over floor i at where[i]: crop_patch at grid poses,
// sample_patch_bilinear at continuous centres.
template <class Where>
std::vector<std::uint8_t> cpu_patches(const Floors& floors, int patch_px, const std::vector<Where>& where) {
  const std::size_t patch_bytes = static_cast<std::size_t>(patch_px) * patch_px;
  std::vector<std::uint8_t> patches(where.size() * patch_bytes);
  for (std::size_t i = 0; i < where.size(); ++i) {
    const std::uint8_t* floor = floors.image(static_cast<int>(i));
    if constexpr (std::is_same_v<Where, PixelPose>) {
      crop_patch(floor, floors.width, floors.height, patch_px, where[i], patches.data() + i * patch_bytes);
    } else {
      sample_patch_bilinear(floor, floors.width, floors.height, patch_px, where[i], patches.data() + i * patch_bytes);
    }
  }
  return patches;
}

std::vector<std::uint8_t> gl_patches(PatchCamera& camera, const std::vector<PixelPose>& poses) {
  std::vector<std::uint8_t> patches(poses.size() * camera.patch_px() * camera.patch_px(), 0xAB);
  camera.capture(poses, patches);
  return patches;
}

// Every grid pose of a floor, row after row: all borders and corners included.
std::vector<PixelPose> every_pose(int width, int height) {
  std::vector<PixelPose> poses;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) poses.push_back({x, y});
  }
  return poses;
}

std::vector<PixelPose> random_poses(int count, int width, int height, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> x(0, width - 1);
  std::uniform_int_distribution<int> y(0, height - 1);
  std::vector<PixelPose> poses(static_cast<std::size_t>(count));
  for (PixelPose& pose : poses) pose = {x(random), y(random)};
  return poses;
}

std::vector<std::uint8_t> gl_patches_at(PatchCamera& camera, const std::vector<FloorPoint>& centres) {
  std::vector<std::uint8_t> patches(centres.size() * camera.patch_px() * camera.patch_px(), 0xAB);
  camera.capture_at(centres, patches);
  return patches;
}

// The continuous centres of the cells at `poses`.
std::vector<FloorPoint> cell_centres(const std::vector<PixelPose>& poses) {
  std::vector<FloorPoint> centres;
  for (const PixelPose& pose : poses)
    centres.push_back({static_cast<float>(pose.x) + 0.5f, static_cast<float>(pose.y) + 0.5f});
  return centres;
}

// Uniform centres over the floor and `margin` px beyond each side, so that windows hang off
// every edge and corner and some lie wholly off the floor.
std::vector<FloorPoint> random_centres(int count, int width, int height, float margin, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> x(-margin, static_cast<float>(width) + margin);
  std::uniform_real_distribution<float> y(-margin, static_cast<float>(height) + margin);
  std::vector<FloorPoint> centres(static_cast<std::size_t>(count));
  for (FloorPoint& centre : centres) centre = {x(random), y(random)};
  return centres;
}

// The largest difference between two sets of patches, in grey levels, and how many bytes differ.
struct Difference {
  int largest = 0;
  std::size_t differing = 0;
  std::size_t first = 0;  // the first byte that differs by `largest`
};

Difference difference(const std::vector<std::uint8_t>& expected, const std::vector<std::uint8_t>& actual) {
  Difference d;
  for (std::size_t i = 0; i < expected.size() && i < actual.size(); ++i) {
    const int delta = std::abs(int{expected[i]} - int{actual[i]});
    if (delta > 0) ++d.differing;
    if (delta > d.largest) {
      d.largest = delta;
      d.first = i;
    }
  }
  return d;
}

// Reports the first differing robot and pixel, not a wall of bytes.
::testing::AssertionResult same_patches(const std::vector<std::uint8_t>& expected,
                                        const std::vector<std::uint8_t>& actual, int patch_px,
                                        const std::vector<PixelPose>& poses) {
  if (expected.size() != actual.size()) {
    return ::testing::AssertionFailure() << "sizes differ: " << expected.size() << " vs " << actual.size();
  }
  const std::size_t patch_bytes = static_cast<std::size_t>(patch_px) * patch_px;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    if (expected[i] != actual[i]) {
      const std::size_t robot = i / patch_bytes;
      const std::size_t pixel = i % patch_bytes;
      return ::testing::AssertionFailure()
             << "robot " << robot << " at pose (" << poses[robot].x << ", " << poses[robot].y << "), m = " << patch_px
             << ", patch row " << pixel / patch_px << " column " << pixel % patch_px << ": expected "
             << int{expected[i]} << ", got " << int{actual[i]};
    }
  }
  return ::testing::AssertionSuccess();
}

TEST(CropPatch, WindowFollowsTheMethodConvention) {
  // 6 x 4 floor with value 10 * y + x, so each pixel names its own coordinates.
  const int width = 6;
  const int height = 4;
  std::vector<std::uint8_t> floor(width * height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) floor[y * width + x] = static_cast<std::uint8_t>(10 * y + x);
  }
  // m = 4 at (2, 1): columns 0..3, rows -1..2; row 0 of the patch is off the floor (y = -1).
  std::vector<std::uint8_t> patch(16, 0xFF);
  crop_patch(floor.data(), width, height, 4, {2, 1}, patch.data());
  const std::vector<std::uint8_t> expected = {0,  0,  0,  0,    // y = -1
                                              0,  1,  2,  3,    // y = 0
                                              10, 11, 12, 13,   // y = 1
                                              20, 21, 22, 23};  // y = 2
  EXPECT_EQ(patch, expected);

  // m = 3 at the bottom-right corner (5, 3): columns 4..6, rows 2..4.
  std::vector<std::uint8_t> corner(9, 0xFF);
  crop_patch(floor.data(), width, height, 3, {5, 3}, corner.data());
  const std::vector<std::uint8_t> expected_corner = {24, 25, 0, 34, 35, 0, 0, 0, 0};
  EXPECT_EQ(corner, expected_corner);
}

TEST(PatchCamera, EveryPoseOfA28x28FloorMatchesTheCpuCropForEveryPatchSize) {
  const int n = 28;
  const std::vector<PixelPose> poses = every_pose(n, n);
  const int robots = static_cast<int>(poses.size());
  for (int m : {1, 2, 3, 5, 6, 7, 28}) {
    SCOPED_TRACE("m = " + std::to_string(m));
    const Floors floors = random_floors(n, n, robots, 100u + static_cast<unsigned>(m));
    PatchCamera camera(n, n, m, robots);
    camera.load_floors(floors.bytes, robots);
    EXPECT_TRUE(same_patches(cpu_patches(floors, m, poses), gl_patches(camera, poses), m, poses));
  }
}

TEST(PatchCamera, BatchesOf1And7And240RobotsMatchTheCpuCrop) {
  const int n = 28;
  const int m = 6;
  PatchCamera camera(n, n, m, 240);
  for (int batch : {1, 7, 240}) {
    SCOPED_TRACE("batch = " + std::to_string(batch));
    const unsigned seed = 7u * static_cast<unsigned>(batch);
    const Floors floors = random_floors(n, n, batch, seed);
    const std::vector<PixelPose> poses = random_poses(batch, n, n, seed + 1);
    camera.load_floors(floors.bytes, batch);
    EXPECT_TRUE(same_patches(cpu_patches(floors, m, poses), gl_patches(camera, poses), m, poses));
  }
}

TEST(PatchCamera, FewerPosesThanFloorsLoaded) {
  const int n = 28;
  const int m = 5;
  const Floors floors = random_floors(n, n, 240, 11);
  PatchCamera camera(n, n, m, 240);
  camera.load_floors(floors.bytes, 240);
  for (int batch : {1, 13, 239}) {
    const std::vector<PixelPose> poses = random_poses(batch, n, n, 12u + static_cast<unsigned>(batch));
    EXPECT_TRUE(same_patches(cpu_patches(floors, m, poses), gl_patches(camera, poses), m, poses));
  }
}

TEST(PatchCamera, NonSquareFloorMatchesTheCpuCropAtEveryPose) {
  const int width = 40;
  const int height = 24;
  const std::vector<PixelPose> poses = every_pose(width, height);
  const int robots = static_cast<int>(poses.size());
  for (int m : {2, 3, 6}) {
    SCOPED_TRACE("m = " + std::to_string(m));
    const Floors floors = random_floors(width, height, robots, 300u + static_cast<unsigned>(m));
    PatchCamera camera(width, height, m, robots);
    camera.load_floors(floors.bytes, robots);
    EXPECT_TRUE(same_patches(cpu_patches(floors, m, poses), gl_patches(camera, poses), m, poses));
  }
}

TEST(PatchCamera, PosesOffTheFloorGiveZerosLikeTheCpuCrop) {
  const int n = 28;
  const int m = 6;
  const std::vector<PixelPose> poses = {{-1, -1},    {-3, 5},      {30, 10},     {27, 30},          {-4, -4},
                                        {100, -100}, {INT_MAX, 0}, {0, INT_MIN}, {INT_MIN, INT_MAX}};
  const int robots = static_cast<int>(poses.size());
  const Floors floors = random_floors(n, n, robots, 21);
  PatchCamera camera(n, n, m, robots);
  camera.load_floors(floors.bytes, robots);
  const std::vector<std::uint8_t> expected = cpu_patches(floors, m, poses);
  EXPECT_TRUE(same_patches(expected, gl_patches(camera, poses), m, poses));
  // The far-away poses see nothing at all; (-1, -1) (window -4 .. 1) still sees floor (1, 1)
  // in its bottom-right corner.
  for (std::size_t i = 4; i < poses.size(); ++i) {
    for (int p = 0; p < m * m; ++p) EXPECT_EQ(expected[i * m * m + p], 0) << "robot " << i;
  }
  EXPECT_EQ(expected[5 * m + 5], floors.image(0)[1 * n + 1]);
}

TEST(PatchCamera, ASingleBrightPixelAppearsWhereTheWindowPutsIt) {
  // A non-square floor, so that swapping x and y or flipping rows cannot go unnoticed.
  const int width = 40;
  const int height = 24;
  const int m = 5;  // window columns x-2 .. x+2
  const int bright_x = 31;
  const int bright_y = 4;
  std::vector<std::uint8_t> floor(static_cast<std::size_t>(width) * height, 0);
  floor[bright_y * width + bright_x] = 200;
  // Robot 0 centred on the pixel, robot 1 with the pixel in its top-right corner, robot 2 with it
  // in its bottom-left corner, robot 3 with it just outside (one column too far left).
  const std::vector<PixelPose> poses = {
      {bright_x, bright_y}, {bright_x - 2, bright_y + 2}, {bright_x + 2, bright_y - 2}, {bright_x + 3, bright_y}};
  const std::vector<std::pair<int, int>> expected_row_column = {{2, 2}, {0, 4}, {4, 0}, {-1, -1}};
  std::vector<std::uint8_t> all_floors;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    all_floors.insert(all_floors.end(), floor.begin(), floor.end());
  }
  PatchCamera camera(width, height, m, 4);
  camera.load_floors(all_floors, 4);
  std::vector<std::uint8_t> patches(4 * m * m, 0xAB);
  camera.capture(poses, patches);
  for (std::size_t robot = 0; robot < poses.size(); ++robot) {
    std::vector<std::uint8_t> cpu(m * m, 0xAB);
    crop_patch(floor.data(), width, height, m, poses[robot], cpu.data());
    for (int row = 0; row < m; ++row) {
      for (int column = 0; column < m; ++column) {
        const bool bright = expected_row_column[robot] == std::make_pair(row, column);
        const int expected = bright ? 200 : 0;
        EXPECT_EQ(patches[robot * m * m + row * m + column], expected)
            << "GL: robot " << robot << " row " << row << " column " << column;
        EXPECT_EQ(cpu[row * m + column], expected) << "CPU: robot " << robot << " row " << row << " column " << column;
      }
    }
  }
}

TEST(PatchCamera, LoadingNewFloorsChangesWhatIsSeen) {
  const int n = 28;
  const int m = 6;
  const std::vector<PixelPose> poses = random_poses(50, n, n, 31);
  PatchCamera camera(n, n, m, 64);
  const Floors first = random_floors(n, n, 64, 32);
  camera.load_floors(first.bytes, 64);
  EXPECT_TRUE(same_patches(cpu_patches(first, m, poses), gl_patches(camera, poses), m, poses));
  // A smaller second batch: the first 50 layers are replaced.
  const Floors second = random_floors(n, n, 50, 33);
  camera.load_floors(second.bytes, 50);
  EXPECT_TRUE(same_patches(cpu_patches(second, m, poses), gl_patches(camera, poses), m, poses));
  EXPECT_NE(cpu_patches(first, m, poses), cpu_patches(second, m, poses));
}

TEST(PatchCamera, TwoCamerasAliveAtOnceStayIndependent) {
  const Floors floors_a = random_floors(28, 28, 10, 41);
  const Floors floors_b = random_floors(40, 24, 5, 42);
  const std::vector<PixelPose> poses_a = random_poses(10, 28, 28, 43);
  const std::vector<PixelPose> poses_b = random_poses(5, 40, 24, 44);
  PatchCamera a(28, 28, 6, 10);
  PatchCamera b(40, 24, 3, 5);
  a.load_floors(floors_a.bytes, 10);
  b.load_floors(floors_b.bytes, 5);
  // Interleaved, so each call must switch to its own context.
  EXPECT_TRUE(same_patches(cpu_patches(floors_a, 6, poses_a), gl_patches(a, poses_a), 6, poses_a));
  EXPECT_TRUE(same_patches(cpu_patches(floors_b, 3, poses_b), gl_patches(b, poses_b), 3, poses_b));
  EXPECT_TRUE(same_patches(cpu_patches(floors_a, 6, poses_a), gl_patches(a, poses_a), 6, poses_a));
  {
    // A third camera created and destroyed in between leaves the others working.
    PatchCamera c(8, 8, 2, 1);
    const Floors floors_c = random_floors(8, 8, 1, 45);
    c.load_floors(floors_c.bytes, 1);
    const std::vector<PixelPose> pose_c = {{3, 4}};
    EXPECT_TRUE(same_patches(cpu_patches(floors_c, 2, pose_c), gl_patches(c, pose_c), 2, pose_c));
  }
  EXPECT_TRUE(same_patches(cpu_patches(floors_b, 3, poses_b), gl_patches(b, poses_b), 3, poses_b));
}

TEST(PatchCamera, LargestPatchAndFloor) {
  const int m = 64;
  const Floors floors = random_floors(512, 512, 3, 51);
  const std::vector<PixelPose> poses = {{0, 0}, {255, 300}, {511, 511}};
  PatchCamera camera(512, 512, m, 3);
  camera.load_floors(floors.bytes, 3);
  EXPECT_TRUE(same_patches(cpu_patches(floors, m, poses), gl_patches(camera, poses), m, poses));
}

TEST(PatchCamera, FourThousandNinetySixRobotsIncludingAPartialUpload) {
  // More robots than llvmpipe's 2048 array layers, with a count that is odd as well.
  const int width = 7;
  const int height = 5;
  const int m = 4;
  PatchCamera camera(width, height, m, 4096);
  for (int count : {4096, 4095}) {
    SCOPED_TRACE("count = " + std::to_string(count));
    const Floors floors = random_floors(width, height, count, 60u + static_cast<unsigned>(count));
    const std::vector<PixelPose> poses = random_poses(count, width, height, 61);
    camera.load_floors(floors.bytes, count);
    EXPECT_TRUE(same_patches(cpu_patches(floors, m, poses), gl_patches(camera, poses), m, poses));
  }
}

TEST(PatchCamera, ReportsItsSizesAndRenderer) {
  PatchCamera camera(28, 28, 6, 240);
  EXPECT_EQ(camera.patch_px(), 6);
  EXPECT_EQ(camera.max_robots(), 240);
  const std::string description = camera.gl_description();
  // The back end ctest named is the one that drew (auto where none is named).
  if (const char* named = std::getenv(kCameraBackendVariable); named != nullptr && std::string(named) != "auto") {
    EXPECT_EQ(camera_backend_name(camera.backend()), std::string(named));
  }
  const std::string backend = camera.backend() == CameraBackend::egl ? "EGL: " : "OSMesa: ";
  EXPECT_EQ(description.rfind(backend, 0), 0u) << description;
  const std::size_t separator = description.find("; ");
  ASSERT_NE(separator, std::string::npos) << description;
  EXPECT_GT(separator, 0u) << description;
  EXPECT_LT(separator + 2, description.size()) << description;
}

TEST(PatchCamera, RejectsInvalidSizes) {
  EXPECT_THROW(PatchCamera(0, 28, 6, 1), std::invalid_argument);
  EXPECT_THROW(PatchCamera(28, -1, 6, 1), std::invalid_argument);
  EXPECT_THROW(PatchCamera(28, 28, 0, 1), std::invalid_argument);
  EXPECT_THROW(PatchCamera(28, 28, 65, 1), std::invalid_argument);
  EXPECT_THROW(PatchCamera(28, 28, 6, 0), std::invalid_argument);
  EXPECT_THROW(PatchCamera(28, 28, 6, 4097), std::invalid_argument);
  EXPECT_THROW(PatchCamera(513, 28, 6, 1), std::invalid_argument);
}

TEST(PatchCamera, RejectsInvalidLoadsAndCaptures) {
  const int n = 28;
  const int m = 6;
  PatchCamera camera(n, n, m, 4);
  const Floors floors = random_floors(n, n, 4, 71);
  std::vector<PixelPose> poses(2);
  std::vector<std::uint8_t> patches(2 * m * m);

  // Capturing before any floor is loaded.
  EXPECT_THROW(camera.capture(poses, patches), std::invalid_argument);

  EXPECT_THROW(camera.load_floors(floors.bytes, 0), std::invalid_argument);
  EXPECT_THROW(camera.load_floors(floors.bytes, 5), std::invalid_argument);
  EXPECT_THROW(camera.load_floors(std::span(floors.bytes).first(4 * n * n - 1), 4), std::invalid_argument);
  EXPECT_THROW(camera.load_floors(floors.bytes, 3), std::invalid_argument);  // too many bytes

  camera.load_floors(std::span(floors.bytes).first(2 * n * n), 2);
  EXPECT_NO_THROW(camera.capture(poses, patches));
  std::vector<PixelPose> three_poses(3);
  std::vector<std::uint8_t> three_patches(3 * m * m);
  EXPECT_THROW(camera.capture(three_poses, three_patches), std::invalid_argument);  // 2 floors

  camera.load_floors(floors.bytes, 4);
  std::vector<PixelPose> five_poses(5);
  std::vector<std::uint8_t> five_patches(5 * m * m);
  EXPECT_THROW(camera.capture(five_poses, five_patches), std::invalid_argument);
  std::vector<std::uint8_t> short_patches(2 * m * m - 1);
  EXPECT_THROW(camera.capture(poses, short_patches), std::invalid_argument);
  std::vector<std::uint8_t> long_patches(2 * m * m + 1);
  EXPECT_THROW(camera.capture(poses, long_patches), std::invalid_argument);

  // No poses, no patches: nothing to do, and no error.
  EXPECT_NO_THROW(camera.capture({}, {}));
}

// capture_at(): bilinear sampling at continuous centres (render/camera.hpp says what filtering).

TEST(SamplePatchBilinear, AtCellCentresIsTheCrop) {
  const Floors floors = random_floors(9, 7, 1, 81);
  for (int m : {1, 2, 5, 6, 8}) {
    for (int y = -5; y < 12; ++y) {
      for (int x = -5; x < 14; ++x) {
        std::vector<std::uint8_t> crop(static_cast<std::size_t>(m) * m, 0xAB);
        std::vector<std::uint8_t> sampled(static_cast<std::size_t>(m) * m, 0xCD);
        crop_patch(floors.image(0), 9, 7, m, {x, y}, crop.data());
        sample_patch_bilinear(floors.image(0), 9, 7, m, {x + 0.5f, y + 0.5f}, sampled.data());
        ASSERT_EQ(crop, sampled) << "m = " << m << " at (" << x << ", " << y << ")";
      }
    }
  }
}

TEST(PatchCameraCaptureAt, AtCellCentresEqualsCaptureAndTheCpuCropBitForBit) {
  const int n = 28;
  for (int m : {1, 2, 5, 6, 8}) {
    SCOPED_TRACE("m = " + std::to_string(m));
    // Every pose of the floor (all edges and corners), then random ones on and off it.
    std::vector<PixelPose> poses = every_pose(n, n);
    std::mt19937 random(400u + static_cast<unsigned>(m));
    std::uniform_int_distribution<int> coordinate(-m - 2, n + m + 1);
    for (int i = 0; i < 300; ++i) poses.push_back({coordinate(random), coordinate(random)});
    const int robots = static_cast<int>(poses.size());
    const Floors floors = random_floors(n, n, robots, 410u + static_cast<unsigned>(m));
    PatchCamera camera(n, n, m, robots);
    camera.load_floors(floors.bytes, robots);
    const std::vector<std::uint8_t> crop = cpu_patches(floors, m, poses);
    const std::vector<FloorPoint> centres = cell_centres(poses);
    // capture_at, capture, capture_at again: each call binds its own program.
    EXPECT_TRUE(same_patches(crop, gl_patches_at(camera, centres), m, poses));
    EXPECT_TRUE(same_patches(crop, gl_patches(camera, poses), m, poses));
    EXPECT_TRUE(same_patches(crop, gl_patches_at(camera, centres), m, poses));
    EXPECT_TRUE(same_patches(crop, cpu_patches(floors, m, centres), m, poses));
  }
}

TEST(PatchCameraCaptureAt, AtCellCentresOnStackedFloorsEqualsTheCpuCrop) {
  // More robots than llvmpipe's 2048 array layers: two floors per layer, where a sample past a
  // floor's bottom edge must read 0, not the next floor's top row.
  const int width = 7;
  const int height = 5;
  const int m = 4;
  const int count = 4095;
  std::vector<PixelPose> poses = every_pose(width, height);
  const std::vector<PixelPose> random = random_poses(count - static_cast<int>(poses.size()), width, height, 421);
  poses.insert(poses.end(), random.begin(), random.end());
  const Floors floors = random_floors(width, height, count, 422);
  PatchCamera camera(width, height, m, 4096);
  camera.load_floors(floors.bytes, count);
  EXPECT_TRUE(same_patches(cpu_patches(floors, m, poses), gl_patches_at(camera, cell_centres(poses)), m, poses));
}

// The stated bound: the camera blends in float, the reference in double, so a blend within float
// error of a half may round the other way; never by more than one grey level. (A throwaway sweep of
// 17.3 million pixels at random centres found 61 that differ, each by 1; the 277 thousand here
// usually show none.)
constexpr int kMaxBilinearDifference = 1;

TEST(PatchCameraCaptureAt, SubPixelCentresMatchTheBilinearReference) {
  struct Case {
    int width, height, m, robots, rounds;
  };
  // 240 robots (the training batch) over their own floors, several patch sizes, a non-square
  // floor, and stacked floors (4096 robots).
  const std::vector<Case> cases = {{28, 28, 1, 240, 4}, {28, 28, 2, 240, 4}, {28, 28, 5, 240, 4}, {28, 28, 6, 240, 10},
                                   {28, 28, 8, 240, 4}, {40, 24, 6, 240, 4}, {7, 5, 4, 4096, 1}};
  int largest = 0;
  std::size_t differing = 0;
  std::size_t pixels = 0;
  std::size_t centres_seen = 0;
  unsigned seed = 500;
  for (const Case& c : cases) {
    SCOPED_TRACE("floor " + std::to_string(c.width) + " x " + std::to_string(c.height) +
                 ", m = " + std::to_string(c.m) + ", " + std::to_string(c.robots) + " robots");
    PatchCamera camera(c.width, c.height, c.m, c.robots);
    for (int round = 0; round < c.rounds; ++round) {
      const Floors floors = random_floors(c.width, c.height, c.robots, ++seed);
      camera.load_floors(floors.bytes, c.robots);
      const std::vector<FloorPoint> centres =
          random_centres(c.robots, c.width, c.height, static_cast<float>(c.m) + 2.0f, ++seed);
      const std::vector<std::uint8_t> expected = cpu_patches(floors, c.m, centres);
      const std::vector<std::uint8_t> actual = gl_patches_at(camera, centres);
      ASSERT_EQ(expected.size(), actual.size());
      const Difference d = difference(expected, actual);
      const std::size_t robot = d.first / (static_cast<std::size_t>(c.m) * c.m);
      EXPECT_LE(d.largest, kMaxBilinearDifference)
          << "robot " << robot << " at (" << centres[robot].x << ", " << centres[robot].y << "), byte "
          << d.first % (static_cast<std::size_t>(c.m) * c.m) << ": expected " << int{expected[d.first]} << ", got "
          << int{actual[d.first]};
      largest = std::max(largest, d.largest);
      differing += d.differing;
      pixels += expected.size();
      centres_seen += centres.size();
    }
  }
  std::printf(
      "capture_at vs sample_patch_bilinear: %zu centres, %zu pixels, max difference %d grey level(s) "
      "(bound %d), %zu pixels differ\n",
      centres_seen, pixels, largest, kMaxBilinearDifference, differing);
  // A difference is a rounding tie broken the other way: rare, not a bias.
  EXPECT_LE(differing * 1000, pixels) << differing << " of " << pixels << " pixels differ";
}

TEST(PatchCameraCaptureAt, ASingleBrightTexelBlendsIntoItsNeighboursByHand) {
  // A non-square floor with one 255 texel; m = 5, so window pixel (i, j) samples the point
  // centre + (i - 2, j - 2).
  const int width = 40;
  const int height = 24;
  const int m = 5;
  const int bright_x = 31;
  const int bright_y = 4;
  std::vector<std::uint8_t> floor(static_cast<std::size_t>(width) * height, 0);
  floor[bright_y * width + bright_x] = 255;
  const float texel_centre_x = bright_x + 0.5f;
  const float texel_centre_y = bright_y + 0.5f;
  struct Expectation {
    FloorPoint centre;
    std::vector<std::pair<std::pair<int, int>, int>> bright;  // ((row, column), grey), all else 0
  };
  const std::vector<Expectation> cases = {
      // Half a pixel right: pixels (2, 1) and (2, 2) each sample half of the texel: 127.5, and
      // the reference rounds halves up, so 128 both.
      {{texel_centre_x + 0.5f, texel_centre_y}, {{{2, 1}, 128}, {{2, 2}, 128}}},
      // A quarter right: 0.75 * 255 = 191.25 -> 191 at the centre, 0.25 * 255 = 63.75 -> 64 left.
      {{texel_centre_x + 0.25f, texel_centre_y}, {{{2, 1}, 64}, {{2, 2}, 191}}},
      // Half a pixel right and down: four pixels of 255 / 4 = 63.75 -> 64.
      {{texel_centre_x + 0.5f, texel_centre_y + 0.5f}, {{{1, 1}, 64}, {{1, 2}, 64}, {{2, 1}, 64}, {{2, 2}, 64}}},
      // Exactly on the texel centre: the crop, 255 in the middle.
      {{texel_centre_x, texel_centre_y}, {{{2, 2}, 255}}},
  };
  const int robots = static_cast<int>(cases.size());
  std::vector<std::uint8_t> all_floors;
  for (int i = 0; i < robots; ++i) all_floors.insert(all_floors.end(), floor.begin(), floor.end());
  std::vector<FloorPoint> centres;
  for (const Expectation& c : cases) centres.push_back(c.centre);
  PatchCamera camera(width, height, m, robots);
  camera.load_floors(all_floors, robots);
  std::vector<std::uint8_t> patches(static_cast<std::size_t>(robots) * m * m, 0xAB);
  camera.capture_at(centres, patches);
  for (int robot = 0; robot < robots; ++robot) {
    std::vector<std::uint8_t> cpu(m * m, 0xAB);
    sample_patch_bilinear(floor.data(), width, height, m, centres[robot], cpu.data());
    for (int row = 0; row < m; ++row) {
      for (int column = 0; column < m; ++column) {
        int expected = 0;
        for (const auto& [where, grey] : cases[robot].bright) {
          if (where == std::make_pair(row, column)) expected = grey;
        }
        EXPECT_EQ(patches[robot * m * m + row * m + column], expected)
            << "GL: case " << robot << " row " << row << " column " << column;
        EXPECT_EQ(cpu[row * m + column], expected) << "CPU: case " << robot << " row " << row << " column " << column;
      }
    }
  }
}

TEST(PatchCameraCaptureAt, TheFloorEdgeBlendsWithBlackAndFarCentresSeeNothing) {
  // A uniform 200 floor: half a pixel past the left edge, the first column blends 200 with the
  // black beyond it (100); far away, and at the largest floats, everything is 0.
  const int n = 8;
  const int m = 2;  // window pixel (i, j) samples centre + (i - 1, j - 1)
  const std::vector<FloorPoint> centres = {{1.0f, 4.5f},
                                           {-1.0e6f, 3.0f},
                                           {3.0f, 1.0e9f},
                                           {std::numeric_limits<float>::max(), -std::numeric_limits<float>::max()},
                                           {-3.5f, -3.5f}};
  const int robots = static_cast<int>(centres.size());
  const std::vector<std::uint8_t> floor(static_cast<std::size_t>(n) * n * robots, 200);
  PatchCamera camera(n, n, m, robots);
  camera.load_floors(floor, robots);
  std::vector<std::uint8_t> patches(static_cast<std::size_t>(robots) * m * m, 0xAB);
  camera.capture_at(centres, patches);
  // Robot 0: columns sample x = 0 (half on texel -1, half on texel 0) and x = 1 (texels 0 and 1).
  const std::vector<std::uint8_t> first = {100, 200, 100, 200};
  EXPECT_EQ(std::vector<std::uint8_t>(patches.begin(), patches.begin() + m * m), first);
  for (int robot = 1; robot < robots; ++robot) {
    for (int p = 0; p < m * m; ++p) EXPECT_EQ(patches[robot * m * m + p], 0) << "robot " << robot;
  }
  for (int robot = 0; robot < robots; ++robot) {
    std::vector<std::uint8_t> cpu(m * m, 0xAB);
    sample_patch_bilinear(floor.data(), n, n, m, centres[robot], cpu.data());
    EXPECT_EQ(cpu, std::vector<std::uint8_t>(patches.begin() + robot * m * m, patches.begin() + (robot + 1) * m * m))
        << "robot " << robot;
  }
}

TEST(PatchCameraCaptureAt, RejectsInvalidCaptures) {
  const int n = 28;
  const int m = 6;
  PatchCamera camera(n, n, m, 4);
  const Floors floors = random_floors(n, n, 4, 91);
  std::vector<FloorPoint> centres(2);
  std::vector<std::uint8_t> patches(2 * m * m);

  EXPECT_THROW(camera.capture_at(centres, patches), std::invalid_argument);  // no floors yet

  camera.load_floors(std::span(floors.bytes).first(2 * n * n), 2);
  EXPECT_NO_THROW(camera.capture_at(centres, patches));
  std::vector<FloorPoint> three_centres(3);
  std::vector<std::uint8_t> three_patches(3 * m * m);
  EXPECT_THROW(camera.capture_at(three_centres, three_patches), std::invalid_argument);  // 2 floors

  camera.load_floors(floors.bytes, 4);
  std::vector<FloorPoint> five_centres(5);
  std::vector<std::uint8_t> five_patches(5 * m * m);
  EXPECT_THROW(camera.capture_at(five_centres, five_patches), std::invalid_argument);
  std::vector<std::uint8_t> short_patches(2 * m * m - 1);
  EXPECT_THROW(camera.capture_at(centres, short_patches), std::invalid_argument);
  std::vector<std::uint8_t> long_patches(2 * m * m + 1);
  EXPECT_THROW(camera.capture_at(centres, long_patches), std::invalid_argument);

  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                    -std::numeric_limits<float>::infinity()}) {
    std::vector<FloorPoint> not_finite = {{3.5f, 3.5f}, {bad, 3.5f}};
    EXPECT_THROW(camera.capture_at(not_finite, patches), std::invalid_argument);
    not_finite[1] = {3.5f, bad};
    EXPECT_THROW(camera.capture_at(not_finite, patches), std::invalid_argument);
  }

  EXPECT_NO_THROW(camera.capture_at({}, {}));
}

}  // namespace
}  // namespace scout::render

namespace scout::render {
namespace {

// The wider view's reference windows, robot i over floor i at its cell.
std::vector<std::uint8_t> cpu_wide(const Floors& floors, WideView wide, const std::vector<PixelPose>& cells) {
  const std::size_t bytes = static_cast<std::size_t>(wide.px) * wide.px;
  std::vector<std::uint8_t> out(cells.size() * bytes);
  for (std::size_t i = 0; i < cells.size(); ++i)
    wide_patch(floors.image(static_cast<int>(i)), floors.width, floors.height, wide, cells[i], out.data() + i * bytes);
  return out;
}

TEST(WidePatch, IsTheMeanOfEachBlockOfTheFloorsGridWithTheFloorEdgeBlack) {
  // A 6 x 4 floor of 10 x + y in blocks of 3 x 3 from its corner: 2 columns of blocks, and 2 rows,
  // the second cut to floor row 3 alone.
  std::vector<std::uint8_t> floor(24);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 6; ++x) floor[y * 6 + x] = static_cast<std::uint8_t>(10 * x + y);
  std::uint8_t out[4] = {};
  // From cell (4, 3), in block (1, 1): the window is blocks (0, 0) .. (1, 1). Block (0, 0):
  // 3 (0 + 10 + 20) + 3 (0 + 1 + 2) = 99 -> 11. Block (1, 0): 3 (30 + 40 + 50) + 9 = 369 -> 41.
  // Block (0, 1), row 3 only: 30 + 9 = 39 -> 4.33 -> 4. Block (1, 1): 120 + 9 = 129 -> 14.33 -> 14.
  wide_patch(floor.data(), 6, 4, WideView{2, 3}, PixelPose{4, 3}, out);
  EXPECT_EQ(std::vector<int>(out, out + 4), (std::vector<int>{11, 41, 4, 14}));
  // Every cell of block (1, 1) sees the same window: the grid, not the cell, places it.
  for (const PixelPose cell : {PixelPose{3, 3}, PixelPose{5, 3}}) {
    std::uint8_t same[4] = {};
    wide_patch(floor.data(), 6, 4, WideView{2, 3}, cell, same);
    EXPECT_EQ(std::vector<int>(same, same + 4), (std::vector<int>{11, 41, 4, 14})) << cell.x;
  }
  // From cell (1, 1), in block (0, 0): blocks (-1, -1) .. (0, 0), the three off the floor black.
  wide_patch(floor.data(), 6, 4, WideView{2, 3}, PixelPose{1, 1}, out);
  EXPECT_EQ(std::vector<int>(out, out + 4), (std::vector<int>{0, 0, 0, 11}));
  // A cell off the floor's corner lies in the block before block 0 (floor division), and an odd
  // side puts the robot's block in the middle: blocks (-2, -2) .. (0, 0), block (0, 0) the last.
  std::uint8_t nine[9] = {};
  wide_patch(floor.data(), 6, 4, WideView{3, 3}, PixelPose{-1, -1}, nine);
  EXPECT_EQ(std::vector<int>(nine, nine + 9), (std::vector<int>{0, 0, 0, 0, 0, 0, 0, 0, 11}));
  wide_patch(floor.data(), 6, 4, WideView{3, 3}, PixelPose{2, 2}, nine);
  EXPECT_EQ(std::vector<int>(nine, nine + 9), (std::vector<int>{0, 0, 0, 0, 11, 41, 0, 4, 14}));
}

TEST(PatchCamera, TheWiderViewEqualsTheCpuReferenceAndLeavesThePatchesAsTheyWere) {
  // Wider and narrower than the patch, and scales up to the largest (whose block means run
  // closest to the float arithmetic's limits).
  for (const WideView wide :
       {WideView{5, 4}, WideView{3, 3}, WideView{8, 1}, WideView{7, 2}, WideView{8, 6}, WideView{4, 16}}) {
    const int width = 37, height = 29, m = 6, count = 60;
    std::vector<PixelPose> poses = random_poses(count - 6, width, height, 77);
    // Corners and poses far off the floor, two near int's limits (the shader's int arithmetic
    // wraps there): the window is black or partly so.
    for (const PixelPose p : {PixelPose{0, 0}, PixelPose{36, 28}, PixelPose{-40, 3}, PixelPose{18, 200},
                              PixelPose{2147483600, 4}, PixelPose{-2147483600, -2147483600}})
      poses.push_back(p);
    const Floors floors = random_floors(width, height, count, 78);
    PatchCamera camera(width, height, m, count, wide);
    EXPECT_EQ(camera.wide_view().px, wide.px);
    camera.load_floors(floors.bytes, count);
    std::vector<std::uint8_t> patches(count * m * m, 0xAB), far(count * wide.px * wide.px, 0xAB);
    camera.capture(poses, patches, far);
    EXPECT_EQ(far, cpu_wide(floors, wide, poses)) << "wide " << wide.px << " x " << wide.scale;
    EXPECT_EQ(patches, cpu_patches(floors, m, poses));
    // capture_at: the wider view at the cell holding each centre.
    std::vector<FloorPoint> centres;
    for (const PixelPose& p : poses) centres.push_back({p.x + 0.7f, p.y + 0.2f});
    std::vector<std::uint8_t> at_patches(count * m * m), at_far(count * wide.px * wide.px, 0xAB);
    camera.capture_at(centres, at_patches, at_far);
    EXPECT_EQ(at_far, cpu_wide(floors, wide, poses)) << "capture_at, wide " << wide.px << " x " << wide.scale;
    // Without the buffer, capture is the patches alone.
    std::vector<std::uint8_t> alone(count * m * m, 0xAB);
    camera.capture(poses, alone);
    EXPECT_EQ(alone, patches);
    // Floors mostly black, as a digit on a larger floor is (the block means skip empty rows): a
    // band of empty rows from 1 row to the whole floor, at the top, in the middle or at the bottom,
    // and single empty rows between inked ones; the last floor all black.
    Floors sparse = floors;
    for (int i = 0; i < count; ++i) {
      const int band = 1 + i % height, start = (i * 5) % height;
      for (int y = 0; y < height; ++y)
        if ((y >= start && y < start + band) || (y + i) % 9 == 0 || i == count - 1)
          std::fill_n(sparse.bytes.begin() + (static_cast<std::ptrdiff_t>(i) * height + y) * width, width, 0);
    }
    camera.load_floors(sparse.bytes, count);
    camera.capture(poses, patches, far);
    EXPECT_EQ(far, cpu_wide(sparse, wide, poses)) << "black rows, wide " << wide.px << " x " << wide.scale;
    // The block means made side by side on a pool's threads, as the environment has them made.
    scout::core::WorkerPool pool(2);
    camera.load_floors(floors.bytes, count, &pool);
    camera.capture(poses, patches, far);
    EXPECT_EQ(far, cpu_wide(floors, wide, poses)) << "over a pool, wide " << wide.px << " x " << wide.scale;
    camera.load_floors(sparse.bytes, count, &pool);
    camera.capture(poses, patches, far);
    EXPECT_EQ(far, cpu_wide(sparse, wide, poses)) << "over a pool, black rows, wide " << wide.px;
  }
}

TEST(PatchCamera, TheWiderViewOnStackedFloorsReadsNoNeighbouringFloor) {
  // More robots than llvmpipe's 2048 array layers: two floors per layer; a block past a floor's
  // bottom edge must count 0, not the next floor's top rows.
  const int width = 9, height = 7, m = 3, count = 4096;
  const WideView wide{4, 3};
  const std::vector<PixelPose> poses = random_poses(count, width, height, 91);
  const Floors floors = random_floors(width, height, count, 92);
  PatchCamera camera(width, height, m, count, wide);
  camera.load_floors(floors.bytes, count);
  std::vector<std::uint8_t> patches(count * m * m), far(count * wide.px * wide.px, 0xAB);
  camera.capture(poses, patches, far);
  EXPECT_EQ(far, cpu_wide(floors, wide, poses));
}

// replace_floors: the slots named see their new floors (patches and wider view), every other slot
// keeps its own, on one layer a floor and on floors stacked two a layer (slots in either half of
// a layer); bad slots are refused and change nothing.
TEST(PatchCamera, ReplacedFloorsAreSeenAndTheOthersKeptOnPlainAndStackedLayers) {
  for (const int count : {40, 4096}) {
    const int width = 11, height = 9, m = 4;
    const WideView wide{3, 2};
    const std::vector<PixelPose> poses = random_poses(count, width, height, 101);
    Floors floors = random_floors(width, height, count, 102);
    const Floors fresh = random_floors(width, height, 4, 103);
    PatchCamera camera(width, height, m, count, wide);
    camera.load_floors(floors.bytes, count);
    const std::vector<int> slots = {count - 1, 0, 7, count / 2 + 1};
    scout::core::WorkerPool pool(2);
    camera.replace_floors(slots, fresh.bytes, count == 40 ? nullptr : &pool);
    const std::size_t floor_bytes = static_cast<std::size_t>(width) * height;
    for (std::size_t k = 0; k < slots.size(); ++k)
      std::copy_n(fresh.image(static_cast<int>(k)), floor_bytes,
                  floors.bytes.begin() + static_cast<std::ptrdiff_t>(floor_bytes * slots[k]));
    std::vector<std::uint8_t> patches(count * m * m), far(count * wide.px * wide.px, 0xAB);
    camera.capture(poses, patches, far);
    EXPECT_EQ(patches, cpu_patches(floors, m, poses)) << count << " floors";
    EXPECT_EQ(far, cpu_wide(floors, wide, poses)) << count << " floors";
    // A slot not loaded, a slot named twice, or the wrong number of bytes: refused, nothing replaced.
    EXPECT_THROW(camera.replace_floors(std::vector<int>{count}, std::span(fresh.bytes).first(floor_bytes)),
                 std::invalid_argument);
    EXPECT_THROW(camera.replace_floors(std::vector<int>{3, 3}, std::span(fresh.bytes).first(2 * floor_bytes)),
                 std::invalid_argument);
    EXPECT_THROW(camera.replace_floors(std::vector<int>{3}, std::span(fresh.bytes).first(floor_bytes - 1)),
                 std::invalid_argument);
    camera.capture(poses, patches, far);
    EXPECT_EQ(patches, cpu_patches(floors, m, poses)) << count << " floors, after the refusals";
    EXPECT_EQ(far, cpu_wide(floors, wide, poses)) << count << " floors, after the refusals";
  }
}

TEST(PatchCamera, TheWiderViewsBadSizesAndBuffersAreRefused) {
  EXPECT_THROW(PatchCamera(28, 28, 6, 4, WideView{65, 2}), std::invalid_argument);
  EXPECT_THROW(PatchCamera(28, 28, 6, 4, WideView{4, 0}), std::invalid_argument);
  EXPECT_THROW(PatchCamera(28, 28, 6, 4, WideView{4, kMaxWideScale + 1}), std::invalid_argument);
  const Floors floors = random_floors(28, 28, 2, 5);
  PatchCamera plain(28, 28, 6, 2);
  plain.load_floors(floors.bytes, 2);
  std::vector<PixelPose> poses = {{3, 3}, {10, 10}};
  std::vector<std::uint8_t> patches(2 * 36), far(2 * 16);
  try {
    plain.capture(poses, patches, far);
    ADD_FAILURE() << "a wider view from a camera without one";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("this camera has no wider view"), std::string::npos) << e.what();
  }
  PatchCamera wide(28, 28, 6, 2, WideView{4, 4});
  wide.load_floors(floors.bytes, 2);
  std::vector<std::uint8_t> short_buffer(2 * 16 - 1);
  EXPECT_THROW(wide.capture(poses, patches, short_buffer), std::invalid_argument);
}

}  // namespace
}  // namespace scout::render
