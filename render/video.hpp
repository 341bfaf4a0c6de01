#pragma once
/// Animations: pictures (snapshot.hpp) written frame by frame as MP4 (OpenCV's VideoWriter
/// through FFmpeg: H.264 `avc1`, else MPEG-4 Part 2 `mp4v`) or as GIF (giflib), atomically.
#include <filesystem>
#include <memory>
#include <string>

#include "render/snapshot.hpp"

namespace scout::render {

enum class VideoFormat { Mp4, Gif };

/// Checks an output path before any work is done: the extension (.mp4 or .gif, any case) names
/// the format, and the folder it is in exists and can be written. Throws InputError with one line
/// naming `option` and the path.
VideoFormat check_video_path(const std::string& option, const std::filesystem::path& file);

/// Frames in, one video file out. Frames go to a temporary file beside `file`, which finish()
/// renames into place: a reader never sees half a video, and a failure (or a destructor without
/// finish()) leaves no file behind.
class VideoWriter {
 public:
  /// `fps`: frames per second, in (0, 100]; a GIF stores each frame's delay in hundredths of a
  /// second, rounded so that the total time stays right.
  VideoWriter(const std::filesystem::path& file, double fps);
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;

  /// Appends a frame; the first fixes the size and every other must match it. Throws InputError
  /// when the encoder fails (a full disk, say).
  void add(const Picture& frame);
  /// Closes the file and moves it into place. Throws InputError if there is no frame.
  void finish();

  int frames() const;
  /// "avc1", "mp4v" or "gif": what the frames were encoded with (after the first frame).
  std::string codec() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace scout::render
