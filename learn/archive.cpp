#include "learn/internal/archive.hpp"

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <unordered_map>

#include "core/error.hpp"

namespace scout::learn {

namespace {

[[noreturn]] void fail(const std::string& why) { throw std::runtime_error(one_line(why)); }

// ---------------------------------------------------------------------------------------------
// The zip container (PKWARE APPNOTE; LibTorch writes it through miniz).

constexpr std::uint32_t kLocalHeader = 0x04034b50;
constexpr std::uint32_t kCentralHeader = 0x02014b50;
constexpr std::uint32_t kEndRecord = 0x06054b50;
constexpr std::uint32_t kZip64EndRecord = 0x06064b50;
constexpr std::uint32_t kZip64Locator = 0x07064b50;
constexpr std::size_t kEndRecordSize = 22;
constexpr std::uint16_t kStored = 0;
constexpr std::uint16_t kDeflated = 8;

/// Little-endian reads that refuse to leave the buffer.
class Bytes {
 public:
  explicit Bytes(std::string_view data) : data_(data) {}
  std::size_t size() const { return data_.size(); }
  std::uint16_t u16(std::uint64_t at) const { return static_cast<std::uint16_t>(le(at, 2)); }
  std::uint32_t u32(std::uint64_t at) const { return static_cast<std::uint32_t>(le(at, 4)); }
  std::uint64_t u64(std::uint64_t at) const { return le(at, 8); }
  std::string_view view(std::uint64_t at, std::uint64_t n) const {
    if (at > data_.size() || n > data_.size() - at)
      fail(fmt::format("zip structure points past the end of the file (offset {}, {} bytes, file {} bytes)", at, n,
                       data_.size()));
    return data_.substr(at, n);
  }

