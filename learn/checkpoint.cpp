#include "learn/internal/checkpoint.hpp"

#include <ATen/CPUGeneratorImpl.h>
#include <fmt/format.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "core/error.hpp"
#include "core/files.hpp"

namespace scout::learn {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

namespace {

// The first line of a library's message (LibTorch appends a multi-line backtrace).
std::string first_line(const char* what) {
  std::string text(what);
  return one_line(text.substr(0, std::min(text.find('\n'), std::size_t{200})));
}

json optional_json(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

std::optional<double> optional_from(const json& row, const char* key) {
  if (!row.contains(key) || row.at(key).is_null()) return std::nullopt;
  return row.at(key).get<double>();
}

json history_json(const std::vector<EpochMetrics>& history) {
  json rows = json::array();
  for (const EpochMetrics& m : history)
    rows.push_back({{"mode", to_string(m.stage)},
                    {"stage", static_cast<int>(m.stage)},
                    {"epoch", m.epoch},
                    {"reward", m.reward},
                    {"loss", m.loss},
                    {"train_accuracy", m.train_accuracy},
                    {"validation_accuracy", m.validation_accuracy},
                    {"images_per_s", m.images_per_s},
                    {"seconds", m.seconds},
                    {"learning_rate", m.learning_rate},
                    {"validation_iid", optional_json(m.validation_iid)},
                    {"validation_goals_only", optional_json(m.validation_goals_only)},
                    {"validation_full_image", optional_json(m.validation_full_image)}});
  return rows;
}

// `learning_rate`: the run's configured rate, for rows written before epochs recorded their own.
std::vector<EpochMetrics> history_from(const json& rows, double learning_rate) {
  std::vector<EpochMetrics> history;
  for (const json& r : rows) {
    EpochMetrics m;
    const int stage = r.at("stage").get<int>();
    if (stage < 0 || stage > 3) throw std::out_of_range("stage");
    m.stage = static_cast<Stage>(stage);
    m.epoch = r.at("epoch").get<int>();
    m.reward = r.at("reward").get<double>();
    m.loss = r.at("loss").get<double>();
    m.train_accuracy = r.at("train_accuracy").get<double>();
    m.validation_accuracy = r.at("validation_accuracy").get<double>();
    m.images_per_s = r.at("images_per_s").get<double>();
    m.seconds = r.at("seconds").get<double>();
    m.learning_rate = r.contains("learning_rate") ? r.at("learning_rate").get<double>() : learning_rate;
    m.validation_iid = optional_from(r, "validation_iid");
    m.validation_goals_only = optional_from(r, "validation_goals_only");
    m.validation_full_image = optional_from(r, "validation_full_image");
    history.push_back(m);
  }
  return history;
}

// Non-finite numbers are not JSON; nlohmann writes them as null. Keep losses readable.
double finite_or_zero(double v) { return std::isfinite(v) ? v : 0.0; }

}  // namespace

fs::path resolve_checkpoint(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec) ? path / kCheckpointFile : path;
}

namespace {

torch::serialize::OutputArchive checkpoint_archive(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer,
                                                   const CheckpointState& state) {
  torch::serialize::OutputArchive archive;
  archive.write("scout_checkpoint_format", c10::IValue(static_cast<int64_t>(kCheckpointFormat)));
  archive.write("config", c10::IValue(state.config.to_json()));
  const EpochSums& p = state.partial;
  json progress = {{"stage", state.cursor.stage},
                   {"epoch", state.cursor.epoch},
                   {"batch", state.cursor.batch},
                   {"partial",
                    {{"reward", finite_or_zero(p.reward)},
                     {"loss", finite_or_zero(p.loss)},
                     {"train_seconds", p.train_seconds},
                     {"correct", p.correct},
                     {"robots", p.robots},
                     {"images", p.images},
                     {"batches", p.batches}}},
                   {"history", history_json(state.history)},
                   {"world_size", state.world_size},
                   {"threads", state.threads}};
  archive.write("progress", c10::IValue(progress.dump()));
  torch::serialize::OutputArchive weights;
  agent.save(weights);
  archive.write("agent", weights);
  if (optimizer) {
    torch::serialize::OutputArchive optimizer_archive;
    optimizer->save(optimizer_archive);
    archive.write("optimizer", optimizer_archive);
  }
  // Sampling uses Scout's own counter-based streams (seed, stage, epoch, batch, robot); LibTorch's
  // generator only initialises weights. Both are kept so that nothing random is lost.
  archive.write("torch_rng_state", at::detail::getDefaultCPUGenerator().get_state());
  return archive;
}

}  // namespace

std::string checkpoint_bytes(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer,
                             const CheckpointState& state) {
  std::ostringstream out;
  checkpoint_archive(agent, optimizer, state).save_to(out);
  return std::move(out).str();
}

void save_checkpoint(const fs::path& file, agent::AgentImpl& agent, torch::optim::Optimizer* optimizer,
                     const CheckpointState& state) {
  // Serialised in memory, then written by Scout's own durable writer (which reports errno: a full
  // disk or a file-size limit is one line, and the previous checkpoint stays).
  core::write_file_atomic(file, checkpoint_bytes(agent, optimizer, state));
}

namespace {

torch::serialize::InputArchive open_archive(const fs::path& given) {
  std::error_code ec;
  const fs::path file = resolve_checkpoint(given);
  if (!fs::is_regular_file(file, ec))
    throw InputError(file.string() + ": no such checkpoint file (expected RUN/checkpoint.pt or a model file)");
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(file.string());
  } catch (const std::exception&) {
    throw InputError(file.string() + ": not a Scout checkpoint (expected a file written by scout train)");
  }
  return archive;
}

torch::serialize::InputArchive open_archive_bytes(const std::string& bytes, const std::string& origin) {
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(bytes.data(), bytes.size());
  } catch (const std::exception&) {
    throw InputError(origin + ": not a Scout checkpoint");
  }
  return archive;
}

