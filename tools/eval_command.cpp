// scout eval: the paper's evaluation protocol (METHOD.md § Evaluation) for a checkpoint on a set
// of digits: a table on stdout, optionally a JSON report and per-image mean probabilities.
#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "learn/checkpoint.hpp"
#include "learn/distributed.hpp"
#include "learn/evaluation.hpp"
#include "learn/trainer.hpp"
#include "tools/commands.hpp"
#include "tools/group.hpp"
#include "tools/network_options.hpp"
#include "tools/output.hpp"
#include "tools/progress.hpp"
#include "worlds/dataset.hpp"

namespace scout::tools {

namespace {

namespace fs = std::filesystem;

struct EvalOptions {
  std::string checkpoint, images, labels, world;
  std::string seed;  // empty: 1
  int runs = 20;
  int baseline_runs = 5;
  bool baseline_runs_given = false;
  int limit = 0;  // the first K images only (0: all)
  std::string json_out, predictions_out;
  std::string precision = "auto";
  GroupFlags group;
};

std::string predictions_csv(const learn::EvalReport& report) {
  const std::size_t classes = report.confusion.size();
  std::string text = "index,label";
  for (std::size_t c = 0; c < classes; ++c) text += fmt::format(",p{}", c);
  text += "\n";
  for (std::size_t i = 0; i < report.probabilities.size(); ++i) {
    text += fmt::format("{},{}", i, report.labels[i]);
    for (double p : report.probabilities[i]) text += fmt::format(",{:.6f}", p);
    text += "\n";
  }
  return text;
}

void print_table(const learn::EvalReport& r) {
  const char* layers = r.learned_actions ? "learned goals and actions"
                       : r.learned_goals ? "learned goals, i.i.d. actions"
                                         : "i.i.d. goals and actions";
  fmt::print("{} on {} images, {} run{} (seed {}; {})\n", r.checkpoint, r.images, r.runs, r.runs == 1 ? "" : "s",
             r.seed, layers);
  fmt::print("  {:<26}{:.4f} ± {:.4f}\n", "accuracy", r.accuracy.mean, r.accuracy.ci95);
  fmt::print("  {:<26}{:.4f} ± {:.4f}\n", "top-2 accuracy", r.top2.mean, r.top2.ci95);
  const std::string baseline_runs = fmt::format("({} run{})", r.baseline_runs, r.baseline_runs == 1 ? "" : "s");
  fmt::print("  {:<26}{:.4f} ± {:.4f}  {}\n", "i.i.d. baseline", r.iid_accuracy, r.iid_ci95, baseline_runs);
  if (std::isnan(r.goals_only_accuracy))
    fmt::print("  {:<26}{}\n", "goals-only baseline", "n/a (no learned goal layer)");
  else
    fmt::print("  {:<26}{:.4f} ± {:.4f}  {}\n", "goals-only baseline", r.goals_only_accuracy, r.goals_only_ci95,
               baseline_runs);
  fmt::print("  {:<26}{:.4f}\n", "full images", r.full_image_accuracy);
  fmt::print("  {:<26}{:.4f}\n", "greedy", r.greedy_accuracy);
  fmt::print(
      "  {:<26}{:.2f} per rollout; {:.1f} % with candidates revealing different pixels (by {:.1f} px), "
      "the more revealing chosen in {:.1f} %\n",
      "axis decisions (chi = 1)", r.axis_decisions_per_rollout, 100 * r.axis_differing_share, r.axis_gap_px,
      100 * r.axis_chose_more_share);
  fmt::print("  {:<26}{:.2f} per rollout (blocked by an obstacle or a teammate, or out of ticks)\n", "stalled moves",
             r.stalled_moves_per_rollout);
  fmt::print("  {:<26}{}\n", "precision", agent::to_string(r.precision));
  fmt::print("  {:<26}{}\n", "runs", r.runs);
  fmt::print("  {:<26}{}\n", "images", r.images);
  fmt::print("  {:<26}{:.1f}\n", "seconds", r.seconds);
  fmt::print("  (± is the half-width of the 95 % Student-t interval over the runs)\n");
}

void eval_command(const EvalOptions& opt, const Context& context) {
  const std::vector<std::string> inputs = {opt.checkpoint, opt.images, opt.labels, opt.world};
  check_output_file("--json", opt.json_out, inputs);
  check_output_file("--predictions", opt.predictions_out, inputs);
  if (!opt.json_out.empty() && !opt.predictions_out.empty() && fs::path(opt.json_out) == fs::path(opt.predictions_out))
    throw InputError("--predictions: expected a file other than --json's");
  learn::EvalConfig config;
  config.checkpoint = opt.checkpoint;
  config.images = opt.images;
  config.labels = opt.labels;
  if (!opt.world.empty()) config.world_file = opt.world;
  config.runs = opt.runs;
  if (opt.baseline_runs_given && opt.baseline_runs > opt.runs)
    throw InputError(
        fmt::format("--baseline-runs: expected at most --runs = {} (the baselines drive the first runs' "
                    "digits), got {}",
                    opt.runs, opt.baseline_runs));
  config.baseline_runs = opt.baseline_runs;
  config.image_limit = opt.limit;
  config.seed = opt.seed.empty() ? 1 : parse_seed(opt.seed);
  config.precision = agent::parse_precision(opt.precision);  // checked by the option; auto resolved by evaluate
  // Data-parallel: every process evaluates a share of the images; rank 0 prints and writes.
  std::unique_ptr<learn::ProcessGroup> group;
  if (const std::optional<learn::GroupOptions> options = group_from_flags(opt.group)) {
    set_rank(options->rank);
    group = learn::ProcessGroup::connect(*options);
    config.threads = threads_per_process(0);
  }
  const bool leader = !group || group->rank() == 0;
  learn::EvalReport report;
  // Once the inputs are read and the first batch is about to run, one line on stderr (what a caller
  // can wait for before signalling) and what the networks run in: after the checks, so that a
  // refusal stays one line.
  config.opened = learn::open_checkpoint(config.checkpoint);  // once: evaluate() reads it no more
  const agent::Precision trained = config.opened->info().config.precision;
  bool started = !leader;
  const core::StopToken stop([&started, &opt, trained] {
    if (!started) {
      started = true;
      std::fprintf(stderr, "scout eval: evaluating, %d run%s\n", opt.runs, opt.runs == 1 ? "" : "s");
      announce_model_precision(opt.precision, trained);
    }
    return interrupt_token().requested();
  });
  // In a group every process drives an equal share at the same pace: the leader reports its own.
  ProgressLine progress(group ? "scout eval (rank 0's share)" : "scout eval", "rollouts");
  if (leader)
    config.on_progress = [&progress](const learn::EvalProgress& e) {
      const std::string what = e.run > 0 ? fmt::format("run {} of {}", e.run, e.runs) : "greedy run";
      progress.update(what, e.rollouts_done, e.rollouts_total, e.seconds);
    };
  report = learn::evaluate(config, stop, group.get());
  // Nothing is written when a signal arrives before here; after it the files are complete.
  interrupt_token().throw_if_requested();
  if (!leader) return;
  print_table(report);
  if (!opt.json_out.empty()) {
    const nlohmann::ordered_json j = eval_document(learn::report_json(report), context.argv, opt.checkpoint, opt.images,
                                                   opt.labels, group ? group->size() : 1);
    write_file_atomic(opt.json_out, j.dump(2) + "\n");
    fmt::print("report:      {}\n", opt.json_out);
  }
  if (!opt.predictions_out.empty()) {
    write_file_atomic(opt.predictions_out, predictions_csv(report));
    fmt::print("predictions: {}\n", opt.predictions_out);
  }
}

}  // namespace

void add_eval_command(CLI::App& app, const Context& context) {
  auto opt = std::make_shared<EvalOptions>();
  auto* cmd = app.add_subcommand(
      "eval",
      "Evaluate a checkpoint on a set of digits (METHOD.md § Evaluation): R stochastic runs with the physics and the "
      "camera in the loop (mean ± 95 % Student-t half-width), top-2, the confusion matrix, the i.i.d. and goals-only "
      "baselines with the same classifier (in the first --baseline-runs runs), the classifier on full images and one "
      "greedy run.");
  cmd->add_option("--checkpoint", opt->checkpoint,
                  "RUN/checkpoint.safetensors, the RUN folder, or a model file written by scout train")
      ->required();
  cmd->add_option("--images", opt->images,
                  "IDX image file (idx3-ubyte, raw or .gz), e.g. data/mnist/t10k-images-idx3-ubyte")
      ->required();
  cmd->add_option("--labels", opt->labels, "IDX label file (idx1-ubyte, raw or .gz), one label per image")->required();
  cmd->add_option("--world", opt->world, "World file (default: the world the checkpoint was trained in)");
  cmd->add_option("--runs", opt->runs, "R: independent stochastic runs over all images")
      ->capture_default_str()
      ->check(decimal_in(1, 10000));
  cmd->add_option("--baseline-runs", opt->baseline_runs,
                  "Runs of each baseline (i.i.d. moves, goals only), the first of the R runs (at most R)")
      ->capture_default_str()
      ->check(decimal_in(1, 10000))
      ->each([opt](const std::string&) { opt->baseline_runs_given = true; });
  cmd->add_option("--seed", opt->seed,
                  "Seed, an integer in [0, 2^64 - 1] (default 1); run k uses a seed derived from it")
      ->check(seed_validator());
  add_model_precision_option(*cmd, opt->precision);
  cmd->add_option("--limit", opt->limit, "Evaluate on the first K images only (0: all)")
      ->capture_default_str()
      ->check(decimal_in(0, 100000000));
  cmd->add_option("--json", opt->json_out, "Also write the report (and a manifest) to this JSON file");
  cmd->add_option("--predictions", opt->predictions_out,
                  "Also write a CSV: index,label,p0,...: each image's class probabilities averaged over the runs");
  add_group_options(*cmd, opt->group);
  add_camera_backend_option(*cmd);
  cmd->callback([opt, &context] {
    install_interrupt_handler();
    if (const std::optional<int> status = launch_local_group(opt->group, context)) throw ExitStatus{*status};
    eval_command(*opt, context);
  });
}

}  // namespace scout::tools
