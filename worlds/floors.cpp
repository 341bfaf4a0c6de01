// The world's floors: a data set split or one PNG file, checked against the camera's limit.
#include "worlds/floors.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string_view>
#include <system_error>

#include "worlds/dataset.hpp"

namespace scout::worlds {

namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const World& world, const std::string& field, const std::string& message) {
  throw InputError(one_line(field_location(world, field) + ": " + message));
}

void check_floor_size(const World& world, const std::string& field, long long width_px, long long height_px) {
  if (width_px > kMaxFloorPx || height_px > kMaxFloorPx)
    fail(world, field,
         "expected a floor of at most " + std::to_string(kMaxFloorPx) + " x " + std::to_string(kMaxFloorPx) +
             " pixels (the camera's limit), got " + std::to_string(width_px) + " x " + std::to_string(height_px));
}

constexpr std::array<std::uint8_t, 8> kPngSignature = {0x89, 0x50, 0x4E, 0x47, 0x0D, 0x0A, 0x1A, 0x0A};
// A 512 x 512 PNG is at most a few MiB even at 16-bit RGBA stored uncompressed; the cap only
// keeps a huge file named .png from being read into memory.
constexpr std::size_t kMaxPngBytes = std::size_t{64} << 20;

// Sends everything written to fd 2 (stderr) to /dev/null while it lives, and quiets OpenCV's
// logger: libpng reports errors such as "libpng error: Read Error" there itself, before OpenCV
// returns an empty image, and a loader's failure must be its one-line InputError only.
// fd 2 is process-wide, so another thread's stderr output in these milliseconds is lost too.
class SilencedStderr {
 public:
  SilencedStderr() : previous_level_(cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT)) {
    std::fflush(stderr);
    saved_ = ::fcntl(STDERR_FILENO, F_DUPFD_CLOEXEC, 0);
    if (saved_ < 0) return;
    const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (null < 0 || ::dup2(null, STDERR_FILENO) < 0) {
      if (null >= 0) ::close(null);
      ::close(saved_);
      saved_ = -1;
      return;
    }
    ::close(null);
  }
  ~SilencedStderr() {
    std::fflush(stderr);
    if (saved_ >= 0) {
      ::dup2(saved_, STDERR_FILENO);
      ::close(saved_);
    }
    cv::utils::logging::setLogLevel(previous_level_);
  }
  SilencedStderr(const SilencedStderr&) = delete;
  SilencedStderr& operator=(const SilencedStderr&) = delete;

 private:
  cv::utils::logging::LogLevel previous_level_;
  int saved_ = -1;
};

// The whole file, or an error text (strerror) when it cannot be read; `too_large` when it has
// more than kMaxPngBytes.
struct FileBytes {
  std::vector<std::uint8_t> bytes;
  std::string error;
  bool too_large = false;
};

FileBytes read_file(const fs::path& file) {
  FileBytes out;
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    out.error = std::strerror(errno);
    return out;
  }
  std::array<std::uint8_t, 65536> buf{};
  for (;;) {
    const ssize_t n = ::read(fd, buf.data(), buf.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      out.error = std::strerror(errno);
      break;
    }
    if (n == 0) break;
    out.bytes.insert(out.bytes.end(), buf.begin(), buf.begin() + n);
    if (out.bytes.size() > kMaxPngBytes) {
      out.too_large = true;
      break;
    }
  }
  ::close(fd);
  return out;
}

std::uint32_t big_endian_u32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
}

