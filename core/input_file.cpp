#include "core/input_file.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "core/error.hpp"

namespace scout::core {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void fail(const fs::path& file, const std::string& what) {
  throw InputError(one_line(file.string() + ": " + what));
}

}  // namespace

RegularFile::RegularFile(fs::path file, int fd, std::uint64_t size) : file_(std::move(file)), fd_(fd), size_(size) {}

RegularFile::RegularFile(RegularFile&& other) noexcept
    : file_(std::move(other.file_)), fd_(other.fd_), size_(other.size_) {
  other.fd_ = -1;
}

RegularFile::~RegularFile() {
  if (fd_ >= 0) ::close(fd_);
}

void RegularFile::read_all(char* out) const {
  std::uint64_t done = 0;
  while (done < size_) {
    const ssize_t n = ::pread(fd_, out + done, static_cast<std::size_t>(std::min<std::uint64_t>(size_ - done, 1 << 30)),
                              static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail(file_, fmt::format("cannot read ({})", std::strerror(errno)));
    if (n == 0) fail(file_, fmt::format("read error: the file shrank below its {} bytes while being read", size_));
    done += static_cast<std::uint64_t>(n);
  }
}

RegularFile open_regular_file(const fs::path& file) {
  // O_NONBLOCK: opening a FIFO for reading otherwise waits for a writer. stat() first would leave
  // a window in which the name is replaced by a FIFO; fstat() of what was opened leaves none.
  const int fd = ::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    if (errno == ENOENT) fail(file, "no such file");
    fail(file, fmt::format("cannot open ({})", std::strerror(errno)));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    const bool folder = S_ISDIR(st.st_mode);
    ::close(fd);
    fail(file, folder ? "is a folder, not a file" : "not a regular file (a FIFO, socket or device)");
  }
  // Reads of a regular file never block; clear the flag anyway, as its meaning for them is unspecified.
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  return RegularFile(file, fd, static_cast<std::uint64_t>(st.st_size));
}

}  // namespace scout::core
