// scout._scout: the C++ side of the Python package. VectorEnvCore wraps env::VectorEnv (arrays
// allocated by NumPy, filled by C++ with the GIL released); AgentCore wraps learn::TrainedAgent, the
// checkpoint's policy and classifier driven from observations. The pure-Python layer
// (python/scout/__init__.py) checks shapes and dtypes and gives the Gymnasium-style API.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "env/protocol.hpp"
#include "env/vector_env.hpp"
#include "learn/rollout.hpp"
#include "learn/trained_agent.hpp"
#include "learn/trainer.hpp"

namespace py = pybind11;

namespace scout::python {
namespace {

template <class T>
using Array = py::array_t<T, py::array::c_style>;

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
                std::optional<std::string> split, std::optional<std::string> data, const std::string& reward) {
    env::VectorEnvConfig c;
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
    py::gil_scoped_release release;
    const auto t0 = std::chrono::steady_clock::now();
    for (py::ssize_t t = 0; t < moves.shape(0); ++t) env_->step({.move = std::span(moves.data() + t * n, n)}, p);
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  const env::VectorEnv& env() const { return *env_; }

 private:
  std::unique_ptr<env::VectorEnv> env_;
};

// The trained agent from observations: the state it reads (y, h, the pose, its goals) rebuilt
// from them exactly (revealed * 255 restores the bytes), so that it chooses what `scout run
// --checkpoint` chooses for the same runs.
class AgentCore {
 public:
  AgentCore(const std::string& model, bool greedy, int threads) : greedy_(greedy) {
    py::gil_scoped_release release;
    learn::set_torch_threads(threads);
    agent_ = learn::TrainedAgent::load(model);
  }

  int classes() const { return agent_->classes(); }

  // Returns (moves (N,), goals (N, 2)).
  py::tuple act(const Array<std::int32_t>& pose, const Array<std::uint8_t>& seen, const Array<float>& revealed,
                const Array<std::int32_t>& time_step, const Array<std::uint64_t>& policy_seed,
                const Array<std::int32_t>& episode, const py::array_t<bool, py::array::c_style>& episode_start,
                int patch_px) {
    const int n = static_cast<int>(pose.shape(0));
    Array<std::int32_t> moves(n);
    Array<std::int32_t> goals({static_cast<py::ssize_t>(n), py::ssize_t{2}});
    std::int32_t* move_out = moves.mutable_data();
    std::int32_t* goal_out = goals.mutable_data();
    {
      py::gil_scoped_release release;
      load_state(pose, seen, revealed, patch_px);
      const std::int32_t* t = time_step.data();
      for (int i = 1; i < n; ++i)
        if (t[i] != t[0])
          throw InputError("scout.Agent: every robot must be at the same move of its episode (time_step " +
                           std::to_string(t[0]) + " and " + std::to_string(t[i]) + "), as make_vec keeps them");
      if (t[0] == 0) {  // new runs: the policy draws from each run's own seed
        agent_->begin(state_.frame, patch_px, std::span(policy_seed.data(), static_cast<std::size_t>(n)), greedy_,
                      false);
        std::fill(goals_.begin(), goals_.end(), grid::Cell::Zero());
        begun_ = true;
      }
      if (!begun_) throw InputError("scout.Agent: act() must first see the robots at time_step 0 (after reset)");
      if (episode_start.data()[0]) agent_->policy().choose_goals(state_, episode.data()[0], goals_);
      env::forced_axes(state_.pose, state_.goal, need_, axes_);
      agent_->policy().choose_axes(state_, need_, axes_);
      for (int i = 0; i < n; ++i) {
        const grid::Cell p = state_.pose[i], g = goals_[i];
        move_out[i] = axes_[i] == grid::Axis::Horizontal ? (g.x() > p.x() ? 0 : 1)
                      : axes_[i] == grid::Axis::Vertical ? (g.y() > p.y() ? 2 : 3)
                                                         : 0;  // at the goal: the goal keeps it there
        goal_out[2 * i] = g.x();
        goal_out[2 * i + 1] = g.y();
      }
    }
    return py::make_tuple(moves, goals);
  }