 private:
  std::uint64_t le(std::uint64_t at, int n) const {
    const std::string_view b = view(at, n);
    std::uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[i]);
    return v;
  }
  std::string_view data_;
};

struct ZipEntry {
  std::string name;  ///< without the archive's folder
  std::uint16_t flags = 0, method = 0;
  std::uint32_t crc = 0;
  std::uint64_t compressed = 0, size = 0;
  std::uint64_t header = 0, data = 0;  ///< offsets of the local header and of the data
  std::uint64_t end = 0;               ///< where the entry ends: after its data and its data descriptor
};

struct ZipDirectory {
  std::string folder;
  std::map<std::string, ZipEntry> entries;
};

// An entry name as a message quotes it: a crafted name may be 64 KiB of anything.
std::string clipped(std::string_view name) {
  return name.size() <= 80 ? std::string(name) : std::string(name.substr(0, 80)) + "...";
}

bool is_digits(std::string_view s, std::size_t max_length = 10) {
  return !s.empty() && s.size() <= max_length &&
         std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

/// The entries Scout's writer makes, relative to the archive's folder.
bool known_entry(std::string_view name) {
  if (name == "data.pkl" || name == "constants.pkl" || name == "version") return true;
  // LibTorch 2.x's writer adds the byte order of the records and a random id of the file.
  if (name == "byteorder" || name == ".data/serialization_id") return true;
  if (name.rfind("data/", 0) == 0) return is_digits(name.substr(5));
  std::string_view code = name;
  if (code.size() > 10 && code.substr(code.size() - 10) == ".debug_pkl") code.remove_suffix(10);
  if (code == "code/__torch__.py") return true;
  constexpr std::string_view kMangled = "code/__torch__/___torch_mangle_";
  if (code.rfind(kMangled, 0) != 0 || code.size() < kMangled.size() + 4) return false;
  if (code.substr(code.size() - 3) != ".py") return false;
  return is_digits(code.substr(kMangled.size(), code.size() - kMangled.size() - 3));
}

// Where the zip directory lies, from the end record (and the zip64 records LibTorch writes).
struct DirectoryPlace {
  std::uint64_t count = 0, offset = 0, size = 0;
  std::uint64_t limit = 0;  // the directory ends by here: the zip64 end record, else the end record
};

// LibTorch's writer puts a zip64 end record and its locator before the end record, even for a
// small archive; `record` is where the locator says the zip64 end record lies.
void check_zip64_record(const Bytes& b, std::uint64_t end, std::uint64_t record) {
  constexpr std::uint64_t kZip64RecordSize = 56;
  if (end < 20 + kZip64RecordSize || record != end - 20 - kZip64RecordSize || b.u32(record) != kZip64EndRecord ||
      b.u64(record + 4) != kZip64RecordSize - 12)
    fail("the zip64 end record is not where its locator says, just before it");
  if (b.u32(record + 16) != 0 || b.u32(record + 20) != 0 || b.u64(record + 24) != b.u64(record + 32))
    fail("a multi-part zip64 archive (Scout's writer makes none)");
}

DirectoryPlace find_directory(const Bytes& b) {
  if (b.size() < kEndRecordSize) fail(fmt::format("{} bytes: too short for a zip archive", b.size()));
  const std::uint64_t end = b.size() - kEndRecordSize;
  if (b.u32(end) != kEndRecord)
    fail("no zip end record at the end of the file (truncated, appended to, or not a LibTorch archive)");
  if (b.u16(end + 4) != 0 || b.u16(end + 6) != 0 || b.u16(end + 8) != b.u16(end + 10) || b.u16(end + 20) != 0)
    fail("a multi-part zip archive or one with a comment (Scout's writer makes neither)");
  DirectoryPlace d{.count = b.u16(end + 10), .offset = b.u32(end + 16), .size = b.u32(end + 12), .limit = end};
  const bool locator = end >= 20 && b.u32(end - 20) == kZip64Locator;
  if (d.count == 0xffff || d.size == 0xffffffff || d.offset == 0xffffffff) {
    // The zip64 end record, found through its locator just before the end record.
    if (!locator) fail("a zip64 archive without its zip64 locator");
    const std::uint64_t record = b.u64(end - 20 + 8);
    check_zip64_record(b, end, record);
    d = {.count = b.u64(record + 32), .offset = b.u64(record + 48), .size = b.u64(record + 40), .limit = record};
  } else if (locator) {
    // The zip64 records of a small archive: the directory ends before them, and they agree.
    const std::uint64_t record = b.u64(end - 20 + 8);
    check_zip64_record(b, end, record);
    if (b.u64(record + 32) != d.count || b.u64(record + 40) != d.size || b.u64(record + 48) != d.offset)
      fail("the zip64 end record and the end record describe different directories");
    d.limit = record;
  }
  if (d.count == 0) fail("an empty zip archive");
  if (d.count > kMaxArchiveEntries) fail(fmt::format("{} zip entries (at most {})", d.count, kMaxArchiveEntries));
  // The directory ends where the end records begin: no bytes between them.
  if (d.offset > d.limit || d.size != d.limit - d.offset)
    fail("the zip directory does not end where the end records begin (bytes between them, or outside the file)");
  return d;
}

// The entry's local header and data descriptor must repeat what the directory says: LibTorch's
// reader takes the directory's word, other zip tools the local header's.
void check_local_header(const Bytes& b, ZipEntry& e, const std::string& full, const std::string& where) {
  constexpr std::uint32_t kDataDescriptor = 0x08074b50;
  if (b.u32(e.header) != kLocalHeader) fail(where + ": no local header at its offset");
  const std::uint16_t local_name = b.u16(e.header + 26);
  if (b.view(e.header + 30, local_name) != full) fail(where + ": its local header names another entry");
  if (b.u16(e.header + 6) != e.flags || b.u16(e.header + 8) != e.method)
    fail(where + ": its local header gives another compression method or other flags than the zip directory");
  e.data = e.header + 30 + local_name + b.u16(e.header + 28);
  const bool descriptor = e.flags & 0x08;
  // With a data descriptor (what miniz writes for LibTorch), the local header's CRC and sizes are
  // zero and the descriptor after the data holds them; without one, the local header does.
  const std::uint64_t local_crc = b.u32(e.header + 14), local_compressed = b.u32(e.header + 18),
                      local_size = b.u32(e.header + 22);
  if (descriptor ? (local_crc | local_compressed | local_size) != 0
                 : local_crc != e.crc || local_compressed != e.compressed || local_size != e.size)
    fail(where + ": its local header gives another CRC-32 or other sizes than the zip directory");
  e.end = e.data + e.compressed;
  if (e.end < e.data) fail(where + ": its data runs past the end of the file");
  if (descriptor) {
    b.view(e.end, 16);  // in bounds
    if (b.u32(e.end) != kDataDescriptor || b.u32(e.end + 4) != e.crc || b.u32(e.end + 8) != e.compressed ||
        b.u32(e.end + 12) != e.size)
      fail(where + ": its data descriptor gives another CRC-32 or other sizes than the zip directory");
    e.end += 16;
  }
}

// Directory entry `i` at `at` (moved on to the next), checked against what Scout's writer makes
// and against its local header. All entries lie in one folder: `folder`, set by the first.
ZipEntry read_entry(const Bytes& b, std::uint64_t& at, std::uint64_t i, const DirectoryPlace& d, std::string& folder) {
  const std::uint64_t directory_end = d.offset + d.size;
  if (at + 46 > directory_end || b.u32(at) != kCentralHeader) fail(fmt::format("zip directory entry {} is damaged", i));
  ZipEntry e;
  e.flags = b.u16(at + 8);
  e.method = b.u16(at + 10);
  e.crc = b.u32(at + 16);
  e.compressed = b.u32(at + 20);
  e.size = b.u32(at + 24);
  const std::uint16_t name_length = b.u16(at + 28), extra_length = b.u16(at + 30), comment_length = b.u16(at + 32);
  const std::uint64_t next = at + 46 + name_length + extra_length + comment_length;
  const std::uint16_t disk = b.u16(at + 34);
  e.header = b.u32(at + 42);
  if (next > directory_end) fail(fmt::format("zip directory entry {} runs past the directory", i));
  const std::string full(b.view(at + 46, name_length));
  at = next;

  const std::size_t slash = full.find('/');
  if (slash == 0 || slash == std::string::npos || full.find('\0') != std::string::npos)
    fail("zip entry '" + clipped(full) + "' is not inside the archive's folder");
  const std::string entry_folder = full.substr(0, slash);
  if (folder.empty()) folder = entry_folder;
  if (entry_folder != folder)
    fail("zip entries in two folders ('" + clipped(folder) + "', '" + clipped(entry_folder) + "')");
  e.name = full.substr(slash + 1);
  const std::string where = "entry " + clipped(full);
  if (!known_entry(e.name)) fail(where + ": not an entry Scout's checkpoint writer makes");
  if (e.flags & 0x41) fail(where + ": encrypted");
  // Bits 3 (a data descriptor follows the data) and 11 (UTF-8 names): what miniz sets for LibTorch.
  if (e.flags & ~0x0808) fail(fmt::format("{}: zip flags 0x{:04x} (Scout's writer sets only 0x0808)", where, e.flags));
  if (extra_length != 0 || comment_length != 0 || disk != 0)
    fail(where + ": an extra field, a comment or a disk number in the zip directory (Scout's writer makes none)");
  if (e.method != kStored && e.method != kDeflated)
    fail(fmt::format("{}: compression method {} (expected 0, stored, or 8, deflated)", where, e.method));
  if (e.compressed == 0xffffffff || e.size == 0xffffffff || e.header == 0xffffffff)
    fail(where + ": larger than 4 GiB (zip64 entries are not written by Scout)");
  if (e.method == kStored && e.compressed != e.size)
    fail(fmt::format("{}: stored, but its sizes differ ({} and {} bytes)", where, e.compressed, e.size));
  if (e.name.rfind("data/", 0) == 0 && e.method != kStored) fail(where + ": a tensor record must be stored");
  check_local_header(b, e, full, where);
  return e;
}

ZipDirectory read_directory(const Bytes& b) {
  const DirectoryPlace d = find_directory(b);
  ZipDirectory out;
  std::vector<ZipEntry> by_offset;
  std::uint64_t at = d.offset;
  for (std::uint64_t i = 0; i < d.count; ++i) {
    const ZipEntry e = read_entry(b, at, i, d, out.folder);
    if (!out.entries.emplace(e.name, e).second) fail("entry " + clipped(out.folder + "/" + e.name) + ": appears twice");
    by_offset.push_back(e);
  }
  if (at != d.offset + d.size) fail("the zip directory's size does not match its entries");
  // Every byte of the file belongs to an entry, the directory or the end records: the entries
  // follow each other from the first byte (no prefix, gap or unlisted record between them) and
  // the directory follows the last.
  std::sort(by_offset.begin(), by_offset.end(),
            [](const ZipEntry& x, const ZipEntry& y) { return x.header < y.header; });
  std::uint64_t expected = 0;
  for (const ZipEntry& e : by_offset) {
    if (e.header != expected)
      fail(fmt::format("entry {}: starts at byte {}, where {} (expected the entries to follow each other from byte 0)",
                       clipped(out.folder + "/" + e.name), e.header,
                       expected == 0 ? "the file begins" : "the entry before it ends at " + std::to_string(expected)));
    expected = e.end;
  }
  if (expected != d.offset)
    fail(fmt::format("the zip directory starts at byte {}, the last entry ends at byte {}", d.offset, expected));
  for (const char* required : {"data.pkl", "constants.pkl", "version"})
    if (!out.entries.count(required)) fail(std::string("no ") + required + " entry");
  return out;
}

std::uint32_t crc32_of(std::string_view data) {
  return static_cast<std::uint32_t>(
      ::crc32_z(0L, reinterpret_cast<const Bytef*>(data.data()), static_cast<z_size_t>(data.size())));
}

/// The entry's bytes (inflated if deflated, at most `limit`), CRC-checked. `budget` bounds the
/// bytes read out of all entries together (deflate expands up to 1032 times).
std::string entry_bytes(const Bytes& b, const ZipDirectory& zip, const ZipEntry& e, std::uint64_t limit,
                        std::uint64_t& budget) {
  const std::string where = "entry " + clipped(zip.folder + "/" + e.name);
  if (e.size > limit) fail(fmt::format("{}: {} bytes (at most {})", where, e.size, limit));
  if (e.size > budget)
    fail(fmt::format("{}: the entries hold more than {} bytes of code and pickles", where,
                     kMaxPickleBytes + kMaxSmallBytesTotal));
  budget -= e.size;
  const std::string_view raw = b.view(e.data, e.compressed);
  std::string out;
  if (e.method == kStored) {
    out.assign(raw);
  } else {
    out.resize(e.size);
    z_stream z{};
    if (inflateInit2(&z, -MAX_WBITS) != Z_OK) fail(where + ": zlib could not start");
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()));
    z.avail_in = static_cast<uInt>(raw.size());
    z.next_out = reinterpret_cast<Bytef*>(out.data());
    z.avail_out = static_cast<uInt>(out.size());
    const int status = inflate(&z, Z_FINISH);
    const std::uint64_t produced = z.total_out;
    inflateEnd(&z);
    if (status != Z_STREAM_END || produced != e.size)
      fail(fmt::format("{}: its deflated data is damaged (expected {} bytes)", where, e.size));
  }
  if (crc32_of(out) != e.crc) fail(where + ": CRC-32 mismatch (the file is damaged)");
  return out;
}

