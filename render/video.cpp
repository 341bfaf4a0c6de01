// Videos of trajectory pictures: MP4 through OpenCV's VideoWriter (FFmpeg), GIF through giflib
// (OpenCV 4.6 cannot write GIF). Both are written to a temporary file that finish() renames.
#include "render/video.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <gif_lib.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "core/error.hpp"
#include "core/files.hpp"

namespace scout::render {

namespace fs = std::filesystem;

VideoFormat check_video_path(const std::string& option, const fs::path& file) {
  std::string extension = file.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  VideoFormat format;
  if (extension == ".mp4")
    format = VideoFormat::Mp4;
  else if (extension == ".gif")
    format = VideoFormat::Gif;
  else
    throw InputError(fmt::format("{}: {}: expected a file name ending in .mp4 or .gif, got {}", option, file.string(),
                                 extension.empty() ? std::string("no extension") : "\"" + extension + "\""));
  std::error_code ec;
  if (fs::is_directory(file, ec))
    throw InputError(fmt::format("{}: {}: expected a file, got a folder", option, file.string()));
  const fs::path folder = file.parent_path().empty() ? fs::path(".") : file.parent_path();
  if (!fs::is_directory(folder, ec))
    throw InputError(fmt::format("{}: {}: the folder {} does not exist", option, file.string(), folder.string()));
  if (::access(folder.c_str(), W_OK) != 0)
    throw InputError(fmt::format("{}: {}: the folder {} is not writable", option, file.string(), folder.string()));
  return format;
}

namespace {

// The GIF side: each frame gets its own 256-colour palette (median cut, giflib's
// GifQuantizeBuffer) and a graphics control block with its delay; the file loops forever.
class GifEncoder {
 public:
  GifEncoder(const fs::path& file, int width, int height) : width_(width), height_(height) {
    // Opened here rather than by EGifOpenFileName, which creates files 0600: a video is as
    // readable as any other output (0666 less the umask).
    const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) throw InputError(fmt::format("{}: cannot create: {}", file.string(), std::strerror(errno)));
    int error = 0;
    gif_.reset(EGifOpenFileHandle(fd, &error));  // owns fd from here on, closed by EGifCloseFile
    if (gif_ == nullptr) {
      ::close(fd);
      throw InputError(fmt::format("{}: cannot create: {}", file.string(), GifErrorString(error)));
    }
    EGifSetGifVersion(gif_.get(), true);
    check(EGifPutScreenDesc(gif_.get(), width, height, 8, 0, nullptr), file);
    // NETSCAPE2.0: loop forever.
    static const char kApplication[] = "NETSCAPE2.0";
    static const unsigned char kLoop[3] = {1, 0, 0};
    check(EGifPutExtensionLeader(gif_.get(), APPLICATION_EXT_FUNC_CODE), file);
    check(EGifPutExtensionBlock(gif_.get(), 11, kApplication), file);
    check(EGifPutExtensionBlock(gif_.get(), 3, kLoop), file);
    check(EGifPutExtensionTrailer(gif_.get()), file);
    const std::size_t area = static_cast<std::size_t>(width) * height;
    red_.resize(area);
    green_.resize(area);
    blue_.resize(area);
    indices_.resize(area);
  }
  GifEncoder(const GifEncoder&) = delete;
  GifEncoder& operator=(const GifEncoder&) = delete;

