// scout run: headless rollouts of a world, with trajectory.json, images and manifest.json; driven
// by mode (i), or by a trained agent with --checkpoint.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <span>

#include "core/digest.hpp"
#include "core/random.hpp"
#include "core/timing.hpp"
#include "env/runs.hpp"
#include "learn/checkpoint.hpp"
#include "learn/rollout.hpp"
#include "learn/trained_agent.hpp"
#include "render/snapshot.hpp"
#include "render/video.hpp"
#include "tools/commands.hpp"
#include "tools/network_options.hpp"
#include "tools/output.hpp"
#include "tools/run_video.hpp"
#include "worlds/dataset.hpp"
#include "worlds/floors.hpp"

namespace scout::tools {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

/// The robots of one command run together at most this many at a time (a training batch).
constexpr int kBatchRobots = 240;

struct RunOptions {
  std::string world;
  std::string out;
  std::string data_root;
  std::string seed;  // empty: the world file's
  int count = 1;
  bool overwrite = false;
  bool no_images = false;
  int scale = 10;
  std::string checkpoint;  // empty: mode (i)
  std::string precision = "auto";
  bool greedy = false;
  bool heat_map = false;
  std::string video;  // empty: none
  double fps = 30;
};

std::vector<env::PlannedRun> plan_runs(const worlds::World& world, const worlds::FloorSet& floors,
                                       const grid::FloorFrame& frame, std::uint64_t seed, int count) {
  const env::RunSequence sequence(world, frame, floors.size(), seed);
  std::vector<env::PlannedRun> runs(count);
  for (int k = 0; k < count; ++k) runs[k] = sequence.run(static_cast<std::uint64_t>(k));
  return runs;
}

json cell_json(const grid::Cell& c) { return json::array({c.x(), c.y()}); }

// A robot's moves, one line each, as the JSON array's text.
std::string steps_json(const learn::RolloutRecord& record) {
  std::string text = "[";
  for (const learn::StepRecord& s : record.steps) {
    json step;
    step["episode"] = s.episode;
    step["step"] = s.step;
    step["goal"] = cell_json(s.goal);
    step["axis"] = grid::to_string(s.axis);
    step["sampled"] = s.sampled;
    step["command"] = cell_json(s.command);
    step["ticks"] = s.result.ticks;
    step["settled"] = s.result.settled;
    // Only where a scenario section made them happen, so that an exact world's file is as before.
    if (s.result.pushed) step["pushed"] = true;
    if (s.result.blocked) step["blocked"] = true;
    step["pose_m"] = json::array({s.pose_m.x(), s.pose_m.y()});
    step["grid_pose"] = cell_json(s.grid_pose);
    step["revealed_px"] = s.revealed_px;
    text += (&s == record.steps.data() ? "\n    " : ",\n    ") + step.dump();
  }
  return text + "\n  ]";
}

// One run as JSON text: its fields on one line, then one line per step (readable, and grep-able
// by step, in files of any size). A team's first robot is the run's own start and steps; the
// others follow under "teammates" ({"start", "steps"} each; revealed_px counts the team's).
// `probabilities`: the trained agent's pi_c at the end (empty without --checkpoint, and then the
// text is exactly what it always was).
std::string run_json(const env::PlannedRun& run, std::span<const learn::RolloutRecord> team,
                     const worlds::FloorSet& floors, std::span<const float> probabilities) {
  const learn::RolloutRecord& record = team.front();
  json j;
  j["seed"] = run.seed;
  j["dataset"] = floors.source;
  j["split"] = floors.split ? json(worlds::to_string(*floors.split)) : json(nullptr);
  j["index"] = run.index;
  // A composed floor (floor.layout): its size and where its digits and clutter went, so that the
  // floor can be rebuilt and the robot's search judged (only then: other worlds' files are as before).
  const worlds::FloorPlan plan = floors.composer.plan(run.index, floors.size(), run.floor_key);
  int label = floors.labels[run.index];
  if (!floors.composer.copies_images()) {
    label = 0;
    j["floor_px"] = json::array({floors.width_px(), floors.height_px()});
    json digits = json::array();
    for (int d = 0; d < plan.digit_count; ++d) {
      digits.push_back({{"index", plan.digits[d].image},
                        {"label", floors.labels[plan.digits[d].image]},
                        {"at", json::array({plan.digits[d].x, plan.digits[d].y})}});
      label += floors.labels[plan.digits[d].image];
    }
    j["digits"] = digits;
    json clutter = json::array();
    for (const worlds::FloorPlan::Piece& c : plan.clutter)
      clutter.push_back(
          {{"index", c.image}, {"from", json::array({c.from_x, c.from_y})}, {"at", json::array({c.x, c.y})}});
    if (!plan.clutter.empty()) j["clutter"] = clutter;
  }
  j["label"] = label >= 0 ? json(label) : json(nullptr);
  j["start"] = cell_json(record.start);
  if (!probabilities.empty()) {
    j["prediction"] = std::max_element(probabilities.begin(), probabilities.end()) - probabilities.begin();
    j["probabilities"] = std::vector<float>(probabilities.begin(), probabilities.end());
  }
  std::string text = j.dump();
  text.pop_back();  // the closing brace: the steps follow
  text += ", \"steps\": " + steps_json(record);
  if (team.size() > 1) {
    text += ", \"teammates\": [";
    for (std::size_t k = 1; k < team.size(); ++k)
      text += std::string(k == 1 ? "\n  " : ",\n  ") + "{\"start\": " + cell_json(team[k].start).dump() +
              ", \"steps\": " + steps_json(team[k]) + "}";
    text += "\n  ]";
  }
  return text + "}";
}

/// What a trained agent adds to a run's pictures: the class-probability bars and, per episode,
/// the goal distribution pi_g it drew that episode's goal from.
struct AgentOverlay {
  std::span<const float> class_probabilities;  ///< empty: no bars
  const learn::TrainedAgent* agent = nullptr;  ///< set: heat maps of robot `robot`
  int robot = 0;
};

/// What the world's scenario sections add to a run's pictures.
struct ScenarioMarks {
  bool true_path = false;                   ///< imperfect motion or pushes: where the robot really went
  const std::uint8_t* obstacles = nullptr;  ///< H * W obstacle mask; null: none
  const std::uint8_t* slip = nullptr;       ///< H * W slip-zone mask; null: none
  bool faint_floor = false;                 ///< a composed floor: its unseen part shows faintly
  render::WideView wide{};                  ///< the camera's wider view (px 0: none)
};

// The poses robot `record` had visited by snapshot `snap`, and, where motion is imperfect, its
// centre's true path up to that snapshot's last move.
void robot_paths(const learn::RolloutRecord& record, const learn::SnapshotRecord& snap, bool true_path,
                 std::vector<render::PixelPose>& path, std::vector<render::FloorPoint>& ticks_path) {
  for (std::size_t p = 0; p < snap.path_length; ++p) path.push_back({.x = record.path[p].x(), .y = record.path[p].y()});
  if (!true_path) return;
  std::size_t ticks = 1;
  for (std::size_t k = 0; k + 1 < snap.path_length && k < record.steps.size(); ++k)
    ticks += static_cast<std::size_t>(record.steps[k].result.ticks);
  for (std::size_t t = 0; t < std::min(ticks, record.tick_path_px.size()); ++t)
    ticks_path.push_back(
        {static_cast<float>(record.tick_path_px[t].x()), static_cast<float>(record.tick_path_px[t].y())});
}

// The run's pictures: one at each episode's start and one at the end; a team's robots all in
// each (the first robot's snapshots carry the team's seen pixels).
void write_images(const fs::path& folder, int run_number, std::span<const learn::RolloutRecord> team,
                  const std::uint8_t* floor, const grid::FloorFrame& frame, int patch_px, int scale,
                  const ScenarioMarks& marks, const AgentOverlay& overlay, std::vector<std::string>& written) {
  const learn::RolloutRecord& record = team.front();
  for (std::size_t i = 0; i < record.snapshots.size(); ++i) {
    const learn::SnapshotRecord& snap = record.snapshots[i];
    render::Snapshot s;
    s.floor = floor;
    s.width_px = frame.width_px;
    s.height_px = frame.height_px;
    s.revealed = snap.seen.data();
    s.faint_unseen_floor = marks.faint_floor;
    s.patch_px = patch_px;
    if (!snap.wide_seen.empty()) {
      s.wide_revealed = snap.wide_revealed.data();
      s.wide_seen = snap.wide_seen.data();
      s.wide = marks.wide;
    }
    s.robot = {.x = snap.robot.x(), .y = snap.robot.y()};
    if (snap.goal) s.goal = render::PixelPose{.x = snap.goal->x(), .y = snap.goal->y()};
    robot_paths(record, snap, marks.true_path, s.path, s.true_path);
    for (std::size_t k = 1; k < team.size(); ++k) {
      const learn::SnapshotRecord& mate = team[k].snapshots[i];
      render::Snapshot::Teammate& t = s.teammates.emplace_back();
      t.robot = {.x = mate.robot.x(), .y = mate.robot.y()};
      if (mate.goal) t.goal = render::PixelPose{.x = mate.goal->x(), .y = mate.goal->y()};
      robot_paths(team[k], mate, marks.true_path, t.path, t.true_path);
    }
    s.obstacles = marks.obstacles;
    s.slip = marks.slip;
    s.scale = scale;
    const bool final_image = !snap.goal;
    // The bars show the final prediction on every picture of the run (the classifier is asked
    // once, after the last move, as in training and evaluation).
    s.class_probabilities = overlay.class_probabilities;
    if (overlay.agent && !final_image) s.goal_probabilities = overlay.agent->goal_map(overlay.robot, snap.episode);
    const std::string name = final_image ? fmt::format("run{:03d}_final.png", run_number)
                                         : fmt::format("run{:03d}_episode{}.png", run_number, snap.episode);
    render::write_png(folder / name, render::draw_snapshot(s));
    written.push_back(name);
  }
}

// A bad video path is refused before any work, like a bad --out.
void check_video_options(const RunOptions& opt) {
  if (opt.video.empty()) return;
  render::check_video_path("--video", opt.video);
  if (opt.fps > 50 && render::check_video_path("--video", opt.video) == render::VideoFormat::Gif)
    throw InputError(
        fmt::format("--fps: expected at most 50 for a GIF (browsers slow faster ones down), got {}", opt.fps));
  // --out is replaced as a whole when it is committed: a video inside it would be lost.
  std::error_code ec;
  const fs::path video = fs::weakly_canonical(fs::absolute(opt.video), ec);
  const fs::path out = fs::weakly_canonical(fs::absolute(opt.out), ec);
  const auto [stop, _] = std::mismatch(out.begin(), out.end(), video.begin(), video.end());
  if (!ec && stop == out.end())
    throw InputError(
        fmt::format("--video: {}: expected a file outside --out's folder {} (written as a whole)", opt.video, opt.out));
}

// What scout run drives: the trained agent (none: mode (i)), the world and its floors.
struct RunSetup {
  std::unique_ptr<learn::TrainedAgent> agent;
  worlds::World world;
  worlds::FloorSet floors;
  grid::FloorFrame frame;
  std::vector<std::uint8_t> obstacle_mask;  // H * W, 1 on an obstacle; empty without obstacles
  std::vector<std::uint8_t> slip_mask;      // H * W, 1 on a slip zone; empty without zones
};

// 1 on the floor pixels whose centre lies on an obstacle of `layout` (what pictures draw in brick red).
std::vector<std::uint8_t> obstacle_mask(const worlds::ObstacleSpec& layout, const grid::FloorFrame& frame) {
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(frame.area_px()));
  for (int y = 0; y < frame.height_px; ++y)
    for (int x = 0; x < frame.width_px; ++x)
      mask[static_cast<std::size_t>(y) * frame.width_px + x] = layout.covers(x + 0.5, y + 0.5) ? 1 : 0;
  return mask;
}

