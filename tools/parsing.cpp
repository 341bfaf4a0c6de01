#include "tools/parsing.hpp"

#include <CLI/CLI.hpp>
#include <charconv>
#include <cstdlib>

#include "render/camera.hpp"

namespace scout::tools {

std::uint64_t parse_seed(const std::string& text) {
  std::uint64_t value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end)
    throw InputError("--seed: expected an integer in [0, 18446744073709551615], got '" + text + "'");
  return value;
}

CLI::Validator seed_validator() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        try {
          parse_seed(text);
          return {};
        } catch (const InputError&) {
          return "expected an integer in [0, 18446744073709551615], got '" + text + "'";
        }
      },
      "UINT64");
}

void add_camera_backend_option(CLI::App& command) {
  command
      .add_option_function<std::string>(
          "--camera-backend", [](const std::string& name) { setenv(render::kCameraBackendVariable, name.c_str(), 1); },
          "The camera's GL back end: auto (OSMesa where it works, else EGL), osmesa or egl (default: "
          "$SCOUT_CAMERA_BACKEND, else auto)")
      ->check(one_of(render::parse_camera_backend, "auto, osmesa, egl", "BACKEND"));
}

CLI::Validator decimal_in(long long lo, long long hi) {
  const std::string expected = "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  return CLI::Validator(
      [lo, hi, expected](std::string& text) -> std::string {
        long long value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        const bool plain = !text.empty() && ptr == end && ec == std::errc() && (text.size() == 1 || text[0] != '0');
        if (!plain || value < lo || value > hi) return expected + ", got '" + text + "'";
        return {};
      },
      "INT in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
}

std::string unknown_command_message(const CLI::App& app, int argc, char** argv) {
  const CLI::App* at = &app;
  std::string path = app.get_name();
  for (int i = 1; i < argc && argv[i][0] != '-'; ++i) {
    const std::string word = argv[i];
    auto named = const_cast<CLI::App*>(at)->get_subcommands([&](const CLI::App* sub) { return sub->check_name(word); });
    if (!named.empty()) {
      at = named.front();
      path += " " + at->get_name();
      continue;
    }
    auto all = const_cast<CLI::App*>(at)->get_subcommands([](const CLI::App*) { return true; });
    if (all.empty()) return {};  // a positional argument, e.g. the world file
    std::string names;
    for (const CLI::App* sub : all) names += (names.empty() ? "" : ", ") + sub->get_name();
    return "scout: usage error: unknown command '" + one_line(word) + "' (commands: " + names + "; see " + path +
           " --help)";
  }
  return {};
}

}  // namespace scout::tools
