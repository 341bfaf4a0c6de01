// scout bench sim: agent-steps per second of the simulation (physics + camera), and of each alone.
// scout bench train: training images per second in each mode, and where a step's time goes.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <sstream>

#include "core/install_layout.hpp"
#include "core/memory.hpp"
#include "core/random.hpp"
#include "core/seed_streams.hpp"
#include "core/timing.hpp"
#include "env/runs.hpp"
#include "learn/auto_precision.hpp"
#include "learn/distributed.hpp"
#include "learn/rollout.hpp"
#include "learn/training_bench.hpp"
#include "render/camera.hpp"
#include "sim/robots.hpp"
#include "tools/commands.hpp"
#include "tools/group.hpp"
#include "tools/network_options.hpp"
#include "tools/output.hpp"
#include "worlds/dataset.hpp"
#include "worlds/floors.hpp"

namespace scout::tools {

namespace {

namespace fs = std::filesystem;
using core::Clock;
using core::median;
using core::seconds_since;

struct BenchOptions {
  std::string world = (core::files_root() / "worlds" / "mnist.yaml").string();
  std::string data_root;
  std::string json_out;
  int robots = 240;
  int repeats = 21;
  std::vector<int> floor_sizes;  // --floor-sizes: the same world on floors of these sides, one after the other
};

struct TrainBenchOptions {
  std::string world = (core::files_root() / "worlds" / "mnist.yaml").string();
  std::string data_root;
  std::string json_out;
  SettingOptions settings;  // the training settings bench train takes (the library's defaults: the paper preset)
  std::string modes = "i,ii,iii";
  int floor_side = 0;  // --floor-size: the world's task on a square floor of this side (0: the world's floor)
  int batches = 5, warmup = 1, threads = 0;
  bool force = false;
  GroupFlags group;
};

template <typename F>
std::vector<double> time_repeats(int repeats, F&& body) {
  std::vector<double> seconds;
  for (int r = 0; r < repeats; ++r) {
    interrupt_token().throw_if_requested();
    const auto t0 = Clock::now();
    body(r);
    seconds.push_back(seconds_since(t0));
  }
  return seconds;
}

// The batch bench sim drives: n different digits (or the world's one) and starts, as a training
// batch would have.
struct SimBatch {
  worlds::World world;
  worlds::FloorSet floors;
  grid::FloorFrame frame;
  int n = 0, moves_per_rollout = 0;
  std::size_t area = 0;
  std::vector<std::uint8_t> floor_pixels;
  std::vector<grid::Cell> starts;
  std::vector<std::uint64_t> motion_seeds;  // each robot's motion errors and pushes (worlds that have them)
};

// `floor_side`: the world on a floor of that side (floor.size_px), its task and layout unchanged;
// `without_wide_view`: with its camera's wider view off.
SimBatch gather_sim_batch(const BenchOptions& opt, std::optional<int> floor_side = std::nullopt,
                          bool without_wide_view = false) {
  SimBatch b;
  b.world = worlds::load_world(opt.world);
  if (floor_side) b.world.floor.size_px = worlds::FloorSize{*floor_side, *floor_side};
  if (without_wide_view) b.world.camera.wide_px = 0;
  const fs::path data_root = opt.data_root.empty() ? worlds::default_data_root() : fs::path(opt.data_root);
  b.floors = worlds::load_floors(b.world, data_root);
  b.frame = {
      .width_px = b.floors.width_px(), .height_px = b.floors.height_px(), .pixel_size_m = b.world.floor.pixel_size_m};
  b.n = opt.robots;
  const int K = b.world.team.robots;
  if (b.n % K != 0)
    throw InputError(fmt::format("--robots: expected a multiple of the world's team.robots = {}, got {}", K, b.n));
  b.moves_per_rollout = b.world.task.episodes / K * b.world.task.steps;  // each robot's
  b.area = static_cast<std::size_t>(b.frame.area_px());
  core::Rng rng(b.world.seed);
  b.floor_pixels.resize(b.area * b.n);
  b.starts.resize(b.n);
  b.motion_seeds.resize(b.n);
  for (int i = 0; i < b.n; ++i) {
    const int index = b.world.floor.index
                          ? *b.world.floor.index
                          : static_cast<int>(core::uniform_below(rng, static_cast<std::uint64_t>(b.floors.size())));
    b.floors.floor(
        index, core::derive_seed(core::derive_seed(b.world.seed, static_cast<std::uint64_t>(i)), streams::kRunFloor),
        std::span(b.floor_pixels.data() + b.area * i, b.area));
    // Derived, not drawn from `rng`: the floors and starts stay those of every earlier bench.
    b.motion_seeds[i] =
        core::derive_seed(core::derive_seed(b.world.seed, static_cast<std::uint64_t>(i)), streams::kRobotMotion);
    if (K == 1) {
      b.starts[i] = env::draw_start(b.world, b.frame, b.motion_seeds[i], rng);
    } else if (i % K == K - 1) {  // a team: one floor, starts apart, seeds from its first robot's
      const int first = i - (K - 1);
      const std::vector<grid::Cell> starts = env::draw_team_starts(b.world, b.frame, b.motion_seeds[first], rng);
      for (int k = 0; k < K; ++k) {
        b.starts[first + k] = starts[k];
        b.motion_seeds[first + k] = env::member_seed(b.motion_seeds[first], k);
        std::copy_n(b.floor_pixels.data() + b.area * first, b.area, b.floor_pixels.data() + b.area * (first + k));
      }
    }
  }
  return b;
}

std::vector<std::uint64_t> sim_seeds(int n, int repeat) {
  std::vector<std::uint64_t> seeds(n);
  for (int i = 0; i < n; ++i)
    seeds[i] = core::derive_seed(static_cast<std::uint64_t>(repeat), static_cast<std::uint64_t>(i));
  return seeds;
}

// What bench sim measured: medians per batch, seconds, and what the recorded batch's moves did.
struct SimFigures {
  double together = 0, physics = 0, camera = 0, crop = 0;
  int threads = 0;
  long ticks = 0, driven_moves = 0, all_moves = 0;
  double peak_speed = 0;
  std::string camera_description;
  // Camera alone under each back end this build has, the chosen one first: seconds per batch, or
  // why the back end could not make a context; and whether its patches equal the chosen one's.
  struct Backend {
    std::string name, unavailable;
    double seconds = 0;
    bool same_patches = false;
  };
  std::vector<Backend> backends;
};

void count_moves(const std::vector<learn::RolloutRecord>& recorded, SimFigures& f) {
  for (const auto& rec : recorded)
    for (const auto& s : rec.steps) {
      f.ticks += s.result.ticks;
      f.all_moves += 1;
      f.driven_moves += s.command != grid::Cell::Zero();
      f.peak_speed = std::max(f.peak_speed, s.result.peak_speed_mps);
    }
}

// Physics alone, camera alone and the CPU crop, replaying the commands and poses of `recorded`.
void time_sim_parts(const BenchOptions& opt, const SimBatch& b, const std::vector<learn::RolloutRecord>& recorded,
                    SimFigures& f) {
  const int n = b.n, moves = b.moves_per_rollout;
  // Physics alone: the recorded commands replayed on a fresh batch of bodies.
  sim::RobotBatch robots(b.frame, sim::RobotParams::from_world(b.world), n);
  std::vector<std::vector<grid::Cell>> commands(moves, std::vector<grid::Cell>(n));
  std::vector<std::vector<render::PixelPose>> poses(moves, std::vector<render::PixelPose>(n));
  std::vector<std::vector<render::FloorPoint>> centres(moves, std::vector<render::FloorPoint>(n));
  for (int i = 0; i < n; ++i)
    for (int m = 0; m < moves; ++m) {
      const learn::StepRecord& s = recorded[i].steps[m];
      commands[m][i] = s.command;
      poses[m][i] = {.x = s.grid_pose.x(), .y = s.grid_pose.y()};
      centres[m][i] = {.x = static_cast<float>(s.pose_m.x() / b.frame.pixel_size_m),
                       .y = static_cast<float>(s.pose_m.y() / b.frame.pixel_size_m)};
    }
  std::vector<sim::MoveResult> results(n);
  // Each run's own boxes, as the rollouts had them: drawn from its first robot's motion seed (a
  // team's robots share one floor).
  const int K = b.world.team.robots;
  if (b.world.obstacles.random_boxes > 0)
    for (int i = 0; i < n; i += K) robots.set_obstacles(i, env::run_obstacles(b.world, b.frame, b.motion_seeds[i]));
  f.physics = median(time_repeats(opt.repeats, [&](int) {
    for (int i = 0; i < n; ++i) robots.place(i, b.starts[i], b.motion_seeds[i]);
    for (int m = 0; m < moves; ++m) robots.move(commands[m], results);
  }));
  // Camera alone: the recorded poses rendered and read back (with the world's wider view), under
  // the back end the run chose (--camera-backend, SCOUT_CAMERA_BACKEND, else auto) and then each
  // other one this build has, for the figures side by side.
  const int patch = b.world.camera.patch_px;
  const render::WideView wide{b.world.camera.wide_px, b.world.camera.wide_scale};
  const std::size_t patch_bytes = static_cast<std::size_t>(n) * patch * patch;
  const std::size_t wide_bytes = static_cast<std::size_t>(n) * wide.px * wide.px;
  std::vector<std::uint8_t> patches(patch_bytes), wide_patches(wide_bytes);
  std::vector<std::uint8_t> chosen_patches, chosen_wide;  // the chosen back end's last move
  // As the environment does: crops at grid poses where moves land on cells, else the floor sampled
  // at the true centres.
  const bool exact = b.world.ideal_motion();
  const auto time_camera = [&](render::CameraBackend backend) {
    render::PatchCamera camera(b.frame.width_px, b.frame.height_px, patch, n, wide, backend);
    camera.load_floors(b.floor_pixels, n);
    SimFigures::Backend figure{render::camera_backend_name(camera.backend()), {}, 0, true};
    figure.seconds = median(time_repeats(opt.repeats, [&](int) {
      for (int m = 0; m < moves; ++m) {
        if (exact)
          camera.capture(poses[m], patches, wide_patches);
        else
          camera.capture_at(centres[m], patches, wide_patches);
      }
    }));
    if (chosen_patches.empty()) {
      chosen_patches = patches;
      chosen_wide = wide_patches;
    } else {
      figure.same_patches = patches == chosen_patches && wide_patches == chosen_wide;
    }
    return std::pair{figure, camera.backend()};
  };
  const auto [chosen, chosen_backend] = time_camera(render::CameraBackend::automatic);
  f.camera = chosen.seconds;
  f.backends = {chosen};
  for (const render::CameraBackend other : render::built_camera_backends()) {
    if (other == chosen_backend) continue;
    try {
      f.backends.push_back(time_camera(other).first);
    } catch (const std::runtime_error& e) {
      f.backends.push_back({render::camera_backend_name(other), one_line(e.what()), 0, false});
    }
  }
  f.threads = robots.threads();
  // The CPU crop of the same windows: the floor any renderer is measured against.
  f.crop = median(time_repeats(opt.repeats, [&](int) {
    for (int k = 0; k < moves; ++k)
      for (int i = 0; i < n; ++i)
        render::crop_patch(b.floor_pixels.data() + b.area * i, b.frame.width_px, b.frame.height_px, patch, poses[k][i],
                           patches.data() + static_cast<std::size_t>(i) * patch * patch);
  }));
}

// A batch's engine and one recorded batch, whose commands and poses the physics-only and
// camera-only runs replay.
struct SimRun {
  std::unique_ptr<learn::RolloutEngine> engine;
  std::vector<learn::RolloutRecord> recorded;
};

SimRun start_sim_run(const SimBatch& b) {
  SimRun run{make_engine(b.world, b.frame, b.n), {}};
  learn::RandomPolicy recorded_policy(sim_seeds(b.n, -1));
  run.recorded = run.engine->run(b.floor_pixels, b.starts, b.motion_seeds, recorded_policy, true);
  run.engine->reset_timing();
  return run;
}

// Physics and camera together: one whole rollout of mode (i), nothing recorded; `repeat` seeds
// its random moves.
void run_sim_rollout(const SimBatch& b, SimRun& run, int repeat) {
  learn::RandomPolicy policy(sim_seeds(b.n, repeat));
  run.engine->run(b.floor_pixels, b.starts, b.motion_seeds, policy, false);
}

// The figures but `together`, from a started run.
SimFigures time_sim_alone(const BenchOptions& opt, const SimBatch& b, const SimRun& run) {
  SimFigures f;
  count_moves(run.recorded, f);
  time_sim_parts(opt, b, run.recorded, f);
  f.camera_description = run.engine->camera_description();
  return f;
}

SimFigures time_sim(const BenchOptions& opt, const SimBatch& b) {
  SimRun run = start_sim_run(b);
  // One line on stderr says the timing has begun (what a caller can wait for before signalling).
  std::fprintf(stderr, "scout bench sim: timing %d repeats\n", opt.repeats);
  const double together = median(time_repeats(opt.repeats, [&](int r) { run_sim_rollout(b, run, r); }));
  SimFigures f = time_sim_alone(opt, b, run);
  f.together = together;
  return f;
}

void print_sim(const BenchOptions& opt, const SimBatch& b, const SimFigures& f) {
  const worlds::World& world = b.world;
  const double steps = double(b.n) * b.moves_per_rollout;
  const int K = world.team.robots;
  const std::string shape =
      K == 1 ? fmt::format("E={} x T={}", world.task.episodes, world.task.steps)
             : fmt::format("E/K={} x T={}, teams of K={}", world.task.episodes / K, world.task.steps, K);
  const std::string wide = world.camera.wide() ? fmt::format(" and a wider view of {0}x{0} pixels of {1}x{1}",
                                                             world.camera.wide_px, world.camera.wide_scale)
                                               : std::string();
  fmt::print("scout bench sim: {} robots x {} moves ({}), m={}{}, {} repeats, {} physics threads\n", b.n,
             b.moves_per_rollout, shape, world.camera.patch_px, wide, opt.repeats, f.threads);
  fmt::print("  world {}: {:.3g} m/px, max speed {} m/s, dt {:.4g} s\n", opt.world, b.frame.pixel_size_m,
             world.robot.max_speed_mps, world.physics.dt_s);
  fmt::print("  {:<22} {:>10} {:>18}\n", "median per batch", "ms", "agent-steps/s");
  fmt::print("  {:<22} {:>10.2f} {:>18.0f}\n", "physics + camera", f.together * 1e3, steps / f.together);
  fmt::print("  {:<22} {:>10.2f} {:>18.0f}\n", "physics alone", f.physics * 1e3, steps / f.physics);
  fmt::print("  {:<22} {:>10.2f} {:>18.0f}   ({:.0f} patches/s{})\n", "camera alone, " + f.backends[0].name,
             f.camera * 1e3, steps / f.camera, steps / f.camera,
             world.ideal_motion() ? "" : ", sampled at the true centres");
  for (std::size_t i = 1; i < f.backends.size(); ++i) {
    const SimFigures::Backend& other = f.backends[i];
    const std::string label = "camera alone, " + other.name;
    if (!other.unavailable.empty())
      fmt::print("  {:<22} {:>10} {:>18}   (unavailable: {})\n", label, "-", "-", other.unavailable);
    else
      fmt::print("  {:<22} {:>10.2f} {:>18.0f}   ({:.2f} x {}'s speed; patches {} {}'s)\n", label, other.seconds * 1e3,
                 steps / other.seconds, f.camera / other.seconds, f.backends[0].name,
                 other.same_patches ? "equal to" : "DIFFER from", f.backends[0].name);
  }
  fmt::print("  {:<22} {:>10.2f} {:>18.0f}   (reference: the same patches cropped on the CPU)\n", "CPU crop",
             f.crop * 1e3, steps / f.crop);
  fmt::print("  ticks per move: {:.2f} over all moves, {:.2f} over moves that drive ({} of {} moves are no-ops)\n",
             double(f.ticks) / f.all_moves, f.driven_moves ? double(f.ticks) / f.driven_moves : 0.0,
             f.all_moves - f.driven_moves, f.all_moves);
  fmt::print("  peak speed reached: {:.3f} m/s (the controller's limit {} m/s{})\n", f.peak_speed,
             world.robot.max_speed_mps,
             world.ideal_motion() ? "" : "; scale errors and pushes may carry the robot faster");
  // The project's targets (issue: world side), for the paper preset's batch of 240.
  constexpr double kTargetAgentSteps = 300'000, kTargetPatches = 2'000'000;
  fmt::print("  targets: physics + camera >= {:.0f} agent-steps/s: {}; camera >= {:.0f} patches/s: {}\n",
             kTargetAgentSteps, steps / f.together >= kTargetAgentSteps ? "met" : "NOT met", kTargetPatches,
             steps / f.camera >= kTargetPatches ? "met" : "NOT met");
  fmt::print("  camera: {}\n", f.camera_description);
  fmt::print("  memory: peak resident {}\n", core::format_bytes(core::peak_resident_bytes()));
}

void write_sim_json(const BenchOptions& opt, const SimBatch& b, const SimFigures& f, const Context& context) {
  const double steps = double(b.n) * b.moves_per_rollout;
  nlohmann::ordered_json j;
  j["robots"] = b.n;
  j["moves_per_rollout"] = b.moves_per_rollout;  // each robot's
  j["team_robots"] = b.world.team.robots;
  j["repeats"] = opt.repeats;
  j["threads"] = f.threads;
  j["peak_resident_bytes"] = core::peak_resident_bytes();
  j["median_ms"] = {{"physics_and_camera", f.together * 1e3},
                    {"physics", f.physics * 1e3},
                    {"camera", f.camera * 1e3},
                    {"cpu_crop", f.crop * 1e3}};
  j["agent_steps_per_s"] = {
      {"physics_and_camera", steps / f.together}, {"physics", steps / f.physics}, {"camera", steps / f.camera}};
  j["patches_per_s"] = steps / f.camera;
  // Camera alone per back end, the chosen one first.
  nlohmann::ordered_json backends = nlohmann::ordered_json::object();
  for (const SimFigures::Backend& backend : f.backends) {
    if (!backend.unavailable.empty())
      backends[backend.name] = {{"unavailable", backend.unavailable}};
    else
      backends[backend.name] = {{"median_ms", backend.seconds * 1e3},
                                {"patches_per_s", steps / backend.seconds},
                                {"patches_equal_to_chosen", backend.same_patches}};
  }
  j["camera_backends"] = backends;
  j["ticks_per_move"] = double(f.ticks) / f.all_moves;
  j["ticks_per_driving_move"] = f.driven_moves ? double(f.ticks) / f.driven_moves : 0.0;
  j["peak_speed_mps"] = f.peak_speed;
  j["manifest"] = make_manifest(context.argv, worlds::to_yaml(b.world), b.floors.files, f.camera_description);
  write_file_atomic(opt.json_out, j.dump(2) + "\n");
}

// --floor-sizes: the world's task on floors of each side, in one process, and each figure beside
// the first size's (the speed a larger floor keeps). A world with a wider view is timed on each
// floor with it and without it. The rollouts of physics + camera are timed floor after floor
// within each repeat, so that a slow spell of a shared machine falls on every floor alike.
void bench_sim_floor_sizes(const BenchOptions& opt) {
  const bool wide = worlds::load_world(opt.world).camera.wide();
  std::vector<SimBatch> batches;            // per floor: without the wider view, then (a world with one) with it
  for (const int side : opt.floor_sizes) {  // every size checked before anything is timed
    try {
      batches.push_back(gather_sim_batch(opt, side, /*without_wide_view=*/true));
      if (wide) batches.push_back(gather_sim_batch(opt, side));
    } catch (const InputError& e) {
      throw InputError(fmt::format("--floor-sizes: {}: {}", side, e.what()));
    }
  }
  fmt::print("scout bench sim: {} robots, {} repeats, the world {} on floors of each size\n", opt.robots, opt.repeats,
             opt.world);
  fmt::print("  {:<10} {:<18} {:>18} {:>8} {:>18} {:>18} {:>11}   {}\n", "floor", "camera", "physics + camera", "ratio",
             "physics alone", "camera alone", "ticks/move", "a rollout's physics | camera | observing, ms");
  std::vector<SimRun> runs;
  for (const SimBatch& b : batches) runs.push_back(start_sim_run(b));
  std::vector<std::vector<double>> together_s(batches.size());
  std::fprintf(stderr, "scout bench sim: timing %d repeats\n", opt.repeats);
  for (int r = 0; r < opt.repeats; ++r)
    for (std::size_t k = 0; k < batches.size(); ++k) {
      interrupt_token().throw_if_requested();
      const auto t0 = Clock::now();
      run_sim_rollout(batches[k], runs[k], r);
      together_s[k].push_back(seconds_since(t0));
    }
  double first[2] = {0, 0};  // the first floor's figure without and with the wider view
  for (std::size_t k = 0; k < batches.size(); ++k) {
    const SimBatch& b = batches[k];
    const SimFigures f = time_sim_alone(opt, b, runs[k]);
    const double steps = double(b.n) * b.moves_per_rollout, together = steps / median(together_s[k]);
    const worlds::CameraSpec& camera = b.world.camera;
    double& reference = first[camera.wide() ? 1 : 0];
    if (reference == 0) reference = together;
    const std::string view = camera.wide() ? fmt::format("patch + wide {0}x{0}/{1}", camera.wide_px, camera.wide_scale)
                                           : std::string("patch");
    // Where the timed rollouts spent their time (means).
    const env::EnvTiming& spent = runs[k].engine->timing().env;
    const double per_rollout_ms = 1e3 / opt.repeats;
    fmt::print("  {:<10} {:<18} {:>18.0f} {:>7.0f}% {:>18.0f} {:>18.0f} {:>11.2f}   {:.2f} | {:.2f} | {:.2f}\n",
               fmt::format("{} x {}", b.frame.width_px, b.frame.height_px), view, together, 100 * together / reference,
               steps / f.physics, steps / f.camera, f.all_moves > 0 ? double(f.ticks) / f.all_moves : 0.0,
               spent.physics_s * per_rollout_ms, spent.render_s * per_rollout_ms, spent.observe_s * per_rollout_ms);
  }
  fmt::print(
      "  (agent-steps/s, medians; ratio: physics + camera against the first floor with the same camera;\n"
      "   ticks/move: physics ticks per move of the recorded rollout (a larger floor has fewer moves that\n"
      "   stop short at a goal already reached);\n"
      "   wide PxP/S: the wider view's P x P pixels, each the mean of S x S floor pixels; observing: the\n"
      "   robots' floors loaded and cleared as runs start, and each look revealed into y and the coarse map)\n");
  fmt::print("  memory: peak resident {}\n", core::format_bytes(core::peak_resident_bytes()));
}

void bench_sim(const BenchOptions& opt, const Context& context) {
  if (opt.robots < 1) throw InputError("--robots: expected a positive integer");
  if (opt.repeats < 1) throw InputError("--repeats: expected a positive integer");
  check_output_file("--json", opt.json_out);
  if (!opt.floor_sizes.empty()) {
    if (!opt.json_out.empty()) throw InputError("--json: expected no --floor-sizes with it (one world's figures)");
    bench_sim_floor_sizes(opt);
    return;
  }
  const SimBatch batch = gather_sim_batch(opt);
  const SimFigures figures = time_sim(opt, batch);
  print_sim(opt, batch, figures);
  if (!opt.json_out.empty()) write_sim_json(opt, batch, figures, context);
}

std::vector<learn::Stage> parse_modes(const std::string& text) {
  std::vector<learn::Stage> modes;
  if (!text.empty() && text.back() == ',')
    throw InputError("expected a comma-separated list of distinct modes i, ii, iii; got '" + one_line(text) + "'");
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    const learn::Stage stage = part == "i"     ? learn::Stage::ModeI
                               : part == "ii"  ? learn::Stage::ModeII
                               : part == "iii" ? learn::Stage::ModeIII
                                               : learn::Stage::Pretrain;
    if (stage == learn::Stage::Pretrain || std::find(modes.begin(), modes.end(), stage) != modes.end())
      throw InputError("expected a comma-separated list of distinct modes i, ii, iii; got '" + one_line(text) + "'");
    modes.push_back(stage);
  }
  if (modes.empty()) throw InputError("expected a comma-separated list of modes i, ii, iii; got nothing");
  return modes;
}

// The training bench's config: the command line's settings over the library's defaults.
learn::TrainBenchConfig bench_train_config(const TrainBenchOptions& opt) {
  learn::TrainBenchConfig config;
  config.modes = parse_modes(opt.modes);
  learn::TrainConfig& c = config.train;
  c = opt.settings.applied_to(learn::TrainConfig{});
  c.world = worlds::load_world(opt.world);
  if (c.world.floor.dataset.empty())
    throw InputError(opt.world + ": floor.dataset: the training bench needs a data set (a PNG floor has no labels)");
  if (opt.floor_side > 0) c.world.floor.size_px = worlds::FloorSize{opt.floor_side, opt.floor_side};
  const fs::path data_root = opt.data_root.empty() ? worlds::default_data_root() : fs::path(opt.data_root);
  c.data_folder = worlds::dataset_folder(c.world.floor.dataset, data_root);
  c.precision = learn::resolve_precision(c.precision);
  c.seed = c.world.seed;
  if (c.network.goals_only) {
    // The bench runs no schedule, but a goals-only agent has no mode iii to time.
    c.epochs[2] = 0;
    for (const learn::Stage mode : config.modes)
      if (mode == learn::Stage::ModeIII)
        throw InputError(
            "--modes: a goals-only agent (--goals-only) has no mode iii (its actions are i.i.d.: time mode "
            "ii)");
  }
  c.validate(setting_option);
  config.batches = opt.batches;
  config.warmup = opt.warmup;
  config.threads = opt.threads;
  config.force_memory = opt.force;
  return config;
}

void print_train_bench(const TrainBenchOptions& opt, const learn::TrainConfig& c,
                       const learn::TrainBenchReport& report) {
  opt.settings.announce_precision();
  const agent::NetworkConfig& n = c.network;
  fmt::print(
      "scout bench train: {}{} (E={} x T={}, m={}), N={} x B={} = {} robots, {}, {}{} LibTorch threads, "
      "median of {} batches after {} warm-up\n",
      opt.world, opt.floor_side > 0 ? fmt::format(" on a {0} x {0} floor", opt.floor_side) : std::string(),
      c.world.task.episodes, c.world.task.steps, c.world.camera.patch_px, c.rollouts, c.batch_images, report.robots,
      agent::to_string(c.precision), report.world_size > 1 ? fmt::format("{} processes x ", report.world_size) : "",
      report.threads, opt.batches, opt.warmup);
  fmt::print("  widths: planners {} (width x depth), classifier {}\n", agent::describe_planners(n),
             agent::describe_classifier(n));
  fmt::print("  {:<5} {:>9} {:>9}   {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}   {:>12}\n", "mode", "images/s", "s/step",
             "physics", "render", "state", "forward", "backward", "adam", "chi=1/batch");
  for (const learn::ModeBench& m : report.modes) {
    const double total = m.sum.total_s;
    auto share = [total](double part) { return fmt::format("{:.1f}%", total > 0 ? 100 * part / total : 0.0); };
    fmt::print("  {:<5} {:>9.1f} {:>9.3f}   {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}   {:>12.0f}\n",
               learn::to_string(m.mode), m.images_per_s, m.median_step_s, share(m.sum.physics_s), share(m.sum.render_s),
               share(m.sum.state_s), share(m.sum.forward_s), share(m.sum.backward_s), share(m.sum.optimizer_s),
               m.action_decisions);
  }
  fmt::print("  memory: peak resident {} (estimated {}{})\n", core::format_bytes(report.peak_bytes),
             core::format_bytes(report.estimated_bytes), report.world_size > 1 ? ", rank 0" : "");
  if (report.world_size > 1)
    for (const learn::ModeBench& m : report.modes)
      fmt::print(
          "  mode {:<3}: all-reduce of {:.0f} KiB of gradients over {} processes: {:.1f} ms per step ({:.1f}%)\n",
          learn::to_string(m.mode), report.all_reduce_bytes / 1024, report.world_size,
          1000 * m.sum.all_reduce_s / std::max(1, m.batches),
          m.sum.total_s > 0 ? 100 * m.sum.all_reduce_s / m.sum.total_s : 0.0);
  // The project's targets (issue: fast training), for the paper preset at width 16, depth 3.
  constexpr double kTargetModeIII = 30, kMaxSimulationShare = 0.05;
  const bool preset =
      c.rollouts == 4 && c.batch_images == 60 && n.planner_width == 16 && n.planner_depth == 3 && !n.goals_only;
  for (const learn::ModeBench& m : report.modes) {
    if (!preset || m.mode != learn::Stage::ModeIII) continue;
    fmt::print(
        "  targets: mode iii >= {:.0f} images/s: {}; simulation (physics + render) < {:.0f}% of a step: {} "
        "({:.2f}%)\n",
        kTargetModeIII, m.images_per_s >= kTargetModeIII ? "met" : "NOT met", 100 * kMaxSimulationShare,
        m.simulation_share() < kMaxSimulationShare ? "met" : "NOT met", 100 * m.simulation_share());
  }
}

void write_train_bench_json(const TrainBenchOptions& opt, const learn::TrainConfig& c,
                            const learn::TrainBenchReport& report, const Context& context) {
  const agent::NetworkConfig& n = c.network;
  nlohmann::ordered_json j;
  j["robots"] = report.robots;
  j["rollouts"] = c.rollouts;
  j["batch_images"] = c.batch_images;
  j["threads"] = report.threads;
  j["world_size"] = report.world_size;
  j["all_reduce_bytes"] = report.all_reduce_bytes;
  j["peak_resident_bytes"] = report.peak_bytes;
  j["estimated_bytes"] = report.estimated_bytes;
  j["precision"] = agent::to_string(c.precision);
  j["batches"] = opt.batches;
  j["warmup"] = opt.warmup;
  j["network"] = {{"planner_width", n.planner_width},
                  {"planner_depth", n.planner_depth},
                  {"classifier", agent::to_string(n.classifier)},
                  {"classifier_width", n.classifier_width},
                  {"classifier_depth", n.classifier_depth},
                  {"goal_context", n.goal_context},
                  {"goals_only", n.goals_only}};
  nlohmann::ordered_json modes = nlohmann::ordered_json::array();
  for (const learn::ModeBench& m : report.modes) {
    const double total = m.sum.total_s;
    auto share = [total](double part) { return total > 0 ? part / total : 0.0; };
    modes.push_back({{"mode", learn::to_string(m.mode)},
                     {"images_per_s", m.images_per_s},
                     {"median_step_s", m.median_step_s},
                     {"share",
                      {{"physics", share(m.sum.physics_s)},
                       {"render", share(m.sum.render_s)},
                       {"state", share(m.sum.state_s)},
                       {"forward", share(m.sum.forward_s)},
                       {"backward", share(m.sum.backward_s)},
                       {"optimizer", share(m.sum.optimizer_s)},
                       {"all_reduce", share(m.sum.all_reduce_s)}}},
                     {"all_reduce_s_per_step", m.batches ? m.sum.all_reduce_s / m.batches : 0.0},
                     {"simulation_share", m.simulation_share()},
                     {"action_decisions_per_batch", m.action_decisions}});
  }
  j["modes"] = modes;
  j["manifest"] = make_manifest(context.argv, worlds::to_yaml(c.world), report.data_files, "");
  write_file_atomic(opt.json_out, j.dump(2) + "\n");
}

void bench_train(const TrainBenchOptions& opt, const Context& context) {
  check_output_file("--json", opt.json_out);
  learn::TrainBenchConfig config = bench_train_config(opt);
  // Data-parallel: every process drives its share of each batch; rank 0 prints.
  std::unique_ptr<learn::ProcessGroup> group;
  if (const std::optional<learn::GroupOptions> options = group_from_flags(opt.group)) {
    set_rank(options->rank);
    group = learn::ProcessGroup::connect(*options);
    config.threads = threads_per_process(opt.threads);
  }
  const learn::TrainBenchReport report = [&] {
    try {
      return learn::bench_training(config, interrupt_token(), group.get());
    } catch (const InputError& e) {  // a floor the data's images do not fit, say: name the option
      if (opt.floor_side == 0) throw;
      throw InputError(fmt::format("--floor-size: {}: {}", opt.floor_side, e.what()));
    }
  }();
  if (group && group->rank() != 0) return;
  print_train_bench(opt, config.train, report);
  if (!opt.json_out.empty()) write_train_bench_json(opt, config.train, report, context);
}

}  // namespace

