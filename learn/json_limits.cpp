#include "learn/internal/json_limits.hpp"

#include <fmt/format.h>

#include <stdexcept>

namespace scout::learn {

std::optional<std::size_t> json_nested_beyond(std::string_view text, int max_depth) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return i;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return std::nullopt;
}

nlohmann::json parse_json_bounded(std::string_view text, std::size_t max_values) {
  if (const std::optional<std::size_t> at = json_nested_beyond(text, kMaxJsonNesting))
    throw std::runtime_error(
        fmt::format("arrays and objects nested more than {} deep (at byte {})", kMaxJsonNesting, *at));
  std::size_t values = 0;
  const nlohmann::json::parser_callback_t count = [&](int, nlohmann::json::parse_event_t, nlohmann::json&) {
    if (++values > max_values) throw std::runtime_error(fmt::format("more than {} values", max_values));
    return true;
  };
  return nlohmann::json::parse(text, count);
}

}  // namespace scout::learn
