#include "learn/trainer.hpp"

#include <fmt/format.h>
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <thread>

#include "core/digest.hpp"
#include "core/error.hpp"
#include "core/fault_injection.hpp"
#include "core/files.hpp"
#include "core/memory.hpp"
#include "core/random.hpp"
#include "core/seed_streams.hpp"
#include "core/timing.hpp"
#include "learn/auto_precision.hpp"
#include "learn/checkpoint.hpp"
#include "learn/distributed.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/checkpoint.hpp"
#include "learn/internal/objective.hpp"
#include "learn/internal/precision.hpp"
#include "worlds/dataset.hpp"
#include "worlds/floor_layout.hpp"

namespace scout::learn {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;
using core::Clock;
using core::seconds_since;

namespace {

std::uint64_t stage_epoch_seed(std::uint64_t seed, std::uint64_t stream, Stage stage, int epoch) {
  return core::derive_seed(core::derive_seed(core::derive_seed(seed, stream), index(stage)), epoch);
}

std::array<int, kTrainingStages> stage_epochs(const TrainConfig& c) {
  return {c.pretrain_epochs, c.epochs[0], c.epochs[1], c.epochs[2]};
}

// The layer's module; null for the action layer of a goals-only agent, which has none.
torch::nn::Module* layer(agent::AgentImpl& a, Layer l) {
  switch (l) {
    case Layer::Goal:
      return a.goal.get();
    case Layer::Action:
      return a.action ? a.action.get() : nullptr;
    case Layer::Classifier:
      break;
  }
  return a.classifier.get();
}

}  // namespace

int set_torch_threads(int threads) {
  const int n = threads > 0 ? threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  torch::set_num_threads(n);
  return torch::get_num_threads();
}

std::string metrics_csv_header() {
  return "mode,epoch,reward,loss,train_accuracy,validation_accuracy,images_per_s,seconds,learning_rate,"
         "validation_iid,validation_goals_only,validation_full_image,gradient_norm\n";
}

namespace {
// An empty field for a figure a row does not have (rows written before it was measured).
std::string csv_optional(const std::optional<double>& v) { return v ? fmt::format("{:.6f}", *v) : std::string(); }
// A gradient's norm spans orders of magnitude over a run: significant digits, not decimals.
std::string csv_gradient_norm(const std::optional<double>& v) { return v ? fmt::format("{:.6g}", *v) : std::string(); }
}  // namespace

std::string metrics_csv_row(const EpochMetrics& m) {
  return fmt::format("{},{},{:.6f},{:.6f},{:.6f},{:.6f},{:.3f},{:.3f},{},{},{},{},{}\n", to_string(m.stage), m.epoch,
                     m.reward, m.loss, m.train_accuracy, m.validation_accuracy, m.images_per_s, m.seconds,
                     m.learning_rate, csv_optional(m.validation_iid), csv_optional(m.validation_goals_only),
                     csv_optional(m.validation_full_image), csv_gradient_norm(m.gradient_norm));
}

// ---------------------------------------------------------------------------------------------
// The run.

struct Trainer::Impl {
  TrainConfig config;
  fs::path run_dir;
  int threads = 1;
  bool force_memory = false;  // a new run's memory estimate is not checked
  worlds::LabeledImages train, validation;
  worlds::FloorComposer composer{0, 0};  // the world's floor layout over the images
  grid::FloorFrame frame;
  agent::Agent agent{nullptr};
  std::unique_ptr<torch::optim::Adam> optimizer;
  std::unique_ptr<RolloutEngine> engine;
  std::unique_ptr<AgentPolicy> policy;
  ScheduleCursor cursor;
  std::string manifest;  // JSON text, stored in checkpoints
  std::vector<EpochMetrics> history;
  EpochSums sums;  // of the epoch in progress (non-empty after an interrupt)
  std::vector<fs::path> data_files;
  // Data-parallel training: this process's group (null: one process). Every rank drives its
  // share of each batch's images; rank 0 alone writes files.
  ProcessGroup* group = nullptr;