RunSetup gather_run(const RunOptions& opt) {
  RunSetup setup;
  if (!opt.checkpoint.empty()) {
    setup.agent = learn::TrainedAgent::load(opt.checkpoint, agent::parse_precision(opt.precision));
    if (opt.heat_map && !setup.agent->learned().goals)
      throw InputError(opt.checkpoint +
                       ": --heat-map: expected a checkpoint with a learned goal layer (trained in mode (ii) or "
                       "(iii)); this one drives with i.i.d. goals");
    announce_model_precision(opt.precision, setup.agent->config().precision);
  }
  setup.world = worlds::load_world(opt.world);
  if (!opt.seed.empty()) setup.world.seed = parse_seed(opt.seed);
  const fs::path data_root = opt.data_root.empty() ? worlds::default_data_root() : fs::path(opt.data_root);
  setup.floors = worlds::load_floors(setup.world, data_root);
  setup.frame = {.width_px = setup.floors.width_px(),
                 .height_px = setup.floors.height_px(),
                 .pixel_size_m = setup.world.floor.pixel_size_m};
  const grid::FloorFrame& frame = setup.frame;
  if (!opt.no_images && std::max(frame.width_px, frame.height_px) * opt.scale > render::kMaxPictureSidePx)
    throw InputError(
        fmt::format("--scale: expected at most {} for a {} x {} floor (pictures up to {} px a side), got {}",
                    render::kMaxPictureSidePx / std::max(frame.width_px, frame.height_px), frame.width_px,
                    frame.height_px, render::kMaxPictureSidePx, opt.scale));
  if (!setup.world.obstacles.no_fixed()) setup.obstacle_mask = obstacle_mask(setup.world.obstacles, setup.frame);
  if (!setup.world.motion.slip_zones.empty()) {
    setup.slip_mask.resize(static_cast<std::size_t>(setup.frame.area_px()));
    for (int y = 0; y < setup.frame.height_px; ++y)
      for (int x = 0; x < setup.frame.width_px; ++x)
        setup.slip_mask[static_cast<std::size_t>(y) * setup.frame.width_px + x] =
            setup.world.motion.slip_at(x + 0.5, y + 0.5) > 0.0 ? 1 : 0;
  }
  return setup;
}