  // log pi_c of every robot (N, D): the classifier on what each has revealed.
  Array<float> classify(const Array<std::int32_t>& pose, const Array<std::uint8_t>& seen, const Array<float>& revealed,
                        int patch_px) {
    const int n = static_cast<int>(pose.shape(0));
    const int d = agent_->classes();
    Array<float> logits({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(d)});
    float* out = logits.mutable_data();
    {
      py::gil_scoped_release release;
      load_state(pose, seen, revealed, patch_px);
      const std::vector<float> p = agent_->classify(state_, n);
      for (std::size_t k = 0; k < p.size(); ++k) out[k] = std::log(std::max(p[k], 1e-30f));
    }
    return logits;
  }

 private:
  void load_state(const Array<std::int32_t>& pose, const Array<std::uint8_t>& seen, const Array<float>& revealed,
                  int patch_px) {
    const int n = static_cast<int>(pose.shape(0));
    const int h = static_cast<int>(seen.shape(1)), w = static_cast<int>(seen.shape(2));
    const grid::FloorFrame frame{
        .width_px = w, .height_px = h, .pixel_size_m = agent_->config().world.floor.pixel_size_m};
    const std::size_t area = static_cast<std::size_t>(w) * h;
    if (frame.width_px != state_.frame.width_px || frame.height_px != state_.frame.height_px ||
        static_cast<int>(poses_.size()) != n) {
      masks_.assign(n, grid::RevealMask(frame));
      poses_.resize(n);
      goals_.assign(n, grid::Cell::Zero());
      need_.resize(n);
      axes_.resize(n);
      observed_.resize(area * n);
      begun_ = false;
    }
    const std::int32_t* p = pose.data();
    for (int i = 0; i < n; ++i) {
      poses_[i] = {p[2 * i], p[2 * i + 1]};
      masks_[i].assign(std::span(seen.data() + area * i, area));
    }
    const float* y = revealed.data();
    for (std::size_t k = 0; k < area * n; ++k) observed_[k] = static_cast<std::uint8_t>(std::lround(y[k] * 255.0f));
    state_.frame = frame;
    state_.patch_px = patch_px;
    state_.count = n;
    state_.pose = poses_;
    state_.goal = goals_;
    state_.seen = masks_;
    state_.observed = observed_;
  }

  std::unique_ptr<learn::TrainedAgent> agent_;
  bool greedy_;
  bool begun_ = false;
  learn::BatchState state_;
  std::vector<grid::Cell> poses_, goals_;
  std::vector<grid::RevealMask> masks_;
  std::vector<std::uint8_t> observed_;
  std::vector<std::uint8_t> need_;
  std::vector<grid::Axis> axes_;
};

}  // namespace
}  // namespace scout::python

PYBIND11_MODULE(_scout, m) {
  using namespace scout::python;
  m.doc() = "Scout's C++ core: the batched robot environment and the trained agent (use the scout package)";
  m.attr("__version__") = SCOUT_VERSION;
  // One clear line for what the caller can fix; nothing reaches the interpreter as a crash.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const scout::InputError& e) {
      PyErr_SetString(PyExc_ValueError, scout::one_line(e.what()).c_str());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, scout::one_line(e.what()).c_str());
    }
  });
  py::class_<VectorEnvCore>(m, "VectorEnvCore")
      .def(py::init<const std::string&, int, std::optional<std::uint64_t>, std::optional<std::string>,
                    std::optional<std::string>, const std::string&>(),
           py::arg("world"), py::arg("num_envs"), py::arg("seed"), py::arg("split"), py::arg("data"), py::arg("reward"))
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
  py::class_<AgentCore>(m, "AgentCore")
      .def(py::init<const std::string&, bool, int>(), py::arg("model"), py::arg("greedy"), py::arg("threads"))
      .def_property_readonly("classes", &AgentCore::classes)
      .def("act", &AgentCore::act, py::arg("pose"), py::arg("seen"), py::arg("revealed"), py::arg("time_step"),
           py::arg("policy_seed"), py::arg("episode"), py::arg("episode_start"), py::arg("patch_px"))
      .def("classify", &AgentCore::classify, py::arg("pose"), py::arg("seen"), py::arg("revealed"),
           py::arg("patch_px"));
}
