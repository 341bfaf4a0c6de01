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
  std::uint16_t method = 0;
  std::uint32_t crc = 0;
  std::uint64_t compressed = 0, size = 0;
  std::uint64_t header = 0, data = 0;  ///< offsets of the local header and of the data
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

DirectoryPlace find_directory(const Bytes& b) {
  if (b.size() < kEndRecordSize) fail(fmt::format("{} bytes: too short for a zip archive", b.size()));
  const std::uint64_t end = b.size() - kEndRecordSize;
  if (b.u32(end) != kEndRecord)
    fail("no zip end record at the end of the file (truncated, appended to, or not a LibTorch archive)");
  if (b.u16(end + 4) != 0 || b.u16(end + 6) != 0 || b.u16(end + 8) != b.u16(end + 10) || b.u16(end + 20) != 0)
    fail("a multi-part zip archive or one with a comment (Scout's writer makes neither)");
  DirectoryPlace d{.count = b.u16(end + 10), .offset = b.u32(end + 16), .size = b.u32(end + 12), .limit = end};
  if (d.count == 0xffff || d.size == 0xffffffff || d.offset == 0xffffffff) {
    // The zip64 end record, found through its locator just before the end record.
    if (end < 20 || b.u32(end - 20) != kZip64Locator) fail("a zip64 archive without its zip64 locator");
    const std::uint64_t record = b.u64(end - 20 + 8);
    if (record >= end - 20 || b.u32(record) != kZip64EndRecord)
      fail("the zip64 end record is not where its locator says");
    d = {.count = b.u64(record + 32), .offset = b.u64(record + 48), .size = b.u64(record + 40), .limit = record};
  } else if (end >= 20 + 56 && b.u32(end - 20) == kZip64Locator) {
    // LibTorch writes the zip64 records even for small archives: the directory ends before them.
    const std::uint64_t record = b.u64(end - 20 + 8);
    if (record < end - 20 && b.u32(record) == kZip64EndRecord) d.limit = record;
  }
  if (d.count == 0) fail("an empty zip archive");
  if (d.count > kMaxArchiveEntries) fail(fmt::format("{} zip entries (at most {})", d.count, kMaxArchiveEntries));
  if (d.offset > d.limit || d.size > d.limit - d.offset) fail("the zip directory lies outside the file");
  return d;
}

