// The safetensors format (learn/internal/safetensors.hpp): what Scout writes reads back bit for bit, and
// every malformed file is refused in one line naming the part, without allocating beyond it.
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "learn/internal/safetensors.hpp"

namespace scout::learn::safetensors {
namespace {

std::span<const std::byte> as_bytes(const std::string& s) {
  return {reinterpret_cast<const std::byte*>(s.data()), s.size()};
}

template <typename T>
std::span<const std::byte> as_bytes(const std::vector<T>& v) {
  return {reinterpret_cast<const std::byte*>(v.data()), v.size() * sizeof(T)};
}

// A file from a header text and `data_bytes` bytes of data.
std::string file_with_header(const std::string& header, std::size_t data_bytes) {
  std::string out;
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((header.size() >> (8 * i)) & 0xff));
  return out + header + std::string(data_bytes, '\0');
}

std::string refusal(const std::string& file) {
  try {
    parse(as_bytes(file), "f.safetensors");
  } catch (const InputError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(Safetensors, WhatIsWrittenReadsBackBitForBit) {
  const std::vector<float> weights = {1.5f, -2.0f, 0.0f, 3.25f, 1e-30f, -0.0f};
  const std::vector<std::int64_t> counts = {7, -1, std::numeric_limits<std::int64_t>::max()};
  const std::string file = write({{"goal.head.weight", DType::F32, {2, 3}, as_bytes(weights)},
                                  {"adam.step", DType::I64, {3}, as_bytes(counts)},
                                  {"empty", DType::F32, {0, 4}, {}}},
                                 {{"config", "{\"classes\": 10}"}, {"format", "2"}});
  const std::uint64_t header = static_cast<std::uint8_t>(file[0]) | (static_cast<std::uint8_t>(file[1]) << 8);
  EXPECT_EQ(header % 8, 0u) << "the header is padded to 8 bytes";
  const File parsed = parse(as_bytes(file), "f.safetensors");
  EXPECT_EQ(parsed.metadata.at("config"), "{\"classes\": 10}");
  EXPECT_EQ(parsed.metadata.at("format"), "2");
  ASSERT_EQ(parsed.tensors.size(), 3u);
  const TensorView* w = parsed.find("goal.head.weight");
  ASSERT_NE(w, nullptr);
  EXPECT_EQ(w->dtype, DType::F32);
  EXPECT_EQ(w->shape, (std::vector<std::int64_t>{2, 3}));
  ASSERT_EQ(w->bytes.size(), weights.size() * 4);
  EXPECT_EQ(std::memcmp(w->bytes.data(), weights.data(), w->bytes.size()), 0);
  const TensorView* c = parsed.find("adam.step");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(std::memcmp(c->bytes.data(), counts.data(), c->bytes.size()), 0);
  EXPECT_EQ(parsed.find("empty")->elements(), 0);
}

TEST(Safetensors, TheWriterRefusesWhatItCannotWrite) {
  const std::vector<float> three = {1, 2, 3};
  EXPECT_THROW(write({{"a", DType::F32, {2, 2}, as_bytes(three)}}, {}), std::invalid_argument);
  EXPECT_THROW(write({{"a", DType::F32, {3}, as_bytes(three)}, {"a", DType::F32, {3}, as_bytes(three)}}, {}),
               std::invalid_argument);
  EXPECT_THROW(write({{"__metadata__", DType::F32, {3}, as_bytes(three)}}, {}), std::invalid_argument);
}

TEST(Safetensors, MalformedFilesAreRefusedInOneLineNamingThePart) {
  const std::string ok = R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})";
  ASSERT_EQ(refusal(file_with_header(ok, 8)), "accepted");
  const struct {
    std::string name, file, expected;
  } cases[] = {
      {"shorter than the length", std::string(5, '\0'), "fewer than the 8 of the header length"},
      {"a header length past the end", file_with_header(ok, 8).substr(0, 20), "the header length says"},
      {"a huge header length", std::string("\xff\xff\xff\xff\xff\xff\xff\x7f", 8) + "{}", "the header length says"},
      {"not JSON", file_with_header("{\"a\": [1, ", 0), "the header is not JSON"},
      {"not an object", file_with_header("[1, 2]", 0), "not a JSON object"},
      {"deep nesting", file_with_header(std::string(100000, '['), 0), "nests deeper than 3 levels"},
      {"deep nesting in an object", file_with_header("{\"a\":{\"b\":{\"c\":{\"d\":1}}}}", 0), "nests deeper"},
      {"a duplicate name",
       file_with_header(
           R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},"a":{"dtype":"F32","shape":[1],"data_offsets":[4,8]}})",
           8),
       "names 'a' twice"},
      {"a bf16 tensor", file_with_header(R"({"a":{"dtype":"BF16","shape":[4],"data_offsets":[0,8]}})", 8),
       "Scout stores F32 and I64 only"},
      {"bytes that do not match the shape",
       file_with_header(R"({"a":{"dtype":"F32","shape":[3],"data_offsets":[0,8]}})", 8),
       "takes 12 bytes, data_offsets give 8"},
      {"offsets past the end", file_with_header(R"({"a":{"dtype":"F32","shape":[4],"data_offsets":[0,16]}})", 8),
       "data_offsets [0, 16], the data after the header is 8 bytes"},
      {"offsets backwards", file_with_header(R"({"a":{"dtype":"F32","shape":[0],"data_offsets":[8,0]}})", 8),
       "data_offsets [8, 0] run backwards"},
      {"a gap", file_with_header(R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[4,8]}})", 8), "starts at byte 4"},
      {"overlapping tensors",
       file_with_header(
           R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]},"b":{"dtype":"F32","shape":[2],"data_offsets":[4,12]}})",
           12),
       "starts at byte 4 of the data, where the one before it ends at 8"},
      {"bytes after the last tensor", file_with_header(ok, 12), "4 bytes before the file does"},
      {"a shape that overflows",
       file_with_header(R"({"a":{"dtype":"F32","shape":[4294967296,4294967296],"data_offsets":[0,8]}})", 8),
       "more than 2^60 elements"},
      {"a negative size", file_with_header(R"({"a":{"dtype":"F32","shape":[-2],"data_offsets":[0,8]}})", 8),
       "not a whole number >= 0"},
      {"a metadata number", file_with_header(R"({"__metadata__":{"step":5}})", 0),
       "__metadata__: step is not a string"},
      {"an extra field", file_with_header(R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8],"x":1}})", 8),
       "expected exactly dtype, shape and data_offsets"},
  };
  for (const auto& c : cases) {
    const std::string message = refusal(c.file);
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.name << ": " << message;
    EXPECT_EQ(message.rfind("f.safetensors: ", 0), 0u) << c.name << ": " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << c.name << ": " << message;
  }
}

TEST(Safetensors, AHeaderLargerThanTheLimitIsRefusedBeforeItIsParsed) {
  const std::string header = "{\"__metadata__\":{\"pad\":\"" + std::string(5 << 20, 'x') + "\"}}";
  EXPECT_NE(refusal(file_with_header(header, 0)).find("more than the 4194304 Scout reads"), std::string::npos);
}

// The Python package's writer sorts the header's names and may lay the bytes out in another
// order: any order of names is read, as long as the bytes tile the data.
TEST(Safetensors, NamesInAnotherOrderThanTheirBytesAreRead) {
  const std::string header =
      R"({"z":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},"a":{"dtype":"I64","shape":[],"data_offsets":[4,12]}})";
  ASSERT_EQ(refusal(file_with_header(header, 12)), "accepted");
  const std::string file = file_with_header(header, 12);
  const File parsed = parse(as_bytes(file), "f.safetensors");
  EXPECT_EQ(parsed.tensors.front().name, "z");
  EXPECT_TRUE(parsed.find("a")->shape.empty());
  EXPECT_EQ(parsed.find("a")->elements(), 1);
}

}  // namespace
}  // namespace scout::learn::safetensors