void add_bench_command(CLI::App& app, const Context& context) {
  auto* bench = app.add_subcommand("bench", "Benchmarks (medians over repeated runs).");
  bench->require_subcommand(1);
  auto opt = std::make_shared<BenchOptions>();
  auto* sim_cmd = bench->add_subcommand("sim",
                                        "Agent-steps/s of the simulation for a batch of robots driven by mode (i): "
                                        "physics + camera, physics alone, camera alone.");
  sim_cmd->add_option("--world", opt->world, "World file")->capture_default_str();
  sim_cmd->add_option("--data", opt->data_root,
                      "Data folder (default: $SCOUT_DATA, else <source>/data; installed: ~/.local/share/scout)");
  sim_cmd->add_option("--robots", opt->robots, "Robots in the batch")
      ->capture_default_str()
      ->check(decimal_in(1, render::kMaxCameraRobots));
  sim_cmd->add_option("--repeats", opt->repeats, "Timed repetitions")
      ->capture_default_str()
      ->check(decimal_in(1, 10000));
  sim_cmd->add_option("--json", opt->json_out, "Also write the figures to this JSON file");
  sim_cmd
      ->add_option("--floor-sizes", opt->floor_sizes,
                   "Time the world's task on square floors of these sides in turn (floor.size_px; each at least the "
                   "images' size), e.g. 28,60,100, each beside the first")
      ->delimiter(',')
      ->check(CLI::Range(1, 512));
  add_camera_backend_option(*sim_cmd);
  sim_cmd->callback([opt, &context] {
    install_interrupt_handler();
    bench_sim(*opt, context);
  });

  auto topt = std::make_shared<TrainBenchOptions>();
  auto* train_cmd = bench->add_subcommand(
      "train",
      "Training images/s in each mode with the physics and the camera in the loop (the paper preset: N = 4, B = 60), "
      "and the share of a step spent in physics, rendering, state building, forward, backward and Adam.");
  train_cmd->add_option("--world", topt->world, "World file")->capture_default_str();
  train_cmd->add_option("--data", topt->data_root,
                        "Data folder (default: $SCOUT_DATA, else <source>/data; installed: ~/.local/share/scout)");
  topt->settings.add_to(*train_cmd, /*bench=*/true);
  train_cmd
      ->add_option("--floor-size", topt->floor_side,
                   "Time the world's task on a square floor of this side (floor.size_px; at least the images' size), "
                   "e.g. 60")
      ->check(CLI::Range(1, 512));
  train_cmd->add_option("--modes", topt->modes, "Modes to time: a comma-separated list of i, ii, iii")
      ->capture_default_str()
      ->check(parsed_by(parse_modes, "MODES"));
  train_cmd->add_option("--batches", topt->batches, "Timed batches per mode")
      ->capture_default_str()
      ->check(decimal_in(1, 10000));
  train_cmd->add_option("--warmup", topt->warmup, "Untimed batches per mode first")
      ->capture_default_str()
      ->check(decimal_in(0, 1000));
  train_cmd->add_flag("--force", topt->force,
                      "Run even when the estimated memory exceeds what is available (the smallest of MemAvailable, "
                      "the cgroup limit and $SCOUT_MEMORY_LIMIT)");
  train_cmd->add_option("--threads", topt->threads, "LibTorch threads per process (0: the cores divided among them)")
      ->capture_default_str()
      ->check(decimal_in(0, 256));
  train_cmd->add_option("--json", topt->json_out, "Also write the figures to this JSON file");
  add_group_options(*train_cmd, topt->group);
  add_camera_backend_option(*train_cmd);
  train_cmd->callback([topt, &context] {
    install_interrupt_handler();
    if (const std::optional<int> status = launch_local_group(topt->group, context)) throw ExitStatus{*status};
    bench_train(*topt, context);
  });
}

}  // namespace scout::tools
