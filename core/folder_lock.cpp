#include "core/folder_lock.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/error.hpp"

namespace scout::core {

bool take_folder_for_this_process(const std::filesystem::path& folder) {
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw InputError(fmt::format("{}: cannot open ({})", folder.string(), std::strerror(errno)));
  int taken = 0;
  do {
    taken = ::flock(fd, LOCK_EX | LOCK_NB);
  } while (taken != 0 && errno == EINTR);
  if (taken != 0) {
    const int error = errno;
    ::close(fd);
    if (error == EWOULDBLOCK) return false;
    throw InputError(fmt::format("{}: cannot lock ({})", folder.string(), std::strerror(error)));
  }
  // The descriptor stays open, and the lock held, for the rest of the process: the kernel
  // releases both when it exits, however it exits. O_CLOEXEC keeps it out of child processes.
  return true;
}

}  // namespace scout::core