  int rank() const { return group ? group->rank() : 0; }
  int ranks() const { return group ? group->size() : 1; }
  // This rank's contiguous share [first, end) of `count` items (shares differ by at most one).
  std::pair<int, int> share(int count) const { return share_of(count, rank(), ranks()); }
  // Sums a few figures over the ranks (each rank's own when alone).
  template <std::size_t N>
  void sum_over_ranks(std::array<double, N>& values) {
    if (group) group->all_reduce_sum(std::span<double>(values));
  }

  // new_run: D (network.classes) comes from the training labels; a resumed run keeps its own.
  void setup(int thread_request, bool new_run) {
    threads = set_torch_threads(thread_request);
    train = worlds::load_split(config.data_folder, worlds::Split::Train);
    composer = worlds::FloorComposer(config.world, train.images.cols, train.images.rows);
    // D: the digits' classes, or the sums of a floor of several (FloorComposer::classes).
    if (new_run && !train.labels.empty())
      config.network.classes =
          std::max(2, composer.classes(*std::max_element(train.labels.begin(), train.labels.end()) + 1));
    if (new_run) {  // c from the floor images; an auto precision is resolved for this CPU and stored so
      config.network.image_channels = train.images.channels;
      config.precision = resolve_precision(config.precision);
    }
    validation = worlds::load_split(config.data_folder, worlds::Split::Validation);
    data_files = train.files;
    for (const fs::path& f : validation.files)
      if (std::find(data_files.begin(), data_files.end(), f) == data_files.end()) data_files.push_back(f);
    auto limit = [](worlds::LabeledImages& d, int k) {
      if (k <= 0 || k >= d.images.count) return;
      d.images.count = k;
      d.images.pixels.resize(static_cast<std::size_t>(k) * d.images.rows * d.images.cols);
      d.labels.resize(k);
    };
    limit(train, config.train_limit);
    limit(validation, config.validation_limit);
    const std::string origin = config.data_folder.string();
    if (train.images.count == 0) throw InputError(origin + ": no training images");
    // A floor of n digits is labelled by their sum: each label times n must stay a class.
    const int n = composer.digits();
    const std::string sum_note =
        n > 1 ? fmt::format(" (floors of {} digits, labelled by their sum up to {} x the label)", n, n) : std::string();
    for (std::uint8_t label : train.labels)
      if (label * n >= config.network.classes)
        throw InputError(fmt::format("{}: a training label is {}, the network has {} classes{}", origin, label,
                                     config.network.classes, sum_note));
    for (std::uint8_t label : validation.labels)
      if (label * n >= config.network.classes)
        throw InputError(
            fmt::format("{}: a validation label is {}, the network has {} classes (from the training labels){}", origin,
                        label, config.network.classes, sum_note));
    worlds::check_against_floor(config.world, composer.width_px(), composer.height_px());
    if (config.network.wide_view && !config.world.camera.wide())
      throw InputError(config.world.file.string() +
                       ": camera.wide_px: expected a wider view (wide_px > 0) for planners that read it (--wide-view)");
    frame = {.width_px = composer.width_px(),
             .height_px = composer.height_px(),
             .pixel_size_m = config.world.floor.pixel_size_m};
    if (new_run)  // before the networks and the robots take it
      core::check_memory(estimate_training_bytes(config, frame.width_px, frame.height_px),
                         fmt::format("training B x N = {} x {} robots on {} x {} floors with these networks",
                                     config.batch_images, config.rollouts, frame.width_px, frame.height_px),
                         force_memory);
    if (new_run) check_checkpoint_size(config.network);  // what it writes, it must read back
    torch::manual_seed(config.seed);
    agent = agent::Agent(config.network);
    optimizer =
        std::make_unique<torch::optim::Adam>(agent->parameters(), torch::optim::AdamOptions(config.learning_rate));
    build_engine();
  }

  // A checkpoint's weights, Adam's state and the schedule's position, into the networks and the
  // optimizer that setup() built from its config.
  void restore(const Checkpoint& checkpoint, const CheckpointState& state) {
    checkpoint.contents().load_into(*agent, optimizer.get());
    // Adam's stored state carries the rate it ran with; the config's (possibly new) rate wins.
    for (torch::optim::OptimizerParamGroup& param_group : optimizer->param_groups())
      static_cast<torch::optim::AdamOptions&>(param_group.options()).lr(config.learning_rate);
    cursor = state.cursor;
    history = state.history;
    sums = state.partial;
    manifest = state.manifest;
  }