// ---------------------------------------------------------------------------------------------
// The pickles: protocol 2 as LibTorch's pickler writes them, run by a machine that knows only
// those opcodes and globals.

// Values live in the machine's arena and point at each other by plain pointers: a crafted memo
// can make a list or a module contain itself, which shared ownership would leak.
struct Value;
using Ref = Value*;

struct Value {
  enum class Kind { None, Bool, Int, Float, String, Tuple, List, Dict, Global, Object, Storage, Tensor };
  Kind kind = Kind::None;
  std::int64_t number = 0;  ///< Bool, Int; Storage: numel
  double real = 0;
  std::string text;                        ///< String; Global: "module name"; Object: its class; Storage, Tensor: dtype
  std::string key;                         ///< Storage: the record's name under data/
  std::vector<Ref> items;                  ///< Tuple, List; Dict: key, value, key, value...; Tensor: its sizes as Ints
  Ref state = nullptr;                     ///< Object: its attributes (a Dict) once BUILD ran
  std::optional<std::int64_t> long_value;  ///< Tensor: a one-element Long tensor's value, read from its record
  int depth = 1;                           ///< how deep values nest in it, as far as its items were known
};

struct DtypeInfo {
  const char* name;
  int bytes;
};
constexpr DtypeInfo kDtypes[] = {{"Float", 4}, {"Double", 8}, {"Half", 2}, {"BFloat16", 2}, {"Long", 8},
                                 {"Int", 4},   {"Short", 2},  {"Char", 1}, {"Byte", 1},     {"Bool", 1}};

std::optional<DtypeInfo> storage_dtype(std::string_view global) {
  // "torch FloatStorage" -> Float
  constexpr std::string_view kModule = "torch ";
  constexpr std::string_view kSuffix = "Storage";
  if (global.rfind(kModule, 0) != 0 || global.size() <= kModule.size() + kSuffix.size() ||
      global.substr(global.size() - kSuffix.size()) != kSuffix)
    return std::nullopt;
  const std::string_view name = global.substr(kModule.size(), global.size() - kModule.size() - kSuffix.size());
  for (const DtypeInfo& d : kDtypes)
    if (name == d.name) return d;
  return std::nullopt;
}

/// "__torch__ Module" or "__torch__.___torch_mangle_N Module": a class of the writer's code.
bool module_class(std::string_view global) {
  if (global == "__torch__ Module") return true;
  constexpr std::string_view kPrefix = "__torch__.___torch_mangle_";
  constexpr std::string_view kSuffix = " Module";
  if (global.rfind(kPrefix, 0) != 0 || global.size() <= kPrefix.size() + kSuffix.size()) return false;
  if (global.substr(global.size() - kSuffix.size()) != kSuffix) return false;
  return is_digits(global.substr(kPrefix.size(), global.size() - kPrefix.size() - kSuffix.size()));
}

/// The code entry that defines a module class.
std::string class_file(std::string_view global) {
  if (global == "__torch__ Module") return "code/__torch__.py";
  const std::string_view module = global.substr(0, global.find(' '));
  return "code/__torch__/" + std::string(module.substr(std::string_view("__torch__.").size())) + ".py";
}

enum class PickleKind { Data, Debug, Constants };

class PickleMachine {
 public:
  /// `file`: the whole archive, where a one-element Long tensor's value is read from its record.
  PickleMachine(std::string_view code, std::string where, PickleKind kind, const ZipDirectory& zip, const Bytes& file)
      : code_(code), where_(std::move(where)), kind_(kind), zip_(zip), file_(file) {}

  /// The storage records the tensors of a run() refer to (each by exactly one tensor).
  const std::set<std::string>& records_used() const { return records_used_; }

