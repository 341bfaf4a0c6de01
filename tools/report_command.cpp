// scout report: the paper's table and figures for a model or a run, in one folder. Scout gathers
// the numbers (an evaluation on the official test digits, the training history, a budget sweep,
// the robustness table over scenario worlds, test episodes) into report-data.json; a small matplotlib script that ships
// with Scout (tools/report/scout_report.py, run on the project's Python, .venv) draws the figures and writes REPORT.md.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/digest.hpp"
#include "core/install_layout.hpp"
#include "core/process.hpp"
#include "core/random.hpp"
#include "core/seed_streams.hpp"
#include "core/timing.hpp"
#include "env/runs.hpp"
#include "learn/checkpoint.hpp"
#include "learn/evaluation.hpp"
#include "learn/rollout.hpp"
#include "learn/trained_agent.hpp"
#include "tools/commands.hpp"
#include "tools/network_options.hpp"
#include "tools/output.hpp"
#include "tools/progress.hpp"
#include "worlds/dataset.hpp"
#include "worlds/floor_layout.hpp"
#include "worlds/idx.hpp"
#include "worlds/world.hpp"

namespace scout::tools {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

// The paper's figures (§ Experiments) and, for scale, the glimpse models' published points on
// MNIST 28 x 28: another task (a glimpse jumps anywhere, Scout's robot drives), drawn at the
// largest share of the digit their glimpses can reveal.
constexpr double kPaperAccuracy = 94.61, kPaperCi95 = 0.17, kPaperTop2 = 98.30, kPaperFullImage = 94.92;
constexpr double kPaperTransfer = 95.19;
struct GlimpsePoint {
  const char* source;
  int glimpses, side;
  double accuracy;  // per cent
};
constexpr GlimpsePoint kGlimpsePoints[] = {
    {"RAM (Mnih et al. 2014)", 4, 8, 98.46},
    {"RAM (Mnih et al. 2014)", 6, 8, 98.88},
    {"MRAM (2025; glimpses taken as RAM's 8 x 8)", 7, 8, 99.20},
};

struct ReportOptions {
  std::string model;  // a model file or a run folder
  std::string out;
  std::string eval_file;
  std::string images, labels;  // default: the official test digits of data set mnist
  std::string data_root;
  std::vector<std::string> compare;          // LABEL=EVAL.json
  std::vector<std::string> sweep_compare;    // LABEL=MODEL: its budget curve beside this model's
  std::vector<std::string> scenario_agents;  // WORLD.yaml=MODEL: an agent trained for that world
  int runs = 20;
  int sweep_digits = 1000;
  int sweep_runs = 2;
  std::vector<std::string> scenarios;  // world files of the robustness table
  int scenario_digits = 1000;
  int scenario_runs = 5;
  int episodes = 8;
  std::string seed;  // empty: 1
  std::string precision = "auto";
  bool overwrite = false;
};

json read_json_file(const fs::path& file, const std::string& option) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: {}: cannot open", option, file.string()));
  json j = json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    throw InputError(fmt::format("{}: {}: expected a JSON object (an evaluation written by scout eval --json)", option,
                                 file.string()));
  return j;
}

// An evaluation report as `scout eval --json` writes it: the fields the report reads, checked.
void check_eval_json(const json& j, const fs::path& file) {
  auto number_at = [&](const json& parent, const char* key, const std::string& path) {
    if (!parent.is_object() || !parent.contains(key) || !parent[key].is_number())
      throw InputError(fmt::format("{}: {}: expected a number", file.string(), path));
  };
  for (const char* interval : {"accuracy", "top2"}) {
    if (!j.contains(interval) || !j[interval].is_object())
      throw InputError(fmt::format("{}: {}: expected an object with mean and ci95", file.string(), interval));
    number_at(j[interval], "mean", std::string(interval) + ".mean");
    number_at(j[interval], "ci95", std::string(interval) + ".ci95");
  }
  number_at(j, "full_image_accuracy", "full_image_accuracy");
  // Optional fields, copied into the report: a number or null where present.
  auto number_or_null = [&](const json& parent, const char* key, const std::string& path) {
    if (parent.contains(key) && !parent[key].is_number() && !parent[key].is_null())
      throw InputError(fmt::format("{}: {}: expected a number or null", file.string(), path));
  };
  number_or_null(j, "greedy_accuracy", "greedy_accuracy");
  number_or_null(j, "revealed_fraction", "revealed_fraction");
  for (const char* count : {"runs", "images"})
    if (j.contains(count) && !j[count].is_number_integer())
      throw InputError(fmt::format("{}: {}: expected an integer", file.string(), count));
  for (const char* text : {"precision", "checkpoint"})
    if (j.contains(text) && !j[text].is_string())
      throw InputError(fmt::format("{}: {}: expected a string", file.string(), text));
  if (!j.contains("confusion") || !j["confusion"].is_array() || j["confusion"].empty())
    throw InputError(fmt::format("{}: confusion: expected a square matrix of numbers", file.string()));
  const std::size_t classes = j["confusion"].size();
  for (const json& row : j["confusion"]) {
    if (!row.is_array() || row.size() != classes)
      throw InputError(fmt::format("{}: confusion: expected a square matrix of numbers", file.string()));
    for (const json& v : row)
      if (!v.is_number())
        throw InputError(fmt::format("{}: confusion: expected a square matrix of numbers", file.string()));
  }
  if (!j.contains("baselines") || !j["baselines"].is_object())
    throw InputError(fmt::format("{}: baselines: expected an object with iid and goals_only", file.string()));
  number_or_null(j["baselines"], "iid", "baselines.iid");
  number_or_null(j["baselines"], "goals_only", "baselines.goals_only");
  for (const char* interval : {"accuracy", "top2"})
    for (const char* key : {"mean", "ci95"}) {
      const double v = j[interval][key].get<double>();
      if (!(v >= 0 && v <= 1))
        throw InputError(
            fmt::format("{}: {}.{}: expected a fraction in [0, 1], got {}", file.string(), interval, key, v));
    }
}