CheckpointState read_state(torch::serialize::InputArchive& archive, const std::string& name);
void load_weights(torch::serialize::InputArchive& archive, const std::string& name, agent::AgentImpl& agent,
                  torch::optim::Optimizer* optimizer);

}  // namespace

CheckpointState read_checkpoint_state(const fs::path& file) {
  torch::serialize::InputArchive archive = open_archive(file);
  return read_state(archive, file.string());
}

CheckpointState read_checkpoint_state_bytes(const std::string& bytes, const std::string& origin) {
  torch::serialize::InputArchive archive = open_archive_bytes(bytes, origin);
  return read_state(archive, origin);
}

void load_checkpoint_weights(const fs::path& file, agent::AgentImpl& agent, torch::optim::Optimizer* optimizer) {
  torch::serialize::InputArchive archive = open_archive(file);
  load_weights(archive, file.string(), agent, optimizer);
}

void load_checkpoint_weights_bytes(const std::string& bytes, const std::string& origin, agent::AgentImpl& agent,
                                   torch::optim::Optimizer* optimizer) {
  torch::serialize::InputArchive archive = open_archive_bytes(bytes, origin);
  load_weights(archive, origin, agent, optimizer);
}

namespace {

CheckpointState read_state(torch::serialize::InputArchive& archive, const std::string& name) {
  c10::IValue version, config, progress;
  if (!archive.try_read("scout_checkpoint_format", version) || !version.isInt())
    throw InputError(name + ": not a Scout checkpoint (no scout_checkpoint_format entry)");
  if (version.toInt() != kCheckpointFormat)
    throw InputError(fmt::format("{}: scout_checkpoint_format: this build reads format {}, the file has {}", name,
                                 kCheckpointFormat, version.toInt()));
  if (!archive.try_read("config", config) || !config.isString())
    throw InputError(name + ": config: missing from the checkpoint");
  CheckpointState state;
  state.config = TrainConfig::from_json(config.toStringRef(), name);
  if (!archive.try_read("progress", progress) || !progress.isString())
    throw InputError(name + ": progress: missing from the checkpoint");
  try {
    const json p = json::parse(progress.toStringRef());
    state.cursor = {p.at("stage").get<int>(), p.at("epoch").get<int>(), p.at("batch").get<int>()};
    const json& q = p.at("partial");
    state.partial = {q.at("reward").get<double>(), q.at("loss").get<double>(), q.at("train_seconds").get<double>(),
                     q.at("correct").get<long>(),  q.at("robots").get<long>(), q.at("images").get<long>(),
                     q.at("batches").get<long>()};
    state.history = history_from(p.at("history"), state.config.learning_rate);
    state.world_size = p.contains("world_size") ? p.at("world_size").get<int>() : 1;
    state.threads = p.contains("threads") ? p.at("threads").get<int>() : 0;
  } catch (const std::exception& e) {
    throw InputError(name + ": progress: unreadable (" + one_line(e.what()) + ")");
  }
  if (state.cursor.stage < 0 || state.cursor.stage > 4 || state.cursor.epoch < 0 || state.cursor.batch < 0)
    throw InputError(name + ": progress: the schedule position is out of range");
  return state;
}

void load_weights(torch::serialize::InputArchive& archive, const std::string& origin, agent::AgentImpl& agent,
                  torch::optim::Optimizer* optimizer) {
  // LibTorch's load replaces each tensor with the file's whatever its shape: compare afterwards.
  std::vector<std::pair<std::string, std::vector<std::int64_t>>> shapes;
  for (const auto& p : agent.named_parameters()) shapes.emplace_back(p.key(), p.value().sizes().vec());
  for (const auto& b : agent.named_buffers()) shapes.emplace_back(b.key(), b.value().sizes().vec());
  const std::string mismatch = ": agent: the weights do not match the checkpoint's network config (";
  try {
    torch::serialize::InputArchive weights;
    archive.read("agent", weights);
    agent.load(weights);
  } catch (const std::exception& e) {
    throw InputError(origin + mismatch + first_line(e.what()) + ")");
  }
  const auto parameters = agent.named_parameters();
  const auto buffers = agent.named_buffers();
  for (const auto& [name, shape] : shapes) {
    const torch::Tensor* t = parameters.find(name);
    if (!t) t = buffers.find(name);
    if (!t || t->sizes().vec() != shape)
      throw InputError(origin + mismatch + name + " is " + (t ? c10::str(t->sizes()) : std::string("missing")) +
                       ", the config gives " + c10::str(c10::IntArrayRef(shape)) + ")");
  }
  if (optimizer) {
    try {
      torch::serialize::InputArchive optimizer_archive;
      archive.read("optimizer", optimizer_archive);
      optimizer->load(optimizer_archive);
    } catch (const std::exception& e) {
      throw InputError(origin + ": optimizer: missing or unreadable (a model file cannot be resumed; " +
                       first_line(e.what()) + ")");
    }
  }
}

}  // namespace

agent::Agent load_agent(const fs::path& file, CheckpointState* state) {
  CheckpointState read = read_checkpoint_state(file);
  agent::Agent agent(read.config.network);
  load_checkpoint_weights(file, *agent, nullptr);
  agent->eval();
  if (state) *state = std::move(read);
  return agent;
}

CheckpointInfo export_model(const fs::path& checkpoint, const fs::path& model_file) {
  CheckpointState state;
  agent::Agent agent = load_agent(resolve_checkpoint(checkpoint), &state);
  save_checkpoint(model_file, *agent, nullptr, state);
  return {kCheckpointFormat, std::move(state.config), state.cursor, std::move(state.history), state.world_size};
}

CheckpointInfo read_checkpoint_info(const fs::path& file) {
  CheckpointState state = read_checkpoint_state(file);
  CheckpointInfo info;
  info.format_version = kCheckpointFormat;
  info.config = std::move(state.config);
  info.cursor = state.cursor;
  info.history = std::move(state.history);
  info.world_size = state.world_size;
  return info;
}

}  // namespace scout::learn