  // Robots for this rank's share of a batch: B x N alone, ceil(B / ranks) x N in a group.
  void build_engine() {
    const int robots = (config.batch_images + ranks() - 1) / ranks() * config.rollouts * config.world.team.robots;
    policy.reset();
    engine.reset();
    engine = std::make_unique<RolloutEngine>(config.world, frame, robots);
    policy = std::make_unique<AgentPolicy>(*agent, frame, config.world.camera.patch_px, robots);
  }

  // The floors of this epoch: composed anew every epoch where the world has a floor layout (a
  // digit lands elsewhere each time), and the validation floors, the same every epoch.
  worlds::FloorSource training_floors() const {
    return {&train, composer, stage_epoch_seed(config.seed, streams::kTrainFloors, cursor.stage, cursor.epoch)};
  }
  worlds::FloorSource validation_floors() const {
    return {&validation, composer, core::derive_seed(config.seed, streams::kTrainValidationFloors)};
  }

  Stage stage() const { return cursor.stage; }
  bool past_last_stage() const { return cursor.stage == Stage::Done; }
  // True when no stage from the cursor on has an epoch left (without moving the cursor).
  bool schedule_done() const {
    const auto epochs = stage_epochs(config);
    for (Stage st = cursor.stage; st != Stage::Done; st = next(st))
      if ((st == cursor.stage ? cursor.epoch : 0) < epochs[index(st)]) return false;
    return true;
  }

  // Skips stages with no epochs left.
  void normalise_cursor() {
    const auto epochs = stage_epochs(config);
    while (!past_last_stage() && cursor.epoch >= epochs[index(cursor.stage)]) {
      cursor.stage = next(cursor.stage);
      cursor.epoch = 0;
      cursor.batch = 0;
    }
  }

  // Which layers Adam may change in `stage`: frozen layers only learn from full images.
  void set_trainable(Stage s) {
    for (int l = 0; l < 3; ++l) {
      const bool trainable = s == Stage::Pretrain ? static_cast<Layer>(l) == Layer::Classifier : !config.frozen[l];
      if (torch::nn::Module* m = layer(*agent, static_cast<Layer>(l)))
        for (torch::Tensor& p : m->parameters()) p.set_requires_grad(trainable);
    }
  }

  int batch_images_for(Stage s) const {
    return s == Stage::Pretrain ? config.batch_images * config.rollouts : config.batch_images;
  }
  int batches_per_epoch(Stage s) const {
    const int b = batch_images_for(s);
    return (train.images.count + b - 1) / b;
  }

  std::vector<int> epoch_order() const {
    std::vector<int> order(train.images.count);
    for (int i = 0; i < train.images.count; ++i) order[i] = i;
    core::Rng rng(stage_epoch_seed(config.seed, streams::kTrainOrder, cursor.stage, cursor.epoch));
    core::shuffle(order, rng);
    return order;
  }

