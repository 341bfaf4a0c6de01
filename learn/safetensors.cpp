#include "learn/internal/safetensors.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>

#include "core/error.hpp"

namespace scout::learn::safetensors {

static_assert(std::endian::native == std::endian::little,
              "safetensors stores little-endian bytes; Scout copies them as they are");

namespace {

using json = nlohmann::json;

constexpr std::size_t kLengthBytes = 8;
// The file's object (depth 0), a tensor's or the metadata's object (1), a shape or data_offsets (2).
constexpr int kMaxDepth = 2;

std::uint64_t read_le64(std::span<const std::byte> bytes) {
  std::uint64_t value = 0;
  for (int i = 7; i >= 0; --i) value = (value << 8) | static_cast<std::uint8_t>(bytes[i]);
  return value;
}

void append_le64(std::string& out, std::uint64_t value) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((value >> (8 * i)) & 0xff));
}

bool parse_dtype(const std::string& text, DType& dtype) {
  if (text == "F32")
    dtype = DType::F32;
  else if (text == "I64")
    dtype = DType::I64;
  else
    return false;
  return true;
}

// The product of a shape, or -1 where it exceeds `limit`.
std::int64_t checked_elements(const std::vector<std::int64_t>& shape, std::int64_t limit) {
  std::int64_t n = 1;
  for (const std::int64_t d : shape) {
    if (d < 0 || (d != 0 && n > limit / d)) return -1;
    n *= d;
  }
  return n <= limit ? n : -1;
}

// Parse events (each key, value and bracket is one) a header of `limits` can need: per tensor its
// name, its object's start and end, the dtype's key and value, the shape's key, start, end and up
// to max_rank sizes, and data_offsets' key, start, end and two values (13 + max_rank); per metadata
// entry a key and a value; the brackets around them.
std::size_t max_events(const Limits& limits) {
  return (limits.max_tensors + 1) * (13 + static_cast<std::size_t>(limits.max_rank)) + 2 * limits.max_metadata_entries +
         16;
}

}  // namespace

const char* to_string(DType dtype) { return dtype == DType::F32 ? "F32" : "I64"; }
std::size_t element_size(DType dtype) { return dtype == DType::F32 ? 4 : 8; }

const TensorView* File::find(const std::string& name) const {
  for (const TensorView& t : tensors)
    if (t.name == name) return &t;
  return nullptr;
}

bool looks_like_zip(std::span<const std::byte> bytes) {
  return bytes.size() >= 4 && bytes[0] == std::byte{'P'} && bytes[1] == std::byte{'K'} && bytes[2] == std::byte{3} &&
         bytes[3] == std::byte{4};
}

std::string write(const std::vector<TensorBytes>& tensors, const std::map<std::string, std::string>& metadata,
                  const Limits& limits) {
  // nlohmann's ordered_json keeps the tensors in the order given, as their bytes follow.
  nlohmann::ordered_json header = nlohmann::ordered_json::object();
  std::uint64_t offset = 0;
  std::set<std::string> names;
  if (tensors.size() > limits.max_tensors)
    throw std::invalid_argument(fmt::format("safetensors: {} tensors, at most {}", tensors.size(), limits.max_tensors));
  if (metadata.size() > limits.max_metadata_entries)
    throw std::invalid_argument(
        fmt::format("safetensors: {} metadata entries, at most {}", metadata.size(), limits.max_metadata_entries));
  for (const TensorBytes& t : tensors) {
    if (t.name.empty() || t.name == "__metadata__" || t.name.size() > limits.max_name_bytes)
      throw std::invalid_argument(
          fmt::format("safetensors: a tensor name of 1 to {} bytes other than __metadata__, got '{}'",
                      limits.max_name_bytes, t.name.substr(0, 80)));
    if (!names.insert(t.name).second) throw std::invalid_argument("safetensors: tensor " + t.name + " twice");
    if (t.shape.size() > static_cast<std::size_t>(limits.max_rank))
      throw std::invalid_argument("safetensors: tensor " + t.name + " has too many dimensions");
    const std::int64_t n = checked_elements(t.shape, std::numeric_limits<std::int64_t>::max() / 8);
    if (n < 0 || static_cast<std::uint64_t>(n) * element_size(t.dtype) != t.bytes.size())
      throw std::invalid_argument(
          fmt::format("safetensors: tensor {}: {} bytes do not make its shape", t.name, t.bytes.size()));
    header[t.name] = {
        {"dtype", to_string(t.dtype)}, {"shape", t.shape}, {"data_offsets", {offset, offset + t.bytes.size()}}};
    offset += t.bytes.size();
  }
  if (!metadata.empty()) header["__metadata__"] = metadata;
  std::string text = header.dump();
  text.append((8 - text.size() % 8) % 8, ' ');
  if (text.size() > limits.max_header_bytes)
    throw std::invalid_argument(fmt::format("safetensors: a header of {} bytes, more than the {} a reader takes",
                                            text.size(), limits.max_header_bytes));
  std::string out;
  out.reserve(kLengthBytes + text.size() + offset);
  append_le64(out, text.size());
  out += text;
  for (const TensorBytes& t : tensors) out.append(reinterpret_cast<const char*>(t.bytes.data()), t.bytes.size());
  return out;
}

