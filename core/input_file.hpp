#pragma once
/// Reading a file a user names as input (a checkpoint, an IDX file) without trusting what it is:
/// opened without blocking and refused unless it is a regular file, so that a FIFO, a terminal or
/// a device given as `--images` or as a checkpoint is one line of error instead of a process that
/// blocks in open() or read() for ever (and ignores SIGTERM meanwhile); its size is known before a
/// byte is read, so that a caller refuses a file beyond its bound from the size alone.
#include <cstdint>
#include <filesystem>

namespace scout::core {

/// An open regular file (open_regular_file), closed when destroyed.
class RegularFile {
 public:
  RegularFile(const RegularFile&) = delete;
  RegularFile& operator=(const RegularFile&) = delete;
  RegularFile(RegularFile&& other) noexcept;
  RegularFile& operator=(RegularFile&&) = delete;
  ~RegularFile();

  /// The size when opened (fstat), in bytes.
  std::uint64_t size() const { return size_; }
  /// Reads the whole file, size() bytes, into `out`. Throws InputError naming the file if a read
  /// fails or the file is no longer that long.
  void read_all(char* out) const;

 private:
  friend RegularFile open_regular_file(const std::filesystem::path& file);
  RegularFile(std::filesystem::path file, int fd, std::uint64_t size);
  std::filesystem::path file_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

/// Opens `file` for reading, never blocking: throws InputError "FILE: no such file", "FILE: is a
/// folder, not a file", "FILE: not a regular file (a FIFO, socket or device)" or "FILE: cannot
/// open (REASON)".
RegularFile open_regular_file(const std::filesystem::path& file);

}  // namespace scout::core