// The digits an evaluation was made on, by SHA-256 (its manifest's data_sha256), or none.
std::vector<std::string> evaluated_data(const json& eval) {
  std::vector<std::string> out;
  if (!eval.contains("manifest") || !eval["manifest"].is_object()) return out;
  const json& m = eval["manifest"];
  if (!m.contains("data_sha256") || !m["data_sha256"].is_object()) return out;
  for (const auto& [path, sha] : m["data_sha256"].items())
    if (sha.is_string()) out.push_back(sha.get<std::string>());
  return out;
}

// The manifest a model or run came with: RUN/manifest.json, or X-manifest.json beside X.safetensors.
fs::path manifest_beside(const fs::path& model) {
  std::error_code ec;
  if (fs::is_directory(model, ec)) return model / kManifestFile;
  return model.parent_path() / (model.stem().string() + "-manifest.json");
}

// The evaluation a model or run keeps beside it: RUN/test-eval.json, or X-test-eval.json.
fs::path eval_beside(const fs::path& model) {
  std::error_code ec;
  if (fs::is_directory(model, ec)) return model / "test-eval.json";
  return model.parent_path() / (model.stem().string() + "-test-eval.json");
}

// A command line as a shell would take it back: "scout" and the arguments, quoted where needed.
std::string shell_line(const json& argv) {
  std::string line = "scout";
  for (std::size_t i = 1; i < argv.size(); ++i) {
    const std::string a = argv[i].is_string() ? argv[i].get<std::string>() : argv[i].dump();
    if (!a.empty() && a.find_first_of(" \t\n'\"\\$`*?[]{}()<>|&;#~") == std::string::npos) {
      line += " " + a;
      continue;
    }
    std::string quoted = "'";
    for (char c : a) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    line += " " + quoted + "'";
  }
  return line;
}

// One run's commands in its manifest: the first, then each resumption, as shell lines.
void append_run_commands(const json& m, std::vector<std::string>& out) {
  if (!m.is_object()) return;
  if (m.contains("command_line") && m["command_line"].is_array()) out.push_back(shell_line(m["command_line"]));
  if (m.contains("resumed") && m["resumed"].is_array())
    for (const json& r : m["resumed"])
      if (r.is_object() && r.contains("command_line") && r["command_line"].is_array())
        out.push_back(shell_line(r["command_line"]));
}

// The training commands in a manifest, as shell lines. A model trained in several runs, each
// started (--init-from) from the one before, lists the earlier runs' manifests under "lineage",
// earliest first (models/mnist-manifest.json): their commands come first.
std::vector<std::string> training_commands(const fs::path& manifest) {
  std::vector<std::string> out;
  std::error_code ec;
  if (!fs::is_regular_file(manifest, ec)) return out;
  std::ifstream in(manifest, std::ios::binary);
  const json m = json::parse(in, nullptr, false);
  if (m.is_discarded() || !m.is_object()) return out;
  if (m.contains("lineage") && m["lineage"].is_array()) {
    // How the runs connect (file names that have changed since, the exports between them).
    if (m.contains("lineage_note") && m["lineage_note"].is_string())
      out.push_back("# " + m["lineage_note"].get<std::string>());
    for (const json& run : m["lineage"]) append_run_commands(run, out);
  }
  append_run_commands(m, out);
  return out;
}

std::string eval_command_of(const json& eval) {
  if (eval.contains("manifest") && eval["manifest"].is_object() && eval["manifest"].contains("command_line") &&
      eval["manifest"]["command_line"].is_array())
    return shell_line(eval["manifest"]["command_line"]);
  return {};
}

// What the report's table reads of an evaluation.
json eval_summary(const json& e) {
  json s;
  s["accuracy"] = e["accuracy"];
  s["top2"] = e["top2"];
  s["confusion"] = e["confusion"];
  s["baselines"] = e["baselines"];
  s["full_image"] = e["full_image_accuracy"];
  s["greedy"] = e.contains("greedy_accuracy") ? e["greedy_accuracy"] : json(nullptr);
  s["runs"] = e.contains("runs") ? e["runs"] : json(nullptr);
  s["images"] = e.contains("images") ? e["images"] : json(nullptr);
  s["precision"] = e.contains("precision") ? e["precision"] : json(nullptr);
  s["revealed_fraction"] = e.contains("revealed_fraction") ? e["revealed_fraction"] : json(nullptr);
  // Which layers were learned (an agent without an action planner is its own goals-only baseline).
  if (e.contains("learned") && e["learned"].is_object() && e["learned"].contains("actions") &&
      e["learned"]["actions"].is_boolean())
    s["learned"] = {{"actions", e["learned"]["actions"]}};
  return s;
}

json history_json(const std::vector<learn::EpochMetrics>& history) {
  json rows = json::array();
  auto optional = [](const std::optional<double>& v) { return v ? json(*v) : json(nullptr); };
  for (const learn::EpochMetrics& m : history)
    rows.push_back({{"mode", learn::to_string(m.stage)},
                    {"epoch", m.epoch},
                    {"validation_accuracy", m.validation_accuracy},
                    {"validation_iid", optional(m.validation_iid)},
                    {"validation_goals_only", optional(m.validation_goals_only)},
                    {"validation_full_image", optional(m.validation_full_image)},
                    {"gradient_norm", optional(m.gradient_norm)},
                    {"seconds", m.seconds},
                    {"learning_rate", m.learning_rate}});
  return rows;
}

// What one of the report's extra evaluations (a budget point, a scenario world) runs.
struct AgentEval {
  worlds::World world;
  fs::path images, labels;
  int runs = 1, digits = 0;
  std::uint64_t seed = 1;
  int baseline_runs = 0;  // > 0: the baselines too (i.i.d. moves, goals only, full images, greedy)
};

