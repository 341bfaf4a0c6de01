// render::VideoWriter: MP4 through OpenCV and GIF through giflib, read back frame by frame with
// the same libraries' decoders; atomic (nothing until finish(), no temporary left behind); bad
// paths refused with one line before any frame.
#include <gif_lib.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "render/video.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::render {
namespace {

namespace fs = std::filesystem;

// A frame whose left part is white up to column `k * 4`: frames differ, and frame k can be told
// from its bright columns.
Picture frame(int k, int width = 64, int height = 48) {
  Picture p;
  p.width = width;
  p.height = height;
  p.bgr.assign(static_cast<std::size_t>(width) * height * 3, 20);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < std::min(width, k * 4); ++x)
      for (int c = 0; c < 3; ++c) p.bgr[(static_cast<std::size_t>(y) * width + x) * 3 + c] = 235;
  return p;
}

int bright_columns(const cv::Mat& bgr) {
  int n = 0;
  for (int x = 0; x < bgr.cols; ++x) n += bgr.at<cv::Vec3b>(bgr.rows / 2, x)[1] > 128 ? 1 : 0;
  return n;
}

std::vector<fs::path> files_in(const fs::path& folder) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(folder)) out.push_back(e.path().filename());
  return out;
}

TEST(VideoWriter, Mp4FramesReadBackInOrder) {
  scout::testing::TempDir dir("video");
  const fs::path file = dir.path() / "run.mp4";
  {
    VideoWriter video(file, 25);
    for (int k = 0; k < 12; ++k) video.add(frame(k));
    EXPECT_FALSE(fs::exists(file)) << "the video appeared before finish()";
    video.finish();
    EXPECT_EQ(video.frames(), 12);
    EXPECT_TRUE(video.codec() == "avc1" || video.codec() == "mp4v") << video.codec();
  }
  EXPECT_EQ(files_in(dir.path()), std::vector<fs::path>{"run.mp4"}) << "a temporary file was left behind";
  cv::VideoCapture in(file.string(), cv::CAP_FFMPEG);
  ASSERT_TRUE(in.isOpened());
  EXPECT_NEAR(in.get(cv::CAP_PROP_FPS), 25.0, 0.01);
  int frames = 0;
  for (cv::Mat image; in.read(image); ++frames) {
    EXPECT_EQ(image.cols, 64);
    EXPECT_EQ(image.rows, 48);
    // Lossy, but the white band's width is kept to within a few columns.
    EXPECT_NEAR(bright_columns(image), std::min(64, frames * 4), 3) << "frame " << frames;
  }
  EXPECT_EQ(frames, 12);
}

TEST(VideoWriter, OddSizedMp4FramesArePaddedToEvenSizes) {
  scout::testing::TempDir dir("video");
  const fs::path file = dir.path() / "odd.MP4";  // the extension in any case
  VideoWriter video(file, 30);
  for (int k = 0; k < 3; ++k) video.add(frame(k, 63, 47));
  video.finish();
  cv::VideoCapture in(file.string(), cv::CAP_FFMPEG);
  cv::Mat image;
  ASSERT_TRUE(in.read(image));
  EXPECT_EQ(image.cols, 64);
  EXPECT_EQ(image.rows, 48);
}