FloorSet load_png(const World& world) {
  const fs::path& file = world.floor.image;
  const std::string got = "got '" + file.string() + "'";
  const auto not_a_png = [&](const std::string& why) {
    fail(world, "floor.image", "expected a PNG file, " + got + " (" + why + ")");
  };
  const auto unreadable = [&]() {
    fail(world, "floor.image", "expected a readable PNG image, " + got + " (corrupt or truncated)");
  };

  std::error_code ec;
  const fs::file_status status = fs::status(file, ec);
  if (status.type() == fs::file_type::not_found) not_a_png("no such file");
  if (ec) not_a_png("cannot read it: " + ec.message());
  if (fs::is_directory(status)) not_a_png("a folder");
  if (!fs::is_regular_file(status)) not_a_png("not a regular file");

  const FileBytes read = read_file(file);
  if (!read.error.empty()) not_a_png("cannot read it: " + read.error);
  if (read.too_large) not_a_png("larger than " + std::to_string(kMaxPngBytes >> 20) + " MiB");
  const std::vector<std::uint8_t>& bytes = read.bytes;
  if (bytes.empty()) not_a_png("not a PNG: the file is empty");
  if (bytes.size() < kPngSignature.size() || !std::equal(kPngSignature.begin(), kPngSignature.end(), bytes.begin()))
    not_a_png("not a PNG: bad signature");

  // The first chunk is IHDR (length 13): its width and height let an oversized floor be refused
  // before the decoder allocates it.
  constexpr std::size_t kIhdrEnd = 8 + 4 + 4 + 13 + 4;  // signature, length, type, data, CRC
  if (bytes.size() < kIhdrEnd || big_endian_u32(&bytes[8]) != 13 || std::memcmp(&bytes[12], "IHDR", 4) != 0)
    unreadable();
  const std::uint32_t width = big_endian_u32(&bytes[16]);
  const std::uint32_t height = big_endian_u32(&bytes[20]);
  if (width == 0 || height == 0 || width > 0x7fffffffu || height > 0x7fffffffu) unreadable();
  check_floor_size(world, "floor.image", width, height);

  cv::Mat gray;
  {
    const SilencedStderr quiet;
    try {
      const cv::Mat encoded(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<std::uint8_t*>(bytes.data()));
      gray = cv::imdecode(encoded, cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception&) {
      gray.release();
    }
  }
  if (gray.empty() || gray.type() != CV_8UC1 || gray.cols != static_cast<int>(width) ||
      gray.rows != static_cast<int>(height))
    unreadable();

  FloorSet set;
  set.images.count = 1;
  set.images.rows = gray.rows;
  set.images.cols = gray.cols;
  set.images.pixels.resize(static_cast<std::size_t>(gray.rows) * gray.cols);
  for (int r = 0; r < gray.rows; ++r)
    std::copy_n(gray.ptr<std::uint8_t>(r), gray.cols,
                set.images.pixels.data() + static_cast<std::size_t>(r) * gray.cols);
  set.labels = {-1};
  set.source = file.string();
  set.files = {file};
  return set;
}

FloorSet load_dataset(const World& world, const fs::path& data_root) {
  fs::path folder;
  LabeledImages data;
  try {
    folder = dataset_folder(world.floor.dataset, data_root);
    data = load_split(folder, world.floor.split);
  } catch (const InputError& e) {
    // The data set's own message names its folder or file; the prefix names the world's field.
    // The project's MNIST is the data set most often missing: say how to install it.
    std::error_code ec;
    const bool mnist_missing =
        (world.floor.dataset == "mnist" || world.floor.dataset == "mnist-10k") && !fs::is_directory(folder, ec);
    const std::string hint =
        !mnist_missing ? ""
        : data_root == default_data_root()
            ? " (run `scout data` to install MNIST there, or set SCOUT_DATA to a data folder that has it)"
            : " (run `scout data --data " + data_root.string() + "` to install MNIST there)";
    fail(world, "floor.dataset", e.what() + hint);
  }
  FloorSet set;
  set.images = std::move(data.images);
  set.labels.assign(data.labels.begin(), data.labels.end());
  set.source = world.floor.dataset;
  set.split = world.floor.split;
  set.files = std::move(data.files);
  if (set.images.count == 0)
    fail(world, "floor.split", "expected a split with images, got an empty one in " + folder.string());
  if (world.floor.index && *world.floor.index >= set.images.count)
    fail(world, "floor.index",
         "expected an index in [0, " + std::to_string(set.images.count - 1) + "] or random, got " +
             std::to_string(*world.floor.index));
  return set;
}

}  // namespace

FloorSet load_floors(const World& world, const std::filesystem::path& data_root) {
  const bool png = !world.floor.image.empty();
  FloorSet set = png ? load_png(world) : load_dataset(world, data_root);
  set.composer = FloorComposer(world, set.images.cols, set.images.rows);
  check_floor_size(world,
                   png                   ? "floor.image"
                   : world.floor.size_px ? "floor.size_px"
                                         : "floor.dataset",
                   set.width_px(), set.height_px());
  check_against_floor(world, set.width_px(), set.height_px());
  return set;
}

}  // namespace scout::worlds