// The learned agent of the model opened once (alone, unless `what` asks for its baselines), with
// its own progress line.
learn::EvalReport evaluate_agent(const ReportOptions& opt, const learn::Checkpoint& checkpoint, const AgentEval& what,
                                 const std::string& label) {
  ProgressLine progress("scout report", "rollouts");  // one per evaluation: each has its own clock
  learn::EvalConfig config;
  config.checkpoint = checkpoint.file();
  config.opened = checkpoint;  // every evaluation runs the networks opened once
  config.images = what.images;
  config.labels = what.labels;
  config.world = what.world;
  config.runs = what.runs;
  config.seed = what.seed;
  config.image_limit = what.digits;
  config.agent_only = what.baseline_runs == 0;
  if (what.baseline_runs > 0) config.baseline_runs = what.baseline_runs;
  config.precision = agent::parse_precision(opt.precision);
  config.on_progress = [&](const learn::EvalProgress& e) {
    progress.update(label, e.rollouts_done, e.rollouts_total, e.seconds);
  };
  return learn::evaluate(config, interrupt_token());
}

// The budget sweep: the same networks at other patch sizes m, and at other numbers of episodes E
// (T as trained), on the first `digits` test digits.
json budget_sweep(const ReportOptions& opt, const learn::Checkpoint& checkpoint, const fs::path& images,
                  const fs::path& labels, std::uint64_t seed, bool moves_only = false,
                  const std::string& label = "budget point") {
  const worlds::World& trained = checkpoint.info().config.world;
  struct Point {
    int patch, episodes;
    const char* kind;
  };
  std::vector<Point> points;
  if (!moves_only)
    for (int m : {2, 4, 6, 8, 10}) points.push_back({m, trained.task.episodes, "patch"});
  // A team of K robots shares the E episodes out: only the E that K divides.
  for (int e : {1, 2, 4, 6, 8})
    if (e % trained.team.robots == 0) points.push_back({trained.camera.patch_px, e, "moves"});
  json out;
  out["digits"] = opt.sweep_digits;
  out["runs"] = opt.sweep_runs;
  out["trained"] = {
      {"patch_px", trained.camera.patch_px}, {"episodes", trained.task.episodes}, {"steps", trained.task.steps}};
  out["seed"] = seed;
  out["points"] = json::array();
  int point = 0;
  for (const Point& p : points) {
    ++point;
    worlds::World world = trained;
    world.camera.patch_px = p.patch;
    world.task.episodes = p.episodes;
    const learn::EvalReport r =
        evaluate_agent(opt, checkpoint, {world, images, labels, opt.sweep_runs, opt.sweep_digits, seed},
                       fmt::format("{} {} of {}", label, point, points.size()));
    out["points"].push_back({{"kind", p.kind},
                             {"patch_px", p.patch},
                             {"episodes", p.episodes},
                             {"steps", world.task.steps},
                             {"accuracy", r.accuracy.mean},
                             {"ci95", r.accuracy.ci95},
                             {"revealed_fraction", r.revealed_fraction}});
    fmt::print("  budget: m = {:>2}, E x T = {} x {}: accuracy {:.4f}, {:.1f} % revealed\n", p.patch, p.episodes,
               world.task.steps, r.accuracy.mean, 100 * r.revealed_fraction);
    std::fflush(stdout);
  }
  return out;
}

// The robustness table (docs/SCENARIOS.md): the model in its own world and in each scenario world,
// on the first `digits` test digits, `runs` stochastic runs each, the same seed throughout.
json robustness(const ReportOptions& opt, const learn::Checkpoint& checkpoint, const std::vector<worlds::World>& worlds,
                const fs::path& images, const fs::path& labels, std::uint64_t seed) {
  json out;
  out["digits"] = opt.scenario_digits;
  out["runs"] = opt.scenario_runs;
  out["seed"] = seed;
  out["rows"] = json::array();
  std::vector<std::pair<std::string, worlds::World>> rows = {{"the model's world", checkpoint.info().config.world}};
  for (const worlds::World& w : worlds) rows.emplace_back(w.file.stem().string(), w);
  int row = 0;
  for (const auto& [name, world] : rows) {
    ++row;
    const learn::EvalReport r =
        evaluate_agent(opt, checkpoint, {world, images, labels, opt.scenario_runs, opt.scenario_digits, seed},
                       fmt::format("scenario {} of {}", row, rows.size()));
    out["rows"].push_back({{"world", name},
                           {"file", row == 1 ? std::string() : world.file.string()},
                           {"accuracy", r.accuracy.mean},
                           {"ci95", r.accuracy.ci95},
                           {"revealed_fraction", r.revealed_fraction},
                           {"stalled_moves", r.stalled_moves_per_rollout}});
    fmt::print("  robustness: {:<20} accuracy {:.4f} ± {:.4f}, {:.2f} stalled moves per rollout\n", name,
               r.accuracy.mean, r.accuracy.ci95, r.stalled_moves_per_rollout);
    std::fflush(stdout);
  }
  return out;
}

