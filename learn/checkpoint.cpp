#include "learn/internal/checkpoint.hpp"

#include <ATen/CPUGeneratorImpl.h>
#include <fmt/format.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>

#include "agent/config.hpp"
#include "core/error.hpp"
#include "core/files.hpp"
#include "learn/internal/archive.hpp"

namespace scout::learn {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

namespace {

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
    if (stage < 0 || stage >= kTrainingStages) throw std::out_of_range("stage");
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
  json progress = {{"stage", index(state.cursor.stage)},
                   {"epoch", state.cursor.epoch},
                   {"batch", state.cursor.batch},
                   {"partial",
                    {{"reward", finite_or_zero(p.reward)},
                     {"loss", finite_or_zero(p.loss)},
                     {"train_seconds", p.train_seconds},
                     {"correct", p.correct},
                     {"robots", p.rollouts},
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

// The file's bytes; a checkpoint is read whole (Scout checks it before LibTorch parses it).
std::string read_checkpoint_file(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec))
    throw InputError(file.string() + ": no such checkpoint file (expected RUN/checkpoint.pt or a model file)");
  std::ifstream in(file, std::ios::binary);
  std::string bytes;
  if (in) {
    const std::uintmax_t size = fs::file_size(file, ec);
    if (!ec) bytes.reserve(static_cast<std::size_t>(size));
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  if (!in && !in.eof()) throw InputError(file.string() + ": cannot read it (" + std::strerror(errno) + ")");
  return bytes;
}

// Which tensors a Scout archive holds besides the agent's, and what bounds them.
bool optimizer_tensor_fits(const ArchiveTensor& t, const std::set<std::vector<std::int64_t>>& parameter_shapes) {
  // Adam's moments have their parameter's shape; its bookkeeping ("param_groups/size") is scalar.
  return (t.dtype == "Float" && parameter_shapes.count(t.sizes)) ||
         ((t.dtype == "Long" || t.dtype == "Float") && t.numel() <= 1);
}

// The non-tensor part of a checkpoint: its "progress" entry (the schedule's position, the epoch in
// progress, the history, the run's processes and threads).
void read_progress(const std::string& text, const std::string& origin, CheckpointState& state) {
  int stage = 0;
  try {
    const json p = json::parse(text);
    stage = p.at("stage").get<int>();
    state.cursor = {Stage::Done, p.at("epoch").get<int>(), p.at("batch").get<int>()};
    const json& q = p.at("partial");
    state.partial = {q.at("reward").get<double>(), q.at("loss").get<double>(), q.at("train_seconds").get<double>(),
                     q.at("correct").get<long>(),  q.at("robots").get<long>(), q.at("images").get<long>(),
                     q.at("batches").get<long>()};
    state.history = history_from(p.at("history"), state.config.learning_rate);
    state.world_size = p.contains("world_size") ? p.at("world_size").get<int>() : 1;
    state.threads = p.contains("threads") ? p.at("threads").get<int>() : 0;
  } catch (const std::exception& e) {
    throw InputError(origin + ": progress: unreadable (" + one_line(e.what()) + ")");
  }
  if (stage < 0 || stage > index(Stage::Done) || state.cursor.epoch < 0 || state.cursor.batch < 0)
    throw InputError(origin + ": progress: the schedule position is out of range");
  state.cursor.stage = static_cast<Stage>(stage);
}

// Each tensor's name, shape and type against the agent the config describes; Adam's tensors must
// have a parameter's shape. The agent is built only once the file is known to hold that many
// weights, so that a crafted config cannot make Scout allocate more than the file's own size.
void check_tensors(const ArchiveContents& contents, const agent::NetworkConfig& network, const std::string& origin) {
  const std::string agent_prefix = "agent.";
  std::map<std::string, const ArchiveTensor*> agent_tensors;
  std::int64_t agent_values = 0;
  for (const ArchiveTensor& t : contents.tensors) {
    if (t.path.rfind(agent_prefix, 0) != 0) continue;
    agent_tensors[t.path.substr(agent_prefix.size())] = &t;
    agent_values += t.numel();
  }
  const std::string mismatch = ": agent: the weights do not match the checkpoint's network config (";
  const std::int64_t parameters = agent::parameter_count(network);
  if (agent_values < parameters)
    throw InputError(fmt::format("{}{}it gives {} parameters, the file holds {} values)", origin, mismatch, parameters,
                                 agent_values));

  // Building the reference agent draws initial weights from LibTorch's generator: put its state
  // back, so that checking a file never changes what a later construction draws.
  struct GeneratorRestore {
    at::Generator generator = at::detail::getDefaultCPUGenerator();
    at::Tensor state = generator.get_state();
    ~GeneratorRestore() { generator.set_state(state); }
  } restore;
  agent::Agent reference(network);
  std::set<std::vector<std::int64_t>> parameter_shapes;
  std::size_t expected = 0;
  const auto expect = [&](const std::string& name, const torch::Tensor& value) {
    ++expected;
    const auto it = agent_tensors.find(name);
    if (it == agent_tensors.end()) throw InputError(origin + mismatch + name + " is missing)");
    const ArchiveTensor& t = *it->second;
    if (t.sizes != value.sizes().vec() || t.dtype != c10::toString(value.scalar_type()))
      throw InputError(origin + mismatch + name + " is " + t.dtype + " " + c10::str(c10::IntArrayRef(t.sizes)) +
                       ", the config gives " + c10::toString(value.scalar_type()) + " " + c10::str(value.sizes()) +
                       ")");
  };
  for (const auto& p : reference->named_parameters()) {
    expect(p.key(), p.value());
    parameter_shapes.insert(p.value().sizes().vec());
  }
  for (const auto& b : reference->named_buffers()) expect(b.key(), b.value());
  if (agent_tensors.size() != expected)
    throw InputError(origin + mismatch + "the file holds " + std::to_string(agent_tensors.size()) +
                     " tensors, the config " + std::to_string(expected) + ")");

  std::int64_t optimizer_values = 0;
  for (const ArchiveTensor& t : contents.tensors) {
    if (t.path.rfind(agent_prefix, 0) == 0) continue;
    if (t.path == "torch_rng_state" && t.dtype == "Byte" && t.sizes.size() == 1 && t.numel() <= (1 << 20)) continue;
    if (t.path.rfind("optimizer.", 0) == 0 && optimizer_tensor_fits(t, parameter_shapes)) {
      optimizer_values += t.numel();
      continue;
    }
    throw InputError(origin + ": not a Scout checkpoint (tensor " + t.path + ", " + t.dtype + " " +
                     c10::str(c10::IntArrayRef(t.sizes)) + ", is not one Scout's writer makes)");
  }
  // Adam keeps two moments per parameter (three with AMSGrad).
  if (optimizer_values > 3 * parameters + 1024)
    throw InputError(fmt::format("{}: optimizer: {} values for {} parameters (Adam keeps at most three per parameter)",
                                 origin, optimizer_values, parameters));
}

// Holds the archive against what Scout's writer produces before LibTorch parses it: its structure
// (learn/internal/archive.hpp), then its format number, its config and progress, and its tensors.
// Every check has one place and one message. Returns the state the file holds.
CheckpointState check_archive(const std::string& bytes, const std::string& origin) {
  ArchiveContents contents;
  try {
    contents = inspect_archive(bytes);
  } catch (const std::runtime_error& e) {
    throw InputError(origin + ": not a Scout checkpoint (" + e.what() + ")");
  }
  const auto format = contents.ints.find("scout_checkpoint_format");
  if (format == contents.ints.end())
    throw InputError(origin + ": not a Scout checkpoint (no scout_checkpoint_format entry)");
  if (format->second != kCheckpointFormat)
    throw InputError(fmt::format("{}: scout_checkpoint_format: this build reads format {}, the file has {}", origin,
                                 kCheckpointFormat, format->second));
  const auto config = contents.strings.find("config");
  if (config == contents.strings.end()) throw InputError(origin + ": config: missing from the checkpoint");
  CheckpointState state;
  state.config = TrainConfig::from_json(config->second, origin);
  const auto progress = contents.strings.find("progress");
  if (progress == contents.strings.end()) throw InputError(origin + ": progress: missing from the checkpoint");
  read_progress(progress->second, origin, state);
  check_tensors(contents, state.config.network, origin);
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
  // LibTorch's load makes each tensor share the archive's storage: give the agent its own, so that
  // training one agent never changes what the opened checkpoint holds.
  {
    torch::NoGradGuard no_grad;
    for (torch::Tensor& t : agent.parameters()) t.set_(t.clone());
    for (torch::Tensor& t : agent.buffers()) t.set_(t.clone());
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

std::atomic<int> g_opened{0};

}  // namespace

int checkpoints_opened() { return g_opened.load(); }

Checkpoint::Checkpoint(std::shared_ptr<const Contents> contents) : contents_(std::move(contents)) {}
const fs::path& Checkpoint::file() const { return contents_->file; }
const CheckpointInfo& Checkpoint::info() const { return contents_->info; }

Checkpoint open_checkpoint_bytes(const std::string& bytes, const std::string& origin) {
  ++g_opened;
  auto contents = std::make_shared<Checkpoint::Contents>();
  contents->file = origin;
  contents->state = check_archive(bytes, origin);
  try {
    contents->archive.load_from(bytes.data(), bytes.size());
  } catch (const std::exception& e) {
    throw InputError(origin + ": not a Scout checkpoint (" + first_line(e.what()) + ")");
  }
  const CheckpointState& s = contents->state;
  contents->info = {kCheckpointFormat, s.config, s.cursor, s.history, s.world_size};
  return Checkpoint(std::move(contents));
}

Checkpoint open_checkpoint(const fs::path& path) {
  const fs::path file = resolve_checkpoint(path);
  return open_checkpoint_bytes(read_checkpoint_file(file), file.string());
}

void Checkpoint::Contents::load_into(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer) const {
  load_weights(archive, file.string(), agent, optimizer);
}

agent::Agent Checkpoint::Contents::networks() const {
  if (model.is_empty()) {
    agent::Agent built(state.config.network);
    load_into(*built, nullptr);
    built->eval();
    model = built;
  }
  return model;
}

agent::Agent load_agent(const Checkpoint& checkpoint, CheckpointState* state) {
  if (state) *state = checkpoint.contents().state;
  return checkpoint.contents().networks();
}

agent::Agent load_agent(const fs::path& file, CheckpointState* state) {
  return load_agent(open_checkpoint(file), state);
}

CheckpointInfo export_model(const Checkpoint& checkpoint, const fs::path& model_file) {
  save_checkpoint(model_file, *checkpoint.contents().networks(), nullptr, checkpoint.contents().state);
  return checkpoint.info();
}

}  // namespace scout::learn
