// `scout run --video` end to end: real Box2D ticks and the tiny trained agent of the EvalRun
// fixture; the file decoded again (giflib, OpenCV) holds exactly one frame per physics tick plus
// the documented holds; bad paths are one line before any work.
#include <gif_lib.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <string>

#include "tests/support/eval_run_fixture.hpp"

namespace scout::testing::run_video_tests {

using namespace scout::testing::eval_run_support;

// What append_run_frames promises, from trajectory.json: a hold of round(0.4 fps) frames on each
// episode's goal, a frame per tick (one for a move that needed none), round(fps) at the end.
int expected_frames(const json& trajectory, double fps, int episodes) {
  const int goal_hold = std::max(1, static_cast<int>(std::lround(fps * 0.4)));
  const int final_hold = std::max(1, static_cast<int>(std::lround(fps)));
  int frames = 0;
  for (const json& run : trajectory["runs"]) {
    frames += episodes * goal_hold + final_hold;
    for (const json& step : run["steps"]) frames += std::max(1, step["ticks"].get<int>());
  }
  return frames;
}

struct GifInfo {
  int frames = 0, width = 0, height = 0;
};

GifInfo read_gif(const fs::path& file) {
  GifInfo info;
  int error = 0;
  GifFileType* gif = DGifOpenFileName(file.c_str(), &error);
  if (gif == nullptr) return info;
  if (DGifSlurp(gif) == GIF_OK) info = {gif->ImageCount, gif->SWidth, gif->SHeight};
  DGifCloseFile(gif, &error);
  return info;
}

TEST_F(EvalRun, AGifHoldsOneFramePerPhysicsTickOfEveryRun) {
  const Result r = scout("run " + world() + " --checkpoint " + checkpoint() + " --out " + path("gif-out") +
                         " --count 2 --no-images --scale 8 --video " + path("runs.gif") + " --fps 20");
  ASSERT_EQ(r.status, 0) << r.output;
  const json trajectory = read_json(path("gif-out") + "/trajectory.json");
  const int expected = expected_frames(trajectory, 20, 2);
  const json video = read_json(path("gif-out") + "/manifest.json")["outputs"]["video"];
  EXPECT_EQ(video["frames"], expected);
  EXPECT_EQ(video["codec"], "gif");
  const GifInfo gif = read_gif(path("runs.gif"));
  EXPECT_EQ(gif.frames, expected);
  EXPECT_EQ(gif.height, kSide * 8);
  EXPECT_GT(gif.width, kSide * 8) << "no prediction panel beside the floor";
  EXPECT_NE(r.output.find("video:      " + path("runs.gif") + " (" + std::to_string(expected) + " frames"),
            std::string::npos)
      << r.output;
}

TEST_F(EvalRun, AnMp4OfModeIHasTheFloorOnlyAndEveryTick) {
  // Without a checkpoint: mode (i), no prediction, so no panel.
  const Result r = scout("run " + world() + " --out " + path("mp4-out") + " --count 1 --no-images --scale 10 --video " +
                         path("run.mp4"));
  ASSERT_EQ(r.status, 0) << r.output;
  const json trajectory = read_json(path("mp4-out") + "/trajectory.json");
  cv::VideoCapture in(path("run.mp4"), cv::CAP_FFMPEG);
  ASSERT_TRUE(in.isOpened());
  int frames = 0;
  for (cv::Mat image; in.read(image); ++frames) {
    ASSERT_EQ(image.cols, kSide * 10);
    ASSERT_EQ(image.rows, kSide * 10);
  }
  EXPECT_EQ(frames, expected_frames(trajectory, 30, 2));  // --fps defaults to 30
}

// With the wider view, the frames show its coarse map where the patch has not been (a little
// lighter than the unseen floor, over whole blocks), not only its window's outline: the last frame
// of the same run (mode i moves read no observation) differs from the one without the view over
// far more pixels than the outline's, and only where the view looked.
TEST_F(EvalRun, VideosOfAWorldWithAWiderViewShowItsCoarseMap) {
  const std::string base = read_file(world());
  std::ofstream(path("wide.yaml")) << std::string(base).replace(base.find("camera: {patch_px: 3}"), 21,
                                                                "camera: {patch_px: 3, wide_px: 3, wide_scale: 2}");
  const auto last_frame = [&](const std::string& world_file, const std::string& name) {
    const Result r = scout("run " + world_file + " --out " + path(name + "-out") +
                           " --count 1 --no-images --scale 10 --video " + path(name + ".mp4"));
    EXPECT_EQ(r.status, 0) << r.output;
    cv::VideoCapture in(path(name + ".mp4"), cv::CAP_FFMPEG);
    cv::Mat last;
    for (cv::Mat image; in.read(image);) last = image.clone();
    return last;
  };
  const cv::Mat plain = last_frame(world(), "plain"), wide = last_frame(path("wide.yaml"), "wide");
  ASSERT_FALSE(plain.empty());
  ASSERT_EQ(plain.size(), wide.size());
  cv::Mat difference;
  cv::absdiff(plain, wide, difference);
  cv::Mat grey;
  cv::cvtColor(difference, grey, cv::COLOR_BGR2GRAY);
  const int changed = cv::countNonZero(grey > 12);
  // The window's outline: 6 floor pixels a side at scale 10, a perimeter of about 240 pixels, a
  // few wide; a block of the coarse map alone is 20 x 20 pixels, and a run covers several.
  EXPECT_GT(changed, 1500) << "pixels that differ: " << changed;
}

TEST_F(EvalRun, BadVideoPathsAreOneLineBeforeAnyWork) {
  const std::string bad[][2] = {
      {path("v.avi"), "--video: " + path("v.avi") + ": expected a file name ending in .mp4 or .gif, got \".avi\""},
      {path("no/such/v.gif"),
       "--video: " + path("no/such/v.gif") + ": the folder " + path("no/such") + " does not exist"},
      {path("v.gif") + " --fps 60", "--fps: expected at most 50 for a GIF (browsers slow faster ones down), got 60"}};
  for (const auto& [file, message] : bad) {
    // A world file that does not exist: the video path is checked first.
    const Result r = scout("run " + path("missing.yaml") + " --out " + path("never") + " --video " + file);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_EQ(r.output, "scout: error: " + message + "\n");
    EXPECT_FALSE(fs::exists(path("never")));
  }
  // Inside an --out folder that --overwrite replaces as a whole, the video would be lost.
  fs::create_directories(path("old-out"));
  const Result inside =
      scout("run " + world() + " --out " + path("old-out") + " --overwrite --video " + path("old-out") + "/v.mp4");
  EXPECT_EQ(inside.status, 1) << inside.output;
  EXPECT_EQ(inside.output, "scout: error: --video: " + path("old-out") +
                               "/v.mp4: expected a file outside --out's folder " + path("old-out") +
                               " (written as a whole)\n");
  const Result fps = scout("run " + world() + " --out " + path("never") + " --video " + path("v.gif") + " --fps 0");
  EXPECT_EQ(fps.status, 2) << fps.output;
  EXPECT_FALSE(fs::exists(path("v.gif")));
}

}  // namespace scout::testing::run_video_tests