// Test episodes for the picture grid: the first test digits in order, driven by the agent with
// its goal maps recorded; half right and half wrong where there are enough wrong ones.
json test_episodes(const ReportOptions& opt, const learn::Checkpoint& checkpoint, const worlds::ImageSet& images,
                   const std::vector<std::uint8_t>& labels, std::uint64_t seed) {
  std::unique_ptr<learn::TrainedAgent> agent =
      learn::TrainedAgent::load(checkpoint, agent::parse_precision(opt.precision));
  // One robot per picture: a model trained in a team world is shown driving alone here (its
  // team's figures are the evaluation's).
  worlds::World world = agent->config().world;
  world.team = {};
  // The floors of the model's world (composed where it has a floor layout), keyed as the
  // evaluation keys its floors: the same floors and labels as the figures beside them.
  const worlds::FloorComposer composer(world, images.cols, images.rows);
  worlds::check_against_floor(world, composer.width_px(), composer.height_px());
  const grid::FloorFrame frame{
      .width_px = composer.width_px(), .height_px = composer.height_px(), .pixel_size_m = world.floor.pixel_size_m};
  const int n = std::min(images.count, 240);
  const std::size_t area = static_cast<std::size_t>(frame.area_px());
  const std::uint64_t floor_key = core::derive_seed(seed, streams::kEvalFloors);
  std::vector<std::uint8_t> floors(area * n);
  std::vector<int> floor_labels(n);
  for (int i = 0; i < n; ++i)
    floor_labels[i] = composer.compose(images, labels, i, floor_key, std::span(floors.data() + area * i, area));
  std::vector<grid::Cell> starts(n);
  std::vector<std::uint64_t> policy_seeds(n);
  std::vector<std::uint64_t> motion_seeds(n);
  for (int i = 0; i < n; ++i) {
    const std::uint64_t seed_i = core::derive_seed(seed, static_cast<std::uint64_t>(i));
    policy_seeds[i] = core::derive_seed(seed_i, streams::kRunPolicy);
    motion_seeds[i] = core::derive_seed(seed_i, streams::kRunMotion);
    core::Rng start_rng(core::derive_seed(seed_i, streams::kRunStart));
    starts[i] = env::draw_start(world, frame, motion_seeds[i], start_rng);
  }
  const auto engine = make_engine(world, frame, n);
  agent->begin(frame, world.camera.patch_px, policy_seeds, /*greedy=*/false, agent->learned().goals);
  const std::vector<learn::RolloutRecord> records = engine->run(floors, starts, motion_seeds, agent->policy());
  const std::vector<float> probabilities = agent->classify(engine->state(), n);
  const int classes = agent->classes();

  std::vector<int> right, wrong;
  for (int i = 0; i < n; ++i) {
    const float* p = probabilities.data() + static_cast<std::size_t>(i) * classes;
    const int predicted = static_cast<int>(std::max_element(p, p + classes) - p);
    (predicted == floor_labels[i] ? right : wrong).push_back(i);
  }
  const int want_wrong = std::min<int>(opt.episodes / 2, static_cast<int>(wrong.size()));
  const int want_right = std::min<int>(opt.episodes - want_wrong, static_cast<int>(right.size()));
  std::vector<int> chosen(right.begin(), right.begin() + want_right);
  chosen.insert(chosen.end(), wrong.begin(), wrong.begin() + want_wrong);

  json out = json::array();
  const int last_episode = world.task.episodes - 1;
  for (int i : chosen) {
    const learn::RolloutRecord& r = records[i];
    const float* p = probabilities.data() + static_cast<std::size_t>(i) * classes;
    json e;
    e["index"] = i;
    e["label"] = floor_labels[i];
    e["prediction"] = static_cast<int>(std::max_element(p, p + classes) - p);
    e["probabilities"] = std::vector<float>(p, p + classes);
    e["width"] = frame.width_px;
    e["height"] = frame.height_px;
    e["patch_px"] = world.camera.patch_px;
    e["floor"] = std::vector<int>(floors.begin() + static_cast<std::ptrdiff_t>(area * i),
                                  floors.begin() + static_cast<std::ptrdiff_t>(area * (i + 1)));
    e["seen"] = r.snapshots.back().seen;
    json path = json::array();
    for (const grid::Cell& c : r.path) path.push_back({c.x(), c.y()});
    e["path"] = path;
    json goals = json::array();
    for (const learn::StepRecord& s : r.steps)
      if (s.step == 0) goals.push_back({s.goal.x(), s.goal.y()});
    e["goals"] = goals;
    if (agent->learned().goals) {
      e["goal_map"] = agent->goal_map(i, last_episode);
      e["goal_map_episode"] = last_episode + 1;
    }
    out.push_back(e);
  }
  return out;
}

std::string cpu_name() {
  std::ifstream in("/proc/cpuinfo");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("model name", 0) == 0) {
      const std::size_t colon = line.find(':');
      if (colon != std::string::npos) return line.substr(line.find_first_not_of(' ', colon + 1));
    }
  return "an unknown CPU";
}

fs::path report_script() {
  if (const char* env = std::getenv("SCOUT_REPORT_SCRIPT"); env != nullptr && *env != '\0') return env;
  return core::files_root() / "tools" / "report" / "scout_report.py";
}

std::string python_interpreter() {
  if (const char* env = std::getenv("SCOUT_PYTHON"); env != nullptr && *env != '\0') return env;
  // An installed program's `scout` command sets SCOUT_PYTHON to the Python it is installed for
  // (python/_scout_command.py); run by its path, the python3 on PATH (an active environment's).
  if (core::installed_files()) return "python3";
  // The project's environment (.venv/, with matplotlib from PyPI; another python3 on PATH may lack
  // it).
  return SCOUT_PYTHON;
}

// Another model's row in the table: LABEL=EVAL.json.
struct Compared {
  std::string label;
  fs::path file;
  json eval;
  fs::path model;                            // the evaluated model, where it is on this machine ("": not found)
  std::vector<learn::EpochMetrics> history;  // its training history, drawn beside the model's
};

// The model an evaluation names: its path as scout eval was given it (relative to where it ran,
// usually the source tree), else a file of that name beside the evaluation; "" where neither is.
fs::path evaluated_model(const json& eval, const fs::path& eval_file) {
  if (!eval.contains("checkpoint") || !eval["checkpoint"].is_string()) return {};
  const fs::path given = eval["checkpoint"].get<std::string>();
  std::error_code ec;
  // A model evaluated as X.pt (Scout's format 1) is found as the X.safetensors it was converted to.
  for (const fs::path& name : {given, fs::path(given).replace_extension(learn::kCheckpointExtension)}) {
    if (fs::exists(name, ec)) return name;
    const fs::path beside = eval_file.parent_path() / name.filename();
    if (fs::exists(beside, ec)) return beside;
  }
  return {};
}

