// IDX files (the MNIST format). Every byte read is untrusted: a size from a header is compared
// with the bytes actually present before anything is allocated from it, and every failure is an
// InputError of one line that names the file.
#include "worlds/idx.hpp"

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

#include "core/files.hpp"
#include "core/input_file.hpp"

namespace scout::worlds {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t kImagesMagic = 0x00000803;  // unsigned byte, 3 dimensions
constexpr std::uint32_t kLabelsMagic = 0x00000801;  // unsigned byte, 1 dimension
constexpr std::size_t kImagesHeader = 16;           // magic, count, rows, cols
constexpr std::size_t kLabelsHeader = 8;            // magic, count
constexpr std::uint32_t kMaxSide = 4096;
// The largest pixel or label payload accepted (INT_MAX bytes, just under 2 GiB). Real data sets
// are far smaller; the bound stops a hostile header or a gzip bomb from exhausting memory and
// keeps every count representable in ImageSet's int fields.
constexpr std::uint64_t kMaxPayload = INT_MAX;
// A file on disk may exceed its payload by its header and, if gzipped, by deflate's framing
// (5 bytes per 64 KiB stored block at worst); anything larger cannot be valid.
constexpr std::uint64_t kMaxFileBytes = kMaxPayload + (std::uint64_t{1} << 20);

[[noreturn]] void fail(const fs::path& file, const std::string& what) {
  throw InputError(fmt::format("{}: {}", file.string(), what));
}

std::uint32_t read_be32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
}

void put_be32(std::uint8_t* p, std::uint32_t v) {
  p[0] = static_cast<std::uint8_t>(v >> 24);
  p[1] = static_cast<std::uint8_t>(v >> 16);
  p[2] = static_cast<std::uint8_t>(v >> 8);
  p[3] = static_cast<std::uint8_t>(v);
}

// Gzip is recognised by its magic bytes, not the file name: raw IDX always starts with 00 00.
bool is_gzip(const std::uint8_t* p, std::size_t n) { return n >= 2 && p[0] == 0x1f && p[1] == 0x8b; }

// Owns a z_stream so that every exit path (including exceptions) releases zlib's state.
struct Inflater {
  z_stream zs{};
  bool ready = false;
  ~Inflater() {
    if (ready) inflateEnd(&zs);
  }
};

// Decompresses a whole gzip file, member after member (as gunzip does for `cat a.gz b.gz`).
// The output grows with the data actually produced and stops past `max_out` bytes, so neither a
// header nor the gzip trailer's size field decides an allocation.
std::vector<std::uint8_t> gunzip(const std::vector<std::uint8_t>& in, std::size_t max_out, const fs::path& origin) {
  Inflater inf;
  if (inflateInit2(&inf.zs, 16 + MAX_WBITS) != Z_OK) fail(origin, "cannot initialise zlib");
  inf.ready = true;

  // zlib counts in uInt: feed and drain in slices that always fit.
  constexpr std::size_t kSlice = std::size_t{1} << 30;
  std::vector<std::uint8_t> out;
  std::size_t consumed = 0, produced = 0;
  for (;;) {
    if (produced == out.size()) {
      if (out.size() > max_out) fail(origin, "gzip data decompresses to more than the 2 GiB limit");
      const std::size_t grow = std::max<std::size_t>(out.size(), std::size_t{1} << 16);
      out.resize(std::min(out.size() + grow, max_out + 1));
    }
    const std::size_t in_avail = std::min(in.size() - consumed, kSlice);
    const std::size_t out_avail = std::min(out.size() - produced, kSlice);
    inf.zs.next_in = const_cast<Bytef*>(in.data() + consumed);  // zlib's API is not const-correct
    inf.zs.avail_in = static_cast<uInt>(in_avail);
    inf.zs.next_out = out.data() + produced;
    inf.zs.avail_out = static_cast<uInt>(out_avail);
    const int rc = inflate(&inf.zs, Z_NO_FLUSH);
    consumed += in_avail - inf.zs.avail_in;
    produced += out_avail - inf.zs.avail_out;

    if (rc == Z_STREAM_END) {
      if (consumed == in.size()) break;
      if (is_gzip(in.data() + consumed, in.size() - consumed)) {
        inflateReset(&inf.zs);  // another gzip member follows
        continue;
      }
      fail(origin, fmt::format("{} bytes of trailing garbage after the gzip data", in.size() - consumed));
    }
    if (rc == Z_OK) continue;
    if (rc == Z_BUF_ERROR) {
      if (produced == out.size()) continue;  // output full: grow it and go on
      if (consumed == in.size()) fail(origin, "truncated gzip data: the compressed stream ends early");
      fail(origin, "corrupt gzip data: no progress possible");
    }
    if (rc == Z_MEM_ERROR) fail(origin, "out of memory while decompressing gzip data");
    const char* why = inf.zs.msg != nullptr ? inf.zs.msg : "invalid stream";
    fail(origin, fmt::format("corrupt gzip data: {}", why));
  }
  out.resize(produced);
  return out;
}