namespace {

// One parse: the checks in the order the bytes are read, each failure one line naming `origin`.
class Parser {
 public:
  Parser(std::span<const std::byte> bytes, const std::string& origin, const Limits& limits)
      : bytes_(bytes), origin_(origin), limits_(limits) {}

  File run() {
    if (bytes_.size() < kLengthBytes)
      fail(fmt::format("{} bytes, fewer than the 8 of the header length", bytes_.size()));
    const std::uint64_t header_bytes = read_le64(bytes_.first(kLengthBytes));
    if (header_bytes > bytes_.size() - kLengthBytes)
      fail(fmt::format("the header length says {} bytes, the file has {} after it", header_bytes,
                       bytes_.size() - kLengthBytes));
    if (header_bytes > limits_.max_header_bytes)
      fail(fmt::format("a header of {} bytes, more than the {} Scout reads", header_bytes, limits_.max_header_bytes));
    const std::string_view text(reinterpret_cast<const char*>(bytes_.data()) + kLengthBytes, header_bytes);
    const json header = parse_header(text);
    data_ = bytes_.subspan(kLengthBytes + header_bytes);
    File file;
    for (const auto& [name, entry] : header.items()) {
      if (name == "__metadata__")
        read_metadata(entry, file);
      else
        file.tensors.push_back(read_tensor(name, entry));
    }
    check_tiling(file);
    return file;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(origin_ + ": not a valid safetensors file: " + one_line(what));
  }

  // The header as JSON: nesting, the number of values and duplicate names are refused from the
  // parser's callback, before the tree grows past what a valid header makes.
  json parse_header(std::string_view text) const {
    std::vector<std::set<std::string>> keys(kMaxDepth + 1);
    std::size_t events = 0;
    const std::size_t event_limit = max_events(limits_);
    const json::parser_callback_t check = [&](int depth, json::parse_event_t event, json& parsed) {
      if (++events > event_limit)
        fail(fmt::format("the header holds more than the {} values {} tensors need", event_limit, limits_.max_tensors));
      if (event == json::parse_event_t::object_start || event == json::parse_event_t::array_start) {
        if (depth > kMaxDepth) fail(fmt::format("the header nests deeper than {} levels", kMaxDepth + 1));
        if (event == json::parse_event_t::object_start) keys[static_cast<std::size_t>(depth)].clear();
      } else if (event == json::parse_event_t::key) {
        const std::string& key = parsed.get_ref<const std::string&>();
        if (!keys[static_cast<std::size_t>(depth - 1)].insert(key).second)
          fail("the header names '" + key.substr(0, 80) + "' twice");
      }
      return true;
    };
    json header;
    try {
      header = json::parse(text, check);
    } catch (const json::exception& e) {
      fail("the header is not JSON (" + first_line(e.what()) + ")");
    }
    if (!header.is_object()) fail("the header is not a JSON object");
    return header;
  }

  void read_metadata(const json& entry, File& file) const {
    if (!entry.is_object()) fail("__metadata__ is not a map of strings to strings");
    if (entry.size() > limits_.max_metadata_entries)
      fail(fmt::format("__metadata__ has {} entries, at most {}", entry.size(), limits_.max_metadata_entries));
    for (const auto& [key, value] : entry.items()) {
      if (!value.is_string()) fail("__metadata__: " + key.substr(0, 80) + " is not a string");
      file.metadata[key] = value.get<std::string>();
    }
  }

