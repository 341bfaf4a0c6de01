#include "core/files.hpp"

#include <fmt/format.h>

#include <fstream>
#include <random>

#include "core/error.hpp"

namespace scout::core {

namespace fs = std::filesystem;

fs::path temporary_path_beside(const fs::path& file) {
  std::random_device rd;
  return file.parent_path() / fmt::format(".{}.tmp-{:08x}", file.filename().string(), rd());
}

void write_file_atomic(const fs::path& file, const std::string& text) {
  const fs::path tmp = temporary_path_beside(file);
  std::error_code ec;
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.close();
    if (!out) {
      fs::remove(tmp, ec);
      throw InputError(file.string() + ": cannot write");
    }
  }
  fs::rename(tmp, file, ec);
  if (ec) {
    const std::string why = ec.message();
    fs::remove(tmp, ec);
    throw InputError(file.string() + ": cannot write (" + why + ")");
  }
}

}  // namespace scout::core