std::vector<std::uint8_t> read_file(const fs::path& file) {
  // Opened without blocking and refused unless a regular file: a FIFO given as --images would
  // otherwise block in open() for ever.
  const core::RegularFile in = core::open_regular_file(file);
  if (in.size() > kMaxFileBytes) fail(file, fmt::format("{} bytes, more than the 2 GiB limit", in.size()));
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(in.size()));
  in.read_all(reinterpret_cast<char*>(bytes.data()));
  return bytes;
}

// The decompressed content (or the raw bytes themselves) of an IDX file.
struct Content {
  const std::vector<std::uint8_t>* raw = nullptr;
  std::vector<std::uint8_t> inflated;  // filled only for gzip input
  bool gzipped = false;
  const std::vector<std::uint8_t>& get() const { return gzipped ? inflated : *raw; }
};

Content open_content(const std::vector<std::uint8_t>& raw, std::size_t header, const fs::path& origin) {
  Content c;
  c.raw = &raw;
  c.gzipped = is_gzip(raw.data(), raw.size());
  if (c.gzipped) c.inflated = gunzip(raw, header + kMaxPayload, origin);
  return c;
}

std::string magic_problem(std::uint32_t magic, std::uint32_t expected) {
  const bool images = expected == kImagesMagic;
  std::string msg = fmt::format("bad magic 0x{:08x}, expected 0x{:08x} ({})", magic, expected,
                                images ? "idx3-ubyte images" : "idx1-ubyte labels");
  if (images && magic == kLabelsMagic) msg += "; this is an idx1-ubyte label file";
  if (!images && magic == kImagesMagic) msg += "; this is an idx3-ubyte image file";
  return msg;
}

// "file has Y" counts payload bytes; for gzip input they are the decompressed ones.
std::string size_problem(const std::string& header_says, std::uint64_t need, std::uint64_t have, bool gzipped) {
  const char* note = gzipped ? " (after decompression)" : "";
  if (have < need) return fmt::format("truncated: {} = {} bytes, file has {}{}", header_says, need, have, note);
  return fmt::format("trailing garbage: {} = {} bytes, file has {}{} ({} extra bytes)", header_says, need, have, note,
                     have - need);
}

void write_atomically(const fs::path& file, const std::uint8_t* header, std::size_t header_size,
                      const std::uint8_t* body, std::size_t body_size) {
  std::error_code ec;
  if (file.has_parent_path()) {
    fs::create_directories(file.parent_path(), ec);
    if (ec) fail(file, fmt::format("cannot create folder {}: {}", file.parent_path().string(), ec.message()));
  }
  // Readers never see a half-written file: the data goes to a sibling, which then replaces the
  // target in one rename (atomic on POSIX file systems).
  fs::path tmp = file;
  tmp += ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) fail(file, fmt::format("cannot write {}: {}", tmp.string(), std::strerror(errno)));
    out.write(reinterpret_cast<const char*>(header), static_cast<std::streamsize>(header_size));
    out.write(reinterpret_cast<const char*>(body), static_cast<std::streamsize>(body_size));
    out.close();
    if (!out) {
      fs::remove(tmp, ec);
      fail(file, fmt::format("write failed for {}", tmp.string()));
    }
  }
  core::commit_file(tmp, file);  // synced, renamed, the folder synced: a power cut keeps one whole file
}

}  // namespace

