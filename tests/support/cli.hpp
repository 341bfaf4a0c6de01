#pragma once
// Helpers for end-to-end tests of the `scout` program and for writing raw IDX files.
#include <sys/wait.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <string>

namespace scout::testing {

/// What a command did: its exit status (-1 if it did not exit normally) and its output.
struct CliResult {
  int status = -1;
  std::string output;  ///< stdout and stderr together
};

/// Runs `program ARGS` through the shell with stderr folded into stdout.
inline CliResult run_cli(const std::string& program, const std::string& args) {
  const std::string command = program + " " + args + " 2>&1";
  CliResult r;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe)) r.output += buffer.data();
  const int raw = pclose(pipe);
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return r;
}

/// Appends a 32-bit big-endian integer (IDX headers).
inline void put_u32_be(std::string& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<char>((v >> shift) & 0xFF));
}

/// Starts raw IDX image and label files of `count` rows x cols images (their headers).
inline void put_idx_headers(std::string& images, std::string& labels, int count, int rows, int cols) {
  put_u32_be(images, 0x803);
  put_u32_be(images, static_cast<std::uint32_t>(count));
  put_u32_be(images, static_cast<std::uint32_t>(rows));
  put_u32_be(images, static_cast<std::uint32_t>(cols));
  put_u32_be(labels, 0x801);
  put_u32_be(labels, static_cast<std::uint32_t>(count));
}

}  // namespace scout::testing
