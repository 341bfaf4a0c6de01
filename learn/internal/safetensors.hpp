#pragma once
/// The safetensors file format (https://huggingface.co/docs/safetensors), read and written by
/// Scout itself, torch-free: an 8-byte little-endian header length N, N bytes of a JSON header
/// naming each tensor's dtype, shape and byte range ("data_offsets", relative to the data after
/// the header) and a "__metadata__" map of strings to strings, then the tensors' raw
/// little-endian bytes. The format holds only numbers and strings, so a file cannot run code;
/// what is left to check is that every part is where the header says and that the header says
/// what a Scout file says. parse() does the first before a byte is copied; learn/checkpoint.cpp
/// the second.
#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "learn/internal/private.hpp"

namespace scout::learn::safetensors {

/// The dtypes Scout stores: F32 (weights, Adam's moments) and I64 (counts: Adam's steps, a
/// network's integer buffers). NumPy has no bf16, so a bf16 run's weights are stored as what they
/// are between steps, fp32.
enum class DType { F32, I64 };
const char* to_string(DType dtype);  ///< "F32", "I64"
std::size_t element_size(DType dtype);

/// One tensor to write: its name, dtype, shape and bytes (little-endian, row-major; exactly
/// product(shape) * element_size(dtype) of them).
struct TensorBytes {
  std::string name;
  DType dtype = DType::F32;
  std::vector<std::int64_t> shape;
  std::span<const std::byte> bytes;
};

/// What parse() accepts and write() produces. The defaults hold every file Scout writes with room
/// to spare (a ResNet-18 checkpoint has about 300 tensors and a header of 60 KB).
struct Limits {
  std::size_t max_header_bytes = std::size_t{4} << 20;  ///< the JSON header
  std::size_t max_tensors = 1024;
  int max_rank = 8;  ///< dimensions of one tensor
  std::size_t max_name_bytes = 256;
  std::size_t max_metadata_entries = 32;
};

/// The whole file in memory: the header (tensors in the order given, then "__metadata__"),
/// padded with spaces to a multiple of 8 bytes as the reference writer does, so that the data
/// starts 8-byte aligned; then the tensors' bytes back to back (a tensor after one of an odd
/// number of F32 values starts 4-byte aligned: readers copy, as Scout's does). Throws
/// std::invalid_argument for a duplicate or empty name, the name "__metadata__", bytes that do
/// not match the shape, or a file parse() would refuse under `limits`.
std::string write(const std::vector<TensorBytes>& tensors, const std::map<std::string, std::string>& metadata,
                  const Limits& limits = {});

/// A tensor of a parsed file: a view into the file's bytes.
struct TensorView {
  std::string name;
  DType dtype = DType::F32;
  std::vector<std::int64_t> shape;
  std::span<const std::byte> bytes;
  std::int64_t elements() const { return static_cast<std::int64_t>(bytes.size() / element_size(dtype)); }
};

/// A parsed file: views into the bytes given to parse(), which must outlive it.
struct File {
  std::map<std::string, std::string> metadata;
  std::vector<TensorView> tensors;  ///< in the order of their bytes in the file
  /// The tensor called `name`, or null.
  const TensorView* find(const std::string& name) const;
};

/// Parses and checks a whole file: the header length against the file's length; the header as
/// JSON of at most Limits::max_header_bytes, nested at most 3 deep (the file, a tensor, its
/// shape or offsets) and of a bounded number of values, refused while parsing, before the tree
/// grows; no name twice; every tensor's dtype (F32 or I64 only), shape (sizes >= 0, the rank
/// bounded, the product without overflow) and byte range (end - begin = elements × element size;
/// the ranges in order of their starts begin at 0, follow each other without gap or overlap, and
/// end at the file's end); the metadata a map of strings to strings. Throws InputError in one
/// line naming `origin` and the part. Allocates only the header's tree and the tensor list: the
/// views point into `bytes`.
File parse(std::span<const std::byte> bytes, const std::string& origin, const Limits& limits = {});

/// Whether `bytes` begin as a zip archive does (a LibTorch .pt file, Scout's format 1).
bool looks_like_zip(std::span<const std::byte> bytes);

}  // namespace scout::learn::safetensors
