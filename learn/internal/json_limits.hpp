#pragma once
/// Bounds on JSON that comes from a file (a checkpoint's config and progress), checked before
/// nlohmann's parser builds anything: a crafted file must not make the parser recurse or
/// allocate without bound.
#include <cstddef>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "learn/internal/private.hpp"

namespace scout::learn {

/// The deepest nesting of arrays and objects in the JSON a checkpoint holds (the config, the
/// progress): Scout's writer nests them 3 deep; a crafted 400,000 deep is refused before
/// nlohmann's parser builds it.
inline constexpr int kMaxJsonNesting = 16;

/// Where `text` (JSON) first opens an array or object more than `max_depth` deep; nullopt when it
/// never does. Counts brackets outside strings only; the JSON parser checks the rest.
std::optional<std::size_t> json_nested_beyond(std::string_view text, int max_depth);

/// `text` parsed as JSON, refused (std::runtime_error, a short reason) while parsing, before the
/// tree grows, when it nests more than kMaxJsonNesting deep or holds more than `max_values` values
/// (keys, values and brackets each count one): what a crafted entry can make the parser allocate
/// is bounded by `max_values`, not by the text's size.
nlohmann::json parse_json_bounded(std::string_view text, std::size_t max_values);

}  // namespace scout::learn
