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
#include "core/input_file.hpp"
#include "core/memory.hpp"
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
                    {"validation_full_image", optional_json(m.validation_full_image)},
                    {"gradient_norm", optional_json(m.gradient_norm)}});
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
    m.gradient_norm = optional_from(r, "gradient_norm");
    history.push_back(m);
  }
  return history;
}

// Non-finite numbers are not JSON; nlohmann writes them as null. Keep losses readable.
double finite_or_zero(double v) { return std::isfinite(v) ? v : 0.0; }

}  // namespace

void check_checkpoint_size(const agent::NetworkConfig& network) {
  // Weights and Adam's two moments, 4 bytes each; the rest (buffers, code, pickles) is small.
  const std::uint64_t bytes = 12 * static_cast<std::uint64_t>(agent::parameter_count(network)) + (1 << 20);
  if (bytes > kMaxCheckpointBytes)
    throw InputError(fmt::format(
        "network: {} parameters make checkpoints of about {} (weights and Adam's two "
        "moments), more than the {} Scout reads; choose a narrower or shallower network",
        agent::parameter_count(network), core::format_bytes(bytes), core::format_bytes(kMaxCheckpointBytes)));
}

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
                     {"batches", p.batches},
                     {"gradient_norm", finite_or_zero(p.gradient_norm)},
                     {"gradient_steps", p.gradient_steps}}},
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

// The file's bytes; a checkpoint is read whole (Scout checks it before LibTorch parses it). Its
// size is bounded before a byte is read, and a FIFO or a device is refused without blocking.
std::string read_checkpoint_file(const fs::path& file) {
  std::error_code ec;
  if (!fs::exists(file, ec))
    throw InputError(file.string() + ": no such checkpoint file (expected RUN/checkpoint.pt or a model file)");
  const core::RegularFile in = core::open_regular_file(file);
  if (in.size() > kMaxCheckpointBytes)
    throw InputError(fmt::format("{}: {} bytes, more than the {} a Scout checkpoint may have", file.string(), in.size(),
                                 core::format_bytes(kMaxCheckpointBytes)));
  // Read, then copied into LibTorch's tensors: about twice its size at the peak.
  const std::optional<core::AvailableMemory> available = core::available_memory();
  if (available && 2 * in.size() > available->bytes)
    throw InputError(fmt::format("{}: reading its {} needs about twice that much memory, {} is available ({})",
                                 file.string(), core::format_bytes(in.size()), core::format_bytes(available->bytes),
                                 available->bound));
  std::string bytes(static_cast<std::size_t>(in.size()), '\0');
  in.read_all(bytes.data());
  return bytes;
}