  void add(const Picture& frame, int delay_cs, const fs::path& file) {
    const std::size_t area = static_cast<std::size_t>(width_) * height_;
    for (std::size_t i = 0; i < area; ++i) {
      blue_[i] = frame.bgr[3 * i];
      green_[i] = frame.bgr[3 * i + 1];
      red_[i] = frame.bgr[3 * i + 2];
    }
    int colours = 256;
    ColorMapObject* palette = GifMakeMapObject(256, nullptr);
    if (palette == nullptr) throw InputError(file.string() + ": out of memory for a GIF palette");
    const int quantised = GifQuantizeBuffer(static_cast<unsigned>(width_), static_cast<unsigned>(height_), &colours,
                                            red_.data(), green_.data(), blue_.data(), indices_.data(), palette->Colors);
    if (quantised == GIF_ERROR) {
      GifFreeMapObject(palette);
      throw InputError(file.string() + ": GIF colour quantisation failed");
    }
    GraphicsControlBlock control{};
    control.DisposalMode = DISPOSE_DO_NOT;
    control.UserInputFlag = false;
    control.DelayTime = delay_cs;
    control.TransparentColor = NO_TRANSPARENT_COLOR;
    GifByteType extension[4];
    const std::size_t length = EGifGCBToExtension(&control, extension);
    int rc = EGifPutExtension(gif_.get(), GRAPHICS_EXT_FUNC_CODE, static_cast<int>(length), extension);
    if (rc != GIF_ERROR) rc = EGifPutImageDesc(gif_.get(), 0, 0, width_, height_, false, palette);
    for (int y = 0; y < height_ && rc != GIF_ERROR; ++y)
      rc = EGifPutLine(gif_.get(), indices_.data() + static_cast<std::size_t>(y) * width_, width_);
    GifFreeMapObject(palette);
    check(rc, file);
  }

  void close(const fs::path& file) {
    int error = 0;
    const int rc = EGifCloseFile(gif_.release(), &error);  // frees it whatever it returns
    if (rc == GIF_ERROR) throw InputError(fmt::format("{}: cannot write: {}", file.string(), GifErrorString(error)));
  }

 private:
  void check(int rc, const fs::path& file) {
    if (rc == GIF_ERROR)
      throw InputError(fmt::format("{}: cannot write: {}", file.string(), GifErrorString(gif_->Error)));
  }

  // Closed (and the file handle with it) on every way out, a throw in the constructor included.
  struct Closer {
    void operator()(GifFileType* gif) const {
      int error = 0;
      EGifCloseFile(gif, &error);
    }
  };
  std::unique_ptr<GifFileType, Closer> gif_;
  int width_, height_;
  std::vector<GifByteType> red_, green_, blue_, indices_;
};

}  // namespace

struct VideoWriter::Impl {
  fs::path file, temporary;
  VideoFormat format = VideoFormat::Mp4;
  double fps = 30;
  int width = 0, height = 0;  // of the pictures; MP4 frames are padded to even sizes
  int frames = 0;
  std::string codec;
  cv::VideoWriter mp4;
  std::unique_ptr<GifEncoder> gif;
  bool finished = false;

  void open_mp4(int even_width, int even_height) {
    // H.264 first (what players expect); FFmpeg builds without an H.264 encoder still have MPEG-4.
    for (const char* fourcc : {"avc1", "mp4v"}) {
      if (mp4.open(temporary.string(), cv::CAP_FFMPEG,
                   cv::VideoWriter::fourcc(fourcc[0], fourcc[1], fourcc[2], fourcc[3]), fps,
                   cv::Size(even_width, even_height), true) &&
          mp4.isOpened()) {
        codec = fourcc;
        return;
      }
    }
    throw InputError(
        fmt::format("{}: OpenCV's VideoWriter cannot write MP4 here (neither avc1 nor mp4v)", file.string()));
  }

  // Hundredths of a second for frame k, so that k frames always last round(k * 100 / fps).
  int gif_delay_cs(int k) const {
    const auto at = [this](int n) { return static_cast<int>(std::lround(n * 100.0 / fps)); };
    return std::max(1, at(k + 1) - at(k));
  }
};