// Where each run goes as it is driven, and what the runs add up to.
struct RunOutputs {
  std::ofstream trajectory;  // streamed run by run, so memory does not grow with --count
  std::unique_ptr<render::VideoWriter> video;
  fs::path images_dir;
  std::vector<std::string> images;
  long moves = 0, ticks = 0, revealed = 0;
};

// One run's record into trajectory.json, the video and its pictures.
// `team`: the run's robot, or its team's robots in order (the first is robot `robot` of the batch).
void emit_run(const RunOptions& opt, const RunSetup& setup, const env::PlannedRun& run, int run_number,
              std::span<const learn::RolloutRecord> team, const std::uint8_t* floor, std::span<const float> p,
              int robot, RunOutputs& out) {
  const learn::RolloutRecord& rec = team.front();
  out.trajectory << (run_number == 0 ? "\n  " : ",\n  ") << run_json(run, team, setup.floors, p);
  for (const learn::RolloutRecord& r : team) {
    for (const learn::StepRecord& s : r.steps) out.ticks += s.result.ticks;
    out.moves += static_cast<long>(r.steps.size());
  }
  out.revealed += rec.steps.empty() ? 0 : rec.steps.back().revealed_px;  // the team's
  const worlds::World& world = setup.world;
  // A world that draws boxes per run draws this run's; otherwise every run has the world's.
  const std::vector<std::uint8_t> own_mask =
      world.obstacles.random_boxes > 0 ? obstacle_mask(run.obstacles, setup.frame) : std::vector<std::uint8_t>{};
  const std::vector<std::uint8_t>& mask = own_mask.empty() ? setup.obstacle_mask : own_mask;
  const ScenarioMarks marks{.true_path = !world.ideal_motion(),
                            .obstacles = mask.empty() ? nullptr : mask.data(),
                            .slip = setup.slip_mask.empty() ? nullptr : setup.slip_mask.data(),
                            .faint_floor = world.floor.composed(),
                            .wide = {world.camera.wide_px, world.camera.wide_scale}};
  if (out.video) {
    interrupt_token().throw_if_requested();
    append_run_frames(*out.video, {.records = team,
                                   .floor = floor,
                                   .frame = setup.frame,
                                   .patch_px = world.camera.patch_px,
                                   .robot_radius_px = world.robot.radius_m / world.floor.pixel_size_m,
                                   .scale = opt.scale,
                                   .class_probabilities = p,
                                   .fps = opt.fps,
                                   .exact_motion = world.ideal_motion(),
                                   .obstacles = marks.obstacles,
                                   .slip = marks.slip,
                                   .faint_floor = marks.faint_floor,
                                   .wide = {world.camera.wide_px, world.camera.wide_scale}});
  }
  if (!opt.no_images) {
    interrupt_token().throw_if_requested();
    const AgentOverlay overlay{
        .class_probabilities = p, .agent = opt.heat_map ? setup.agent.get() : nullptr, .robot = robot};
    write_images(out.images_dir, run_number, team, floor, setup.frame, world.camera.patch_px, opt.scale, marks, overlay,
                 out.images);
  }
}