// The non-tensor part of a checkpoint: its "progress" entry (the schedule's position, the epoch in
// progress, the history, the run's processes and threads).
void read_progress(const std::string& text, const std::string& origin, CheckpointState& state) {
  int stage = 0;
  if (const std::optional<std::size_t> at = json_nested_beyond(text, kMaxJsonNesting))
    throw InputError(
        fmt::format("{}: progress: arrays and objects nested more than {} deep (at byte {}; Scout's "
                    "writer nests 3)",
                    origin, kMaxJsonNesting, *at));
  try {
    const json p = json::parse(text);
    stage = p.at("stage").get<int>();
    state.cursor = {Stage::Done, p.at("epoch").get<int>(), p.at("batch").get<int>()};
    const json& q = p.at("partial");
    state.partial = {.reward = q.at("reward").get<double>(),
                     .loss = q.at("loss").get<double>(),
                     .train_seconds = q.at("train_seconds").get<double>(),
                     .correct = q.at("correct").get<long>(),
                     .rollouts = q.at("robots").get<long>(),
                     .images = q.at("images").get<long>(),
                     .batches = q.at("batches").get<long>(),
                     // Absent from files written before the gradient norm was measured.
                     .gradient_norm = q.value("gradient_norm", 0.0),
                     .gradient_steps = q.value("gradient_steps", 0L)};
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

// The config's networks against the file's size, before anything is built from the config: a
// config that declares a billion parameters in a file of a megabyte is refused in microseconds.
void check_network_fits(const agent::NetworkConfig& network, std::size_t file_bytes, const std::string& origin) {
  const std::int64_t parameters = agent::parameter_count(network);
  if (static_cast<std::uint64_t>(parameters) > file_bytes / sizeof(float))
    throw InputError(fmt::format("{}: config: the network has {} parameters ({} of weights), the whole file holds {}",
                                 origin, parameters, core::format_bytes(4 * static_cast<std::uint64_t>(parameters)),
                                 core::format_bytes(file_bytes)));
}

// Plain values (strings, numbers) where Scout's writer stores them: the format number, the config
// and the progress at the root, Adam's bookkeeping under optimizer. (check_optimizer), nothing else.
void check_plain_values(const ArchiveContents& contents, const std::string& origin) {
  const auto check = [&](const std::string& path) {
    if (path == "scout_checkpoint_format" || path == "config" || path == "progress" || path.rfind("optimizer.", 0) == 0)
      return;
    throw InputError(origin + ": not a Scout checkpoint (" + path + " is not a value Scout's writer stores)");
  };
  for (const auto& item : contents.strings) check(item.first);
  for (const auto& item : contents.ints) check(item.first);
  for (const auto& item : contents.floats) check(item.first);
  for (const auto& item : contents.bools) check(item.first);
  for (const auto& item : contents.float_pairs) check(item.first);
}

// Each agent tensor's name, shape and type against the agent the config describes. The agent is
// built only once the file is known to hold that many weights, so that a crafted config cannot
// make Scout allocate more than the file's own size. Returns the parameters' shapes in the
// order Adam keeps them.
std::vector<std::vector<std::int64_t>> check_agent_tensors(const ArchiveContents& contents,
                                                           const agent::NetworkConfig& network,
                                                           const std::string& origin) {
  const std::string agent_prefix = "agent.";
  std::map<std::string, const ArchiveTensor*> agent_tensors;
  std::int64_t agent_values = 0;
  for (const ArchiveTensor& t : contents.tensors) {
    if (t.path.rfind(agent_prefix, 0) != 0) continue;
    agent_tensors[t.path.substr(agent_prefix.size())] = &t;
    agent_values += t.numel();  // each at most the file's size (inspect_archive): no overflow
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
  std::vector<std::vector<std::int64_t>> parameter_shapes;
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
    parameter_shapes.push_back(p.value().sizes().vec());
  }
  for (const auto& b : reference->named_buffers()) expect(b.key(), b.value());
  if (agent_tensors.size() != expected)
    throw InputError(origin + mismatch + "the file holds " + std::to_string(agent_tensors.size()) +
                     " tensors, the config " + std::to_string(expected) + ")");
  return parameter_shapes;
}

// The tensors besides the agent's: LibTorch's generator state, as the generator's get_state()
// makes it, and Adam's (check_optimizer).
void check_other_tensors(const ArchiveContents& contents, const std::string& origin) {
  const std::int64_t rng_bytes = at::detail::getDefaultCPUGenerator().get_state().numel();
  bool rng = false;
  for (const ArchiveTensor& t : contents.tensors) {
    if (t.path.rfind("agent.", 0) == 0 || t.path.rfind("optimizer.", 0) == 0) continue;
    if (t.path == "torch_rng_state" && t.dtype == "Byte" && t.sizes == std::vector<std::int64_t>{rng_bytes}) {
      rng = true;
      continue;
    }
    throw InputError(origin + ": not a Scout checkpoint (tensor " + t.path + ", " + t.dtype + " " +
                     c10::str(c10::IntArrayRef(t.sizes)) + ", is not one Scout's writer makes)");
  }
  if (!rng) throw InputError(fmt::format("{}: torch_rng_state: missing (expected Byte [{}])", origin, rng_bytes));
}

// Adam's state, as LibTorch's Adam writes it for Scout's one parameter group: every value where
// the writer puts it, of its type and in its range, and nothing else. LibTorch's reader would
// take a NaN beta or amsgrad as they are, and silently drop the moments of a parameter whose key
// it cannot match: a resumed run would not continue the one that wrote the file.
class OptimizerCheck {
 public:
  OptimizerCheck(const ArchiveContents& contents, const std::string& origin) : contents_(contents), origin_(origin) {
    const auto add = [this](const auto& values) {
      for (const auto& item : values)
        if (item.first.rfind(kPrefix, 0) == 0) unchecked_.insert(item.first.substr(kPrefix.size()));
    };
    add(contents.strings), add(contents.ints), add(contents.floats), add(contents.bools), add(contents.float_pairs);
    for (const ArchiveTensor& t : contents.tensors)
      if (t.path.rfind(kPrefix, 0) == 0) unchecked_.insert(t.path.substr(kPrefix.size()));
  }

  // `shapes`: the agent's parameters' shapes, in the order Adam holds them.
  void run(const std::vector<std::vector<std::int64_t>>& shapes) {
    if (unchecked_.empty()) return;  // a model file: no optimizer
    if (text("pytorch_version") != "1.5.0") refuse("pytorch_version is not 1.5.0, what LibTorch's writer stores");
    if (count("param_groups.param_groups/size") != 1) refuse("expected one parameter group, as Scout's Adam has");
    const std::map<std::string, std::size_t> keys = parameter_keys(shapes.size());
    options();
    for (const auto& [key, index] : keys) state(key, shapes[index]);
    if (!unchecked_.empty())
      refuse(*unchecked_.begin() + " is not a value LibTorch's Adam stores for Scout's parameters");
  }

 private:
  static inline const std::string kPrefix = "optimizer.";
  static inline const std::string kGroup = "param_groups.param_groups/0.";

  [[noreturn]] void refuse(const std::string& what) const {
    throw InputError(origin_ + ": optimizer: " + one_line(what));
  }
  // Marks `path` checked; false when the file does not hold it.
  template <class Map>
  const typename Map::mapped_type* take(const Map& values, const std::string& path) {
    const auto it = values.find(kPrefix + path);
    if (it == values.end()) return nullptr;
    unchecked_.erase(path);
    return &it->second;
  }
  const std::string& text(const std::string& path) {
    const std::string* v = take(contents_.strings, path);
    if (!v) refuse(path + ": missing (expected a string)");
    return *v;
  }
  double real(const std::string& path) {
    const double* v = take(contents_.floats, path);
    if (!v) refuse(path + ": missing (expected a number)");
    return *v;
  }
  const ArchiveTensor& tensor(const std::string& path) {
    for (const ArchiveTensor& t : contents_.tensors)
      if (t.path == kPrefix + path) {
        unchecked_.erase(path);
        return t;
      }
    refuse(path + ": missing (expected a tensor)");
  }
  // A count LibTorch's reader loops over: a 0-d Long tensor.
  std::int64_t count(const std::string& path) {
    const ArchiveTensor& t = tensor(path);
    if (t.dtype != "Long" || !t.sizes.empty() || !t.value) refuse(path + ": expected a 0-d Long tensor (a count)");
    return *t.value;
  }

  // params/0 ... params/N-1: the key (a parameter's address when written: "0x..." by LibTorch 1.x,
  // decimal by 2.x) under which each parameter's state is kept, one per agent parameter, all
  // different. Returns key -> index.
  std::map<std::string, std::size_t> parameter_keys(std::size_t parameters) {
    const std::string group = kGroup;
    if (count(group + "params/size") != static_cast<std::int64_t>(parameters))
      refuse(fmt::format("{}params/size: expected {}, the agent's parameters", group, parameters));
    std::map<std::string, std::size_t> keys;
    for (std::size_t i = 0; i < parameters; ++i) {
      const std::string path = group + "params/" + std::to_string(i);
      const std::string& key = text(path);
      const bool hex = key.size() > 2 && key.size() <= 18 && key.rfind("0x", 0) == 0 &&
                       key.find_first_not_of("0123456789abcdef", 2) == std::string::npos;
      const bool decimal = !key.empty() && key.size() <= 20 && key.find_first_not_of("0123456789") == std::string::npos;
      if (!hex && !decimal)
        refuse(path + ": expected a parameter key (an address: 0x and hexadecimal digits, or decimal digits), got '" +
               key.substr(0, 40) + "'");
      if (!keys.emplace(key, i).second) refuse(path + ": the key " + key + " is another parameter's too");
    }
    return keys;
  }

  void options() {
    const std::string at = std::string(kGroup) + "options.";
    const double lr = real(at + "lr"), eps = real(at + "eps"), weight_decay = real(at + "weight_decay");
    if (!std::isfinite(lr) || lr <= 0) refuse(fmt::format("{}lr: expected a finite number > 0, got {}", at, lr));
    if (!std::isfinite(eps) || eps <= 0) refuse(fmt::format("{}eps: expected a finite number > 0, got {}", at, eps));
    if (weight_decay != 0)
      refuse(fmt::format("{}weight_decay: expected 0, as Scout's Adam has, got {}", at, weight_decay));
    const std::pair<double, double>* betas = take(contents_.float_pairs, at + "betas");
    const auto beta = [](double b) { return std::isfinite(b) && b >= 0 && b < 1; };
    if (!betas || !beta(betas->first) || !beta(betas->second))
      refuse(at + "betas: expected two numbers in [0, 1)" +
             (betas ? fmt::format(", got ({}, {})", betas->first, betas->second) : std::string(", got none")));
    const bool* amsgrad = take(contents_.bools, at + "amsgrad");
    if (!amsgrad || *amsgrad) refuse(at + "amsgrad: expected false, as Scout's Adam has");
  }

  // One parameter's state, if it has one (a parameter that never had a gradient has none).
  void state(const std::string& key, const std::vector<std::int64_t>& shape) {
    const std::string at = "state." + key + ".";
    const std::int64_t* step = take(contents_.ints, at + "step");
    if (!step) {
      for (const char* moment : {"exp_avg", "exp_avg_sq"})
        if (unchecked_.count(at + moment)) refuse(at + "step: missing beside " + moment);
      return;
    }
    if (*step < 0) refuse(fmt::format("{}step: expected a count >= 0, got {}", at, *step));
    for (const char* moment : {"exp_avg", "exp_avg_sq"}) {
      const ArchiveTensor& t = tensor(at + moment);
      if (t.dtype != "Float" || t.sizes != shape)
        refuse(at + moment + ": " + t.dtype + " " + c10::str(c10::IntArrayRef(t.sizes)) + ", expected Float " +
               c10::str(c10::IntArrayRef(shape)) + ", its parameter's shape");
    }
  }

  const ArchiveContents& contents_;
  const std::string& origin_;
  std::set<std::string> unchecked_;  // paths under optimizer. not checked yet
};

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
  check_network_fits(state.config.network, bytes.size(), origin);
  const auto progress = contents.strings.find("progress");
  if (progress == contents.strings.end()) throw InputError(origin + ": progress: missing from the checkpoint");
  read_progress(progress->second, origin, state);
  check_plain_values(contents, origin);
  check_other_tensors(contents, origin);
  OptimizerCheck(contents, origin).run(check_agent_tensors(contents, state.config.network, origin));
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
