#pragma once
// A zip reader and a stored-only writer for the checkpoint tests (test_checkpoint_fuzz.cpp,
// test_hostile_checkpoints.cpp): a checkpoint's entries unpacked, changed and packed again with
// correct CRCs, so that a change reaches the checks behind the zip's (learn/internal/archive.hpp).
#include <zlib.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace scout::testing {

struct ZipFile {
  std::string folder;
  std::vector<std::pair<std::string, std::string>> entries;  // name (inside the folder), bytes
};

inline std::uint32_t le32(const std::string& b, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b.at(at + i));
  return v;
}
inline std::uint16_t le16(const std::string& b, std::size_t at) {
  return static_cast<std::uint16_t>(static_cast<unsigned char>(b.at(at)) |
                                    (static_cast<unsigned char>(b.at(at + 1)) << 8));
}
inline void put16(std::string& out, std::uint32_t v) {
  out.push_back(static_cast<char>(v & 0xff));
  out.push_back(static_cast<char>((v >> 8) & 0xff));
}
inline void put32(std::string& out, std::uint32_t v) {
  put16(out, v & 0xffff);
  put16(out, v >> 16);
}
inline void set32(std::string& b, std::size_t at, std::uint32_t v) {
  std::string bytes;
  put32(bytes, v);
  b.replace(at, 4, bytes);
}

/// One entry as the zip directory lists it.
struct ZipListing {
  std::string name;  // with the folder
  std::uint16_t method = 0;
  std::uint32_t compressed = 0, size = 0, header = 0;
  std::size_t data = 0;  // where its data starts, after the local header
};

// Scout's own (valid) archives only: no zip64 sizes, methods 0 and 8.
inline std::vector<ZipListing> list_zip(const std::string& zip) {
  const std::size_t end = zip.size() - 22;
  const std::uint16_t count = le16(zip, end + 10);
  std::size_t at = le32(zip, end + 16);
  std::vector<ZipListing> out;
  for (int i = 0; i < count; ++i) {
    ZipListing e;
    e.method = le16(zip, at + 10);
    e.compressed = le32(zip, at + 20);
    e.size = le32(zip, at + 24);
    const std::uint16_t name_length = le16(zip, at + 28);
    e.name = zip.substr(at + 46, name_length);
    e.header = le32(zip, at + 42);
    at += 46 + name_length + le16(zip, at + 30) + le16(zip, at + 32);
    e.data = e.header + 30 + le16(zip, e.header + 26) + le16(zip, e.header + 28);
    out.push_back(e);
  }
  return out;
}

inline ZipFile unpack(const std::string& zip) {
  ZipFile out;
  for (const ZipListing& e : list_zip(zip)) {
    std::string bytes = zip.substr(e.data, e.compressed);
    if (e.method == 8) {
      std::string inflated(e.size, '\0');
      z_stream z{};
      inflateInit2(&z, -MAX_WBITS);
      z.next_in = reinterpret_cast<Bytef*>(bytes.data());
      z.avail_in = static_cast<uInt>(bytes.size());
      z.next_out = reinterpret_cast<Bytef*>(inflated.data());
      z.avail_out = static_cast<uInt>(inflated.size());
      if (inflate(&z, Z_FINISH) != Z_STREAM_END) throw std::runtime_error("unpack: " + e.name + " does not inflate");
      inflateEnd(&z);
      bytes = std::move(inflated);
    }
    out.folder = e.name.substr(0, e.name.find('/'));
    out.entries.emplace_back(e.name.substr(e.name.find('/') + 1), std::move(bytes));
  }
  return out;
}

/// What pack() adds that Scout's writer never makes: bytes before the first entry, or between
/// the first and the second.
struct PackExtras {
  std::size_t prefix = 0;
  std::size_t gap = 0;
};

inline std::string pack(const ZipFile& zip, const PackExtras& extras = {}) {
  std::string out(extras.prefix, 'J'), directory;
  for (std::size_t i = 0; i < zip.entries.size(); ++i) {
    const auto& [name, bytes] = zip.entries[i];
    if (i == 1) out.append(extras.gap, 'G');
    const std::string full = zip.folder + "/" + name;
    const auto crc = static_cast<std::uint32_t>(crc32_z(0, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
    const auto offset = static_cast<std::uint32_t>(out.size());
    for (std::string* record : {&out, &directory}) {
      const bool central = record == &directory;
      put32(*record, central ? 0x02014b50 : 0x04034b50);
      if (central) put16(*record, 20);  // made by
      put16(*record, 20);               // needed
      put16(*record, 0);                // flags
      put16(*record, 0);                // stored
      put32(*record, 0);                // time, date
      put32(*record, crc);
      put32(*record, static_cast<std::uint32_t>(bytes.size()));
      put32(*record, static_cast<std::uint32_t>(bytes.size()));
      put16(*record, static_cast<std::uint32_t>(full.size()));
      put16(*record, 0);  // extra
      if (central) {
        put16(*record, 0);  // comment
        put16(*record, 0);  // disk
        put16(*record, 0);  // internal attributes
        put32(*record, 0);  // external attributes
        put32(*record, offset);
      }
      *record += full;
      if (!central) *record += bytes;
    }
  }
  const auto directory_offset = static_cast<std::uint32_t>(out.size());
  out += directory;
  put32(out, 0x06054b50);
  put32(out, 0);
  put16(out, static_cast<std::uint32_t>(zip.entries.size()));
  put16(out, static_cast<std::uint32_t>(zip.entries.size()));
  put32(out, static_cast<std::uint32_t>(directory.size()));
  put32(out, directory_offset);
  put16(out, 0);
  return out;
}

inline std::string& entry(ZipFile& zip, const std::string& name) {
  for (auto& [n, bytes] : zip.entries)
    if (n == name) return bytes;
  throw std::runtime_error("no entry " + name);
}

}  // namespace scout::testing