// The SHA-256s an evaluation of `checkpoint` may name: the file's own, and that of the .pt file it
// was converted from (its manifest's converted_from), whose evaluation holds for the same weights.
std::vector<std::string> checkpoint_digests(const fs::path& checkpoint, const learn::Checkpoint& opened) {
  std::vector<std::string> digests = {core::sha256_hex(checkpoint)};
  const json manifest = json::parse(opened.info().manifest.empty() ? "{}" : opened.info().manifest, nullptr, false);
  if (manifest.is_object() && manifest.contains("converted_from") && manifest["converted_from"].is_object() &&
      manifest["converted_from"].contains("sha256") && manifest["converted_from"]["sha256"].is_string())
    digests.push_back(manifest["converted_from"]["sha256"].get<std::string>());
  return digests;
}

// Everything a report reads, read and checked before minutes of work.
struct ReportInputs {
  explicit ReportInputs(learn::Checkpoint model_checkpoint) : opened(std::move(model_checkpoint)) {}
  learn::Checkpoint opened;  // the model, opened once for the evaluation, the sweep and the episodes
  fs::path model, checkpoint;
  std::string checkpoint_sha;
  std::uint64_t seed = 1;
  fs::path images, labels, script, eval_file;
  std::vector<Compared> compared;
  json eval;                             // the model's evaluation; null: the report evaluates it
  std::vector<worlds::World> scenarios;  // --scenarios, loaded
  std::vector<std::pair<std::string, learn::Checkpoint>> sweep_compared;  // --sweep-compare, opened
  struct ScenarioAgent {
    worlds::World world;
    std::string model;
    learn::Checkpoint opened;
  };
  std::vector<ScenarioAgent> scenario_agents;  // --scenario-agent, loaded and opened
  worlds::ImageSet test_images;
  std::vector<std::uint8_t> test_labels;
};

// "LEFT=RIGHT" split at the first '=', both sides non-empty; else one line naming the option.
std::pair<std::string, std::string> split_pair(const std::string& entry, const char* option, const char* expected) {
  const std::size_t eq = entry.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == entry.size())
    throw InputError(fmt::format("{}: expected {}, got \"{}\"", option, expected, entry));
  return {entry.substr(0, eq), entry.substr(eq + 1)};
}

std::vector<Compared> read_compared(const ReportOptions& opt) {
  std::vector<Compared> compared;
  for (const std::string& entry : opt.compare) {
    const std::size_t eq = entry.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == entry.size())
      throw InputError(fmt::format("--compare: expected LABEL=EVAL.json, got \"{}\"", entry));
    Compared c{entry.substr(0, eq), entry.substr(eq + 1), {}, {}, {}};
    c.eval = read_json_file(c.file, "--compare");
    check_eval_json(c.eval, c.file);
    c.model = evaluated_model(c.eval, c.file);
    // A model found is opened like any other (a file that is not a Scout model is refused here,
    // before minutes of work); its history draws its curve beside this model's.
    if (!c.model.empty()) c.history = learn::open_checkpoint(learn::resolve_checkpoint(c.model)).info().history;
    compared.push_back(std::move(c));
  }
  return compared;
}

// The model's evaluation beside it (or --eval), held to the model and to the test digits.
void read_model_eval(const ReportOptions& opt, ReportInputs& in) {
  std::error_code ec;
  in.eval_file = opt.eval_file;
  if (in.eval_file.empty() && fs::is_regular_file(eval_beside(in.model), ec)) in.eval_file = eval_beside(in.model);
  if (in.eval_file.empty()) return;
  const fs::path& eval_file = in.eval_file;
  json& eval = in.eval;
  eval = read_json_file(eval_file, "--eval");
  check_eval_json(eval, eval_file);
  const std::vector<std::string> digests = checkpoint_digests(in.checkpoint, in.opened);
  if (eval.contains("manifest") && eval["manifest"].is_object() && eval["manifest"].contains("checkpoint_sha256") &&
      std::find(digests.begin(), digests.end(), eval["manifest"]["checkpoint_sha256"]) == digests.end())
    throw InputError(fmt::format("--eval: {}: manifest.checkpoint_sha256: expected {} (the SHA-256 of {}), got {}",
                                 eval_file.string(), in.checkpoint_sha, in.checkpoint.string(),
                                 eval["manifest"]["checkpoint_sha256"].dump()));
  // The table says which digits its figures come from: an evaluation of other digits (the
  // 10,000-digit set's test split, say) is refused rather than shown as the official test set.
  const std::vector<std::string> evaluated = evaluated_data(eval);
  for (const fs::path& file : {in.images, in.labels}) {
    const std::string sha = core::sha256_hex(file);
    if (std::find(evaluated.begin(), evaluated.end(), sha) == evaluated.end())
      throw InputError(fmt::format(
          "--eval: {}: manifest.data_sha256: expected an evaluation of {} (SHA-256 {}), got one of other digits "
          "(evaluate again with scout eval, or give --images and --labels)",
          eval_file.string(), file.string(), sha));
  }
}

