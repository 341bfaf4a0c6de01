#include "core/files.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <random>

#include "core/error.hpp"
#include "core/fault_injection.hpp"

namespace scout::core {

namespace fs = std::filesystem;

namespace {

// Closes a descriptor on every path out.
struct Descriptor {
  int fd = -1;
  ~Descriptor() {
    if (fd >= 0) ::close(fd);
  }
};

[[noreturn]] void fail(const fs::path& file, int error) {
  throw InputError(fmt::format("{}: cannot write ({})", file.string(), std::strerror(error)));
}

// fsync of a file or folder; `name` is the file the user knows of.
void sync_path(const fs::path& path, int flags, const fs::path& name) {
  Descriptor d{::open(path.c_str(), flags | O_CLOEXEC)};
  if (d.fd < 0) fail(name, errno);
  if (::fsync(d.fd) != 0) fail(name, errno);
}

fs::path folder_of(const fs::path& file) {
  const fs::path parent = file.parent_path();
  return parent.empty() ? fs::path(".") : parent;
}

}  // namespace

fs::path temporary_path_beside(const fs::path& file) {
  std::random_device rd;
  return file.parent_path() / fmt::format(".{}.tmp-{:08x}", file.filename().string(), rd());
}

void sync_directory(const fs::path& folder) { sync_path(folder, O_RDONLY | O_DIRECTORY, folder); }

void commit_file(const fs::path& temporary, const fs::path& file) {
  std::error_code ec;
  try {
    sync_path(temporary, O_RDONLY, file);
  } catch (...) {
    fs::remove(temporary, ec);
    throw;
  }
  fs::rename(temporary, file, ec);
  if (ec) {
    const int error = ec.value();
    fs::remove(temporary, ec);
    fail(file, error);
  }
  sync_directory(folder_of(file));
}

void write_file_atomic(const fs::path& file, const std::string& text) {
  const fs::path tmp = temporary_path_beside(file);
  Descriptor d{::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666)};
  if (d.fd < 0) fail(file, errno);
  auto give_up = [&](int error) {
    std::error_code ec;
    fs::remove(tmp, ec);
    fail(file, error);
  };
  // Two halves, with the hard-kill tests' point between them (a kill mid-write).
  const std::size_t half = text.size() / 2;
  for (const auto& [from, to] : {std::pair{std::size_t{0}, half}, std::pair{half, text.size()}}) {
    for (std::size_t done = from; done < to;) {
      const ssize_t n = ::write(d.fd, text.data() + done, to - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) give_up(n < 0 ? errno : ENOSPC);
      done += static_cast<std::size_t>(n);
    }
    if (from == 0) fault_point("file-write");
  }
  const int closed = ::close(d.fd);
  d.fd = -1;
  if (closed != 0) give_up(errno);
  commit_file(tmp, file);
}

}  // namespace scout::core
