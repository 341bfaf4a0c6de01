#include "learn/internal/checkpoint.hpp"

#include <ATen/CPUGeneratorImpl.h>
#include <fmt/format.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <span>

#include "agent/config.hpp"
#include "core/error.hpp"
#include "core/files.hpp"
#include "core/input_file.hpp"
#include "core/memory.hpp"
#include "learn/internal/json_limits.hpp"
#include "learn/internal/safetensors.hpp"

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

// A whole number in [lo, hi] (nlohmann's get<int>() would wrap 2^32 + 1 to 1 and take 1e300).
std::int64_t whole(const nlohmann::json& value, std::int64_t lo, std::int64_t hi, const char* what) {
  if (!value.is_number_integer()) throw std::runtime_error(fmt::format("{}: expected a whole number", what));
  const std::int64_t v = value.is_number_unsigned() && value.get<std::uint64_t>() > std::uint64_t{INT64_MAX}
                             ? INT64_MAX
                             : value.get<std::int64_t>();
  if (v < lo || v > hi) throw std::runtime_error(fmt::format("{}: expected {} to {}, got {}", what, lo, hi, v));
  return v;
}

// `learning_rate`: the run's configured rate, for rows written before epochs recorded their own.
// Rows are in the schedule's order, at most kMaxEpochs of a stage.
std::vector<EpochMetrics> history_from(const nlohmann::json& rows, double learning_rate) {
  if (!rows.is_array()) throw std::runtime_error("history: expected a list of epochs");
  if (rows.size() > static_cast<std::size_t>(kTrainingStages) * kMaxEpochs)
    throw std::runtime_error(fmt::format("history: {} epochs, more than a schedule has", rows.size()));
  std::vector<EpochMetrics> history;
  for (const nlohmann::json& r : rows) {
    EpochMetrics m;
    m.stage = static_cast<Stage>(whole(r.at("stage"), 0, kTrainingStages - 1, "history: stage"));
    if (!history.empty() && index(m.stage) < index(history.back().stage))
      throw std::runtime_error("history: a stage before the one of the epoch above it");
    m.epoch = static_cast<int>(whole(r.at("epoch"), 1, kMaxEpochs, "history: epoch"));
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

namespace st = safetensors;

// What every file's metadata says it is.
constexpr const char* kFormatName = "scout-checkpoint";

std::span<const std::byte> tensor_bytes(const torch::Tensor& t) {
  return {static_cast<const std::byte*>(t.data_ptr()), static_cast<std::size_t>(t.nbytes())};
}

st::DType dtype_of(const torch::Tensor& t, const std::string& name) {
  if (t.scalar_type() == torch::kFloat) return st::DType::F32;
  if (t.scalar_type() == torch::kLong) return st::DType::I64;
  throw std::logic_error("checkpoint: tensor " + name + " is " + c10::toString(t.scalar_type()) +
                         "; Scout stores Float and Long");
}

// Adam's options as the file's "optimizer" metadata.
std::string adam_options_json(const torch::optim::AdamOptions& o) {
  return json({{"type", "adam"},
               {"lr", o.lr()},
               {"betas", {std::get<0>(o.betas()), std::get<1>(o.betas())}},
               {"eps", o.eps()},
               {"weight_decay", o.weight_decay()},
               {"amsgrad", o.amsgrad()}})
      .dump();
}

std::string progress_json(const CheckpointState& state) {
  const EpochSums& p = state.partial;
  return json({{"stage", index(state.cursor.stage)},
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
               {"threads", state.threads}})
      .dump();
}

}  // namespace

std::string checkpoint_bytes(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer,
                             const CheckpointState& state) {
  // Every tensor as a contiguous CPU tensor kept alive until the file is assembled.
  std::vector<torch::Tensor> held;
  std::vector<st::TensorBytes> tensors;
  const auto add = [&](const std::string& name, const torch::Tensor& value) {
    held.push_back(value.detach().to(torch::kCPU).contiguous());
    tensors.push_back({name, dtype_of(held.back(), name), held.back().sizes().vec(), tensor_bytes(held.back())});
  };
  held.reserve(4 * agent.parameters().size() + agent.buffers().size());
  for (const auto& p : agent.named_parameters()) add(kAgentPrefix + p.key(), p.value());
  for (const auto& b : agent.named_buffers()) add(kAgentPrefix + b.key(), b.value());
  std::map<std::string, std::string> metadata = {{"format", kFormatName},
                                                 {"format_version", std::to_string(kCheckpointFormat)},
                                                 {"config", state.config.to_json()},
                                                 {"progress", progress_json(state)}};
  if (!state.manifest.empty()) metadata["manifest"] = state.manifest;
  // What the reader takes (check_metadata): a run whose history outgrows it is told so, and the
  // previous checkpoint stays (about 7,000 epochs).
  for (const auto& [key, limit] : {std::pair{"progress", kMaxProgressBytes}, std::pair{"manifest", kMaxManifestBytes}})
    if (metadata.count(key) && metadata[key].size() > limit)
      throw InputError(fmt::format("checkpoint: its {} takes {} bytes, more than the {} a checkpoint stores", key,
                                   metadata[key].size(), core::format_bytes(limit)));
  if (optimizer) {
    auto& adam = dynamic_cast<torch::optim::Adam&>(*optimizer);
    metadata["optimizer"] =
        adam_options_json(static_cast<const torch::optim::AdamOptions&>(adam.param_groups().front().options()));
    // Per parameter, by its name: Adam's step and two moments (none for a parameter that never had
    // a gradient: a frozen layer, an unconsulted action planner).
    for (const auto& p : agent.named_parameters()) {
      const auto it = adam.state().find(adam_state_key(p.value()));
      if (it == adam.state().end()) continue;
      const auto& s = static_cast<const torch::optim::AdamParamState&>(*it->second);
      const std::string at = kOptimizerPrefix + p.key();
      add(at + ".exp_avg", s.exp_avg());
      add(at + ".exp_avg_sq", s.exp_avg_sq());
      add(at + ".step", torch::tensor(static_cast<std::int64_t>(s.step()), torch::kLong));
    }
  }
  try {
    return st::write(tensors, metadata);
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("checkpoint: cannot be written (") + e.what() + ")");
  }
}