  // One optimisation step in three parts: (1) forward and backward, (2) the gradient hook,
  // (3) Adam's step. Returns the loss; when it is not finite nothing has changed.
  //
  // In a group each rank rolls out its share of the batch's images (an image's N rollouts stay
  // together, for the leave-one-out baseline) from the same per-robot seeds as one process would,
  // weights its mean loss by its share of the images, and the flattened gradients are summed over
  // the ranks: the batch's mean, so every rank takes the same Adam step as one process would (up
  // to the order of the sums).
  double train_batch(std::span<const int> indices, int batch_index, const TrainHooks& hooks) {
    const Stage s = stage();
    agent->train();
    // Frozen layers keep their BatchNorm statistics too (ResNet-18).
    if (s != Stage::Pretrain)
      for (int l = 0; l < 3; ++l)
        if (torch::nn::Module* m = layer(*agent, static_cast<Layer>(l)); m && config.frozen[l]) m->eval();
    clear_gradients(*agent);
    const auto [first, end] = share(static_cast<int>(indices.size()));
    const std::span<const int> mine = indices.subspan(first, end - first);
    torch::Tensor loss;
    // This rank's reward sum, rollouts classified right, and rollouts.
    std::array<double, 3> figures{};
    if (mine.empty()) {
      // More ranks than images in the last batch: nothing to roll out; zeros join the sums.
    } else if (s == Stage::Pretrain) {
      const auto area = static_cast<std::size_t>(frame.area_px());
      std::vector<std::uint8_t> floors(area * mine.size());
      std::vector<std::int64_t> labels(mine.size());
      const worlds::FloorSource source = training_floors();
      for (std::size_t i = 0; i < mine.size(); ++i)
        labels[i] = source.floor(mine[i], std::span(floors.data() + i * area, area));
      torch::Tensor x = full_images(floors, static_cast<int>(mine.size()), frame);
      torch::Tensor log_probs = classifier_log_probs(*agent, x, config.precision);
      torch::Tensor target = torch::from_blob(labels.data(), {static_cast<long>(labels.size())}, torch::kLong).clone();
      loss = torch::nll_loss(log_probs, target);
      const torch::Tensor reward = -torch::nll_loss(log_probs.detach(), target, {}, at::Reduction::None);
      figures = {reward.sum().item<double>(), static_cast<double>(count_correct(log_probs.detach(), labels)),
                 static_cast<double>(labels.size())};
    } else {
      const std::uint64_t stream = core::derive_seed(
          stage_epoch_seed(config.seed, streams::kTrainBatch, cursor.stage, cursor.epoch), batch_index);
      const RolloutBatch batch = make_batch(training_floors(), mine, config.rollouts, config.world, frame, stream,
                                            static_cast<std::uint64_t>(first) * config.rollouts);
      const EstimatorOptions est{.rollouts_per_image = config.rollouts,
                                 .leave_one_out = config.leave_one_out,
                                 .entropy_bonus = config.entropy_bonus,
                                 .distillation = config.distillation,
                                 .stalled_move_cost = config.stalled_move_cost};
      const BatchOutcome out = run_batch(*agent, *engine, *policy, batch, sampling_for(s, true, config.precision), est);
      loss = -out.objective;
      figures = {out.reward.sum().item<double>(), static_cast<double>(count_correct(out.log_probs, batch.labels)),
                 static_cast<double>(batch.rollouts())};
    }
    double value = 0;
    if (!group) {
      add_figures(figures);
      value = backward_if_finite(loss);
      if (!std::isfinite(value)) return value;
      if (hooks.on_gradients) apply_gradient_hook(*agent, hooks.on_gradients);
      add_gradient_norm(gradient_norm(*agent));
    } else {
      // The batch's loss and figures over the ranks first: a non-finite loss anywhere stops every
      // rank before any of them steps.
      const double weight = static_cast<double>(mine.size()) / static_cast<double>(indices.size());
      std::array<double, 4> summed = {figures[0], figures[1], figures[2],
                                      mine.empty() ? 0.0 : loss.item<double>() * weight};
      sum_over_ranks(summed);
      add_figures({summed[0], summed[1], summed[2]});
      value = summed[3];
      if (!std::isfinite(value)) return value;
      if (loss.defined() && loss.requires_grad()) (loss * weight).backward();
      apply_gradient_hook(*agent, [&](std::span<float> gradients) {
        group->all_reduce_sum(gradients);
        if (hooks.on_gradients) hooks.on_gradients(gradients);
        double squares = 0;
        for (const float g : gradients) squares += static_cast<double>(g) * g;
        add_gradient_norm(std::sqrt(squares));
      });
    }
    core::fault_point("batch");
    // Adam skips parameters without a gradient: frozen layers, an unconsulted action planner, and
    // everything in a stage whose layers are all frozen.
    optimizer->step();
    return value;
  }

  // Every step's norm is summed, so that an epoch resumed from a checkpoint reports the mean over
  // all its steps; `gradient_steps` falls short of the epoch's batches when its first part was
  // trained by a build that did not measure it.
  void add_gradient_norm(double norm) {
    sums.gradient_norm += norm;
    sums.gradient_steps += 1;
  }

  void add_figures(const std::array<double, 3>& figures) {
    sums.reward += figures[0];
    sums.correct += std::lround(figures[1]);
    sums.rollouts += std::lround(figures[2]);
  }