ReportInputs gather_report_inputs(const ReportOptions& opt) {
  if (opt.episodes < 0 || opt.episodes > 64)
    throw InputError(fmt::format("--episodes: expected 0..64, got {}", opt.episodes));
  const fs::path checkpoint = learn::resolve_checkpoint(opt.model);
  ReportInputs in(learn::open_checkpoint(checkpoint));
  in.model = opt.model;
  in.checkpoint = checkpoint;
  in.seed = opt.seed.empty() ? 1 : parse_seed(opt.seed);
  const fs::path data_root = opt.data_root.empty() ? worlds::default_data_root() : fs::path(opt.data_root);
  const fs::path test_folder = worlds::dataset_folder("mnist", data_root);
  in.images = opt.images.empty() ? test_folder / "t10k-images-idx3-ubyte" : fs::path(opt.images);
  in.labels = opt.labels.empty() ? test_folder / "t10k-labels-idx1-ubyte" : fs::path(opt.labels);
  if (opt.images.empty() != opt.labels.empty())
    throw InputError("--images and --labels: expected both or neither (default: the official MNIST test set)");
  in.script = report_script();
  std::error_code ec;
  if (!fs::is_regular_file(in.script, ec))
    throw InputError(
        fmt::format("{}: the report's plotting script is missing (set SCOUT_REPORT_SCRIPT)", in.script.string()));
  in.compared = read_compared(opt);
  for (const std::string& file : opt.scenarios) in.scenarios.push_back(worlds::load_world(file));
  for (const std::string& entry : opt.sweep_compare) {
    auto [label, model] = split_pair(entry, "--sweep-compare", "LABEL=MODEL");
    in.sweep_compared.emplace_back(label, learn::open_checkpoint(learn::resolve_checkpoint(model)));
  }
  for (const std::string& entry : opt.scenario_agents) {
    auto [world, model] = split_pair(entry, "--scenario-agent", "WORLD.yaml=MODEL");
    in.scenario_agents.push_back(
        {worlds::load_world(world), model, learn::open_checkpoint(learn::resolve_checkpoint(model))});
  }
  in.checkpoint_sha = core::sha256_hex(checkpoint);
  read_model_eval(opt, in);
  worlds::LabeledImages test = worlds::read_labeled_idx(in.images, in.labels);
  in.test_images = std::move(test.images);
  in.test_labels = std::move(test.labels);
  return in;
}

// The model evaluated here (no evaluation beside it): eval.json in the report's folder.
json evaluate_model(const ReportOptions& opt, const ReportInputs& in, const Context& context, const OutputDir& out) {
  fmt::print("  evaluating on {} digits, {} runs (no evaluation beside the model)\n", in.test_images.count, opt.runs);
  std::fflush(stdout);
  learn::EvalConfig config;
  config.checkpoint = in.checkpoint;
  config.opened = in.opened;
  config.images = in.images;
  config.labels = in.labels;
  config.runs = opt.runs;
  config.seed = in.seed;
  config.precision = agent::parse_precision(opt.precision);
  ProgressLine progress("scout report", "rollouts");
  config.on_progress = [&](const learn::EvalProgress& e) {
    progress.update(e.run > 0 ? fmt::format("evaluating, run {} of {}", e.run, e.runs) : "evaluating, greedy run",
                    e.rollouts_done, e.rollouts_total, e.seconds);
  };
  const learn::EvalReport r = learn::evaluate(config, interrupt_token());
  json eval = eval_document(learn::report_json(r), context.argv, in.checkpoint, in.images, in.labels, 1);
  write_file_atomic(out.path() / "eval.json", eval.dump(2) + "\n");
  return eval;
}

json paper_figures() {
  json glimpse_models = json::array();
  for (const GlimpsePoint& g : kGlimpsePoints)
    glimpse_models.push_back({{"source", g.source},
                              {"accuracy", g.accuracy},
                              {"glimpses", g.glimpses},
                              {"side", g.side},
                              {"revealed_fraction", std::min(1.0, g.glimpses * g.side * g.side / 784.0)}});
  return {{"accuracy", kPaperAccuracy},    {"ci95", kPaperCi95},         {"top2", kPaperTop2},
          {"full_image", kPaperFullImage}, {"transfer", kPaperTransfer}, {"glimpse_models", glimpse_models}};
}

json compared_rows(const std::vector<Compared>& compared) {
  json rows = json::array();
  for (const Compared& c : compared) {
    json e;
    e["label"] = c.label;
    e["eval"] = eval_summary(c.eval);
    e["eval_source"] = c.file.string();
    e["eval_command"] = eval_command_of(c.eval);
    if (c.eval.contains("checkpoint") && c.eval["checkpoint"].is_string()) {
      // The manifest beside the model, or beside the evaluation where the model is not here.
      const fs::path model = !c.model.empty()
                                 ? c.model
                                 : c.file.parent_path() / fs::path(c.eval["checkpoint"].get<std::string>()).filename();
      e["train_commands"] = training_commands(manifest_beside(model));
    }
    if (!c.model.empty()) e["history"] = history_json(c.history);
    rows.push_back(e);
  }
  return rows;
}

// The budget sweep into the report's data, and the paper's and this model's points on it.
void add_sweep(const ReportOptions& opt, const ReportInputs& in, json& data) {
  fmt::print("  budget sweep: {} digits, {} runs per point\n", std::min(opt.sweep_digits, in.test_images.count),
             opt.sweep_runs);
  std::fflush(stdout);
  data["sweep"] = budget_sweep(opt, in.opened, in.images, in.labels, in.seed);
  data["sweep"]["digits"] = std::min(opt.sweep_digits, in.test_images.count);
  // The paper's task on the sweep's axis: its point sits where this model's m = 6, 4 x 5 does.
  for (const json& p : data["sweep"]["points"])
    if (p["patch_px"] == 6 && p["episodes"] == 4 && p["steps"] == 5)
      data["paper"]["revealed_fraction"] = p["revealed_fraction"];
  // Other models' budget curves (E x T at their m), drawn beside this model's.
  data["sweep"]["compared"] = json::array();
  for (const auto& [label, checkpoint] : in.sweep_compared)
    data["sweep"]["compared"].push_back(
        {{"label", label},
         {"points", budget_sweep(opt, checkpoint, in.images, in.labels, in.seed, /*moves_only=*/true,
                                 fmt::format("{}: budget point", label))["points"]}});
  const worlds::World& world = in.opened.info().config.world;
  if (data["model"]["revealed_fraction"].is_null())
    for (const json& p : data["sweep"]["points"])
      if (p["patch_px"] == world.camera.patch_px && p["episodes"] == world.task.episodes)
        data["model"]["revealed_fraction"] = p["revealed_fraction"];
}