// Runs first .. first + n - 1, driven together in one batch (a team's K robots each).
void drive_batch(const RunOptions& opt, const RunSetup& setup, std::span<const env::PlannedRun> runs, int first,
                 learn::RolloutEngine& engine, RunOutputs& out) {
  const int n = static_cast<int>(runs.size());
  const int K = setup.world.team.robots;
  const std::size_t area = static_cast<std::size_t>(setup.frame.area_px());
  std::vector<std::uint8_t> batch_floors(area * n * K);
  std::vector<grid::Cell> starts(n * K);
  std::vector<std::uint64_t> policy_seeds(n * K);
  std::vector<std::uint64_t> motion_seeds(n * K);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < K; ++k) {
      const int r = i * K + k;
      setup.floors.floor(runs[i].index, runs[i].floor_key, std::span(batch_floors.data() + area * r, area));
      starts[r] = runs[i].starts[k];
      policy_seeds[r] = env::member_seed(runs[i].policy_seed, k);
      motion_seeds[r] = env::member_seed(runs[i].motion_seed, k);
    }
  learn::TrainedAgent* agent = setup.agent.get();
  std::vector<learn::RolloutRecord> records;
  std::vector<float> probabilities;  // n * K * D with a checkpoint; a team's robots hold one y
  if (agent) {
    agent->begin(setup.frame, setup.world.camera.patch_px, policy_seeds, opt.greedy, opt.heat_map && !opt.no_images);
    records = engine.run(batch_floors, starts, motion_seeds, agent->policy());
    probabilities = agent->classify(engine.state(), n * K);
  } else {
    learn::RandomPolicy policy(policy_seeds);
    records = engine.run(batch_floors, starts, motion_seeds, policy);
  }
  const std::size_t classes = agent ? static_cast<std::size_t>(agent->classes()) : 0;
  for (int i = 0; i < n; ++i) {
    const std::size_t robot = static_cast<std::size_t>(i) * K;
    const std::span<const float> p =
        agent ? std::span<const float>(probabilities.data() + classes * robot, classes) : std::span<const float>();
    emit_run(opt, setup, runs[i], first + i, std::span<const learn::RolloutRecord>(records).subspan(robot, K),
             batch_floors.data() + area * robot, p, static_cast<int>(robot), out);
  }
}