  // The classifier on the full validation images (in a group, each rank classifies its share).
  double validation_full_image_accuracy() {
    torch::NoGradGuard no_grad;
    agent->eval();
    const int n = validation.images.count;
    if (n == 0) return 0;
    const auto [begin, end] = share(n);
    const int chunk = engine->max_robots();
    const auto area = static_cast<std::size_t>(frame.area_px());
    std::array<double, 1> correct{};
    for (int first = begin; first < end; first += chunk) {
      const int k = std::min(chunk, end - first);
      std::vector<std::uint8_t> floors(area * k);
      std::vector<std::int64_t> labels(k);
      const worlds::FloorSource source = validation_floors();
      for (int i = 0; i < k; ++i) labels[i] = source.floor(first + i, std::span(floors.data() + area * i, area));
      torch::Tensor x = full_images(floors, k, frame);
      correct[0] += count_correct(classifier_log_probs(*agent, x, config.precision), labels);
    }
    sum_over_ranks(correct);
    return correct[0] / n;
  }

  // One stochastic pass of `sampling` over the validation digits: image i drives with robot
  // seed derive_seed(derive_seed(seed, stream), i), the same every epoch and however the images
  // are split into batches and over ranks.
  double validation_rollout_accuracy(Sampling sampling, std::uint64_t stream) {
    torch::NoGradGuard no_grad;
    agent->eval();
    const int n = validation.images.count;
    if (n == 0) return 0;
    sampling.with_grad = false;
    sampling.precision = config.precision;
    const auto [begin, end] = share(n);
    const int chunk = engine->max_robots() / config.world.team.robots;  // rollouts: whole teams
    std::array<double, 1> correct{};
    for (int first = begin; first < end; first += chunk) {
      const int k = std::min(chunk, end - first);
      std::vector<int> indices(k);
      for (int i = 0; i < k; ++i) indices[i] = first + i;
      const RolloutBatch batch = make_batch(validation_floors(), indices, 1, config.world, frame,
                                            core::derive_seed(config.seed, stream), static_cast<std::uint64_t>(first));
      const BatchOutcome out = run_batch(*agent, *engine, *policy, batch, sampling,
                                         {.rollouts_per_image = 1, .leave_one_out = false, .entropy_bonus = 0});
      correct[0] += count_correct(out.log_probs, batch.labels);
      core::fault_point("validation");
    }
    sum_over_ranks(correct);
    return correct[0] / n;
  }

  // The epoch's validation figures: this stage's policy (full images in pretraining), the two
  // baselines with the same classifier, and the classifier on full images. The goals-only
  // baseline waits for a learned goal layer (mode ii on): before it, the planner is untrained.
  // In mode (i) the stage's policy is the i.i.d. baseline itself.
  void validate(EpochMetrics& m) {
    const Stage s = stage();
    m.validation_full_image = validation_full_image_accuracy();
    if (s == Stage::ModeII || s == Stage::ModeIII) {
      Sampling goals_only;
      goals_only.learned_goals = true;
      m.validation_goals_only = validation_rollout_accuracy(goals_only, streams::kTrainValidationGoalsOnly);
    }
    if (s == Stage::Pretrain) {
      m.validation_accuracy = *m.validation_full_image;
      m.validation_iid = validation_rollout_accuracy(Sampling{}, streams::kTrainValidationIid);
    } else {
      m.validation_accuracy =
          validation_rollout_accuracy(sampling_for(s, false, config.precision), streams::kTrainValidation);
      m.validation_iid = s == Stage::ModeI ? m.validation_accuracy
                                           : validation_rollout_accuracy(Sampling{}, streams::kTrainValidationIid);
    }
  }

  void write_metrics() const {
    if (rank() != 0) return;
    std::string text = metrics_csv_header();
    for (const EpochMetrics& m : history) text += metrics_csv_row(m);
    core::write_file_atomic(run_dir / kMetricsFile, text);
  }

  void save() {
    if (rank() != 0) return;
    save_checkpoint(run_dir / kCheckpointFile, *agent, optimizer.get(), state());
  }

  CheckpointState state() const {
    CheckpointState state;
    state.config = config;
    state.cursor = cursor;
    state.history = history;
    state.partial = sums;
    state.world_size = ranks();
    state.threads = threads;
    state.manifest = manifest;
    return state;
  }

  // True when a stop was asked for on any rank: all ranks stop after the same batch.
  bool stop_requested(const core::StopToken& stop) {
    std::array<double, 1> asked = {stop.requested() ? 1.0 : 0.0};
    sum_over_ranks(asked);
    return asked[0] > 0;
  }