  TensorView read_tensor(const std::string& name, const json& entry) {
    if (++tensors_ > limits_.max_tensors) fail(fmt::format("more than {} tensors", limits_.max_tensors));
    const std::string at = "tensor '" + name.substr(0, 80) + "'";
    if (name.empty() || name.size() > limits_.max_name_bytes)
      fail(fmt::format("a tensor name of {} bytes (1 to {})", name.size(), limits_.max_name_bytes));
    if (!entry.is_object() || entry.size() != 3 || !entry.contains("dtype") || !entry.contains("shape") ||
        !entry.contains("data_offsets"))
      fail(at + ": expected exactly dtype, shape and data_offsets");
    TensorView view;
    view.name = name;
    const json& dtype = entry.at("dtype");
    if (!dtype.is_string() || !parse_dtype(dtype.get<std::string>(), view.dtype))
      fail(at + ": dtype " + dtype.dump().substr(0, 40) + " (Scout stores F32 and I64 only)");
    const json& shape = entry.at("shape");
    if (!shape.is_array() || shape.size() > static_cast<std::size_t>(limits_.max_rank))
      fail(fmt::format("{}: the shape is not a list of at most {} sizes", at, limits_.max_rank));
    for (const json& size : shape) {
      if (!size.is_number_unsigned() || size.get<std::uint64_t>() > std::numeric_limits<std::int64_t>::max())
        fail(at + ": a size that is not a whole number >= 0: " + size.dump().substr(0, 40));
      view.shape.push_back(size.get<std::int64_t>());
    }
    const json& offsets = entry.at("data_offsets");
    if (!offsets.is_array() || offsets.size() != 2 || !offsets[0].is_number_unsigned() ||
        !offsets[1].is_number_unsigned())
      fail(at + ": data_offsets is not two whole numbers >= 0");
    const std::uint64_t begin = offsets[0].get<std::uint64_t>(), end = offsets[1].get<std::uint64_t>();
    if (begin > end) fail(fmt::format("{}: data_offsets [{}, {}] run backwards", at, begin, end));
    if (end > data_.size())
      fail(fmt::format("{}: data_offsets [{}, {}], the data after the header is {} bytes", at, begin, end,
                       data_.size()));
    // At most 2^60 elements: their byte count cannot overflow; more cannot fit a file Scout reads.
    const std::int64_t elements = checked_elements(view.shape, std::int64_t{1} << 60);
    if (elements < 0 || static_cast<std::uint64_t>(elements) * element_size(view.dtype) != end - begin)
      fail(fmt::format("{}: {} {} takes {} bytes, data_offsets give {}", at, to_string(view.dtype), shape.dump(),
                       elements < 0 ? std::string("more than 2^60 elements' worth of")
                                    : std::to_string(static_cast<std::uint64_t>(elements) * element_size(view.dtype)),
                       end - begin));
    view.bytes = data_.subspan(begin, end - begin);
    return view;
  }

  // The byte ranges, in order, tile the data exactly: no gap, no overlap, nothing after.
  void check_tiling(File& file) const {
    std::sort(file.tensors.begin(), file.tensors.end(), [](const TensorView& a, const TensorView& b) {
      return a.bytes.data() != b.bytes.data() ? a.bytes.data() < b.bytes.data() : a.bytes.size() < b.bytes.size();
    });
    std::uint64_t expected = 0;
    for (const TensorView& t : file.tensors) {
      const auto begin = static_cast<std::uint64_t>(t.bytes.data() - data_.data());
      if (begin != expected)
        fail(fmt::format(
            "tensor '{}' starts at byte {} of the data, where {} (the tensors follow each other "
            "without gap or overlap)",
            t.name.substr(0, 80), begin,
            expected == 0 ? std::string("the data begins") : "the one before it ends at " + std::to_string(expected)));
      expected = begin + t.bytes.size();
    }
    if (expected != data_.size())
      fail(fmt::format("the tensors end at byte {} of the data, {} bytes before the file does", expected,
                       data_.size() - expected));
  }

  std::span<const std::byte> bytes_;
  const std::string& origin_;
  const Limits& limits_;
  std::span<const std::byte> data_;
  std::size_t tensors_ = 0;
};

}  // namespace

File parse(std::span<const std::byte> bytes, const std::string& origin, const Limits& limits) {
  return Parser(bytes, origin, limits).run();
}

}  // namespace scout::learn::safetensors