TEST(VideoWriter, GifFramesDelaysAndLoopReadBackWithGiflib) {
  scout::testing::TempDir dir("video");
  const fs::path file = dir.path() / "run.gif";
  constexpr int kFrames = 9;
  {
    VideoWriter video(file, 30);
    for (int k = 0; k < kFrames; ++k) video.add(frame(k));
    video.finish();
    EXPECT_EQ(video.codec(), "gif");
  }
  EXPECT_EQ(files_in(dir.path()), std::vector<fs::path>{"run.gif"});
  // As readable as any other output: 0666 less the umask (giflib alone would make it 0600).
  const mode_t mask = ::umask(0);
  ::umask(mask);
  EXPECT_EQ(static_cast<unsigned>(fs::status(file).permissions()), 0666u & ~static_cast<unsigned>(mask));
  int error = 0;
  GifFileType* gif = DGifOpenFileName(file.c_str(), &error);
  ASSERT_NE(gif, nullptr) << GifErrorString(error);
  ASSERT_EQ(DGifSlurp(gif), GIF_OK) << GifErrorString(gif->Error);
  EXPECT_EQ(gif->SWidth, 64);
  EXPECT_EQ(gif->SHeight, 48);
  ASSERT_EQ(gif->ImageCount, kFrames);
  int total_cs = 0;
  bool loops = false;
  for (int i = 0; i < gif->ImageCount; ++i) {
    GraphicsControlBlock control;
    ASSERT_EQ(DGifSavedExtensionToGCB(gif, i, &control), GIF_OK) << i;
    total_cs += control.DelayTime;
    const SavedImage& image = gif->SavedImages[i];
    ASSERT_NE(image.ImageDesc.ColorMap, nullptr);
    // The white band's width, from the palette colours of the middle row.
    int bright = 0;
    const int row = 24 * image.ImageDesc.Width;
    for (int x = 0; x < image.ImageDesc.Width; ++x)
      bright += image.ImageDesc.ColorMap->Colors[image.RasterBits[row + x]].Green > 128 ? 1 : 0;
    EXPECT_EQ(bright, std::min(64, i * 4)) << "frame " << i;
    for (int b = 0; b < image.ExtensionBlockCount; ++b)
      if (image.ExtensionBlocks[b].Function == APPLICATION_EXT_FUNC_CODE) loops = true;
  }
  // 9 frames at 30 fps last 0.3 s: 30 hundredths, though no single delay can be 3.33.
  EXPECT_EQ(total_cs, 30);
  EXPECT_TRUE(loops || gif->ExtensionBlockCount > 0) << "no NETSCAPE2.0 loop block";
  DGifCloseFile(gif, &error);
}

TEST(VideoWriter, NoFinishLeavesNothingBehind) {
  scout::testing::TempDir dir("video");
  for (const char* name : {"a.mp4", "a.gif"}) {
    {
      VideoWriter video(dir.path() / name, 30);
      video.add(frame(1));
      video.add(frame(2));
    }  // an error or an interrupt unwinds here
    EXPECT_TRUE(fs::is_empty(dir.path())) << name;
  }
  VideoWriter empty(dir.path() / "b.gif", 30);
  EXPECT_THROW(empty.finish(), InputError);
}

TEST(VideoWriter, FramesOfAnotherSizeAreRefused) {
  scout::testing::TempDir dir("video");
  VideoWriter video(dir.path() / "a.gif", 30);
  video.add(frame(1));
  EXPECT_THROW(video.add(frame(1, 32, 32)), std::invalid_argument);
}

std::string refusal(const std::string& option, const fs::path& file) {
  try {
    check_video_path(option, file);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(VideoPath, BadPathsAreOneLineNamingOptionAndFile) {
  scout::testing::TempDir dir("video");
  EXPECT_EQ(check_video_path("--video", dir.path() / "a.gif"), VideoFormat::Gif);
  EXPECT_EQ(check_video_path("--video", dir.path() / "a.Mp4"), VideoFormat::Mp4);
  const fs::path avi = dir.path() / "a.avi";
  EXPECT_EQ(refusal("--video", avi),
            "--video: " + avi.string() + ": expected a file name ending in .mp4 or .gif, got \".avi\"");
  EXPECT_EQ(refusal("--video", dir.path() / "noext"), "--video: " + (dir.path() / "noext").string() +
                                                          ": expected a file name ending in .mp4 or .gif, got no "
                                                          "extension");
  const fs::path missing = dir.path() / "no" / "such" / "a.mp4";
  EXPECT_EQ(refusal("--video", missing), "--video: " + missing.string() + ": the folder " +
                                             (dir.path() / "no" / "such").string() + " does not exist");
  fs::create_directories(dir.path() / "x.gif");
  EXPECT_EQ(refusal("--video", dir.path() / "x.gif"),
            "--video: " + (dir.path() / "x.gif").string() + ": expected a file, got a folder");
  EXPECT_THROW(VideoWriter(dir.path() / "a.gif", 0), InputError);
  EXPECT_THROW(VideoWriter(dir.path() / "a.mp4", 101), InputError);
  EXPECT_THROW(VideoWriter(dir.path() / "a.gif", 60), InputError);  // GIF delays are hundredths
  EXPECT_NO_THROW(VideoWriter(dir.path() / "a.mp4", 60));
}

}  // namespace
}  // namespace scout::render