// Each scenario agent in the world it was trained for, beside its baselines there (random moves:
// i.i.d. goals and axes; goals only: its goals, i.i.d. axes; both with its classifier) and beside
// this model in that world: accuracy, the share of the floor seen and the moves per rollout that
// did not arrive (blocked by an obstacle or a teammate), on the robustness table's digits and runs.
// The agent's evaluation with baselines also makes the full-image and greedy passes scout eval
// makes (about 3R + 1 passes instead of R); the report keeps the baselines only.
json scenario_agents(const ReportOptions& opt, const ReportInputs& in) {
  json out;
  out["digits"] = std::min(opt.scenario_digits, in.test_images.count);
  out["runs"] = opt.scenario_runs;
  out["seed"] = in.seed;
  out["rows"] = json::array();
  int row = 0;
  const std::size_t rows = in.scenario_agents.size();
  for (const ReportInputs::ScenarioAgent& a : in.scenario_agents) {
    ++row;
    AgentEval task{a.world, in.images, in.labels, opt.scenario_runs, opt.scenario_digits, in.seed};
    task.baseline_runs = opt.scenario_runs;
    const learn::EvalReport agent =
        evaluate_agent(opt, a.opened, task, fmt::format("scenario agent {} of {}", row, rows));
    task.baseline_runs = 0;
    const learn::EvalReport model =
        evaluate_agent(opt, in.opened, task, fmt::format("this model in scenario {} of {}", row, rows));
    const bool goals_only = !std::isnan(agent.goals_only_accuracy);  // NaN: the agent has no learned goals
    out["rows"].push_back({{"world", a.world.file.stem().string()},
                           {"agent", a.model},
                           {"accuracy", agent.accuracy.mean},
                           {"ci95", agent.accuracy.ci95},
                           {"revealed_fraction", agent.revealed_fraction},
                           {"stalled_moves", agent.stalled_moves_per_rollout},
                           {"baseline_runs", agent.baseline_runs},
                           {"iid_accuracy", agent.iid_accuracy},
                           {"iid_ci95", agent.iid_ci95},
                           {"goals_only_accuracy", goals_only ? json(agent.goals_only_accuracy) : json(nullptr)},
                           {"goals_only_ci95", goals_only ? json(agent.goals_only_ci95) : json(nullptr)},
                           {"model_accuracy", model.accuracy.mean},
                           {"model_ci95", model.accuracy.ci95},
                           {"model_stalled_moves", model.stalled_moves_per_rollout},
                           {"model_revealed_fraction", model.revealed_fraction}});
    fmt::print(
        "  scenario agent {} in {}: accuracy {:.4f}, random moves {:.4f}, {:.2f} stalled moves per rollout (this "
        "model {:.4f}, {:.2f})\n",
        a.model, a.world.file.stem().string(), agent.accuracy.mean, agent.iid_accuracy, agent.stalled_moves_per_rollout,
        model.accuracy.mean, model.stalled_moves_per_rollout);
    std::fflush(stdout);
  }
  return out;
}

// What report-data.json holds: the paper's figures, this model's evaluation and history, the
// compared rows, the budget sweep and the test episodes.
json report_data(const ReportOptions& opt, const ReportInputs& in, const json& eval, const std::string& eval_source,
                 const Context& context) {
  json data;
  data["command"] = shell_line(json(context.argv));
  data["cpu"] = cpu_name();
  data["paper"] = paper_figures();
  json m;
  m["label"] = fmt::format("Scout: {}", in.model.filename().string());
  m["path"] = in.model.string();
  m["eval"] = eval_summary(eval);
  m["eval"]["data"] = fmt::format("{} ({} digits)", in.images.string(), eval.value("images", in.test_images.count));
  m["eval_source"] = eval_source;
  m["eval_command"] = eval_command_of(eval);
  m["train_commands"] = training_commands(manifest_beside(in.model));
  m["history"] = history_json(in.opened.info().history);
  m["revealed_fraction"] = eval.contains("revealed_fraction") ? eval["revealed_fraction"] : json(nullptr);
  data["model"] = m;
  data["compare"] = compared_rows(in.compared);
  if (opt.sweep_digits > 0) add_sweep(opt, in, data);
  if (!in.scenarios.empty()) {
    fmt::print("  robustness: {} digits, {} runs per world\n", std::min(opt.scenario_digits, in.test_images.count),
               opt.scenario_runs);
    data["robustness"] = robustness(opt, in.opened, in.scenarios, in.images, in.labels, in.seed);
    data["robustness"]["digits"] = std::min(opt.scenario_digits, in.test_images.count);
  }
  if (!in.scenario_agents.empty()) data["scenario_agents"] = scenario_agents(opt, in);
  data["episode_seed"] = in.seed;
  data["episodes"] =
      opt.episodes > 0 ? test_episodes(opt, in.opened, in.test_images, in.test_labels, in.seed) : json::array();
  return data;
}

// The figures and REPORT.md, drawn by the plotting script from report-data.json alone.
void draw_figures(const ReportInputs& in, const OutputDir& out) {
  const core::ProgramResult plot = core::run_program(
      {python_interpreter(), in.script.string(), (out.path() / "report-data.json").string(), out.path().string()},
      fs::current_path(), out.path() / ".plot.log");
  interrupt_token().throw_if_requested();  // a Ctrl-C reached the plotting script too
  if (plot.failed()) {
    const bool missing_module = plot.last_line.find("ModuleNotFoundError") != std::string::npos;
    throw InputError(
        fmt::format("{} {} failed {}{}", python_interpreter(), in.script.string(), plot.describe(python_interpreter()),
                    missing_module ? "; run ./scripts/setup.sh (it installs matplotlib into .venv/)" : ""));
  }
  std::error_code ec;
  fs::remove(out.path() / ".plot.log", ec);
}

