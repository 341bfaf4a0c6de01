#pragma once
// A safetensors file split into its JSON header and its data, to be edited and joined again with
// the header length recomputed: how the hostile-file tests make one change reach the checks behind
// the parser's (learn/internal/safetensors.hpp).
#include <algorithm>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace scout::testing {

struct SafetensorsParts {
  nlohmann::ordered_json header;  ///< tensors by name, and __metadata__
  std::string data;               ///< the bytes after the header
};

inline std::uint64_t header_length(const std::string& bytes) {
  std::uint64_t n = 0;
  for (int i = 7; i >= 0; --i) n = (n << 8) | static_cast<unsigned char>(bytes.at(static_cast<std::size_t>(i)));
  return n;
}

inline std::string length_prefix(std::uint64_t n) {
  std::string out;
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((n >> (8 * i)) & 0xff));
  return out;
}

inline SafetensorsParts split(const std::string& bytes) {
  const std::uint64_t n = header_length(bytes);
  if (8 + n > bytes.size()) throw std::runtime_error("not a safetensors file");
  return {nlohmann::ordered_json::parse(bytes.substr(8, n)), bytes.substr(8 + n)};
}

/// The header text as given (no re-serialisation) with its length in front, then `data`.
inline std::string join_text(const std::string& header, const std::string& data) {
  return length_prefix(header.size()) + header + data;
}

inline std::string join(const SafetensorsParts& parts) { return join_text(parts.header.dump(), parts.data); }

/// A metadata entry (JSON text) parsed, for editing.
inline nlohmann::ordered_json metadata_json(const SafetensorsParts& parts, const std::string& key) {
  return nlohmann::ordered_json::parse(parts.header.at("__metadata__").at(key).get<std::string>());
}

/// [begin, end) of tensor `name` in the data.
inline std::pair<std::size_t, std::size_t> range_of(const SafetensorsParts& parts, const std::string& name) {
  const auto& offsets = parts.header.at(name).at("data_offsets");
  return {offsets[0].get<std::size_t>(), offsets[1].get<std::size_t>()};
}

/// A file's tensors in the order of their bytes, each with its header entry and its bytes: edit
/// the list, then assemble() lays the bytes out again back to back.
struct TensorEntry {
  std::string name;
  nlohmann::ordered_json entry;  ///< dtype, shape, data_offsets (rewritten by assemble)
  std::string bytes;
};

inline std::vector<TensorEntry> tensors_of(const SafetensorsParts& parts) {
  std::vector<TensorEntry> out;
  for (const auto& [name, entry] : parts.header.items()) {
    if (name == "__metadata__") continue;
    const auto [begin, end] = range_of(parts, name);
    out.push_back({name, entry, parts.data.substr(begin, end - begin)});
  }
  std::sort(out.begin(), out.end(), [](const TensorEntry& a, const TensorEntry& b) {
    return a.entry.at("data_offsets")[0].get<std::size_t>() < b.entry.at("data_offsets")[0].get<std::size_t>();
  });
  return out;
}

inline SafetensorsParts assemble(const std::vector<TensorEntry>& tensors, const nlohmann::ordered_json& metadata) {
  SafetensorsParts parts;
  parts.header = nlohmann::ordered_json::object();
  for (const TensorEntry& t : tensors) {
    nlohmann::ordered_json entry = t.entry;
    entry["data_offsets"] = {parts.data.size(), parts.data.size() + t.bytes.size()};
    parts.header[t.name] = entry;
    parts.data += t.bytes;
  }
  parts.header["__metadata__"] = metadata;
  return parts;
}

}  // namespace scout::testing
