// scout._scout: the environment side of the Python package. VectorEnvCore wraps env::VectorEnv:
// arrays allocated by NumPy, filled by C++ with the GIL released. Torch-free (scout.Agent's module
// is _scout_agent). Every argument and action is checked once, in C++: here what Python hands
// over (types, dtypes, shapes, what fits in C++'s types), in env::VectorEnv what the values mean
// (moves, logits, goals, seeds per robot). The pure-Python layer (python/scout/) adds nothing but
// the Gymnasium API around it.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/install_layout.hpp"
#include "env/vector_env.hpp"
#include "python/bindings.hpp"
#include "render/snapshot.hpp"

namespace py = pybind11;

namespace scout::python {
namespace {

std::string text_of(py::handle value) { return py::repr(value).cast<std::string>(); }

// A Python function kept for the module's life (never released: the interpreter may be gone when
// static destructors run).
const py::object& python_function(const char* module, const char* name) {
  return *new py::object(py::module_::import(module).attr(name));
}

bool is_integer(py::handle value) {
  static const py::object& integral = python_function("numbers", "Integral");
  return !py::isinstance<py::bool_>(value) && py::isinstance(value, integral);
}

// An integer argument as a Python int (arbitrary size), or TypeError.
py::int_ integer(py::handle value, const std::string& name, const std::string& expected) {
  if (!is_integer(value)) throw py::type_error(name + ": expected " + expected + ", got " + text_of(value));
  return py::int_(py::reinterpret_borrow<py::object>(value));
}

// A seed: an integer in [0, 2**64).
std::uint64_t seed_value(py::handle value, const std::string& name) {
  const py::int_ v = integer(value, name, "an integer in [0, 2**64) or None");
  if (v < py::int_(0) || v > py::int_(std::numeric_limits<std::uint64_t>::max()))
    throw py::value_error(name + ": expected an integer in [0, 2**64), got " + text_of(v));
  return v.cast<std::uint64_t>();
}

std::string path(py::handle value, const std::string& name, const std::string& expected) {
  static const py::object& fspath = python_function("os", "fspath");
  if (!py::isinstance<py::str>(value) && !py::hasattr(value, "__fspath__"))
    throw py::type_error(name + ": expected " + expected + ", got " + text_of(value));
  const py::object p = fspath(value);
  if (!py::isinstance<py::str>(p)) throw py::type_error(name + ": expected " + expected + ", got " + text_of(value));
  // An empty path names no file or folder; C++ would take it as "not given" (data: the default folder).
  if (py::len(p) == 0) throw py::value_error(name + ": expected " + expected + ", got " + text_of(value));
  return p.cast<std::string>();
}

std::string choice(py::handle value, const std::string& name, const std::vector<std::string>& allowed) {
  std::string options;
  for (std::size_t k = 0; k < allowed.size(); ++k)
    options += (k == 0 ? "'" : k + 1 == allowed.size() ? " or '" : ", '") + allowed[k] + "'";
  if (py::isinstance<py::str>(value)) {
    const std::string s = value.cast<std::string>();
    if (std::find(allowed.begin(), allowed.end(), s) != allowed.end()) return s;
  }
  throw py::value_error(name + ": expected " + options + ", got " + text_of(value));
}

worlds::Split parse_split(const std::string& split) {
  if (split == "train") return worlds::Split::Train;
  if (split == "validation") return worlds::Split::Validation;
  return worlds::Split::Test;
}

std::string shape_text(const std::vector<py::ssize_t>& shape) {
  std::string s = "(";
  for (std::size_t k = 0; k < shape.size(); ++k) s += (k ? ", " : "") + std::to_string(shape[k]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

// action[key] as a C-ordered array of T: integers ('i') or floats ('f') of the given shape, with
// integers that fit in int32 and finite floats that fit in float32. What the values mean is
// env::VectorEnv's to check.
template <class T>
Array<T> action_array(const py::dict& action, const char* key, const std::vector<py::ssize_t>& shape) {
  static const py::object& asarray = python_function("numpy", "asarray");
  constexpr bool integers = std::is_integral_v<T>;
  const std::string name = std::string("action['") + key + "']";
  const py::array a = asarray(action[key]);
  const char kind = a.dtype().kind();
  if (integers ? kind != 'i' && kind != 'u' : kind != 'f')
    throw py::type_error(name + ": expected " + (integers ? "integers" : "floats") + ", got dtype " +
                         py::str(a.dtype()).cast<std::string>());
  const std::vector<py::ssize_t> got(a.shape(), a.shape() + a.ndim());
  if (got != shape) throw py::value_error(name + ": expected shape " + shape_text(shape) + ", got " + shape_text(got));
  if (py::isinstance<Array<T>>(a)) return py::reinterpret_borrow<Array<T>>(a);  // already T, C-ordered
  using Wide = std::conditional_t<integers, std::int64_t, double>;
  const auto wide = py::array_t<Wide, py::array::c_style | py::array::forcecast>::ensure(a);
  Array<T> out(shape);
  const Wide* from = wide.data();
  T* to = out.mutable_data();
  for (py::ssize_t k = 0; k < wide.size(); ++k) {
    const Wide v = from[k];
    const bool fits = integers ? v >= std::numeric_limits<T>::min() && v <= std::numeric_limits<T>::max()
                               : !std::isfinite(v) || std::abs(v) <= std::numeric_limits<T>::max();
    if (!fits) {
      std::string where;  // [i], [i][j] or [i][j][c]: the entry's index in the caller's array
      for (py::ssize_t rest = k, d = static_cast<py::ssize_t>(shape.size()) - 1; d >= 0; --d) {
        std::string index("[");
        index += std::to_string(rest % shape[d]);
        index += ']';
        where.insert(0, index);
        rest /= shape[d];
      }
      throw py::value_error(name + where + ": expected " + (integers ? "an int32" : "a logit within float32's range") +
                            ", got " + py::str(py::cast(v)).cast<std::string>());
    }
    to[k] = static_cast<T>(v);
  }
  return out;
}

// One call's output arrays, allocated by NumPy (fresh each call: the caller may keep them).
struct Outputs {
  Array<float> patch, revealed, reward;
  Array<std::int32_t> pose, time_step, label, index, goal_episode;
  Array<std::uint8_t> seen;
  Array<std::uint8_t> occupied;  // worlds with obstacles only (empty otherwise)
  // Worlds with a wider view only (empty otherwise).
  Array<float> wide_patch, wide_revealed;
  Array<std::uint8_t> wide_seen;
  Array<double> pose_m;
  Array<std::uint64_t> policy_seed;
  py::array_t<bool> terminated, truncated, goal_episode_start;

  // In a world with teams of K robots, the per-robot arrays take a team axis: N x K x ...
  explicit Outputs(const env::VectorEnv& e) {
    const py::ssize_t n = e.num_envs(), m = e.patch_px(), h = e.height(), w = e.width(), K = e.team_size();
    const auto per_robot = [&](std::vector<py::ssize_t> tail) {
      tail.insert(tail.begin(), n);
      if (K > 1) tail.insert(tail.begin() + 1, K);
      return tail;
    };
    patch = Array<float>(per_robot({m, m}));
    revealed = Array<float>({n, h, w});
    reward = Array<float>(n);
    pose = Array<std::int32_t>(per_robot({2}));
    time_step = Array<std::int32_t>(n);
    label = Array<std::int32_t>(n);
    index = Array<std::int32_t>(n);
    goal_episode = Array<std::int32_t>(n);
    seen = Array<std::uint8_t>({n, h, w});
    if (e.has_obstacles()) occupied = Array<std::uint8_t>({n, h, w});
    if (const py::ssize_t wp = e.wide_px(); wp > 0) {
      wide_patch = Array<float>(per_robot({wp, wp}));
      wide_revealed = Array<float>({n, h, w});
      wide_seen = Array<std::uint8_t>({n, h, w});
    }
    pose_m = Array<double>(per_robot({2}));
    policy_seed = Array<std::uint64_t>(n);
    terminated = py::array_t<bool>(n);
    truncated = py::array_t<bool>(n);
    goal_episode_start = py::array_t<bool>(n);
  }

  env::VectorOutputs pointers() {
    static_assert(sizeof(bool) == sizeof(std::uint8_t));
    return {.patch = patch.mutable_data(),
            .pose = pose.mutable_data(),
            .revealed = revealed.mutable_data(),
            .seen = seen.mutable_data(),
            .time_step = time_step.mutable_data(),
            .label = label.mutable_data(),
            .index = index.mutable_data(),
            .pose_m = pose_m.mutable_data(),
            .policy_seed = policy_seed.mutable_data(),
            .reward = reward.mutable_data(),
            .terminated = reinterpret_cast<std::uint8_t*>(terminated.mutable_data()),
            .truncated = reinterpret_cast<std::uint8_t*>(truncated.mutable_data()),
            .occupied = occupied.size() > 0 ? occupied.mutable_data() : nullptr,
            .wide_patch = wide_patch.size() > 0 ? wide_patch.mutable_data() : nullptr,
            .wide_revealed = wide_revealed.size() > 0 ? wide_revealed.mutable_data() : nullptr,
            .wide_seen = wide_seen.size() > 0 ? wide_seen.mutable_data() : nullptr};
  }

  // Which goal episode each robot's next move belongs to, and whether it starts one (a goal is due).
  void episodes(const env::VectorEnv& e) {
    const int steps = e.world().task.steps, moves = e.episode_moves();
    auto* t = time_step.data();
    auto* ep = goal_episode.mutable_data();
    auto* start = goal_episode_start.mutable_data();
    for (py::ssize_t i = 0; i < time_step.size(); ++i) {
      ep[i] = std::min(t[i], moves - 1) / steps;
      start[i] = t[i] < moves && t[i] % steps == 0;
    }
  }

  py::dict observation() const {
    py::dict obs;
    obs["patch"] = patch;
    obs["pose"] = pose;
    obs["revealed"] = revealed;
    obs["seen"] = seen;
    if (occupied.size() > 0) obs["occupied"] = occupied;  // worlds with obstacles
    if (wide_patch.size() > 0) {                          // worlds with a wider view
      obs["wide_patch"] = wide_patch;
      obs["wide_revealed"] = wide_revealed;
      obs["wide_seen"] = wide_seen;
    }
    obs["time_step"] = time_step;
    return obs;
  }
  // Keys that no standard Gymnasium wrapper writes ("episode" is RecordEpisodeStatistics').
  py::dict info() const {
    py::dict i;
    i["label"] = label;
    i["index"] = index;
    i["pose_m"] = pose_m;
    i["policy_seed"] = policy_seed;
    i["goal_episode"] = goal_episode;
    i["goal_episode_start"] = goal_episode_start;
    return i;
  }
};

class VectorEnvCore {
 public:
  VectorEnvCore(const py::object& world, const py::object& num_envs, const py::object& seed, const py::object& split,
                const py::object& data, const py::object& reward, bool force, bool autoreset, bool render) {
    env::VectorEnvConfig c;
    c.force = force;
    c.autoreset = autoreset;
    c.world_file = path(world, "world", "a path to a world file");
    const py::int_ n = integer(num_envs, "num_envs", "a positive integer");
    // Out of int64's range stands for itself in VectorEnv's one message (it is out of 1..4096 too).
    c.num_envs = n > py::int_(std::numeric_limits<std::int64_t>::max())   ? std::numeric_limits<std::int64_t>::max()
                 : n < py::int_(std::numeric_limits<std::int64_t>::min()) ? std::numeric_limits<std::int64_t>::min()
                                                                          : n.cast<std::int64_t>();
    if (!seed.is_none()) c.seed = seed_value(seed, "seed");
    if (!split.is_none()) c.split = parse_split(choice(split, "split", {"train", "validation", "test"}));
    if (!data.is_none()) c.data_root = path(data, "data", "a path to a data folder");
    c.reward = choice(reward, "reward", {"dense", "sparse"}) == "dense" ? env::Reward::Dense : env::Reward::Sparse;
    {
      py::gil_scoped_release release;
      env_ = std::make_unique<env::VectorEnv>(c);
    }
    if (render) paths_.emplace(env_->num_envs() * env_->team_size());
    goals_.resize(env_->num_envs() * env_->team_size());
  }

  // seed: None, an integer (the batch's sequence) or a list of num_envs integers or None (one
  // sequence per robot); mask: None or num_envs booleans (Gymnasium's reset_mask).
  py::tuple reset(const py::object& seed, const py::object& mask) {
    env::VectorReset which;
    const auto n = static_cast<std::size_t>(env_->num_envs());
    if (py::isinstance<py::list>(seed) || py::isinstance<py::tuple>(seed)) {
      for (const py::handle s : seed)
        which.robot_seeds.push_back(
            s.is_none() ? std::nullopt
                        : std::optional(seed_value(s, "seed[" + std::to_string(which.robot_seeds.size()) + "]")));
    } else if (!seed.is_none()) {
      which.seed = seed_value(seed, "seed");
    }
    if (!mask.is_none()) {
      const py::array m = py::array::ensure(mask);
      if (!m || m.dtype().kind() != 'b' || m.ndim() != 1)
        throw py::type_error("reset_mask: expected a NumPy array of " + std::to_string(n) + " booleans, got " +
                             text_of(mask));
      const auto flags = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>::ensure(m);
      which.mask.assign(flags.data(), flags.data() + flags.size());
    }
    Outputs out(*env_);
    const env::VectorOutputs p = out.pointers();
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> one_at_a_time(mutex_);  // threads may share an env
      env_->reset(which, p);
      const auto K = static_cast<std::size_t>(env_->team_size());
      for (std::size_t r = 0; r < n * K; ++r)
        if (which.mask.empty() || which.mask[r / K]) goals_[r].reset();
      track();
    }
    out.episodes(*env_);
    return py::make_tuple(out.observation(), out.info());
  }

  // action: {"move": (N,) integers, optional "prediction": (N, D) floats, optional "goal": (N, 2) integers}.
  py::tuple step(const py::object& action_object) {
    if (!py::isinstance<py::dict>(action_object))
      throw py::type_error("action: expected a dict with 'move' (and optionally 'prediction', 'goal'), got " +
                           py::str(py::type::handle_of(action_object).attr("__name__")).cast<std::string>());
    const auto action = py::reinterpret_borrow<py::dict>(action_object);
    std::vector<std::string> unknown;
    for (const auto& [key, value] : action) {
      const std::string k = py::str(key).cast<std::string>();
      if (k != "move" && k != "prediction" && k != "goal") unknown.push_back(text_of(key));
    }
    if (!unknown.empty()) {
      std::sort(unknown.begin(), unknown.end());
      std::string list;
      for (const std::string& k : unknown) list += (list.empty() ? "" : ", ") + k;
      throw py::value_error("action: unknown key(s) [" + list + "]; expected 'move', 'prediction', 'goal'");
    }
    if (!action.contains("move")) throw py::value_error("action: expected a 'move' entry");
    const py::ssize_t n = env_->num_envs(), K = env_->team_size();
    // A team's robots each take a move (and a goal): (N, K) and (N, K, 2); one prediction per team.
    const Array<std::int32_t> move = action_array<std::int32_t>(
        action, "move", K > 1 ? std::vector<py::ssize_t>{n, K} : std::vector<py::ssize_t>{n});
    std::optional<Array<float>> prediction;
    std::optional<Array<std::int32_t>> goal;
    if (action.contains("prediction") && !action["prediction"].is_none())
      prediction = action_array<float>(action, "prediction", {n, static_cast<py::ssize_t>(env_->classes())});
    if (action.contains("goal") && !action["goal"].is_none())
      goal = action_array<std::int32_t>(action, "goal",
                                        K > 1 ? std::vector<py::ssize_t>{n, K, 2} : std::vector<py::ssize_t>{n, 2});

    Outputs out(*env_);
    const env::VectorOutputs p = out.pointers();
    env::VectorAction a;
    a.move = {move.data(), static_cast<std::size_t>(move.size())};
    if (prediction) a.prediction = {prediction->data(), static_cast<std::size_t>(prediction->size())};
    if (goal) a.goal = {goal->data(), static_cast<std::size_t>(goal->size())};
    {
      py::gil_scoped_release release;  // the arrays stay alive: this frame holds them
      const std::lock_guard<std::mutex> one_at_a_time(mutex_);
      env_->step(a, p);
      if (paths_)
        for (py::ssize_t r = 0; r < n * K; ++r)
          goals_[r] =
              goal ? std::optional(render::PixelPose{goal->data()[2 * r], goal->data()[2 * r + 1]}) : std::nullopt;
      track();
    }
    out.episodes(*env_);
    return py::make_tuple(out.observation(), out.reward, out.terminated, out.truncated, out.info());
  }

  // Env i as `scout run --video` draws it after a move: the floor shaded where unseen, the path
  // of its run so far, its disc and camera window, and the goal of its last action (if any); in a
  // world with teams, every robot of the team in its colour. RGB, `scale` image pixels a floor pixel.
  py::array_t<std::uint8_t> render(int env_index, int scale) {
    if (!paths_) throw InputError("render: the environment was made without render_mode=\"rgb_array\"");
    const int K = env_->team_size();
    if (env_index < 0 || env_index >= env_->num_envs() || (*paths_)[env_index * K].empty())
      throw InputError("render: call reset first");
    const int robot = env_index * K;
    render::Picture picture;
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> one_at_a_time(mutex_);
      const env::VectorEnv& e = *env_;
      const auto area = static_cast<std::size_t>(e.width()) * e.height();
      render::Snapshot s;
      const std::vector<std::uint8_t> floor = e.floor_image(env_index);
      s.floor = floor.data();
      s.width_px = e.width();
      s.height_px = e.height();
      s.revealed = e.batch().revealed().data() + area * robot;
      s.faint_unseen_floor = e.world().floor.composed();
      s.patch_px = e.patch_px();
      std::vector<std::uint8_t> wide_revealed, wide_seen;  // the coarse map per floor pixel
      if (e.wide_px() > 0) {
        const grid::BlockGrid& blocks = e.batch().wide_grid();
        const grid::FloorFrame frame{.width_px = e.width(), .height_px = e.height()};
        const std::size_t block_bytes = static_cast<std::size_t>(blocks.area());
        wide_revealed.resize(area);
        wide_seen.resize(area);
        grid::expand_blocks(blocks, frame, e.batch().wide_revealed().data() + block_bytes * robot,
                            wide_revealed.data());
        grid::expand_blocks(blocks, frame, e.batch().wide_seen().data() + block_bytes * robot, wide_seen.data());
        s.wide_revealed = wide_revealed.data();
        s.wide_seen = wide_seen.data();
        s.wide = {e.wide_px(), e.world().camera.wide_scale};
      }
      s.robot = (*paths_)[robot].back();
      s.goal = goals_[robot];
      s.path = (*paths_)[robot];
      s.scale = scale;
      const double pixel_m = e.world().floor.pixel_size_m;
      const Eigen::Vector2d body = e.batch().pose_m(robot) / pixel_m;
      const double radius_px = e.world().robot.radius_m / pixel_m;
      s.body = render::Snapshot::Body{.x_px = body.x(), .y_px = body.y(), .radius_px = radius_px};
      for (int k = 1; k < K; ++k) {
        render::Snapshot::Teammate& mate = s.teammates.emplace_back();
        mate.robot = (*paths_)[robot + k].back();
        mate.goal = goals_[robot + k];
        mate.path = (*paths_)[robot + k];
        const Eigen::Vector2d at = e.batch().pose_m(robot + k) / pixel_m;
        mate.body = render::Snapshot::Body{.x_px = at.x(), .y_px = at.y(), .radius_px = radius_px};
      }
      picture = render::draw_snapshot(s);
    }
    py::array_t<std::uint8_t> rgb({py::ssize_t{picture.height}, py::ssize_t{picture.width}, py::ssize_t{3}});
    std::uint8_t* to = rgb.mutable_data();
    for (std::size_t k = 0; k + 2 < picture.bgr.size(); k += 3) {
      to[k] = picture.bgr[k + 2];
      to[k + 1] = picture.bgr[k + 1];
      to[k + 2] = picture.bgr[k];
    }
    return rgb;
  }

  // The C++ side of the benchmark: the same steps (moves: steps x N robots, N x K in teams) through
  // env::VectorEnv with one set of output arrays, no Python in the loop. Returns the seconds they took.
  double bench(const Array<std::int32_t>& moves) {
    const std::size_t n = static_cast<std::size_t>(env_->num_envs()) * env_->team_size();
    if (moves.ndim() != 2 || moves.shape(1) != static_cast<py::ssize_t>(n))
      throw InputError("bench: expected moves of shape (steps, " + std::to_string(n) + ")");
    Outputs out(*env_);
    const env::VectorOutputs p = out.pointers();
    const py::ssize_t steps = moves.shape(0);
    const std::int32_t* all = moves.data();
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> one_at_a_time(mutex_);
    const auto t0 = std::chrono::steady_clock::now();
    for (py::ssize_t t = 0; t < steps; ++t) env_->step({.move = std::span(all + t * n, n)}, p);
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  const env::VectorEnv& env() const { return *env_; }

 private:
  // With rendering on: each robot's path in its run so far (a new run starts a new path).
  void track() {
    if (!paths_) return;
    const auto poses = env_->batch().poses();
    for (std::size_t i = 0; i < paths_->size(); ++i) {
      auto& path = (*paths_)[i];
      const render::PixelPose here{poses[i].x(), poses[i].y()};
      if (path.empty() || env_->batch().moves()[i] == 0) path.clear();
      path.push_back(here);
    }
  }

  std::unique_ptr<env::VectorEnv> env_;
  std::optional<std::vector<std::vector<render::PixelPose>>> paths_;  // only with render_mode="rgb_array"
  std::vector<std::optional<render::PixelPose>> goals_;
  std::mutex mutex_;
};

}  // namespace
}  // namespace scout::python

PYBIND11_MODULE(_scout, m) {
  using namespace scout::python;
  m.doc() = "Scout's batched robot environment (use the scout package)";
  m.attr("__version__") = SCOUT_VERSION;
  // Where the world files are (worlds/): the source tree for a build (build/python), the package's
  // share/ folder when installed (core/install_layout.hpp).
  m.attr("files_dir") = scout::core::files_root().string();
  m.attr("installed") = scout::core::installed_files().has_value();
  m.attr("max_envs") = scout::env::VectorEnv::kMaxEnvs;
  register_errors();
  py::class_<VectorEnvCore>(m, "VectorEnvCore")
      .def(py::init<const py::object&, const py::object&, const py::object&, const py::object&, const py::object&,
                    const py::object&, bool, bool, bool>(),
           py::arg("world"), py::arg("num_envs"), py::arg("seed") = py::none(), py::arg("split") = py::none(),
           py::arg("data") = py::none(), py::arg("reward") = "dense", py::arg("force") = false,
           py::arg("autoreset") = true, py::arg("render") = false)
      .def("reset", &VectorEnvCore::reset, py::arg("seed") = py::none(), py::arg("mask") = py::none())
      .def("step", &VectorEnvCore::step, py::arg("action"))
      .def("render", &VectorEnvCore::render, py::arg("robot"), py::arg("scale") = 10)
      .def("bench", &VectorEnvCore::bench, py::arg("moves"))
      .def_property_readonly("num_envs", [](const VectorEnvCore& c) { return c.env().num_envs(); })
      .def_property_readonly("patch_px", [](const VectorEnvCore& c) { return c.env().patch_px(); })
      .def_property_readonly("width", [](const VectorEnvCore& c) { return c.env().width(); })
      .def_property_readonly("height", [](const VectorEnvCore& c) { return c.env().height(); })
      .def_property_readonly("classes", [](const VectorEnvCore& c) { return c.env().classes(); })
      .def_property_readonly("has_obstacles", [](const VectorEnvCore& c) { return c.env().has_obstacles(); })
      .def_property_readonly("team_size", [](const VectorEnvCore& c) { return c.env().team_size(); })
      .def_property_readonly("wide_px", [](const VectorEnvCore& c) { return c.env().wide_px(); })
      .def_property_readonly("episodes", [](const VectorEnvCore& c) { return c.env().world().task.episodes; })
      .def_property_readonly("steps", [](const VectorEnvCore& c) { return c.env().world().task.steps; })
      .def_property_readonly("step_px", [](const VectorEnvCore& c) { return c.env().step_px(); })
      .def_property_readonly("split_size", [](const VectorEnvCore& c) { return c.env().floors().size(); });
}
