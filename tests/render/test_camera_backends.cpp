// The camera's back ends side by side in one process: each makes the context it is asked for,
// their patches are equal to each other and to the CPU reference while cameras of both draw in
// turn, and a bad choice is one clear error. (test_camera.cpp runs once per back end besides.)
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "render/camera.hpp"

namespace scout::render {
namespace {

constexpr int kSide = 28, kPatch = 6, kRobots = 37;

std::vector<std::uint8_t> random_floors(unsigned seed) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(kSide) * kSide * kRobots);
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  for (std::uint8_t& value : bytes) value = static_cast<std::uint8_t>(byte(random));
  return bytes;
}

// Restores SCOUT_CAMERA_BACKEND as it was when the test began.
class BackendVariable {
 public:
  BackendVariable() {
    if (const char* value = std::getenv(kCameraBackendVariable)) saved_ = value, had_ = true;
  }
  ~BackendVariable() {
    if (had_)
      setenv(kCameraBackendVariable, saved_.c_str(), 1);
    else
      unsetenv(kCameraBackendVariable);
  }
  void set(const char* value) { setenv(kCameraBackendVariable, value, 1); }

 private:
  std::string saved_;
  bool had_ = false;
};

TEST(CameraBackends, NamesParseBackAndABadNameSaysWhatIsExpected) {
  for (CameraBackend backend : {CameraBackend::automatic, CameraBackend::osmesa, CameraBackend::egl})
    EXPECT_EQ(parse_camera_backend(camera_backend_name(backend)), backend);
  try {
    parse_camera_backend("opengl");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("auto, osmesa or egl"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'opengl'"), std::string::npos) << e.what();
  }
}

TEST(CameraBackends, EachBuiltBackEndMakesItsOwnContextAndSaysSo) {
  const std::vector<CameraBackend> built = built_camera_backends();
  ASSERT_FALSE(built.empty());
  for (CameraBackend backend : built) {
    PatchCamera camera(kSide, kSide, kPatch, 4, {}, backend);
    EXPECT_EQ(camera.backend(), backend);
    const std::string prefix = backend == CameraBackend::egl ? "EGL: " : "OSMesa: ";
    EXPECT_EQ(camera.gl_description().rfind(prefix, 0), 0u) << camera.gl_description();
  }
}

TEST(CameraBackends, TheVariableChoosesForAutomaticAndAnExplicitChoiceWins) {
  BackendVariable variable;
  for (CameraBackend backend : built_camera_backends()) {
    variable.set(camera_backend_name(backend));
    EXPECT_EQ(PatchCamera(kSide, kSide, kPatch, 1).backend(), backend);
    for (CameraBackend other : built_camera_backends())
      EXPECT_EQ(PatchCamera(kSide, kSide, kPatch, 1, {}, other).backend(), other);
  }
  variable.set("auto");
  EXPECT_EQ(PatchCamera(kSide, kSide, kPatch, 1).backend(), built_camera_backends().front());
}

TEST(CameraBackends, ABadVariableIsOneErrorNamingIt) {
  BackendVariable variable;
  variable.set("vulkan");
  try {
    PatchCamera camera(kSide, kSide, kPatch, 1);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("SCOUT_CAMERA_BACKEND"), std::string::npos) << message;
    EXPECT_NE(message.find("'vulkan'"), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

// Cameras of both back ends alive at once and drawing in turn, each over floors of its own and
// with a patch size of its own (so that a call sent to the other library's context would show):
// each switch rebinds the other library's context, and every capture equals the CPU crop bit for
// bit; capture_at at sub-pixel centres equals between the back ends over the same floors.
TEST(CameraBackends, BothBackEndsInOneProcessDrawInTurnAndAgreeBitForBit) {
  const std::vector<CameraBackend> built = built_camera_backends();
  if (built.size() < 2) GTEST_SKIP() << "this build has one camera back end";
  struct Camera {
    CameraBackend backend;
    int patch_px;
    std::vector<std::uint8_t> floors;
  };
  const std::vector<Camera> cameras{{CameraBackend::osmesa, 6, random_floors(7)},
                                    {CameraBackend::egl, 5, random_floors(8)}};
  const WideView wide{4, 3};
  PatchCamera osmesa(kSide, kSide, cameras[0].patch_px, kRobots, wide, CameraBackend::osmesa);
  PatchCamera egl(kSide, kSide, cameras[1].patch_px, kRobots, wide, CameraBackend::egl);
  PatchCamera* gl[] = {&osmesa, &egl};
  for (int c = 0; c < 2; ++c) gl[c]->load_floors(cameras[c].floors, kRobots);
  std::mt19937 random(11);
  std::uniform_int_distribution<int> cell(-3, kSide + 2);
  for (int round = 0; round < 6; ++round) {
    std::vector<PixelPose> poses(kRobots);
    for (PixelPose& pose : poses) pose = {cell(random), cell(random)};
    for (int c = 0; c < 2; ++c) {
      const int m = cameras[c].patch_px;
      const std::size_t patch_bytes = static_cast<std::size_t>(m) * m;
      std::vector<std::uint8_t> expected(kRobots * patch_bytes), wide_expected(kRobots * 16);
      for (int i = 0; i < kRobots; ++i) {
        const std::uint8_t* floor = cameras[c].floors.data() + static_cast<std::size_t>(i) * kSide * kSide;
        crop_patch(floor, kSide, kSide, m, poses[i], expected.data() + i * patch_bytes);
        wide_patch(floor, kSide, kSide, wide, poses[i], wide_expected.data() + i * 16);
      }
      std::vector<std::uint8_t> patches(kRobots * patch_bytes), wide_patches(kRobots * 16);
      gl[c]->capture(poses, patches, wide_patches);
      EXPECT_EQ(patches, expected) << camera_backend_name(cameras[c].backend) << ", round " << round;
      EXPECT_EQ(wide_patches, wide_expected) << camera_backend_name(cameras[c].backend) << ", round " << round;
    }
  }
  // Sub-pixel: the two back ends over the same floors give the same bytes.
  PatchCamera osmesa_again(kSide, kSide, 6, kRobots, {}, CameraBackend::osmesa);
  osmesa_again.load_floors(cameras[1].floors, kRobots);
  std::uniform_real_distribution<float> point(-2.0f, kSide + 2.0f);
  for (int round = 0; round < 3; ++round) {
    std::vector<FloorPoint> centres(kRobots);
    for (FloorPoint& centre : centres) centre = {point(random), point(random)};
    std::vector<std::uint8_t> from_osmesa(kRobots * 25), from_egl(kRobots * 25), from_osmesa6(kRobots * 36);
    egl.capture_at(centres, from_egl);
    osmesa_again.capture_at(centres, from_osmesa6);
    for (int i = 0; i < kRobots; ++i)  // the 5 x 5 window is the 6 x 6 one less its first row and column
      for (int row = 0; row < 5; ++row)
        for (int column = 0; column < 5; ++column)
          from_osmesa[i * 25 + row * 5 + column] = from_osmesa6[i * 36 + (row + 1) * 6 + column + 1];
    EXPECT_EQ(from_osmesa, from_egl) << "round " << round;
  }
}

}  // namespace
}  // namespace scout::render