  double remaining_images_after_epoch() const {
    const auto epochs = stage_epochs(config);
    double images = 0;
    for (Stage st = cursor.stage; st != Stage::Done; st = next(st)) {
      const int left = epochs[index(st)] - (st == cursor.stage ? cursor.epoch + 1 : 0);
      if (left > 0) images += static_cast<double>(left) * train.images.count;
    }
    return images;
  }

  TrainResult run(const TrainHooks& hooks) {
    normalise_cursor();
    while (!past_last_stage()) {
      const Stage s = stage();
      set_trainable(s);
      const auto epochs = stage_epochs(config);
      const int batches = batches_per_epoch(s);
      const int per_batch = batch_images_for(s);
      const std::vector<int> order = epoch_order();
      const auto epoch_start = Clock::now();
      const double seconds_before = sums.train_seconds;
      auto last_checkpoint = Clock::now();
      for (int b = cursor.batch; b < batches; ++b) {
        if (stop_requested(hooks.stop)) {
          save();
          throw core::Stopped(fmt::format("interrupted in mode {} epoch {} after batch {}/{}; checkpoint saved: {}",
                                          to_string(s), cursor.epoch + 1, cursor.batch, batches,
                                          (run_dir / kCheckpointFile).string()));
        }
        const auto t0 = Clock::now();
        const int first = b * per_batch;
        const int k = std::min(per_batch, train.images.count - first);
        const double loss = train_batch(std::span<const int>(order.data() + first, k), b, hooks);
        if (!std::isfinite(loss)) {
          return {TrainOutcome::NonFinite,
                  fmt::format("the loss is {} in mode {} epoch {} batch {}; training stopped, the last good checkpoint "
                              "is kept ({}); try a smaller --lr",
                              loss, to_string(s), cursor.epoch + 1, b + 1,
                              history.empty() ? "none was written yet" : (run_dir / kCheckpointFile).string())};
        }
        sums.loss += loss;
        sums.batches += 1;
        sums.images += k;
        sums.train_seconds += seconds_since(t0);
        cursor.batch = b + 1;
        if (hooks.checkpoint_every.count() > 0 && b + 1 < batches &&
            Clock::now() - last_checkpoint >= hooks.checkpoint_every) {
          save();  // rank 0 alone; the others need not know
          last_checkpoint = Clock::now();
        }
        if (hooks.on_progress) {
          Progress p;
          p.stage = s;
          p.epoch = cursor.epoch + 1;
          p.epochs = epochs[index(cursor.stage)];
          p.batch = b + 1;
          p.batches = batches;
          p.images_per_s = sums.train_seconds > 0 ? sums.images / sums.train_seconds : 0;
          p.reward = sums.rollouts ? sums.reward / sums.rollouts : 0;
          const double left_this_epoch =
              static_cast<double>(train.images.count - std::min<long>(sums.images, train.images.count));
          p.eta_s = p.images_per_s > 0 ? (left_this_epoch + remaining_images_after_epoch()) / p.images_per_s : 0;
          hooks.on_progress(p);
        }
      }
      EpochMetrics m;
      m.stage = s;
      m.epoch = cursor.epoch + 1;
      m.reward = sums.rollouts ? sums.reward / sums.rollouts : 0;
      m.loss = sums.batches ? sums.loss / sums.batches : 0;
      m.train_accuracy = sums.rollouts ? static_cast<double>(sums.correct) / sums.rollouts : 0;
      m.images_per_s = sums.train_seconds > 0 ? sums.images / sums.train_seconds : 0;
      if (sums.batches > 0 && sums.gradient_steps == sums.batches) m.gradient_norm = sums.gradient_norm / sums.batches;
      validate(m);
      // Wall time: this process's part of the epoch, plus the training time before a resume.
      m.seconds = seconds_before + seconds_since(epoch_start);
      m.learning_rate = config.learning_rate;
      history.push_back(m);
      sums = {};
      cursor.epoch += 1;
      cursor.batch = 0;
      normalise_cursor();
      save();
      write_metrics();
      if (hooks.on_epoch) hooks.on_epoch(m);
    }
    return {TrainOutcome::Finished, "training finished"};
  }
};

Trainer::Trainer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Trainer::Trainer(const TrainConfig& config, fs::path run_dir, int threads, bool force_memory,
                 const Checkpoint* initial_weights)
    : impl_(std::make_unique<Impl>()) {
  config.validate();
  impl_->force_memory = force_memory;
  impl_->config = config;
  impl_->run_dir = std::move(run_dir);
  impl_->setup(threads, /*new_run=*/true);
  if (initial_weights) {
    // setup() takes D and c from the data: they must be the model's for its weights to fit.
    const agent::NetworkConfig& has = initial_weights->info().config.network;
    const agent::NetworkConfig& data = impl_->config.network;
    if (has.classes != data.classes || has.image_channels != data.image_channels)
      throw InputError(fmt::format("{}: the model has {} classes of {}-channel images, the training data {} of {}",
                                   initial_weights->file().string(), has.classes, has.image_channels, data.classes,
                                   data.image_channels));
    if (agent::same_weights(has, data))
      initial_weights->contents().load_into(*impl_->agent, nullptr);
    else  // the model's networks grown by an occupancy channel or a goal context branch, read at zero
      agent::copy_into_grown(*initial_weights->contents().networks(), *impl_->agent);
  }
}

std::unique_ptr<Trainer> Trainer::resume(const fs::path& run_dir, int threads, const ResumeOptions& options) {
  return resume(open_checkpoint(run_dir / kCheckpointFile), run_dir, threads, options);
}

std::unique_ptr<Trainer> Trainer::resume(const Checkpoint& checkpoint, const fs::path& run_dir, int threads,
                                         const ResumeOptions& options) {
  auto impl = std::make_unique<Impl>();
  CheckpointState state = checkpoint.contents().state;
  const std::optional<std::array<int, 3>>& epochs = options.epochs;
  if (epochs) state.config.epochs = *epochs;
  if (options.data_folder) state.config.data_folder = fs::absolute(*options.data_folder);
  if (options.learning_rate) state.config.learning_rate = *options.learning_rate;
  if (options.distillation) state.config.distillation = *options.distillation;
  if (options.precision) state.config.precision = resolve_precision(*options.precision);
  state.config.validate();
  impl->config = state.config;
  impl->run_dir = run_dir;
  // The run's own thread count unless another is asked for: LibTorch's sums depend on it, so
  // only the same count continues the run bit for bit.
  impl->setup(threads > 0 ? threads : state.threads, /*new_run=*/false);
  impl->restore(checkpoint, state);
  // A saved cursor has already skipped the stages with no epochs left; under a longer schedule,
  // continue right after the last epoch trained (run() skips finished stages again).
  if (epochs && !impl->history.empty()) {
    // A layer that has been learned never returns to i.i.d.: earlier stages cannot grow.
    const Stage last_stage = impl->history.back().stage;
    const std::array<int, kTrainingStages> wanted = {state.config.pretrain_epochs, (*epochs)[0], (*epochs)[1],
                                                     (*epochs)[2]};
    for (Stage st = Stage::Pretrain; st != last_stage; st = next(st)) {
      const auto done = std::count_if(impl->history.begin(), impl->history.end(),
                                      [&](const EpochMetrics& m) { return m.stage == st; });
      if (wanted[index(st)] > done)
        throw InputError(
            fmt::format("--epochs: the run has reached mode {}; mode {} cannot follow it (asked for {} "
                        "epochs of it, {} done)",
                        to_string(last_stage), to_string(st), wanted[index(st)], done));
    }
  }
  if (epochs && impl->cursor.batch == 0 && !impl->history.empty()) {
    const EpochMetrics& last = impl->history.back();
    impl->cursor = {last.stage, last.epoch, 0};
  }
  // metrics.csv follows the checkpoint: a run killed between writing the one and the other gets
  // the rows its checkpoint holds.
  impl->write_metrics();
  return std::unique_ptr<Trainer>(new Trainer(std::move(impl)));
}

namespace {

// What every rank of a data-parallel run must agree on, as JSON text: each part of the config
// that the schema table marks (learn/train_config.cpp: the world, the networks and their
// arithmetic, the training settings), and the data's SHA-256s. Paths are left out: machines may
// keep the data in different folders.
constexpr Agreement kAgreed[] = {Agreement::World, Agreement::Networks, Agreement::Training};

std::string agreement_json(const TrainConfig& config, const std::vector<fs::path>& data_files) {
  json parts;
  for (Agreement part : kAgreed) parts[to_string(part)] = agreement_text(config, part);
  json data = json::array();
  for (const fs::path& f : data_files) data.push_back(core::sha256_hex(f));
  parts["data (SHA-256)"] = data;
  return parts.dump();
}

// Pads to a common length for all_gather (JSON text never holds a NUL).
std::vector<json> gather_agreements(ProcessGroup& group, const std::string& text) {
  std::array<double, 1> longest = {0};
  std::vector<double> lengths(group.size(), 0.0);
  lengths[group.rank()] = static_cast<double>(text.size());
  group.all_reduce_sum(std::span<double>(lengths));
  for (double l : lengths) longest[0] = std::max(longest[0], l);
  std::string padded = text;
  padded.resize(static_cast<std::size_t>(longest[0]), '\0');
  std::vector<json> all;
  for (std::string& t : group.all_gather(padded)) all.push_back(json::parse(t.substr(0, t.find('\0'))));
  return all;
}

}  // namespace

std::unique_ptr<Trainer> Trainer::distribute(ProcessGroup& group, int threads,
                                             const std::function<std::unique_ptr<Trainer>()>& make_leader,
                                             const std::optional<TrainConfig>& own_config,
                                             const std::optional<fs::path>& data_folder) {
  std::unique_ptr<Trainer> trainer;
  // 'S' and the checkpoint's bytes, or 'E' when rank 0 could not start.
  std::string payload;
  const std::string origin = "rank 0's training state";
  if (group.rank() == 0) {
    try {
      trainer = make_leader();
      Impl& leader = *trainer->impl_;
      leader.group = &group;
      payload = "S" + checkpoint_bytes(*leader.agent, leader.optimizer.get(), leader.state());
    } catch (const std::exception&) {
      payload = "E";
      group.broadcast(payload);
      throw;
    }
    group.broadcast(payload);
    trainer->impl_->build_engine();
  } else {
    group.broadcast(payload);
    if (payload.empty() || payload[0] != 'S') throw LeaderFailed("rank 0 could not start the run (its error says why)");
    payload.erase(0, 1);
    const Checkpoint checkpoint = open_checkpoint_bytes(payload, origin);
    CheckpointState state = checkpoint.contents().state;
    if (data_folder) state.config.data_folder = fs::absolute(*data_folder);
    auto impl = std::make_unique<Impl>();
    impl->config = state.config;
    impl->group = &group;
    impl->setup(threads, /*new_run=*/false);
    impl->restore(checkpoint, state);
    trainer.reset(new Trainer(std::move(impl)));
  }
  // Every rank compares every rank with rank 0, so that all of them stop with the same line.
  const Impl& impl = *trainer->impl_;
  const std::vector<json> all =
      gather_agreements(group, agreement_json(own_config.value_or(impl.config), impl.data_files));
  for (int r = 1; r < group.size(); ++r)
    for (const auto& [what, part] : all[0].items())
      if (all[r][what] != part)
        throw InputError(
            fmt::format("rank {} asks for other {} than rank 0 (every process must run the same command "
                        "on the same data)",
                        r, what));
  return trainer;
}

Trainer::~Trainer() = default;

TrainResult Trainer::run(const TrainHooks& hooks) { return impl_->run(hooks); }
const TrainConfig& Trainer::config() const { return impl_->config; }
const ScheduleCursor& Trainer::cursor() const { return impl_->cursor; }
bool Trainer::finished() const { return impl_->schedule_done(); }
const std::vector<EpochMetrics>& Trainer::history() const { return impl_->history; }
int Trainer::threads() const { return impl_->threads; }
int Trainer::world_size() const { return impl_->ranks(); }
int Trainer::rank() const { return impl_->rank(); }
fs::path Trainer::checkpoint_file() const { return impl_->run_dir / kCheckpointFile; }
const std::vector<fs::path>& Trainer::data_files() const { return impl_->data_files; }
void Trainer::set_manifest(std::string manifest) { impl_->manifest = std::move(manifest); }

}  // namespace scout::learn