  Ref run() {
    if (code_.size() < 2 || static_cast<unsigned char>(code_[0]) != 0x80 || code_[1] != 2)
      error("not a protocol-2 pickle");
    pos_ = 2;
    while (true) {
      if (pos_ >= code_.size()) error("ends without STOP");
      const unsigned char op = static_cast<unsigned char>(code_[pos_++]);
      if (++values_ > kMaxValues) error("too many values");
      if (op == '.') {
        if (pos_ != code_.size()) error("bytes after STOP");
        if (!marks_.empty() || stack_.size() != 1) error("STOP with an unbalanced stack");
        check_nesting();
        return stack_.back();
      }
      if (!container_op(op) && !scalar_op(op) && !object_op(op))
        error(fmt::format("opcode 0x{:02x} at byte {}, which Scout's writer never emits", op, pos_ - 1));
      if (stack_.size() > kMaxStack) error("stack deeper than " + std::to_string(kMaxStack));
    }
  }

 private:
  // The opcodes, in three groups; each returns false for an opcode not its own.

  // Marks, tuples, lists and dicts.
  bool container_op(unsigned char op) {
    switch (op) {
      case '(':
        marks_.push_back(stack_.size());
        return true;
      case ')':
        push(make(Value::Kind::Tuple));
        return true;
      case 't':
        push(tuple(pop_mark()));
        return true;
      case 0x85:
        push(tuple(pop_n(1)));
        return true;
      case 0x86:
        push(tuple(pop_n(2)));
        return true;
      case 0x87:
        push(tuple(pop_n(3)));
        return true;
      case ']':
        push(make(Value::Kind::List));
        return true;
      case 'a':
        append(pop_n(1));
        return true;
      case 'e':
        append(pop_mark());
        return true;
      case '}':
        push(make(Value::Kind::Dict));
        return true;
      case 's':
        set_items(pop_n(2));
        return true;
      case 'u':
        set_items(pop_mark());
        return true;
      default:
        return false;
    }
  }

  // None, booleans, integers, floats and strings.
  bool scalar_op(unsigned char op) {
    switch (op) {
      case 'N':
        push(make(Value::Kind::None));
        return true;
      case 0x88:
        push(boolean(true));
        return true;
      case 0x89:
        push(boolean(false));
        return true;
      case 'J':
        push(integer(static_cast<std::int32_t>(little(4))));
        return true;
      case 'K':
        push(integer(static_cast<std::int64_t>(little(1))));
        return true;
      case 'M':
        push(integer(static_cast<std::int64_t>(little(2))));
        return true;
      case 0x8a:
        push(long1());
        return true;
      case 'G':
        push(binfloat());
        return true;
      case 'X':
        push(string(take(little(4))));
        return true;
      default:
        return false;
    }
  }

  // Globals, the memo, persistent ids (tensor records) and object construction.
  bool object_op(unsigned char op) {
    switch (op) {
      case 'c':
        push(global());
        return true;
      case 'q':
        memo_put(little(1));
        return true;
      case 'r':
        memo_put(little(4));
        return true;
      case 'h':
        push(memo_get(little(1)));
        return true;
      case 'j':
        push(memo_get(little(4)));
        return true;
      case 'Q':
        push(persistent_id(pop()));
        return true;
      case 'R': {
        Ref args = pop();
        push(reduce(pop(), args));
        return true;
      }
      case 0x81: {
        Ref args = pop();
        push(new_object(pop(), args));
        return true;
      }
      case 'b':
        build(pop());
        return true;
      default:
        return false;
    }
  }

  // How deeply values nest, over everything the pickle made (what the root holds and whatever
  // sits in the memo): LibTorch's unpickler and its IValues recurse once per level, so 150,000
  // one-element tuples overflow its stack. The writer nests a module's attributes two levels below
  // it (the object, its dict), so kMaxNesting leaves room for collect()'s 64 modules. Iterative,
  // each value visited once; a value that contains itself is refused as well.
  void check_nesting() const {
    std::unordered_map<const Value*, int> depth;  // finished values; -1 while on the path
    struct Frame {
      const Value* value;
      std::size_t next;  // the next child to visit (items, then state)
      int deepest;       // the deepest finished child
    };
    std::vector<Frame> path;
    for (const auto& owned : arena_) {
      if (depth.count(owned.get())) continue;
      path.push_back({owned.get(), 0, 0});
      depth[owned.get()] = -1;
      while (!path.empty()) {
        Frame& f = path.back();
        const std::size_t children = f.value->items.size() + (f.value->state ? 1 : 0);
        if (f.next == children) {
          const int finished = f.deepest + 1;
          if (finished > static_cast<int>(kMaxNesting))
            error(fmt::format("values nested more than {} deep", kMaxNesting));
          depth[f.value] = finished;
          path.pop_back();
          if (!path.empty()) path.back().deepest = std::max(path.back().deepest, finished);
          continue;
        }
        const Value* child = f.next < f.value->items.size() ? f.value->items[f.next] : f.value->state;
        ++f.next;
        const auto seen = depth.find(child);
        if (seen != depth.end() && seen->second < 0) error("a value that contains itself (the writer makes a tree)");
        if (seen != depth.end()) {
          f.deepest = std::max(f.deepest, seen->second);
        } else {
          if (path.size() >= kMaxNesting) error(fmt::format("values nested more than {} deep", kMaxNesting));
          depth[child] = -1;
          path.push_back({child, 0, 0});
        }
      }
    }
  }

  static constexpr std::size_t kMaxValues = 1'000'000;
  static constexpr std::size_t kMaxNesting = 150;
  static constexpr std::size_t kMaxStack = 100'000;
  static constexpr std::size_t kMaxRank = 8;

  [[noreturn]] void error(const std::string& why) const { fail(where_ + ": " + why); }

  Ref make(Value::Kind kind) {
    arena_.push_back(std::make_unique<Value>());
    arena_.back()->kind = kind;
    return arena_.back().get();
  }
  Ref boolean(bool b) {
    Ref v = make(Value::Kind::Bool);
    v->number = b;
    return v;
  }
  Ref integer(std::int64_t i) {
    Ref v = make(Value::Kind::Int);
    v->number = i;
    return v;
  }
  Ref string(std::string_view s) {
    Ref v = make(Value::Kind::String);
    v->text = s;
    return v;
  }