json run_manifest(const RunOptions& opt, const RunSetup& setup, const RunOutputs& out,
                  const learn::RolloutEngine& engine, const Context& context) {
  json manifest =
      make_manifest(context.argv, worlds::to_yaml(setup.world), setup.floors.files, engine.camera_description());
  if (const learn::TrainedAgent* agent = setup.agent.get()) {
    manifest["checkpoint"] = {{"path", opt.checkpoint},
                              {"sha256", core::sha256_hex(learn::resolve_checkpoint(opt.checkpoint))},
                              {"greedy", opt.greedy},
                              {"learned_goals", agent->learned().goals},
                              {"learned_actions", agent->learned().actions},
                              {"precision", agent::to_string(agent->precision())}};
  }
  manifest["outputs"] = {{"trajectory", "trajectory.json"}, {"images", out.images}};
  if (out.video)
    manifest["outputs"]["video"] = {
        {"path", opt.video}, {"frames", out.video->frames()}, {"fps", opt.fps}, {"codec", out.video->codec()}};
  return manifest;
}

void print_run_summary(const RunOptions& opt, const RunOutputs& out, const std::string& target, double seconds) {
  fmt::print("{} run{} of {} ({} moves, {:.1f} ticks per move, {:.1f} px revealed per run) in {:.2f} s\n", opt.count,
             opt.count == 1 ? "" : "s", opt.world, out.moves, out.moves ? double(out.ticks) / out.moves : 0.0,
             double(out.revealed) / opt.count, seconds);
  fmt::print("trajectory: {}\n", (fs::path(target) / "trajectory.json").string());
  if (!opt.no_images)
    fmt::print("images:     {} ({} PNG files)\n", (fs::path(target) / "images").string(), out.images.size());
  if (out.video)
    fmt::print("video:      {} ({} frames at {} fps, {})\n", opt.video, out.video->frames(), opt.fps,
               out.video->codec());
}