void report_command(const ReportOptions& opt, const Context& context) {
  const auto t0 = core::Clock::now();
  const ReportInputs in = gather_report_inputs(opt);
  std::vector<fs::path> inputs = {in.model, in.checkpoint, in.images, in.labels};
  if (!in.eval_file.empty()) inputs.push_back(in.eval_file);
  for (const Compared& c : in.compared) inputs.push_back(c.file);
  OutputDir out(opt.out, opt.overwrite, inputs);

  fmt::print("scout report: {} -> {}\n", in.model.string(), opt.out);
  std::fflush(stdout);
  const learn::CheckpointInfo& info = in.opened.info();
  announce_model_precision(opt.precision, info.config.precision);
  const bool evaluate_here = in.eval.is_null();
  const json eval = evaluate_here ? evaluate_model(opt, in, context, out) : in.eval;
  const std::string eval_source = evaluate_here ? "eval.json (evaluated by this report)" : in.eval_file.string();

  json data = report_data(opt, in, eval, eval_source, context);
  interrupt_token().throw_if_requested();
  data["seconds"] = core::seconds_since(t0);
  write_file_atomic(out.path() / "report-data.json", data.dump(1) + "\n");
  draw_figures(in, out);
  json manifest = make_manifest(context.argv, worlds::to_yaml(info.config.world), {in.images, in.labels}, "");
  manifest["checkpoint"] = {{"path", in.model.string()}, {"sha256", in.checkpoint_sha}};
  write_file_atomic(out.path() / kManifestFile, manifest.dump(2) + "\n");
  out.commit();
  fmt::print("report: {} ({:.0f} s)\n", (fs::path(out.target()) / "REPORT.md").string(), core::seconds_since(t0));
}

}  // namespace

void add_report_command(CLI::App& app, const Context& context) {
  auto opt = std::make_shared<ReportOptions>();
  auto* cmd = app.add_subcommand(
      "report",
      "The paper's table and figures for a model or run: DIR/REPORT.md with the paper's figures beside Scout's, "
      "accuracy against epochs with both baselines, the confusion matrix, test episodes and accuracy against the "
      "observation budget (figures drawn by matplotlib on the project's Python, .venv/bin/python; SCOUT_PYTHON "
      "names another).");
  cmd->add_option("model", opt->model,
                  "A model file (models/mnist.safetensors) or a run folder (RUN/checkpoint.safetensors)")
      ->required();
  cmd->add_option("--out", opt->out, "Report folder to create (must not exist unless --overwrite)")->required();
  cmd->add_option("--eval", opt->eval_file,
                  "The model's evaluation (scout eval --json); default: X-test-eval.json beside X.safetensors or "
                  "RUN/test-eval.json, else the report evaluates it");
  cmd->add_option("--images", opt->images, "Test images (default: the official MNIST test set of data set mnist)");
  cmd->add_option("--labels", opt->labels, "Test labels (with --images)");
  cmd->add_option("--data", opt->data_root,
                  "Data folder (default: $SCOUT_DATA, else <source>/data; installed: ~/.local/share/scout)");
  cmd->add_option("--runs", opt->runs, "R: stochastic runs when the report evaluates the model")
      ->capture_default_str()
      ->check(decimal_in(1, 1000));
  cmd->add_option("--compare", opt->compare,
                  "Another model's row in the table: LABEL=EVAL.json (scout eval --json; repeatable)");
  cmd->add_option("--sweep-compare", opt->sweep_compare,
                  "Another model's budget curve (E x T at its m) beside this model's: LABEL=MODEL (repeatable)");
  cmd->add_option("--sweep-digits", opt->sweep_digits, "Test digits per point of the budget sweep (0: no sweep)")
      ->capture_default_str()
      ->check(decimal_in(0, 1000000));
  cmd->add_option("--sweep-runs", opt->sweep_runs, "Stochastic runs per point of the budget sweep")
      ->capture_default_str()
      ->check(decimal_in(1, 100));
  cmd->add_option("--scenarios", opt->scenarios,
                  "World files of the robustness table: the model in each, beside its own world (e.g. "
                  "worlds/scenarios/*.yaml; docs/SCENARIOS.md)");
  cmd->add_option("--scenario-agent", opt->scenario_agents,
                  "An agent trained for a scenario world, in a table beside its baselines (random moves, goals only) "
                  "and this model there, with the share of the floor seen and the moves that did not arrive: "
                  "WORLD.yaml=MODEL (repeatable; --scenario-runs runs each, of the agent and of each baseline)");
  cmd->add_option("--scenario-digits", opt->scenario_digits, "Test digits per world of the robustness table")
      ->capture_default_str()
      ->check(decimal_in(1, 1000000));
  cmd->add_option("--scenario-runs", opt->scenario_runs, "Stochastic runs per world of the robustness table")
      ->capture_default_str()
      ->check(decimal_in(1, 100));
  cmd->add_option("--episodes", opt->episodes, "Test episodes in the picture grid (half right, half wrong)")
      ->capture_default_str()
      ->check(decimal_in(0, 64));
  cmd->add_option("--seed", opt->seed, "Seed of the evaluation, the sweep and the episodes (default 1)")
      ->check(seed_validator());
  add_model_precision_option(*cmd, opt->precision);
  cmd->add_flag("--overwrite", opt->overwrite, "Replace an existing report folder");
  add_camera_backend_option(*cmd);
  cmd->callback([opt, &context] { report_command(*opt, context); });
}

}  // namespace scout::tools