void save_checkpoint(const fs::path& file, agent::AgentImpl& agent, torch::optim::Optimizer* optimizer,
                     const CheckpointState& state) {
  // Serialised in memory, then written by Scout's own durable writer (which reports errno: a full
  // disk or a file-size limit is one line, and the previous checkpoint stays).
  core::write_file_atomic(file, checkpoint_bytes(agent, optimizer, state));
}

namespace {

// The file's bytes; a checkpoint is read whole and checked before a tensor is made from it. Its
// size is bounded before a byte is read, and a FIFO or a device is refused without blocking.
std::string read_checkpoint_file(const fs::path& file) {
  std::error_code ec;
  if (!fs::exists(file, ec)) {
    const fs::path legacy = fs::path(file).replace_extension(".pt");
    if (fs::exists(legacy, ec))
      throw InputError(file.string() + ": no such checkpoint file; " + legacy.string() +
                       " beside it is of Scout's format 1, which this build does not read; if you trust it, convert "
                       "it once: scout convert " +
                       legacy.string() + " --trusted");
    throw InputError(file.string() + ": no such checkpoint file (expected RUN/checkpoint.safetensors or a model file)");
  }
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

}  // namespace

void read_progress(const std::string& text, const std::string& origin, CheckpointState& state) {
  // Every number in its range: a count as a whole number >= 0, the processes and threads within
  // what the command line allows (a resume starts that many threads).
  constexpr std::int64_t kCount = std::int64_t{1} << 50;
  try {
    // The writer's history rows take about 13 bytes per parse event (a key, a value, a bracket): a
    // budget of one per 8 bytes holds them, and bounds a crafted list of zeros (2 bytes a value)
    // to a tree of about twice the text's size.
    const nlohmann::json p = parse_json_bounded(text, std::max<std::size_t>(1024, text.size() / 8));
    state.cursor = {static_cast<Stage>(whole(p.at("stage"), 0, index(Stage::Done), "stage")),
                    static_cast<int>(whole(p.at("epoch"), 0, kMaxEpochs, "epoch")),
                    static_cast<int>(whole(p.at("batch"), 0, INT32_MAX, "batch"))};
    const nlohmann::json& q = p.at("partial");
    state.partial = {.reward = q.at("reward").get<double>(),
                     .loss = q.at("loss").get<double>(),
                     .train_seconds = q.at("train_seconds").get<double>(),
                     .correct = whole(q.at("correct"), 0, kCount, "partial: correct"),
                     .rollouts = whole(q.at("robots"), 0, kCount, "partial: robots"),
                     .images = whole(q.at("images"), 0, kCount, "partial: images"),
                     .batches = whole(q.at("batches"), 0, kCount, "partial: batches"),
                     // Absent from files written before the gradient norm was measured.
                     .gradient_norm = q.value("gradient_norm", 0.0),
                     .gradient_steps = q.contains("gradient_steps")
                                           ? whole(q.at("gradient_steps"), 0, kCount, "partial: gradient_steps")
                                           : 0};
    state.history = history_from(p.at("history"), state.config.learning_rate);
    state.world_size =
        p.contains("world_size") ? static_cast<int>(whole(p.at("world_size"), 1, kMaxProcesses, "world_size")) : 1;
    state.threads = p.contains("threads") ? static_cast<int>(whole(p.at("threads"), 0, kMaxThreads, "threads")) : 0;
  } catch (const std::exception& e) {
    throw InputError(origin + ": progress: " + first_line(e.what()));
  }
}

namespace {

// Building an agent to hold a file's weights draws initial weights from LibTorch's generator: put
// its state back, so that reading a file never changes what a later construction draws (the
// Python package shares the generator with PyTorch).
struct GeneratorRestore {
  at::Generator generator = at::detail::getDefaultCPUGenerator();
  at::Tensor state = generator.get_state();
  ~GeneratorRestore() { generator.set_state(state); }
};

// The config's networks against the file's size, before anything is built from the config: a
// config that declares a billion parameters in a file of a megabyte is refused in microseconds.
void check_network_fits(const agent::NetworkConfig& network, std::size_t file_bytes, const std::string& origin) {
  const std::int64_t parameters = agent::parameter_count(network);
  if (static_cast<std::uint64_t>(parameters) > file_bytes / sizeof(float))
    throw InputError(fmt::format("{}: config: the network has {} parameters ({} of weights), the whole file holds {}",
                                 origin, parameters, core::format_bytes(4 * static_cast<std::uint64_t>(parameters)),
                                 core::format_bytes(file_bytes)));
}

// Batches one epoch of `stage` can have at most: the run's digits (train_limit, else the most a
// data set may hold) in batches of its size.
std::int64_t max_batches_per_epoch(const TrainConfig& c, Stage stage) {
  const std::int64_t images = c.train_limit > 0 ? c.train_limit : kMaxDigits;
  const std::int64_t batch =
      stage == Stage::Pretrain ? std::int64_t{c.batch_images} * c.rollouts : std::int64_t{c.batch_images};
  return (images + batch - 1) / batch;
}

// Where the schedule stands, against the schedule the config gives: at most a stage's epochs done,
// fewer batches than an epoch can have; a finished run at (done, 0, 0).
void check_cursor(const CheckpointState& state, const std::string& origin) {
  const ScheduleCursor& c = state.cursor;
  const std::array<int, kTrainingStages> epochs = {state.config.pretrain_epochs, state.config.epochs[0],
                                                   state.config.epochs[1], state.config.epochs[2]};
  const auto refuse = [&](const std::string& expected) {
    throw InputError(
        fmt::format("{}: progress: the schedule position (mode {}, epoch {}, batch {}) is outside the "
                    "config's schedule ({})",
                    origin, to_string(c.stage), c.epoch, c.batch, expected));
  };
  if (c.stage == Stage::Done) {
    if (c.epoch != 0 || c.batch != 0) refuse("a finished run stands at epoch 0, batch 0");
    return;
  }
  // A stage's epochs all done, before the next stage is entered (a new run's cursor, in a stage of no
  // epochs, until training skips it), is epoch == its count at batch 0.
  const int stage_epochs = epochs[index(c.stage)];
  if (c.epoch > stage_epochs || (c.epoch == stage_epochs && c.batch != 0))
    refuse(fmt::format("mode {} has {} epochs", to_string(c.stage), stage_epochs));
  if (c.batch >= max_batches_per_epoch(state.config, c.stage))
    refuse(fmt::format("an epoch has at most {} batches", max_batches_per_epoch(state.config, c.stage)));
}

// Optimizer steps the config's whole schedule can take: an Adam step count beyond it was not
// written by training (at INT64_MAX, Adam's bias correction overflows into NaN weights).
std::int64_t max_training_steps(const TrainConfig& c) {
  const std::array<int, kTrainingStages> epochs = {c.pretrain_epochs, c.epochs[0], c.epochs[1], c.epochs[2]};
  std::int64_t steps = 0;
  for (Stage s = Stage::Pretrain; s != Stage::Done; s = next(s))
    steps += std::int64_t{epochs[index(s)]} * max_batches_per_epoch(c, s);
  return steps;
}

bool all_finite(const st::TensorView& t) {
  if (t.dtype != st::DType::F32) return true;
  const std::size_t n = t.bytes.size() / sizeof(float);
  for (std::size_t i = 0; i < n; ++i) {
    float v;
    std::memcpy(&v, t.bytes.data() + i * sizeof(float), sizeof v);
    if (!std::isfinite(v)) return false;
  }
  return true;
}

std::string shape_text(const std::vector<std::int64_t>& shape) { return c10::str(c10::IntArrayRef(shape)); }

// A metadata entry as JSON text: at most `max_bytes`, nested at most kMaxJsonNesting deep.
const std::string& metadata_json(const st::File& file, const std::string& key, std::size_t max_bytes,
                                 const std::string& origin) {
  const auto it = file.metadata.find(key);
  if (it == file.metadata.end()) throw InputError(origin + ": " + key + ": missing from the file's metadata");
  if (it->second.size() > max_bytes)
    throw InputError(fmt::format("{}: {}: {} bytes, more than the {} Scout's writer stays within", origin, key,
                                 it->second.size(), core::format_bytes(max_bytes)));
  if (const std::optional<std::size_t> at = json_nested_beyond(it->second, kMaxJsonNesting))
    throw InputError(fmt::format("{}: {}: arrays and objects nested more than {} deep (at byte {})", origin, key,
                                 kMaxJsonNesting, *at));
  return it->second;
}

// The parts of a checkpoint besides its tensors: the format, the config, the progress, the
// manifest, and which metadata keys may appear at all.
CheckpointState check_metadata(const st::File& file, std::size_t file_bytes, const std::string& origin) {
  const auto format = file.metadata.find("format");
  if (format == file.metadata.end() || format->second != kFormatName)
    throw InputError(origin + ": not a Scout checkpoint (its __metadata__ has no format: " + kFormatName + ")");
  const auto version = file.metadata.find("format_version");
  if (version == file.metadata.end() || version->second != std::to_string(kCheckpointFormat))
    throw InputError(
        fmt::format("{}: format_version: this build reads {}, the file has {}", origin, kCheckpointFormat,
                    version == file.metadata.end() ? std::string("none") : one_line(version->second.substr(0, 20))));
  for (const auto& [key, value] : file.metadata)
    if (key != "format" && key != "format_version" && key != "config" && key != "progress" && key != "manifest" &&
        key != "optimizer")
      throw InputError(origin + ": __metadata__: " + one_line(key.substr(0, 80)) +
                       " is not an entry Scout's writer stores");
  CheckpointState state;
  state.config = TrainConfig::from_json(metadata_json(file, "config", kMaxConfigBytes, origin), origin);
  check_network_fits(state.config.network, file_bytes, origin);
  read_progress(metadata_json(file, "progress", kMaxProgressBytes, origin), origin, state);
  check_cursor(state, origin);
  if (file.metadata.count("manifest")) {
    const std::string& manifest = metadata_json(file, "manifest", kMaxManifestBytes, origin);
    try {
      if (!parse_json_bounded(manifest, std::max<std::size_t>(1024, manifest.size() / 8)).is_object())
        throw std::runtime_error("not an object");
    } catch (const std::exception& e) {
      throw InputError(origin + ": manifest: expected a JSON object (" + first_line(e.what()) + ")");
    }
    state.manifest = manifest;
  }
  return state;
}

// Each agent tensor's name, dtype and shape against the agent the config describes, and its
// values finite; a tensor missing, misshapen or of no network is named. Returns the parameters'
// names and shapes, in the order Adam keeps them.
std::vector<std::pair<std::string, std::vector<std::int64_t>>> check_agent_tensors(const st::File& file,
                                                                                   const agent::NetworkConfig& network,
                                                                                   const std::string& origin) {
  const std::string mismatch = ": agent: the weights do not match the checkpoint's network config (";
  // Building the reference agent draws initial weights from LibTorch's generator: its state is put
  // back. (Its size is bounded by the file's: check_network_fits.)
  const GeneratorRestore restore;
  agent::Agent reference(network);
  std::vector<std::pair<std::string, std::vector<std::int64_t>>> parameter_shapes;
  std::set<std::string> expected;
  const auto expect = [&](const std::string& name, const torch::Tensor& value) {
    expected.insert(kAgentPrefix + name);
    const st::TensorView* t = file.find(kAgentPrefix + name);
    if (!t) throw InputError(origin + mismatch + kAgentPrefix + name + " is missing)");
    const st::DType dtype = value.scalar_type() == torch::kLong ? st::DType::I64 : st::DType::F32;
    if (t->shape != value.sizes().vec() || t->dtype != dtype)
      throw InputError(origin + mismatch + t->name + " is " + st::to_string(t->dtype) + " " + shape_text(t->shape) +
                       ", the config gives " + st::to_string(dtype) + " " + c10::str(value.sizes()) + ")");
    if (!all_finite(*t)) throw InputError(origin + ": " + t->name + ": holds values that are not finite (NaN or inf)");
  };
  for (const auto& p : reference->named_parameters()) {
    expect(p.key(), p.value());
    parameter_shapes.emplace_back(p.key(), p.value().sizes().vec());
  }
  for (const auto& b : reference->named_buffers()) expect(b.key(), b.value());
  for (const st::TensorView& t : file.tensors)
    if (t.name.rfind(kAgentPrefix, 0) == 0 && !expected.count(t.name))
      throw InputError(origin + mismatch + one_line(t.name.substr(0, 80)) + " is not a tensor of its networks)");
  return parameter_shapes;
}

// Adam's state, as Scout's Adam keeps it: the options in their ranges (LibTorch would take a NaN
// beta as it is), and per parameter either nothing (it never had a gradient) or a step in
// [1, the schedule's steps] with two finite moments of the parameter's shape (the second >= 0).
// Any other tensor is refused by name.
void check_optimizer(const st::File& file, const CheckpointState& state,
                     const std::vector<std::pair<std::string, std::vector<std::int64_t>>>& parameters,
                     const std::string& origin) {
  std::set<std::string> unchecked;
  for (const st::TensorView& t : file.tensors)
    if (t.name.rfind(kAgentPrefix, 0) != 0) unchecked.insert(t.name);
  const auto refuse = [&](const std::string& what) { throw InputError(origin + ": " + one_line(what)); };
  const auto options = file.metadata.find("optimizer");
  if (options == file.metadata.end()) {
    if (!unchecked.empty())
      refuse(*unchecked.begin() + ": a tensor Scout's writer does not make (no optimizer in __metadata__)");
    return;  // a model file
  }
  const std::string& text = metadata_json(file, "optimizer", kMaxOptimizerBytes, origin);
  try {
    const nlohmann::json o = parse_json_bounded(text, 64);
    const auto number = [&](const char* key) {
      const nlohmann::json& v = o.at(key);
      if (!v.is_number()) throw std::runtime_error(std::string(key) + " is not a number");
      return v.get<double>();
    };
    const double lr = number("lr"), eps = number("eps"), weight_decay = number("weight_decay");
    if (o.at("type") != "adam") refuse("optimizer: type: expected adam, Scout's optimizer");
    if (!std::isfinite(lr) || lr <= 0) refuse(fmt::format("optimizer: lr: expected a finite number > 0, got {}", lr));
    if (!std::isfinite(eps) || eps <= 0)
      refuse(fmt::format("optimizer: eps: expected a finite number > 0, got {}", eps));
    if (weight_decay != 0)
      refuse(fmt::format("optimizer: weight_decay: expected 0, as Scout's Adam has, got {}", weight_decay));
    const nlohmann::json& betas = o.at("betas");
    const auto beta = [](const nlohmann::json& b) {
      return b.is_number() && std::isfinite(b.get<double>()) && b.get<double>() >= 0 && b.get<double>() < 1;
    };
    if (!betas.is_array() || betas.size() != 2 || !beta(betas[0]) || !beta(betas[1]))
      refuse("optimizer: betas: expected two numbers in [0, 1), got " + betas.dump().substr(0, 60));
    if (o.at("amsgrad") != false) refuse("optimizer: amsgrad: expected false, as Scout's Adam has");
    if (o.size() != 6) refuse("optimizer: expected exactly type, lr, betas, eps, weight_decay and amsgrad");
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    refuse("optimizer: unreadable (" + first_line(e.what()) + ")");
  }
  const std::int64_t max_steps = max_training_steps(state.config);
  for (const auto& [name, shape] : parameters) {
    const std::string at = kOptimizerPrefix + name;
    const st::TensorView* step = file.find(at + ".step");
    if (!step) {
      for (const char* moment : {".exp_avg", ".exp_avg_sq"})
        if (unchecked.count(at + moment)) refuse(at + ".step: missing beside " + at + moment);
      continue;
    }
    unchecked.erase(at + ".step");
    if (step->dtype != st::DType::I64 || !step->shape.empty())
      refuse(at + ".step: " + st::to_string(step->dtype) + " " + shape_text(step->shape) +
             ", expected I64 [] (a count)");
    std::int64_t steps = 0;
    std::memcpy(&steps, step->bytes.data(), sizeof steps);
    if (steps < 1 || steps > max_steps)
      refuse(fmt::format("{}.step: {} Adam steps, expected 1 to {} (the config's schedule: at most {} batches)", at,
                         steps, max_steps, max_steps));
    for (const char* moment : {".exp_avg", ".exp_avg_sq"}) {
      const st::TensorView* t = file.find(at + moment);
      if (!t) refuse(at + moment + ": missing beside " + at + ".step");
      unchecked.erase(at + moment);
      if (t->dtype != st::DType::F32 || t->shape != shape)
        refuse(at + moment + ": " + st::to_string(t->dtype) + " " + shape_text(t->shape) + ", expected F32 " +
               shape_text(shape) + ", its parameter's shape");
      if (!all_finite(*t)) refuse(at + moment + ": holds values that are not finite (NaN or inf)");
    }
    const st::TensorView& second = *file.find(at + ".exp_avg_sq");
    for (std::int64_t i = 0; i < second.elements(); ++i) {
      float v;
      std::memcpy(&v, second.bytes.data() + i * sizeof(float), sizeof v);
      if (v < 0) refuse(at + ".exp_avg_sq: holds a negative value (it is a mean of squares)");
    }
  }
  if (!unchecked.empty()) refuse(*unchecked.begin() + ": a tensor Scout's writer does not make");
}

// Holds a parsed file against what Scout's writer produces: its metadata, then its tensors. Every
// check has one place and one message. Returns the state the file holds.
CheckpointState check_checkpoint(const st::File& file, std::size_t file_bytes, const std::string& origin) {
  CheckpointState state = check_metadata(file, file_bytes, origin);
  check_optimizer(file, state, check_agent_tensors(file, state.config.network, origin), origin);
  return state;
}

// Copies a checked tensor's bytes into `into`, which must be a contiguous CPU tensor of its dtype
// and shape (a caller's bug otherwise, never the file's: the file was checked against the config).
void copy_into(const st::TensorView* from, torch::Tensor& into, const std::string& name) {
  const auto dtype = from && from->dtype == st::DType::I64 ? torch::kLong : torch::kFloat;
  if (!from || into.sizes().vec() != from->shape || into.scalar_type() != dtype || !into.is_contiguous() ||
      !into.device().is_cpu() || static_cast<std::size_t>(into.nbytes()) != from->bytes.size())
    throw std::logic_error("checkpoint: " + name + " does not fit the tensor it is loaded into");
  torch::NoGradGuard no_grad;
  std::memcpy(into.data_ptr(), from->bytes.data(), from->bytes.size());
}

torch::Tensor tensor_from(const st::TensorView* from, const std::string& name) {
  if (!from) throw std::logic_error("checkpoint: " + name + " is missing");
  torch::Tensor t = torch::empty(from->shape, from->dtype == st::DType::I64 ? torch::kLong : torch::kFloat);
  copy_into(from, t, name);
  return t;
}

void load_weights(const st::File& file, const std::string& origin, agent::AgentImpl& agent,
                  torch::optim::Optimizer* optimizer) {
  // The agent was built from the checked config: each tensor is there, of its shape and dtype.
  for (auto& p : agent.named_parameters()) copy_into(file.find(kAgentPrefix + p.key()), p.value(), p.key());
  for (auto& b : agent.named_buffers()) copy_into(file.find(kAgentPrefix + b.key()), b.value(), b.key());
  if (!optimizer) return;
  const auto options = file.metadata.find("optimizer");
  if (options == file.metadata.end())
    throw InputError(origin + ": optimizer: missing (a model file holds weights only; it cannot be resumed)");
  auto& adam = dynamic_cast<torch::optim::Adam&>(*optimizer);
  const nlohmann::json o = nlohmann::json::parse(options->second);
  auto& group = static_cast<torch::optim::AdamOptions&>(adam.param_groups().front().options());
  group.lr(o.at("lr").get<double>())
      .betas({o.at("betas")[0].get<double>(), o.at("betas")[1].get<double>()})
      .eps(o.at("eps").get<double>())
      .weight_decay(o.at("weight_decay").get<double>())
      .amsgrad(false);
  adam.state().clear();
  for (const auto& p : agent.named_parameters()) {
    const std::string at = kOptimizerPrefix + p.key();
    const st::TensorView* step = file.find(at + ".step");
    if (!step) continue;
    auto state = std::make_unique<torch::optim::AdamParamState>();
    std::int64_t steps = 0;
    std::memcpy(&steps, step->bytes.data(), sizeof steps);
    state->step(steps);
    state->exp_avg(tensor_from(file.find(at + ".exp_avg"), at + ".exp_avg"));
    state->exp_avg_sq(tensor_from(file.find(at + ".exp_avg_sq"), at + ".exp_avg_sq"));
    adam.state()[adam_state_key(p.value())] = std::move(state);
  }
}

std::atomic<int> g_opened{0};

}  // namespace

int checkpoints_opened() { return g_opened.load(); }

Checkpoint::Checkpoint(std::shared_ptr<const Contents> contents) : contents_(std::move(contents)) {}
const fs::path& Checkpoint::file() const { return contents_->file; }
const CheckpointInfo& Checkpoint::info() const { return contents_->info; }

Checkpoint open_checkpoint_bytes(std::string bytes, const std::string& origin) {
  ++g_opened;
  auto contents = std::make_shared<Checkpoint::Contents>();
  contents->file = origin;
  contents->bytes = std::move(bytes);
  const std::span<const std::byte> view(reinterpret_cast<const std::byte*>(contents->bytes.data()),
                                        contents->bytes.size());
  if (st::looks_like_zip(view)) {
    // A .pt file is most likely Scout's format 1; say how to convert it (only there: the
    // converter runs LibTorch's unpickler, which is for files the user trusts).
    if (fs::path(origin).extension() == ".pt")
      throw InputError(origin +
                       ": a checkpoint of Scout's format 1 (LibTorch's zip and pickles), which this build does not "
                       "read; if you made it or trust who did, convert it once: scout convert " +
                       origin + " --trusted");
    throw InputError(origin +
                     ": a zip archive, not a safetensors file (Scout's models and checkpoints are .safetensors)");
  }
  contents->tensors = st::parse(view, origin);
  contents->state = check_checkpoint(contents->tensors, contents->bytes.size(), origin);
  const CheckpointState& s = contents->state;
  contents->info = {kCheckpointFormat, s.manifest, s.config, s.cursor, s.history, s.world_size};
  return Checkpoint(std::move(contents));
}

Checkpoint open_checkpoint(const fs::path& path) {
  const fs::path file = resolve_checkpoint(path);
  return open_checkpoint_bytes(read_checkpoint_file(file), file.string());
}

void Checkpoint::Contents::load_into(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer) const {
  load_weights(tensors, file.string(), agent, optimizer);
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

std::vector<LoadedTensor> loaded_tensors(const Checkpoint& checkpoint) {
  const Checkpoint::Contents& contents = checkpoint.contents();
  const GeneratorRestore restore;
  agent::Agent agent(contents.state.config.network);
  std::unique_ptr<torch::optim::Adam> adam;
  if (contents.tensors.metadata.count("optimizer"))
    adam = std::make_unique<torch::optim::Adam>(agent->parameters(),
                                                torch::optim::AdamOptions(contents.state.config.learning_rate));
  contents.load_into(*agent, adam.get());
  std::vector<LoadedTensor> out;
  const auto add = [&](const std::string& name, const torch::Tensor& value) {
    const torch::Tensor t = value.detach().contiguous();
    LoadedTensor loaded{name, t.scalar_type() == torch::kLong, t.sizes().vec(), {}, {}};
    if (loaded.integer)
      loaded.integers.assign(t.data_ptr<std::int64_t>(), t.data_ptr<std::int64_t>() + t.numel());
    else
      loaded.floats.assign(t.data_ptr<float>(), t.data_ptr<float>() + t.numel());
    out.push_back(std::move(loaded));
  };
  for (const auto& p : agent->named_parameters()) add(kAgentPrefix + p.key(), p.value());
  for (const auto& b : agent->named_buffers()) add(kAgentPrefix + b.key(), b.value());
  if (adam)
    for (const auto& p : agent->named_parameters()) {
      const auto it = adam->state().find(adam_state_key(p.value()));
      if (it == adam->state().end()) continue;
      const auto& s = static_cast<const torch::optim::AdamParamState&>(*it->second);
      add(kOptimizerPrefix + p.key() + ".exp_avg", s.exp_avg());
      add(kOptimizerPrefix + p.key() + ".exp_avg_sq", s.exp_avg_sq());
      add(kOptimizerPrefix + p.key() + ".step", torch::tensor(static_cast<std::int64_t>(s.step()), torch::kLong));
    }
  return out;
}

CheckpointInfo export_model(const Checkpoint& checkpoint, const fs::path& model_file) {
  save_checkpoint(model_file, *checkpoint.contents().networks(), nullptr, checkpoint.contents().state);
  return checkpoint.info();
}

}  // namespace scout::learn