// Directory entry `i` at `at` (moved on to the next), checked against what Scout's writer makes
// and against its local header. All entries lie in one folder: `folder`, set by the first.
ZipEntry read_entry(const Bytes& b, std::uint64_t& at, std::uint64_t i, const DirectoryPlace& d, std::string& folder) {
  const std::uint64_t directory_end = d.offset + d.size;
  if (at + 46 > directory_end || b.u32(at) != kCentralHeader) fail(fmt::format("zip directory entry {} is damaged", i));
  ZipEntry e;
  const std::uint16_t flags = b.u16(at + 8);
  e.method = b.u16(at + 10);
  e.crc = b.u32(at + 16);
  e.compressed = b.u32(at + 20);
  e.size = b.u32(at + 24);
  const std::uint16_t name_length = b.u16(at + 28);
  const std::uint64_t next = at + 46 + name_length + b.u16(at + 30) + b.u16(at + 32);
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
  if (flags & 0x41) fail(where + ": encrypted");
  if (e.method != kStored && e.method != kDeflated)
    fail(fmt::format("{}: compression method {} (expected 0, stored, or 8, deflated)", where, e.method));
  if (e.compressed == 0xffffffff || e.size == 0xffffffff || e.header == 0xffffffff)
    fail(where + ": larger than 4 GiB (zip64 entries are not written by Scout)");
  if (e.method == kStored && e.compressed != e.size)
    fail(fmt::format("{}: stored, but its sizes differ ({} and {} bytes)", where, e.compressed, e.size));
  if (e.name.rfind("data/", 0) == 0 && e.method != kStored) fail(where + ": a tensor record must be stored");

  // The local header must agree with the directory and its data must end before the directory.
  if (b.u32(e.header) != kLocalHeader) fail(where + ": no local header at its offset");
  const std::uint16_t local_name = b.u16(e.header + 26);
  if (b.view(e.header + 30, local_name) != full) fail(where + ": its local header names another entry");
  e.data = e.header + 30 + local_name + b.u16(e.header + 28);
  if (e.data > d.offset || e.compressed > d.offset - e.data)
    fail(fmt::format("{}: its {} bytes of data run into the zip directory", where, e.compressed));
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
  std::sort(by_offset.begin(), by_offset.end(),
            [](const ZipEntry& x, const ZipEntry& y) { return x.header < y.header; });
  for (std::size_t i = 1; i < by_offset.size(); ++i)
    if (by_offset[i - 1].data + by_offset[i - 1].compressed > by_offset[i].header)
      fail("zip entries " + clipped(by_offset[i - 1].name) + " and " + clipped(by_offset[i].name) + " overlap");
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
  std::string text;        ///< String; Global: "module name"; Object: its class; Storage, Tensor: dtype
  std::string key;         ///< Storage: the record's name under data/
  std::vector<Ref> items;  ///< Tuple, List; Dict: key, value, key, value...; Tensor: its sizes as Ints
  Ref state = nullptr;     ///< Object: its attributes (a Dict) once BUILD ran
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
  PickleMachine(std::string_view code, std::string where, PickleKind kind, const ZipDirectory& zip)
      : code_(code), where_(std::move(where)), kind_(kind), zip_(zip) {}

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

  static constexpr std::size_t kMaxValues = 1'000'000;
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

  Ref tuple(std::vector<Ref> items) {
    Ref v = make(Value::Kind::Tuple);
    v->items = std::move(items);
    return v;
  }
  void append(std::vector<Ref> items) {
    Ref& list = top();
    if (list->kind != Value::Kind::List) error("APPEND to something other than a list");
    for (Ref item : items) list->items.push_back(item);
  }
  void set_items(std::vector<Ref> items) {
    Ref& dict = top();
    if (dict->kind != Value::Kind::Dict) error("SETITEM on something other than a dict");
    if (items.size() % 2) error("SETITEMS with an odd number of values");
    for (std::size_t i = 0; i < items.size(); i += 2)
      if (items[i]->kind != Value::Kind::String) error("a dict key that is not a string");
    for (Ref item : items) dict->items.push_back(item);
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
    const auto [seen, fresh] = storages_.emplace(key, std::make_pair(std::string(dtype->name), numel));
    if (!fresh && seen->second != std::make_pair(std::string(dtype->name), numel))
      error("storage " + key + " is declared twice, differently");
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

  // _rebuild_tensor_v2(storage, offset, sizes, strides, requires_grad, backward_hooks)
  Ref tensor(const std::vector<Ref>& a) {
    if (a.size() != 6 || !is(a[0], Value::Kind::Storage) || !is(a[1], Value::Kind::Int) ||
        !is(a[2], Value::Kind::Tuple) || !is(a[3], Value::Kind::Tuple) || !is(a[4], Value::Kind::Bool) ||
        !is(a[5], Value::Kind::Dict) || !a[5]->items.empty())
      error("a malformed tensor");
    const auto& sizes = a[2]->items;
    const auto& strides = a[3]->items;
    if (sizes.size() != strides.size() || sizes.size() > kMaxRank)
      error(fmt::format("a tensor with {} sizes and {} strides (at most {} of each, as many strides as sizes)",
                        sizes.size(), strides.size(), kMaxRank));
    const std::int64_t offset = a[1]->number;
    const std::int64_t numel = a[0]->number;
    // The last element the tensor reaches must lie inside its storage (no element when a size is
    // 0); checked arithmetic, as a crafted size times a crafted stride overflows 64 bits.
    if (offset < 0) error("a tensor with a negative storage offset");
    std::uint64_t last = static_cast<std::uint64_t>(offset);
    bool empty = false, overflow = false;
    Ref out = make(Value::Kind::Tensor);
    for (std::size_t i = 0; i < sizes.size(); ++i) {
      if (!is(sizes[i], Value::Kind::Int) || !is(strides[i], Value::Kind::Int) || sizes[i]->number < 0 ||
          strides[i]->number < 0)
        error("a tensor size or stride out of range");
      if (sizes[i]->number == 0) {
        empty = true;
      } else {
        std::uint64_t span = 0;
        overflow |= __builtin_mul_overflow(static_cast<std::uint64_t>(sizes[i]->number - 1),
                                           static_cast<std::uint64_t>(strides[i]->number), &span);
        overflow |= __builtin_add_overflow(last, span, &last);
      }
      out->items.push_back(sizes[i]);
    }
    if (!empty && (overflow || last >= static_cast<std::uint64_t>(numel)))
      error(fmt::format("a tensor in storage {} reaches past its {} elements", a[0]->key, numel));
    out->text = a[0]->text;
    return out;
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
  std::map<std::string, std::pair<std::string, std::int64_t>> storages_;
  std::vector<std::unique_ptr<Value>> arena_;
};

/// Collects the tensors under `object` with their dotted paths. The writer's modules form a tree:
/// a module met twice (a crafted memo can make one its own attribute, or share it a billion
/// times) is refused, which also bounds the walk.
void collect(Ref object, const std::string& path, int depth, std::set<Ref>& seen, ArchiveContents& out,
             const std::string& where) {
  if (depth > 64) fail(where + ": modules nested more than 64 deep");
  if (!seen.insert(object).second) fail(where + ": a module appears twice (the writer makes a tree)");
  if (!object->state) fail(where + ": a module without attributes");
  const auto& items = object->state->items;
  for (std::size_t i = 0; i + 1 < items.size(); i += 2) {
    const std::string name = path.empty() ? items[i]->text : path + "." + items[i]->text;
    const Ref value = items[i + 1];
    if (value->kind == Value::Kind::Object) {
      collect(value, name, depth + 1, seen, out, where);
    } else if (value->kind == Value::Kind::Tensor) {
      ArchiveTensor t;
      t.path = name;
      t.dtype = value->text;
      for (Ref size : value->items) t.sizes.push_back(size->number);
      out.tensors.push_back(std::move(t));
    } else if (depth == 0 && value->kind == Value::Kind::String) {
      out.strings[name] = value->text;
    } else if (depth == 0 && value->kind == Value::Kind::Int) {
      out.ints[name] = value->number;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// code/*.py: the TorchScript class stubs the writer makes, e.g.
//   class Module(Module):
//     __parameters__ = ["weight", "bias", ]
//     __buffers__ = []
//     __annotations__ = []
//     __annotations__["0"] = __torch__.___torch_mangle_4.Module
//     weight : Tensor

bool quoted(std::string_view& s) {
  if (s.empty() || s[0] != '"') return false;
  std::size_t i = 1;
  while (i < s.size() && (std::isalnum(static_cast<unsigned char>(s[i])) || s[i] == '_' || s[i] == '.' || s[i] == '/'))
    ++i;
  if (i == 1 || i >= s.size() || s[i] != '"') return false;
  s.remove_prefix(i + 1);
  return true;
}

bool name_list(std::string_view s) {
  if (s == "[]") return true;
  if (s.empty() || s[0] != '[') return false;
  s.remove_prefix(1);
  while (!s.empty() && s[0] == '"') {
    if (!quoted(s) || s.rfind(", ", 0) != 0) return false;
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

bool stub_line(std::string_view line) {
  if (line.rfind("  ", 0) != 0) return false;
  line.remove_prefix(2);
  for (std::string_view list : {"__parameters__ = ", "__buffers__ = "})
    if (line.rfind(list, 0) == 0) return name_list(line.substr(list.size()));
  if (line == "__annotations__ = []") return true;
  constexpr std::string_view kAnnotation = "__annotations__[";
  if (line.rfind(kAnnotation, 0) == 0) {
    line.remove_prefix(kAnnotation.size());
    if (!quoted(line) || line.rfind("] = ", 0) != 0) return false;
    return known_type(line.substr(4));
  }
  const std::size_t colon = line.find(" : ");
  return colon != std::string_view::npos && identifier(line.substr(0, colon)) && known_type(line.substr(colon + 3));
}

void check_stub(std::string_view code, const std::string& where) {
  constexpr std::string_view kHeader = "class Module(Module):\n";
  if (code.rfind(kHeader, 0) != 0) fail(where + ": not a class stub Scout's writer makes (first line)");
  code.remove_prefix(kHeader.size());
  int line_no = 2;
  while (!code.empty()) {
    const std::size_t end = code.find('\n');
    if (end == std::string_view::npos) fail(fmt::format("{}:{}: the line does not end", where, line_no));
    if (!stub_line(code.substr(0, end)))
      fail(fmt::format("{}:{}: not a line of a class stub Scout's writer makes", where, line_no));
    code.remove_prefix(end + 1);
    ++line_no;
  }
}

}  // namespace

std::int64_t ArchiveTensor::numel() const {
  std::int64_t n = 1;
  for (std::int64_t s : sizes) n *= s;
  return n;
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

  for (const auto& [name, e] : zip.entries) {
    if (name.rfind("data/", 0) == 0) {
      // Tensor records: stored (checked above); CRC-checked in place without a copy.
      if (crc32_of(b.view(e.data, e.compressed)) != e.crc)
        fail(where(name) + ": CRC-32 mismatch (the file is damaged)");
    } else if (name.size() > 3 && name.substr(name.size() - 3) == ".py") {
      check_stub(entry_bytes(b, zip, e, kMaxSmallEntryBytes, budget), where(name));
    } else if (name.size() > 10 && name.substr(name.size() - 10) == ".debug_pkl") {
      PickleMachine(entry_bytes(b, zip, e, kMaxSmallEntryBytes, budget), where(name), PickleKind::Debug, zip).run();
    }
  }

  const std::string constants_pickle = entry_bytes(b, zip, entry("constants.pkl"), kMaxSmallEntryBytes, budget);
  PickleMachine constants_machine(constants_pickle, where("constants.pkl"), PickleKind::Constants, zip);
  const Ref constants = constants_machine.run();
  if (constants->kind != Value::Kind::Tuple || !constants->items.empty())
    fail(where("constants.pkl") + ": expected no constants (Scout's writer stores none)");

  const std::string pickle = entry_bytes(b, zip, entry("data.pkl"), kMaxPickleBytes, budget);
  PickleMachine machine(pickle, where("data.pkl"), PickleKind::Data, zip);
  const Ref root = machine.run();
  if (root->kind != Value::Kind::Object || root->text != "__torch__ Module")
    fail(where("data.pkl") + ": the root is not a module");
  ArchiveContents out;
  std::set<Ref> seen;
  collect(root, "", 0, seen, out, where("data.pkl"));
  return out;
}

}  // namespace scout::learn
