#pragma once
/// Labelled image sets on disk: the project's data folder, Debian's Fashion-MNIST, or any
/// folder of IDX files with the standard names, and their train / validation / test splits.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "worlds/idx.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {

/// Images with one label each, and where they came from.
struct LabeledImages {
  ImageSet images;
  std::vector<std::uint8_t> labels;          ///< one per image, 0 .. classes-1
  std::vector<std::filesystem::path> files;  ///< the IDX files read (for manifests)
};

/// Any pair of IDX image and label files (".gz" or raw): at least one image, one label per image.
/// Throws InputError naming the file for anything else (as read_idx_images does for a bad file).
LabeledImages read_labeled_idx(const std::filesystem::path& images, const std::filesystem::path& labels);

/// The project's data folder (where `scout data` installs by default): $SCOUT_DATA if set, else
/// <source tree>/data for a build, and for an installed package (`pip install .`) the user's data
/// folder, $XDG_DATA_HOME/scout or ~/.local/share/scout (core/install_layout.hpp).
std::filesystem::path default_data_root();

/// The data sets known by name: "mnist" (the whole of MNIST, `scout data`), "mnist-10k" (its
/// first 10,000 training digits, for fast tests) and "fashion-mnist" (Debian's package).
std::array<std::string_view, 3> named_datasets();

/// Folder holding data set `name`: "mnist" -> <data_root>/mnist, or <data_root> itself when it
/// holds train-images-idx3-ubyte[.gz] (a user's MNIST download), "mnist-10k" ->
/// <data_root>/mnist-10k, "fashion-mnist" -> /usr/share/datasets/fashion-mnist, anything else is
/// a folder path used as given.
std::filesystem::path dataset_folder(const std::string& name, const std::filesystem::path& data_root);

/// Loads one split of an IDX folder. File names: train-*, validation-*, t10k-* with
/// images-idx3-ubyte / labels-idx1-ubyte, each raw or ".gz". Without validation-* files the
/// validation split is carved out of train-* by the stratified rule (stratified_split) and
/// removed from train. Throws InputError for missing or inconsistent files.
LabeledImages load_split(const std::filesystem::path& folder, Split split);

/// Deterministic stratified selection (METHOD.md § Data): returns, for each of `parts` shares
/// (fractions summing to <= 1), the chosen indices into `labels`, each part shuffled into a
/// fixed order. Per-class quotas use the largest-remainder rule so that each part's total is
/// round(fraction * labels.size()). The same labels and seed give the same result everywhere.
std::vector<std::vector<int>> stratified_split(const std::vector<std::uint8_t>& labels,
                                               const std::vector<double>& fractions, std::uint64_t seed);

/// The fixed seed of the project's data split.
inline constexpr std::uint64_t kSplitSeed = 20190708;

}  // namespace scout::worlds