VideoWriter::VideoWriter(const fs::path& file, double fps) : impl_(std::make_unique<Impl>()) {
  impl_->format = check_video_path("video", file);
  if (!(fps > 0 && fps <= 100)) throw InputError(fmt::format("fps: expected a number in (0, 100], got {}", fps));
  // A GIF keeps delays in hundredths of a second, and browsers slow a delay under 2 to 10.
  if (impl_->format == VideoFormat::Gif && fps > 50)
    throw InputError(fmt::format("fps: expected at most 50 for a GIF ({}), got {}", file.string(), fps));
  impl_->file = file;
  impl_->fps = fps;
  // Beside the target (same file system, so the rename is atomic), named as every temporary of
  // Scout's (".NAME.tmp-PID-XXXXXXXX", so that commit_file removes one a killed writer left), with
  // the same extension after it, which FFmpeg reads to choose the container.
  impl_->temporary = core::temporary_path_beside(file);
  impl_->temporary += file.extension();
}

VideoWriter::~VideoWriter() {
  if (impl_->finished) return;
  impl_->mp4.release();
  impl_->gif.reset();
  std::error_code ignored;
  fs::remove(impl_->temporary, ignored);
}

void VideoWriter::add(const Picture& frame) {
  Impl& v = *impl_;
  if (frame.width <= 0 || frame.height <= 0 ||
      frame.bgr.size() != static_cast<std::size_t>(frame.width) * frame.height * 3)
    throw std::invalid_argument("VideoWriter::add: a picture whose size does not match its bytes");
  if (v.frames == 0) {
    v.width = frame.width;
    v.height = frame.height;
    if (v.format == VideoFormat::Mp4) {
      v.open_mp4(frame.width + frame.width % 2, frame.height + frame.height % 2);
    } else {
      v.gif = std::make_unique<GifEncoder>(v.temporary, frame.width, frame.height);
      v.codec = "gif";
    }
  } else if (frame.width != v.width || frame.height != v.height) {
    throw std::invalid_argument(fmt::format("VideoWriter::add: frame {} is {} x {}, the first was {} x {}", v.frames,
                                            frame.width, frame.height, v.width, v.height));
  }
  if (v.format == VideoFormat::Mp4) {
    const cv::Mat image(frame.height, frame.width, CV_8UC3, const_cast<std::uint8_t*>(frame.bgr.data()));
    if (frame.width % 2 == 0 && frame.height % 2 == 0) {
      v.mp4.write(image);
    } else {  // yuv420p needs even sizes: pad with the last row and column
      cv::Mat padded;
      cv::copyMakeBorder(image, padded, 0, frame.height % 2, 0, frame.width % 2, cv::BORDER_REPLICATE);
      v.mp4.write(padded);
    }
  } else {
    v.gif->add(frame, v.gif_delay_cs(v.frames), v.file);
  }
  ++v.frames;
}

void VideoWriter::finish() {
  Impl& v = *impl_;
  if (v.frames == 0) throw InputError(v.file.string() + ": no frames to write");
  std::error_code ec;
  if (v.format == VideoFormat::Mp4) {
    v.mp4.release();
    // VideoWriter reports no write error: read the file back, so that a full disk (a file cut
    // short, without its index) is an error and not a broken video.
    cv::VideoCapture check(v.temporary.string(), cv::CAP_FFMPEG);
    const double frames = check.isOpened() ? check.get(cv::CAP_PROP_FRAME_COUNT) : -1;
    if (frames != v.frames)
      throw InputError(fmt::format("{}: the MP4 encoder wrote {} of {} frames (is the disk full?)", v.file.string(),
                                   frames < 0 ? 0 : frames, v.frames));
  } else {
    v.gif->close(v.file);
  }
  const auto size = fs::file_size(v.temporary, ec);
  if (ec || size == 0) throw InputError(fmt::format("{}: the encoder wrote nothing", v.file.string()));
  core::commit_file(v.temporary, v.file);
  v.finished = true;
}

int VideoWriter::frames() const { return impl_->frames; }
std::string VideoWriter::codec() const { return impl_->codec; }

}  // namespace scout::render