  std::string_view take(std::uint64_t n) {
    if (n > code_.size() - pos_) error("an argument runs past the end of the pickle");
    const std::string_view s = code_.substr(pos_, n);
    pos_ += n;
    return s;
  }
  std::uint64_t little(int n) {
    const std::string_view b = take(n);
    std::uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[i]);
    return v;
  }
  Ref long1() {
    const std::uint64_t n = little(1);
    if (n > 8) error("an integer wider than 64 bits");
    if (n == 0) return integer(0);
    std::uint64_t v = little(static_cast<int>(n));
    if (n < 8 && (v >> (8 * n - 1)) & 1) v |= ~std::uint64_t{0} << (8 * n);  // sign-extend
    return integer(static_cast<std::int64_t>(v));
  }
  Ref binfloat() {
    const std::string_view b = take(8);
    std::uint64_t bits = 0;
    for (char c : b) bits = (bits << 8) | static_cast<unsigned char>(c);  // big-endian
    Ref v = make(Value::Kind::Float);
    std::memcpy(&v->real, &bits, sizeof bits);
    return v;
  }
  Ref global() {
    const std::size_t module_end = code_.find('\n', pos_);
    if (module_end == std::string_view::npos || module_end - pos_ > 200) error("a malformed GLOBAL");
    const std::size_t name_end = code_.find('\n', module_end + 1);
    if (name_end == std::string_view::npos || name_end - module_end > 200) error("a malformed GLOBAL");
    std::string name(code_.substr(pos_, module_end - pos_));
    name += ' ';
    name += code_.substr(module_end + 1, name_end - module_end - 1);
    pos_ = name_end + 1;
    const bool allowed = kind_ == PickleKind::Debug
                             ? name == "torch.jit._pickle build_intlist"
                             : kind_ == PickleKind::Data &&
                                   (module_class(name) || storage_dtype(name) ||
                                    name == "torch._utils _rebuild_tensor_v2" || name == "collections OrderedDict");
    if (!allowed) error("global '" + name + "', which Scout's writer never uses here");
    if (module_class(name) && !zip_.entries.count(class_file(name)))
      error("class '" + name + "' has no " + class_file(name));
    Ref v = make(Value::Kind::Global);
    v->text = std::move(name);
    return v;
  }

  void push(Ref v) { stack_.push_back(std::move(v)); }
  Ref pop() {
    if (stack_.size() <= (marks_.empty() ? 0 : marks_.back())) error("stack underflow");
    Ref v = stack_.back();
    stack_.pop_back();
    return v;
  }
  std::vector<Ref> pop_n(std::size_t n) {
    const std::size_t floor = marks_.empty() ? 0 : marks_.back();
    if (stack_.size() < floor + n) error("stack underflow");
    std::vector<Ref> items(stack_.end() - static_cast<std::ptrdiff_t>(n), stack_.end());
    stack_.resize(stack_.size() - n);
    return items;
  }
  std::vector<Ref> pop_mark() {
    if (marks_.empty()) error("no MARK to pop to");
    const std::size_t at = marks_.back();
    marks_.pop_back();
    std::vector<Ref> items(stack_.begin() + static_cast<std::ptrdiff_t>(at), stack_.end());
    stack_.resize(at);
    return items;
  }
  Ref& top() {
    if (stack_.size() <= (marks_.empty() ? 0 : marks_.back())) error("stack underflow");
    return stack_.back();
  }

  // A container's depth, as its items are added: a crafted chain of a million one-element tuples
  // is refused at the 151st, before it takes memory (check_nesting() sees what comes later).
  void contain(Ref container, Ref item) {
    container->depth = std::max(container->depth, item->depth + 1);
    if (container->depth > static_cast<int>(kMaxNesting))
      error(fmt::format("values nested more than {} deep", kMaxNesting));
  }
  Ref tuple(std::vector<Ref> items) {
    Ref v = make(Value::Kind::Tuple);
    for (Ref item : items) contain(v, item);
    v->items = std::move(items);
    return v;
  }
  void append(std::vector<Ref> items) {
    Ref& list = top();
    if (list->kind != Value::Kind::List) error("APPEND to something other than a list");
    for (Ref item : items) {
      contain(list, item);
      list->items.push_back(item);
    }
  }
  void set_items(std::vector<Ref> items) {
    Ref& dict = top();
    if (dict->kind != Value::Kind::Dict) error("SETITEM on something other than a dict");
    if (items.size() % 2) error("SETITEMS with an odd number of values");
    for (std::size_t i = 0; i < items.size(); i += 2)
      if (items[i]->kind != Value::Kind::String) error("a dict key that is not a string");
    for (Ref item : items) {
      contain(dict, item);
      dict->items.push_back(item);
    }
  }

  void memo_put(std::uint64_t index) {
    // The writer numbers memo entries 0, 1, 2, ... LibTorch's reader sizes its memo table by the
    // largest index it meets, so one crafted index (2^30) would make it allocate gigabytes.
    if (index > memo_.size()) error(fmt::format("memo entry {} written before entry {}", index, memo_.size()));
    memo_[index] = top();
  }
  Ref memo_get(std::uint64_t index) {
    const auto it = memo_.find(index);
    if (it == memo_.end()) error(fmt::format("memo entry {} read before it was written", index));
    return it->second;
  }

  static bool is(Ref v, Value::Kind kind) { return v && v->kind == kind; }

  Ref persistent_id(Ref id) {
    // ('storage', torch.XStorage, key, 'cpu', numel)
    if (kind_ != PickleKind::Data || !is(id, Value::Kind::Tuple) || id->items.size() != 5)
      error("a persistent id that is not a storage");
    const auto& f = id->items;
    if (!is(f[0], Value::Kind::String) || f[0]->text != "storage" || !is(f[1], Value::Kind::Global) ||
        !is(f[2], Value::Kind::String) || !is(f[3], Value::Kind::String) || !is(f[4], Value::Kind::Int))
      error("a malformed storage reference");
    const std::optional<DtypeInfo> dtype = storage_dtype(f[1]->text);
    if (!dtype) error("storage type '" + f[1]->text + "' is not one Scout writes");
    if (f[3]->text != "cpu") error("storage on device '" + f[3]->text + "' (Scout writes cpu)");
    const std::string& key = f[2]->text;
    if (!is_digits(key)) error("storage key '" + key + "' is not a record number");
    const std::int64_t numel = f[4]->number;
    const auto record = zip_.entries.find("data/" + key);
    if (record == zip_.entries.end()) error("storage " + key + " has no data/" + key + " record");
    if (numel < 0 || static_cast<std::uint64_t>(numel) > record->second.size / dtype->bytes ||
        static_cast<std::uint64_t>(numel) * dtype->bytes != record->second.size)
      error(fmt::format("storage {} declares {} {} elements, its record holds {} bytes", key, numel, dtype->name,
                        record->second.size));
    if (!storages_.insert(key).second) error("storage " + key + " is declared twice (the writer declares each once)");
    Ref v = make(Value::Kind::Storage);
    v->text = dtype->name;
    v->key = key;
    v->number = numel;
    return v;
  }

  Ref reduce(Ref callable, Ref args) {
    if (!is(callable, Value::Kind::Global) || !is(args, Value::Kind::Tuple)) error("REDUCE of something not callable");
    const std::string& name = callable->text;
    const auto& a = args->items;
    if (name == "collections OrderedDict") {
      if (!a.empty()) error("OrderedDict with arguments");
      return make(Value::Kind::Dict);
    }
    if (name == "torch.jit._pickle build_intlist") {
      if (a.size() != 1 || !is(a[0], Value::Kind::List)) error("build_intlist without a list");
      for (Ref item : a[0]->items)
        if (!is(item, Value::Kind::Int)) error("build_intlist of something other than integers");
      return a[0];
    }
    if (name == "torch._utils _rebuild_tensor_v2") return tensor(a);
    error("REDUCE of '" + name + "'");
  }

  // _rebuild_tensor_v2(storage, offset, sizes, strides, requires_grad, backward_hooks), as the
  // writer makes it: a storage of its own, taken whole from its first element, with the
  // contiguous strides of its sizes. A stride of 0 (one element read as millions), an offset or a
  // storage shared between tensors are what LibTorch accepts and Scout's writer never makes.
  Ref tensor(const std::vector<Ref>& a) {
    if (a.size() != 6 || !is(a[0], Value::Kind::Storage) || !is(a[1], Value::Kind::Int) ||
        !is(a[2], Value::Kind::Tuple) || !is(a[3], Value::Kind::Tuple) || !is(a[4], Value::Kind::Bool) ||
        !is(a[5], Value::Kind::Dict) || !a[5]->items.empty())
      error("a malformed tensor");
    const Ref storage = a[0];
    const auto& sizes = a[2]->items;
    const auto& strides = a[3]->items;
    if (sizes.size() != strides.size() || sizes.size() > kMaxRank)
      error(fmt::format("a tensor with {} sizes and {} strides (at most {} of each, as many strides as sizes)",
                        sizes.size(), strides.size(), kMaxRank));
    if (a[1]->number != 0)
      error(fmt::format("a tensor at offset {} of storage {} (the writer's start at 0)", a[1]->number, storage->key));
    if (!records_used_.insert(storage->key).second)
      error("storage " + storage->key + " is shared by two tensors (the writer gives each tensor its own)");
    const std::int64_t elements = contiguous_elements(sizes, strides, storage->key);
    if (elements != storage->number)
      error(fmt::format("a tensor of {} elements in storage {} of {} (the writer's tensors fill their storage)",
                        elements, storage->key, storage->number));
    Ref out = make(Value::Kind::Tensor);
    out->items = sizes;
    out->text = storage->text;
    out->key = storage->key;
    out->number = elements;
    if (out->text == "Long" && elements == 1) {
      // Adam's "params/size" and "param_groups/size": counts LibTorch's reader loops over.
      const std::string_view record = file_.view(zip_.entries.at("data/" + storage->key).data, 8);
      std::uint64_t v = 0;
      for (int i = 7; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(record[i]);
      out->long_value = static_cast<std::int64_t>(v);
    }
    return out;
  }

  // The product of `sizes`, overflow-checked, once `strides` are their contiguous strides: the
  // last dimension's is 1, each other's the next one's times the next size (at least 1, as
  // LibTorch computes them for an empty or a size-1 dimension).
  std::int64_t contiguous_elements(const std::vector<Ref>& sizes, const std::vector<Ref>& strides,
                                   const std::string& key) const {
    std::int64_t elements = 1, expected = 1;
    for (std::size_t i = sizes.size(); i-- > 0;) {
      if (!is(sizes[i], Value::Kind::Int) || !is(strides[i], Value::Kind::Int) || sizes[i]->number < 0)
        error("a tensor size or stride out of range");
      if (strides[i]->number != expected)
        error(
            fmt::format("a tensor in storage {} with stride {} in dimension {} (the writer's contiguous stride is {})",
                        key, strides[i]->number, i, expected));
      const std::int64_t size = sizes[i]->number;
      if (__builtin_mul_overflow(elements, size, &elements) ||
          __builtin_mul_overflow(expected, std::max<std::int64_t>(size, 1), &expected))
        error(fmt::format("a tensor in storage {} whose sizes multiply beyond 64 bits", key));
    }
    return elements;
  }

  Ref new_object(Ref cls, Ref args) {
    if (!is(cls, Value::Kind::Global) || !module_class(cls->text) || !is(args, Value::Kind::Tuple) ||
        !args->items.empty())
      error("NEWOBJ of something other than a module class");
    Ref v = make(Value::Kind::Object);
    v->text = cls->text;
    return v;
  }

  void build(Ref state) {
    Ref& object = top();
    if (!is(object, Value::Kind::Object) || object->state || !is(state, Value::Kind::Dict))
      error("BUILD of something other than a new module with its attributes");
    contain(object, state);
    object->state = state;
  }

  std::string_view code_;
  std::string where_;
  PickleKind kind_;
  const ZipDirectory& zip_;
  std::size_t pos_ = 0;
  std::size_t values_ = 0;
  std::vector<Ref> stack_;
  std::vector<std::size_t> marks_;
  std::unordered_map<std::uint64_t, Ref> memo_;
  const Bytes& file_;
  std::set<std::string> storages_;      // declared by a persistent id
  std::set<std::string> records_used_;  // taken by a tensor
  std::vector<std::unique_ptr<Value>> arena_;
};

