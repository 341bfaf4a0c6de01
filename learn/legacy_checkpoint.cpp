// Scout's checkpoint format 1 (LibTorch's torch::save archive: a zip of pickles and tensor
// records), read only to convert it to format 2 (safetensors). Reading it runs LibTorch's own
// unpickler, which trusts its input: a crafted file can crash it or worse. Format 2 has nothing
// to validate; this file is the one place a .pt file is opened, and only for a file the user
// says they trust (`scout convert --trusted`).
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "agent/config.hpp"
#include "core/digest.hpp"
#include "core/error.hpp"
#include "core/files.hpp"
#include "core/input_file.hpp"
#include "core/memory.hpp"
#include "learn/internal/checkpoint.hpp"

namespace scout::learn {

namespace fs = std::filesystem;

namespace {

constexpr std::int64_t kLegacyFormat = 1;

std::string read_string(torch::serialize::InputArchive& archive, const std::string& key, const std::string& origin) {
  c10::IValue value;
  if (!archive.try_read(key, value) || !value.isString())
    throw InputError(origin + ": " + key + ": missing or not a string (expected a Scout checkpoint of format 1)");
  return value.toStringRef();
}

}  // namespace

CheckpointInfo convert_legacy_checkpoint(const fs::path& legacy, const fs::path& out, const std::string& manifest) {
  const std::string origin = legacy.string();
  const core::RegularFile file = core::open_regular_file(legacy);  // refuses a FIFO or a device
  if (file.size() > kMaxCheckpointBytes)
    throw InputError(fmt::format("{}: {} bytes, more than the {} a Scout checkpoint may have", origin, file.size(),
                                 core::format_bytes(kMaxCheckpointBytes)));
  CheckpointState state;
  agent::Agent agent{nullptr};
  std::unique_ptr<torch::optim::Adam> adam;
  try {
    torch::serialize::InputArchive archive;
    archive.load_from(origin);
    c10::IValue format;
    if (!archive.try_read("scout_checkpoint_format", format) || !format.isInt())
      throw InputError(origin + ": not a Scout checkpoint of format 1 (no scout_checkpoint_format entry)");
    if (format.toInt() != kLegacyFormat)
      throw InputError(fmt::format("{}: scout_checkpoint_format: {}, expected {} (the .pt format)", origin,
                                   format.toInt(), kLegacyFormat));
    state.config = TrainConfig::from_json(read_string(archive, "config", origin), origin);
    read_progress(read_string(archive, "progress", origin), origin, state);
    agent = agent::Agent(state.config.network);
    torch::serialize::InputArchive weights;
    archive.read("agent", weights);
    agent->load(weights);
    torch::serialize::InputArchive optimizer;
    if (archive.try_read("optimizer", optimizer)) {
      adam = std::make_unique<torch::optim::Adam>(agent->parameters(),
                                                  torch::optim::AdamOptions(state.config.learning_rate));
      adam->load(optimizer);
    }
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(origin + ": not readable as a Scout checkpoint of format 1 (" + first_line(e.what()) + ")");
  }
  // The manifest, with where the weights came from: an evaluation of the .pt file names that
  // file's SHA-256 (scout report accepts it for the converted model).
  nlohmann::ordered_json record =
      manifest.empty() ? nlohmann::ordered_json::object() : nlohmann::ordered_json::parse(manifest, nullptr, false);
  if (!record.is_object()) throw InputError(origin + ": its manifest is not a JSON object");
  record["converted_from"] = {
      {"file", legacy.string()}, {"sha256", core::sha256_hex(legacy)}, {"format", kLegacyFormat}};
  state.manifest = record.dump();
  // Checked as every reader checks it before a byte is written: a file LibTorch loads but Scout
  // would refuse (NaN weights, a cursor outside the schedule) never replaces anything at `out`.
  std::string bytes = checkpoint_bytes(*agent, adam.get(), state);
  const CheckpointInfo info = open_checkpoint_bytes(bytes, out.string()).info();
  core::write_file_atomic(out, bytes);
  return info;
}

}  // namespace scout::learn