void run_command(const RunOptions& opt, const Context& context) {
  if (opt.count < 1) throw InputError("--count: expected a positive integer, got " + std::to_string(opt.count));
  check_video_options(opt);
  const RunSetup setup = gather_run(opt);
  const grid::FloorFrame& frame = setup.frame;
  std::vector<fs::path> inputs = setup.floors.files;
  inputs.push_back(opt.world);
  if (setup.agent) inputs.push_back(learn::resolve_checkpoint(opt.checkpoint));
  OutputDir out(opt.out, opt.overwrite, inputs);  // refuses a bad --out before any work is done
  if (!opt.video.empty() && std::max(frame.width_px, frame.height_px) * opt.scale > render::kMaxPictureSidePx)
    throw InputError(fmt::format("--scale: expected at most {} for a video of a {} x {} floor, got {}",
                                 render::kMaxPictureSidePx / std::max(frame.width_px, frame.height_px), frame.width_px,
                                 frame.height_px, opt.scale));
  RunOutputs outputs;
  if (!opt.video.empty()) outputs.video = std::make_unique<render::VideoWriter>(opt.video, opt.fps);

  const auto t0 = core::Clock::now();
  const std::vector<env::PlannedRun> runs = plan_runs(setup.world, setup.floors, frame, setup.world.seed, opt.count);
  // Runs per batch: a team's robots are driven together, up to kBatchRobots robots in all.
  const int batch_robots = std::min(opt.count, std::max(1, kBatchRobots / setup.world.team.robots));
  const auto engine = make_engine(setup.world, frame, batch_robots * setup.world.team.robots);
  outputs.images_dir = out.path() / "images";
  if (!opt.no_images) fs::create_directories(outputs.images_dir);
  // The whole folder is still only moved into place once complete.
  const fs::path trajectory_file = out.path() / "trajectory.json";
  outputs.trajectory.open(trajectory_file, std::ios::binary);
  outputs.trajectory << "{\n \"world\": " << json(opt.world).dump() << ",\n \"seed\": " << setup.world.seed
                     << ",\n \"runs\": [";
  for (int first = 0; first < opt.count; first += batch_robots) {
    interrupt_token().throw_if_requested();
    const int n = std::min(batch_robots, opt.count - first);
    drive_batch(opt, setup, std::span<const env::PlannedRun>(runs).subspan(first, n), first, *engine, outputs);
  }
  const double seconds = core::seconds_since(t0);

  outputs.trajectory << "\n ]\n}\n";
  outputs.trajectory.close();
  if (!outputs.trajectory) throw InputError(trajectory_file.string() + ": cannot write");
  if (outputs.video) outputs.video->finish();
  write_file_atomic(out.path() / kManifestFile, run_manifest(opt, setup, outputs, *engine, context).dump(2) + "\n");
  out.commit();
  print_run_summary(opt, outputs, out.target(), seconds);
}

}  // namespace