// ---------------------------------------------------------------------------------------------
// code/*.py: the TorchScript class stubs the writer makes, e.g.
//   class Module(Module):
//     __parameters__ = ["weight", "bias", ]
//     __buffers__ = []
//     __annotations__ = []
//     __annotations__["0"] = __torch__.___torch_mangle_4.Module
//     weight : Tensor

/// What a class stub declares: each attribute's type, and the attributes it lists as parameters
/// or buffers.
struct ClassStub {
  std::map<std::string, std::string> types;  ///< "weight" -> "Tensor", "0" -> "__torch__.___torch_mangle_4.Module"
  std::set<std::string> listed;              ///< in __parameters__ or __buffers__
};

bool quoted(std::string_view& s, std::string* out = nullptr) {
  if (s.empty() || s[0] != '"') return false;
  std::size_t i = 1;
  while (i < s.size() && (std::isalnum(static_cast<unsigned char>(s[i])) || s[i] == '_' || s[i] == '.' || s[i] == '/'))
    ++i;
  if (i == 1 || i >= s.size() || s[i] != '"') return false;
  if (out) *out = s.substr(1, i - 1);
  s.remove_prefix(i + 1);
  return true;
}

bool name_list(std::string_view s, std::set<std::string>& names) {
  if (s == "[]") return true;
  if (s.empty() || s[0] != '[') return false;
  s.remove_prefix(1);
  std::string name;
  while (!s.empty() && s[0] == '"') {
    if (!quoted(s, &name) || s.rfind(", ", 0) != 0) return false;
    names.insert(name);
    s.remove_prefix(2);
  }
  return s == "]";
}

