#include "core/files.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
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

fs::path stamped_path_beside(const fs::path& target, const std::string& purpose) {
  std::random_device rd;
  return target.parent_path() /
         fmt::format(".{}.{}-{}-{:08x}", target.filename().string(), purpose, static_cast<long>(::getpid()), rd());
}

fs::path temporary_path_beside(const fs::path& file) { return stamped_path_beside(file, "tmp"); }

std::vector<fs::path> stale_entries(const fs::path& folder, const std::string& prefix) {
  const std::string stamp = prefix + "-";
  std::vector<std::pair<fs::file_time_type, fs::path>> found;
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= stamp.size() || name.compare(0, stamp.size(), stamp) != 0) continue;
    // The process id that follows, up to the next '-'.
    const std::size_t dash = name.find('-', stamp.size());
    const std::string digits =
        name.substr(stamp.size(), dash == std::string::npos ? std::string::npos : dash - stamp.size());
    if (digits.empty() || digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const long pid = std::stol(digits);
    // kill(pid, 0) fails with ESRCH only when no such process exists: anything else (running, or
    // another user's) keeps the entry.
    if (pid <= 0 || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
    std::error_code time_error;
    found.emplace_back(fs::last_write_time(it->path(), time_error), it->path());
  }
  std::sort(found.begin(), found.end());
  std::vector<fs::path> out;
  for (auto& [time, path] : found) out.push_back(std::move(path));
  return out;
}

int remove_stale_in(const fs::path& folder, const std::string& prefix) {
  int removed = 0;
  for (const fs::path& entry : stale_entries(folder, prefix)) {
    std::error_code ec;
    if (fs::remove_all(entry, ec) > 0 && !ec) ++removed;
  }
  return removed;
}

int remove_stale_beside(const fs::path& target, const std::string& purpose) {
  return remove_stale_in(folder_of(target), fmt::format(".{}.{}", target.filename().string(), purpose));
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
  remove_stale_beside(file, "tmp");  // what a killed writer of this file left
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