void add_run_command(CLI::App& app, const Context& context) {
  auto opt = std::make_shared<RunOptions>();
  auto* cmd = app.add_subcommand("run",
                                 "Drive robots over a world headless (mode (i): i.i.d. random goals and "
                                 "actions, or a trained agent with --checkpoint) and export trajectory.json, "
                                 "images and manifest.json.");
  cmd->add_option("world", opt->world, "World file (YAML), e.g. worlds/mnist.yaml")->required();
  cmd->add_option("--out", opt->out, "Output folder (must not exist unless --overwrite)")
      ->required()
      ->check(CLI::Validator(
          [](std::string& text) { return text.empty() ? std::string("expected a folder path, got an empty one") : ""; },
          "DIR"));
  cmd->add_option("--seed", opt->seed, "Seed, an integer in [0, 2^64 - 1] (overrides the world file's)")
      ->check(seed_validator());
  cmd->add_option("--count", opt->count, "Number of rollouts (each on its own digit with index: random)")
      ->capture_default_str()
      ->check(decimal_in(1, 1000000));
  cmd->add_option("--data", opt->data_root,
                  "Data folder (default: $SCOUT_DATA, else <source>/data; installed: ~/.local/share/scout)");
  cmd->add_option("--scale", opt->scale, "Image pixels per floor pixel")
      ->capture_default_str()
      ->check(decimal_in(1, 64));
  cmd->add_flag("--overwrite", opt->overwrite, "Replace an existing --out folder");
  cmd->add_flag("--no-images", opt->no_images, "Skip the PNG snapshots");
  auto* checkpoint =
      cmd->add_option("--checkpoint", opt->checkpoint,
                      "Drive with this trained agent (RUN/checkpoint.safetensors), sampling its learned layers as in "
                      "training; its prediction goes into trajectory.json and the pictures");
  cmd->add_flag("--greedy", opt->greedy, "With --checkpoint: argmax goals and actions instead of sampling")
      ->needs(checkpoint);
  add_model_precision_option(*cmd, opt->precision);
  cmd->get_option("--precision")->needs(checkpoint);
  cmd->add_flag("--heat-map", opt->heat_map,
                "With --checkpoint (learned goals): draw each episode's goal distribution on its picture")
      ->needs(checkpoint);
  cmd->add_option("--video", opt->video,
                  "Also animate the runs, one after another, frame by frame at physics ticks: FILE.mp4 (H.264, "
                  "else MPEG-4) or FILE.gif");
  cmd->add_option("--fps", opt->fps,
                  "Video frames per second (one frame per 1/60 s physics tick: 30 plays at half speed)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 100.0));
  add_camera_backend_option(*cmd);
  cmd->callback([opt, &context] {
    install_interrupt_handler();
    run_command(*opt, context);
  });
}

}  // namespace scout::tools