bool known_type(std::string_view t) {
  for (std::string_view plain : {"Tensor", "int", "float", "str", "bool", "Tuple[float, float]"})
    if (t == plain) return true;
  constexpr std::string_view kPrefix = "__torch__.___torch_mangle_";
  constexpr std::string_view kSuffix = ".Module";
  if (t.rfind(kPrefix, 0) != 0 || t.size() <= kPrefix.size() + kSuffix.size()) return false;
  if (t.substr(t.size() - kSuffix.size()) != kSuffix) return false;
  return is_digits(t.substr(kPrefix.size(), t.size() - kPrefix.size() - kSuffix.size()));
}

bool identifier(std::string_view s) {
  if (s.empty() || s.size() > 100 || std::isdigit(static_cast<unsigned char>(s[0]))) return false;
  return std::all_of(s.begin(), s.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

// One line of a stub into `stub`; false for a line the writer does not make, and for a second
// declaration of a name.
bool stub_line(std::string_view line, ClassStub& stub) {
  if (line.rfind("  ", 0) != 0) return false;
  line.remove_prefix(2);
  for (std::string_view list : {"__parameters__ = ", "__buffers__ = "})
    if (line.rfind(list, 0) == 0) return name_list(line.substr(list.size()), stub.listed);
  if (line == "__annotations__ = []") return true;
  constexpr std::string_view kAnnotation = "__annotations__[";
  std::string name;
  std::string_view type;
  if (line.rfind(kAnnotation, 0) == 0) {
    line.remove_prefix(kAnnotation.size());
    if (!quoted(line, &name) || line.rfind("] = ", 0) != 0) return false;
    type = line.substr(4);
  } else {
    const std::size_t colon = line.find(" : ");
    if (colon == std::string_view::npos || !identifier(line.substr(0, colon))) return false;
    name = line.substr(0, colon);
    type = line.substr(colon + 3);
  }
  return known_type(type) && stub.types.emplace(name, std::string(type)).second;
}

ClassStub read_stub(std::string_view code, const std::string& where) {
  constexpr std::string_view kHeader = "class Module(Module):\n";
  if (code.rfind(kHeader, 0) != 0) fail(where + ": not a class stub Scout's writer makes (first line)");
  code.remove_prefix(kHeader.size());
  ClassStub stub;
  int line_no = 2;
  while (!code.empty()) {
    const std::size_t end = code.find('\n');
    if (end == std::string_view::npos) fail(fmt::format("{}:{}: the line does not end", where, line_no));
    if (!stub_line(code.substr(0, end), stub))
      fail(fmt::format("{}:{}: not a line of a class stub Scout's writer makes", where, line_no));
    code.remove_prefix(end + 1);
    ++line_no;
  }
  for (const std::string& name : stub.listed) {
    const auto type = stub.types.find(name);
    if (type == stub.types.end() || type->second != "Tensor")
      fail(where + ": lists '" + clipped(name) + "' as a parameter or buffer without declaring it a Tensor");
  }
  return stub;
}

// ---------------------------------------------------------------------------------------------
// data.pkl's tree of modules, held against the class stubs.

/// Whether `value` is what a stub's `type` declares.
bool of_type(Ref value, const std::string& type) {
  using K = Value::Kind;
  if (type == "Tensor") return value->kind == K::Tensor;
  if (type == "int") return value->kind == K::Int;
  if (type == "float") return value->kind == K::Float;
  if (type == "str") return value->kind == K::String;
  if (type == "bool") return value->kind == K::Bool;
  if (type == "Tuple[float, float]")
    return value->kind == K::Tuple && value->items.size() == 2 && value->items[0]->kind == K::Float &&
           value->items[1]->kind == K::Float;
  // "__torch__.___torch_mangle_4.Module" is the class the pickle names "__torch__.___torch_mangle_4 Module".
  const std::string global = type.substr(0, type.size() - 7) + " Module";
  return value->kind == K::Object && value->text == global;
}

struct Collector {
  const std::map<std::string, ClassStub>& stubs;
  std::string where;
  ArchiveContents& out;
  std::set<Ref> seen;             // modules and tensors met
  std::set<std::string> classes;  // the code entries of the classes met

  /// Collects the tensors and plain values under `object` with their dotted paths, each
  /// attribute as its class stub declares it: no attribute the stub does not declare, none of
  /// another type, none missing (LibTorch would take the pickle's word for what the stub says).
  /// The writer's modules form a tree: a module or tensor met twice (a crafted memo can make a
  /// module its own attribute, or share it a billion times) is refused, which also bounds the walk.
  void module(Ref object, const std::string& path, int depth) {
    if (depth > 64) fail(where + ": modules nested more than 64 deep");
    if (!seen.insert(object).second) fail(where + ": a module appears twice (the writer makes a tree)");
    if (!object->state) fail(where + ": a module without attributes");
    const std::string code = class_file(object->text);
    classes.insert(code);
    const ClassStub& stub = stubs.at(code);
    const auto& items = object->state->items;
    std::set<std::string> names;
    for (std::size_t i = 0; i + 1 < items.size(); i += 2) {
      const std::string& attribute = items[i]->text;
      const std::string name = path.empty() ? attribute : path + "." + attribute;
      if (!names.insert(attribute).second) fail(where + ": " + clipped(name) + " appears twice");
      const auto declared = stub.types.find(attribute);
      if (declared == stub.types.end())
        fail(where + ": " + clipped(name) + " is not an attribute its class stub (" + code + ") declares");
      if (!of_type(items[i + 1], declared->second))
        fail(where + ": " + clipped(name) + " is not the " + declared->second + " its class stub (" + code +
             ") declares");
      value(items[i + 1], name, depth);
    }
    if (names.size() != stub.types.size())
      fail(where + ": " + (path.empty() ? std::string("the root") : clipped(path)) +
           " lacks attributes its class stub (" + code + ") declares");
  }

  void value(Ref v, const std::string& name, int depth) {
    switch (v->kind) {
      case Value::Kind::Object:
        return module(v, name, depth + 1);
      case Value::Kind::Tensor: {
        if (!seen.insert(v).second)
          fail(where + ": " + clipped(name) + " is a tensor met before (the writer makes a tree)");
        ArchiveTensor t;
        t.path = name;
        t.dtype = v->text;
        for (Ref size : v->items) t.sizes.push_back(size->number);
        t.elements = v->number;
        t.value = v->long_value;
        out.tensors.push_back(std::move(t));
        return;
      }
      case Value::Kind::String:
        out.strings[name] = v->text;
        return;
      case Value::Kind::Int:
        out.ints[name] = v->number;
        return;
      case Value::Kind::Float:
        out.floats[name] = v->real;
        return;
      case Value::Kind::Bool:
        out.bools[name] = v->number != 0;
        return;
      case Value::Kind::Tuple:  // Tuple[float, float], checked by of_type
        out.float_pairs[name] = {v->items[0]->real, v->items[1]->real};
        return;
      default:
        fail(where + ": " + clipped(name) + " holds a value Scout's writer never stores");
    }
  }
};

}  // namespace

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

ArchiveContents inspect_archive(std::string_view data) {
  const Bytes b(data);
  const ZipDirectory zip = read_directory(b);
  std::uint64_t budget = kMaxPickleBytes + kMaxSmallBytesTotal;
  const auto entry = [&](const std::string& name) -> const ZipEntry& { return zip.entries.at(name); };
  const auto where = [&](const std::string& name) { return "entry " + clipped(zip.folder + "/" + name); };

  const std::string version = entry_bytes(b, zip, entry("version"), 16, budget);
  const std::string_view digits = std::string_view(version).substr(0, version.find('\n'));
  if (!is_digits(digits, 2) || std::stoi(std::string(digits)) < 1 || std::stoi(std::string(digits)) > 10 ||
      (digits.size() != version.size() && digits.size() + 1 != version.size()))
    fail(where("version") + ": expected a format number from 1 to 10");

  // Written by LibTorch 2.x: the records must be little-endian (what this reader and x86 assume),
  // and the id is a decimal number of at most 64 digits.
  if (zip.entries.count("byteorder") &&
      entry_bytes(b, zip, entry("byteorder"), kMaxSmallEntryBytes, budget) != "little")
    fail(where("byteorder") + ": expected \"little\" (records in little-endian order)");
  if (zip.entries.count(".data/serialization_id") &&
      !is_digits(entry_bytes(b, zip, entry(".data/serialization_id"), kMaxSmallEntryBytes, budget), 64))
    fail(where(".data/serialization_id") + ": expected a decimal id of at most 64 digits");

  std::map<std::string, ClassStub> stubs;
  for (const auto& [name, e] : zip.entries) {
    if (name.rfind("data/", 0) == 0) {
      // Tensor records: stored (checked above); CRC-checked in place without a copy.
      if (crc32_of(b.view(e.data, e.compressed)) != e.crc)
        fail(where(name) + ": CRC-32 mismatch (the file is damaged)");
    } else if (name.size() > 3 && name.substr(name.size() - 3) == ".py") {
      stubs[name] = read_stub(entry_bytes(b, zip, e, kMaxSmallEntryBytes, budget), where(name));
      if (!zip.entries.count(name + ".debug_pkl")) fail(where(name) + ": has no .debug_pkl beside it");
    } else if (name.size() > 10 && name.substr(name.size() - 10) == ".debug_pkl") {
      if (!zip.entries.count(name.substr(0, name.size() - 10))) fail(where(name) + ": has no class stub beside it");
      PickleMachine(entry_bytes(b, zip, e, kMaxSmallEntryBytes, budget), where(name), PickleKind::Debug, zip, b).run();
    }
  }

  const std::string constants_pickle = entry_bytes(b, zip, entry("constants.pkl"), kMaxSmallEntryBytes, budget);
  PickleMachine constants_machine(constants_pickle, where("constants.pkl"), PickleKind::Constants, zip, b);
  const Ref constants = constants_machine.run();
  if (constants->kind != Value::Kind::Tuple || !constants->items.empty())
    fail(where("constants.pkl") + ": expected no constants (Scout's writer stores none)");

  const std::string pickle = entry_bytes(b, zip, entry("data.pkl"), kMaxPickleBytes, budget);
  PickleMachine machine(pickle, where("data.pkl"), PickleKind::Data, zip, b);
  const Ref root = machine.run();
  if (root->kind != Value::Kind::Object || root->text != "__torch__ Module")
    fail(where("data.pkl") + ": the root is not a module");
  ArchiveContents out;
  Collector collector{stubs, where("data.pkl"), out, {}, {}};
  collector.module(root, "", 0);
  // Nothing in the archive that the tree does not use: every record is a tensor's storage, every
  // class stub a module's class.
  for (const auto& [name, e] : zip.entries) {
    if (name.rfind("data/", 0) == 0 && !machine.records_used().count(name.substr(5)))
      fail(where(name) + ": a record no tensor uses (the writer stores only tensors' storages)");
    if (stubs.count(name) && !collector.classes.count(name)) fail(where(name) + ": a class stub no module uses");
  }
  return out;
}

}  // namespace scout::learn
