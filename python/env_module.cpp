// scout._scout: the environment side of the Python package. VectorEnvCore wraps env::VectorEnv:
// arrays allocated by NumPy, filled by C++ with the GIL released. Torch-free (scout.Agent's module
// is _scout_agent). The pure-Python layer (python/scout/__init__.py) checks shapes and dtypes and
// gives the Gymnasium-style API.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "env/vector_env.hpp"
#include "python/bindings.hpp"

namespace py = pybind11;

namespace scout::python {
namespace {

worlds::Split parse_split(const std::string& split) {
  if (split == "train") return worlds::Split::Train;
  if (split == "validation") return worlds::Split::Validation;
  if (split == "test") return worlds::Split::Test;
  throw InputError("split: expected train, validation or test, got \"" + split + "\"");
}

// One call's output arrays, allocated by NumPy (fresh each call: the caller may keep them).
struct Outputs {
  Array<float> patch, revealed, reward;
  Array<std::int32_t> pose, time_step, label, index, episode;
  Array<std::uint8_t> seen;
  Array<double> pose_m;
  Array<std::uint64_t> policy_seed;
  py::array_t<bool> terminated, truncated, episode_start;

  explicit Outputs(const env::VectorEnv& e) {
    const py::ssize_t n = e.num_envs(), m = e.patch_px(), h = e.height(), w = e.width();
    patch = Array<float>({n, m, m});
    revealed = Array<float>({n, h, w});
    reward = Array<float>(n);
    pose = Array<std::int32_t>({n, py::ssize_t{2}});
    time_step = Array<std::int32_t>(n);
    label = Array<std::int32_t>(n);
    index = Array<std::int32_t>(n);
    episode = Array<std::int32_t>(n);
    seen = Array<std::uint8_t>({n, h, w});
    pose_m = Array<double>({n, py::ssize_t{2}});
    policy_seed = Array<std::uint64_t>(n);
    terminated = py::array_t<bool>(n);
    truncated = py::array_t<bool>(n);
    episode_start = py::array_t<bool>(n);
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
            .truncated = reinterpret_cast<std::uint8_t*>(truncated.mutable_data())};
  }

  // Which episode each robot's next move belongs to, and whether it starts one (a goal is due).
  void episodes(const env::VectorEnv& e) {
    const int steps = e.world().task.steps, moves = e.episode_moves();
    auto* t = time_step.data();
    auto* ep = episode.mutable_data();
    auto* start = episode_start.mutable_data();
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
    obs["time_step"] = time_step;
    return obs;
  }
  py::dict info() const {
    py::dict i;
    i["label"] = label;
    i["index"] = index;
    i["pose_m"] = pose_m;
    i["policy_seed"] = policy_seed;
    i["episode"] = episode;
    i["episode_start"] = episode_start;
    return i;
  }
};

class VectorEnvCore {
 public:
  VectorEnvCore(const std::string& world, int num_envs, std::optional<std::uint64_t> seed,
                std::optional<std::string> split, std::optional<std::string> data, const std::string& reward,
                bool force) {
    env::VectorEnvConfig c;
    c.force = force;
    c.world_file = world;
    c.num_envs = num_envs;
    c.seed = seed;
    if (split) c.split = parse_split(*split);
    if (data) c.data_root = *data;
    if (reward != "dense" && reward != "sparse")
      throw InputError("reward: expected \"dense\" or \"sparse\", got \"" + reward + "\"");
    c.reward = reward == "dense" ? env::Reward::Dense : env::Reward::Sparse;
    py::gil_scoped_release release;
    env_ = std::make_unique<env::VectorEnv>(c);
  }

  py::tuple reset(std::optional<std::uint64_t> seed) {
    Outputs out(*env_);
    const env::VectorOutputs p = out.pointers();
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> one_at_a_time(mutex_);  // threads may share an env
      env_->reset(seed, p);
    }
    out.episodes(*env_);
    return py::make_tuple(out.observation(), out.info());
  }

  py::tuple step(const Array<std::int32_t>& move, const std::optional<Array<float>>& prediction,
                 const std::optional<Array<std::int32_t>>& goal) {
    Outputs out(*env_);
    const env::VectorOutputs p = out.pointers();
    env::VectorAction action;
    action.move = {move.data(), static_cast<std::size_t>(move.size())};
    if (prediction) action.prediction = {prediction->data(), static_cast<std::size_t>(prediction->size())};
    if (goal) action.goal = {goal->data(), static_cast<std::size_t>(goal->size())};
    {
      py::gil_scoped_release release;  // the arrays stay alive: the caller holds them
      const std::lock_guard<std::mutex> one_at_a_time(mutex_);
      env_->step(action, p);
    }
    out.episodes(*env_);
    return py::make_tuple(out.observation(), out.reward, out.terminated, out.truncated, out.info());
  }

  // The C++ side of the benchmark: the same steps (moves: steps x N) through env::VectorEnv with
  // one set of output arrays, no Python in the loop. Returns the seconds they took.
  double bench(const Array<std::int32_t>& moves) {
    if (moves.ndim() != 2 || moves.shape(1) != env_->num_envs())
      throw InputError("bench: expected moves of shape (steps, " + std::to_string(env_->num_envs()) + ")");
    Outputs out(*env_);
    const env::VectorOutputs p = out.pointers();
    const std::size_t n = static_cast<std::size_t>(env_->num_envs());
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
  std::unique_ptr<env::VectorEnv> env_;
  std::mutex mutex_;
};

// The trained agent from observations: the state it reads (y, h, the pose, its goals) rebuilt
// from them exactly (revealed * 255 restores the bytes), so that it chooses what `scout run
// --checkpoint` chooses for the same runs.
}  // namespace
}  // namespace scout::python

PYBIND11_MODULE(_scout, m) {
  using namespace scout::python;
  m.doc() = "Scout's batched robot environment (use the scout package)";
  m.attr("__version__") = SCOUT_VERSION;
  register_errors();
  py::class_<VectorEnvCore>(m, "VectorEnvCore")
      .def(py::init<const std::string&, int, std::optional<std::uint64_t>, std::optional<std::string>,
                    std::optional<std::string>, const std::string&, bool>(),
           py::arg("world"), py::arg("num_envs"), py::arg("seed"), py::arg("split"), py::arg("data"), py::arg("reward"),
           py::arg("force") = false)
      .def("reset", &VectorEnvCore::reset, py::arg("seed"))
      .def("step", &VectorEnvCore::step, py::arg("move"), py::arg("prediction"), py::arg("goal"))
      .def("bench", &VectorEnvCore::bench, py::arg("moves"))
      .def_property_readonly("num_envs", [](const VectorEnvCore& c) { return c.env().num_envs(); })
      .def_property_readonly("patch_px", [](const VectorEnvCore& c) { return c.env().patch_px(); })
      .def_property_readonly("width", [](const VectorEnvCore& c) { return c.env().width(); })
      .def_property_readonly("height", [](const VectorEnvCore& c) { return c.env().height(); })
      .def_property_readonly("classes", [](const VectorEnvCore& c) { return c.env().classes(); })
      .def_property_readonly("episodes", [](const VectorEnvCore& c) { return c.env().world().task.episodes; })
      .def_property_readonly("steps", [](const VectorEnvCore& c) { return c.env().world().task.steps; })
      .def_property_readonly("step_px", [](const VectorEnvCore& c) { return c.env().step_px(); })
      .def_property_readonly("split_size", [](const VectorEnvCore& c) { return c.env().floors().size(); });
}
