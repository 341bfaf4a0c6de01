#pragma once
/// Errors for bad input: every message is one line naming the file, the field and what was
/// expected (e.g. "worlds/mnist.yaml:12: camera.patch_px: expected an integer in [1, 28], got 40").
/// Thrown by loaders, caught once in the CLI, printed as one line with exit status 1.
#include <stdexcept>
#include <string>
#include <string_view>

namespace scout {

/// Input that the user can fix: a file, a field, a command-line value.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Makes any text safe inside a one-line message: ASCII control characters (newlines above all,
/// e.g. in a file name or a library's message) become visible escapes; other bytes pass through.
std::string one_line(std::string_view text);

/// A library's message fit for one line: its first line (LibTorch appends a backtrace), without
/// the "[file.cpp:123] " prefix c10d puts in front, clipped to 200 bytes, then one_line().
std::string first_line(std::string_view what);

}  // namespace scout