ImageSet parse_idx_images(const std::vector<std::uint8_t>& bytes, const fs::path& origin) {
  Content content = open_content(bytes, kImagesHeader, origin);
  const std::vector<std::uint8_t>& b = content.get();
  // The magic first: "this is a label file" says more than "the header is short".
  if (b.size() >= 4 && read_be32(b.data()) != kImagesMagic)
    fail(origin, magic_problem(read_be32(b.data()), kImagesMagic));
  if (b.size() < kImagesHeader)
    fail(origin, fmt::format("truncated header: {} bytes, an idx3-ubyte image file starts with a {}-byte header",
                             b.size(), kImagesHeader));
  const std::uint32_t count = read_be32(b.data() + 4);
  const std::uint32_t rows = read_be32(b.data() + 8);
  const std::uint32_t cols = read_be32(b.data() + 12);
  if (rows < 1 || rows > kMaxSide || cols < 1 || cols > kMaxSide)
    fail(origin, fmt::format("bad dimensions {}x{}: rows and columns must be 1..{}", rows, cols, kMaxSide));
  if (count == 0) fail(origin, "header says 0 images; an image file holds at least one");
  // count < 2^32 and rows * cols <= 2^24: the product fits in 64 bits without overflow.
  const std::uint64_t need = std::uint64_t{count} * rows * cols;
  const std::string says = fmt::format("header says {} images of {}x{}", count, rows, cols);
  if (need > kMaxPayload) fail(origin, fmt::format("{} = {} bytes, more than the 2 GiB limit", says, need));
  const std::uint64_t have = b.size() - kImagesHeader;
  if (have != need) fail(origin, size_problem(says, need, have, content.gzipped));

  ImageSet set;
  set.count = static_cast<int>(count);
  set.rows = static_cast<int>(rows);
  set.cols = static_cast<int>(cols);
  if (content.gzipped) {
    // Reuse the decompressed buffer rather than copying tens of megabytes.
    content.inflated.erase(content.inflated.begin(), content.inflated.begin() + kImagesHeader);
    set.pixels = std::move(content.inflated);
  } else {
    set.pixels.assign(b.begin() + kImagesHeader, b.end());
  }
  return set;
}

std::vector<std::uint8_t> parse_idx_labels(const std::vector<std::uint8_t>& bytes, const fs::path& origin) {
  Content content = open_content(bytes, kLabelsHeader, origin);
  const std::vector<std::uint8_t>& b = content.get();
  if (b.size() >= 4 && read_be32(b.data()) != kLabelsMagic)
    fail(origin, magic_problem(read_be32(b.data()), kLabelsMagic));
  if (b.size() < kLabelsHeader)
    fail(origin, fmt::format("truncated header: {} bytes, an idx1-ubyte label file starts with a {}-byte header",
                             b.size(), kLabelsHeader));
  const std::uint32_t count = read_be32(b.data() + 4);
  if (count == 0) fail(origin, "header says 0 labels; a label file holds at least one");
  const std::string says = fmt::format("header says {} labels", count);
  if (count > kMaxPayload) fail(origin, fmt::format("{} = {} bytes, more than the 2 GiB limit", says, count));
  const std::uint64_t have = b.size() - kLabelsHeader;
  if (have != count) fail(origin, size_problem(says, count, have, content.gzipped));

  if (content.gzipped) {
    content.inflated.erase(content.inflated.begin(), content.inflated.begin() + kLabelsHeader);
    return std::move(content.inflated);
  }
  return {b.begin() + kLabelsHeader, b.end()};
}

ImageSet read_idx_images(const fs::path& file) { return parse_idx_images(read_file(file), file); }

std::vector<std::uint8_t> read_idx_labels(const fs::path& file) { return parse_idx_labels(read_file(file), file); }

void write_idx_images(const fs::path& file, const ImageSet& images) {
  // A set that its own reader would refuse is a caller's bug, not bad input.
  if (images.count < 1 || images.rows < 1 || images.rows > static_cast<int>(kMaxSide) || images.cols < 1 ||
      images.cols > static_cast<int>(kMaxSide))
    throw std::invalid_argument(fmt::format("write_idx_images({}): bad shape {} images of {}x{}", file.string(),
                                            images.count, images.rows, images.cols));
  const std::uint64_t need = std::uint64_t(images.count) * std::uint64_t(images.rows) * std::uint64_t(images.cols);
  if (need > kMaxPayload || images.pixels.size() != need)
    throw std::invalid_argument(fmt::format("write_idx_images({}): {} pixels for {} images of {}x{}", file.string(),
                                            images.pixels.size(), images.count, images.rows, images.cols));
  std::uint8_t header[kImagesHeader];
  put_be32(header, kImagesMagic);
  put_be32(header + 4, static_cast<std::uint32_t>(images.count));
  put_be32(header + 8, static_cast<std::uint32_t>(images.rows));
  put_be32(header + 12, static_cast<std::uint32_t>(images.cols));
  write_atomically(file, header, sizeof header, images.pixels.data(), images.pixels.size());
}

void write_idx_labels(const fs::path& file, const std::vector<std::uint8_t>& labels) {
  if (labels.empty() || labels.size() > kMaxPayload)
    throw std::invalid_argument(fmt::format("write_idx_labels({}): {} labels", file.string(), labels.size()));
  std::uint8_t header[kLabelsHeader];
  put_be32(header, kLabelsMagic);
  put_be32(header + 4, static_cast<std::uint32_t>(labels.size()));
  write_atomically(file, header, sizeof header, labels.data(), labels.size());
}

}  // namespace scout::worlds
