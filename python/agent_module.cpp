// scout._scout_agent: scout.Agent's C++ side. AgentCore wraps learn::TrainedAgent, the
// checkpoint's policy and classifier, driven from observations; LibTorch comes with it (through
// learn/'s torch-free facade), so `import scout` alone does not load it.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "env/protocol.hpp"
#include "learn/checkpoint.hpp"
#include "learn/rollout.hpp"
#include "learn/trained_agent.hpp"
#include "learn/trainer.hpp"
#include "python/bindings.hpp"

namespace py = pybind11;

namespace scout::python {
namespace {

// Raw views of one call's observation arrays, taken with the GIL held and checked to describe
// the same robots and floor (the Python layer checks too; this is the last line before C++).
struct Observation {
  int n = 0, height = 0, width = 0, patch_px = 0;
  const std::int32_t* pose = nullptr;
  const std::uint8_t* seen = nullptr;
  const float* revealed = nullptr;
  const std::uint8_t* occupied = nullptr;  // o, in worlds with obstacles; null: all zeros
  // The wider view's coarse map and where it is set, in worlds with one; null: none given.
  const float* wide_revealed = nullptr;
  const std::uint8_t* wide_seen = nullptr;

  Observation(const Array<std::int32_t>& pose_a, const Array<std::uint8_t>& seen_a, const Array<float>& revealed_a,
              int patch, const std::optional<Array<std::uint8_t>>& occupied_a = std::nullopt,
              const std::optional<Array<float>>& wide_revealed_a = std::nullopt,
              const std::optional<Array<std::uint8_t>>& wide_seen_a = std::nullopt) {
    if (seen_a.ndim() != 3 || seen_a.shape(0) < 1)
      throw InputError("obs['seen']: expected shape (num_envs, H, W) with num_envs >= 1");
    n = static_cast<int>(seen_a.shape(0));
    height = static_cast<int>(seen_a.shape(1));
    width = static_cast<int>(seen_a.shape(2));
    if (pose_a.ndim() != 2 || pose_a.shape(0) != n || pose_a.shape(1) != 2)
      throw InputError("obs['pose']: expected shape (" + std::to_string(n) + ", 2)");
    if (revealed_a.ndim() != 3 || revealed_a.shape(0) != n || revealed_a.shape(1) != height ||
        revealed_a.shape(2) != width)
      throw InputError("obs['revealed']: expected the shape of obs['seen']");
    if (patch < 1 || patch > std::min(height, width) * 2 + 1)
      throw InputError("obs['patch']: expected m x m patches, got m = " + std::to_string(patch));
    if (occupied_a) {
      if (occupied_a->ndim() != 3 || occupied_a->shape(0) != n || occupied_a->shape(1) != height ||
          occupied_a->shape(2) != width)
        throw InputError("obs['occupied']: expected the shape of obs['seen']");
      occupied = occupied_a->data();
    }
    if (wide_revealed_a.has_value() != wide_seen_a.has_value())
      throw InputError("obs['wide_revealed'] and obs['wide_seen']: expected both or neither");
    if (wide_revealed_a) {
      for (const py::array* a :
           {static_cast<const py::array*>(&*wide_revealed_a), static_cast<const py::array*>(&*wide_seen_a)})
        if (a->ndim() != 3 || a->shape(0) != n || a->shape(1) != height || a->shape(2) != width)
          throw InputError("obs['wide_revealed'] and obs['wide_seen']: expected the shape of obs['seen']");
      wide_revealed = wide_revealed_a->data();
      wide_seen = wide_seen_a->data();
    }
    patch_px = patch;
    pose = pose_a.data();
    seen = seen_a.data();
    revealed = revealed_a.data();
  }
};

template <class T, class A>
const T* per_robot(const A& a, int n, const char* name) {
  if (a.ndim() != 1 || a.shape(0) != n)
    throw InputError(std::string(name) + ": expected shape (" + std::to_string(n) + ",)");
  return a.data();
}

// The trained agent from observations: the state it reads (y, h, the pose, its goals) rebuilt
// from them exactly (revealed * 255 restores the bytes), so that it chooses what `scout run
// --checkpoint` chooses for the same runs.
class AgentCore {
 public:
  AgentCore(const std::string& model, bool greedy, int threads, const std::string& precision) : greedy_(greedy) {
    agent::Precision asked;
    try {
      asked = agent::parse_precision(precision);
    } catch (const std::invalid_argument& e) {
      throw InputError(e.what());
    }
    py::gil_scoped_release release;
    learn::set_torch_threads(threads);
    agent_ = learn::TrainedAgent::load(model, asked);
  }

  int classes() const { return agent_->classes(); }
  std::string precision() const { return agent::to_string(agent_->precision()); }
  std::string trained_precision() const { return agent::to_string(agent_->config().precision); }
  bool wide_view() const { return agent_->config().network.wide_view; }

  // Returns (moves (N,), goals (N, 2)).
  py::tuple act(const Array<std::int32_t>& pose, const Array<std::uint8_t>& seen, const Array<float>& revealed,
                const Array<std::int32_t>& time_step, const Array<std::uint64_t>& policy_seed,
                const Array<std::int32_t>& episode, const py::array_t<bool, py::array::c_style>& episode_start,
                int patch_px, const std::optional<Array<std::uint8_t>>& occupied,
                const std::optional<Array<float>>& wide_revealed, const std::optional<Array<std::uint8_t>>& wide_seen) {
    const Observation obs(pose, seen, revealed, patch_px, occupied, wide_revealed, wide_seen);
    const int n = obs.n;
    const std::int32_t* t = per_robot<std::int32_t>(time_step, n, "obs['time_step']");
    const std::uint64_t* seeds = per_robot<std::uint64_t>(policy_seed, n, "info['policy_seed']");
    const std::int32_t* episodes = per_robot<std::int32_t>(episode, n, "info['goal_episode']");
    const bool* starts = per_robot<bool>(episode_start, n, "info['goal_episode_start']");
    Array<std::int32_t> moves(n);
    Array<std::int32_t> goals({static_cast<py::ssize_t>(n), py::ssize_t{2}});
    std::int32_t* move_out = moves.mutable_data();
    std::int32_t* goal_out = goals.mutable_data();
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> one_at_a_time(mutex_);
      for (int i = 1; i < n; ++i)
        if (t[i] != t[0])
          throw InputError("scout.Agent: every robot must be at the same move of its episode (time_step " +
                           std::to_string(t[0]) + " and " + std::to_string(t[i]) + "), as make_vec keeps them");
      load_state(obs);
      if (t[0] == 0) {  // new runs: the policy draws from each run's own seed
        agent_->begin(state_.frame, obs.patch_px, std::span(seeds, static_cast<std::size_t>(n)), greedy_, false);
        std::fill(goals_.begin(), goals_.end(), grid::Cell::Zero());
        begun_ = true;
      }
      if (!begun_) throw InputError("scout.Agent: act() must first see the robots at time_step 0 (after reset)");
      if (starts[0]) agent_->policy().choose_goals(state_, episodes[0], goals_);
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
    const Observation obs(pose, seen, revealed, patch_px);
    const int d = agent_->classes();
    Array<float> logits({static_cast<py::ssize_t>(obs.n), static_cast<py::ssize_t>(d)});
    float* out = logits.mutable_data();
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> one_at_a_time(mutex_);
      load_state(obs);
      const std::vector<float> p = agent_->classify(state_, obs.n);
      for (std::size_t k = 0; k < p.size(); ++k) out[k] = std::log(std::max(p[k], 1e-30f));
    }
    return logits;
  }

 private:
  void load_state(const Observation& obs) {
    const int n = obs.n;
    const grid::FloorFrame frame{
        .width_px = obs.width, .height_px = obs.height, .pixel_size_m = agent_->config().world.floor.pixel_size_m};
    const std::size_t area = static_cast<std::size_t>(obs.width) * obs.height;
    if (frame.width_px != state_.frame.width_px || frame.height_px != state_.frame.height_px ||
        static_cast<int>(poses_.size()) != n) {
      masks_.assign(n, grid::RevealMask(frame));
      poses_.resize(n);
      goals_.assign(n, grid::Cell::Zero());
      need_.resize(n);
      axes_.resize(n);
      revealed_.resize(area * n);
      begun_ = false;
    }
    for (int i = 0; i < n; ++i) {
      poses_[i] = {obs.pose[2 * i], obs.pose[2 * i + 1]};
      if (!frame.contains(poses_[i]))
        throw InputError("obs['pose'][" + std::to_string(i) + "]: expected a cell of the floor");
      masks_[i].assign(std::span(obs.seen + area * i, area));
    }
    for (std::size_t k = 0; k < area * n; ++k)
      revealed_[k] = static_cast<std::uint8_t>(std::lround(std::clamp(obs.revealed[k], 0.0f, 1.0f) * 255.0f));
    state_.frame = frame;
    state_.patch_px = obs.patch_px;
    state_.step_px = agent_->config().world.task.step_px;  // the route rule's move length: the model's world's
    state_.count = n;
    state_.pose = poses_;
    state_.goal = goals_;
    state_.seen = masks_;
    state_.revealed = revealed_;
    if (obs.occupied != nullptr) {
      occupied_.assign(obs.occupied, obs.occupied + area * n);
      state_.occupied = occupied_;
    } else {
      state_.occupied = {};
    }
    if (obs.wide_revealed != nullptr) {
      // The observation holds the coarse map per floor pixel (each pixel its block's value, as
      // scout.make_vec writes it); the planners read it a byte a block of the model's world's
      // blocks, from each block's first pixel.
      const grid::BlockGrid blocks = grid::BlockGrid::over(frame, agent_->config().world.camera.wide_scale);
      const std::size_t block_bytes = static_cast<std::size_t>(blocks.area());
      wide_revealed_.resize(block_bytes * n);
      wide_seen_.resize(block_bytes * n);
      for (int i = 0; i < n; ++i)
        for (int v = 0; v < blocks.rows; ++v)
          for (int u = 0; u < blocks.columns; ++u) {
            const std::size_t pixel = area * i + static_cast<std::size_t>(v * blocks.scale) * obs.width +
                                      static_cast<std::size_t>(u * blocks.scale);
            const std::size_t block = block_bytes * i + static_cast<std::size_t>(v) * blocks.columns + u;
            wide_revealed_[block] =
                static_cast<std::uint8_t>(std::lround(std::clamp(obs.wide_revealed[pixel], 0.0f, 1.0f) * 255.0f));
            wide_seen_[block] = obs.wide_seen[pixel];
          }
      // A map from a world whose blocks are not the model's would be read misaligned: refused.
      for (int i = 0; i < n; ++i)
        for (int y = 0; y < obs.height; ++y)
          for (int x = 0; x < obs.width; ++x) {
            const std::size_t pixel = area * i + static_cast<std::size_t>(y) * obs.width + x;
            const std::size_t first = area * i + static_cast<std::size_t>(y / blocks.scale * blocks.scale) * obs.width +
                                      static_cast<std::size_t>(x / blocks.scale * blocks.scale);
            if (obs.wide_revealed[pixel] != obs.wide_revealed[first] || obs.wide_seen[pixel] != obs.wide_seen[first])
              throw InputError("obs['wide_revealed'], obs['wide_seen']: expected each map constant on the model's " +
                               std::to_string(blocks.scale) + " x " + std::to_string(blocks.scale) +
                               " blocks (a world with the model's camera.wide_scale)");
          }
      state_.wide_revealed = wide_revealed_;
      state_.wide_seen = wide_seen_;
      state_.wide_grid = blocks;
    } else {
      state_.wide_revealed = {};
      state_.wide_seen = {};
    }
  }

  std::unique_ptr<learn::TrainedAgent> agent_;
  bool greedy_;
  bool begun_ = false;
  std::mutex mutex_;
  learn::BatchState state_;
  std::vector<grid::Cell> poses_, goals_;
  std::vector<grid::RevealMask> masks_;
  std::vector<std::uint8_t> revealed_;
  std::vector<std::uint8_t> occupied_;
  std::vector<std::uint8_t> wide_revealed_, wide_seen_;
  std::vector<std::uint8_t> need_;
  std::vector<grid::Axis> axes_;
};

// Every tensor of a model or checkpoint as Scout loads it (learn::loaded_tensors): name -> NumPy
// array (float32 or int64), for holding Scout's reading against the safetensors package's.
py::dict checkpoint_tensors(const std::string& path) {
  std::vector<learn::LoadedTensor> tensors;
  {
    py::gil_scoped_release release;
    tensors = learn::loaded_tensors(learn::open_checkpoint(path));
  }
  py::dict out;
  for (const learn::LoadedTensor& t : tensors) {
    if (t.integer)
      out[py::str(t.name)] = py::array_t<std::int64_t>(t.shape, t.integers.data());
    else
      out[py::str(t.name)] = py::array_t<float>(t.shape, t.floats.data());
  }
  return out;
}

}  // namespace
}  // namespace scout::python

PYBIND11_MODULE(_scout_agent, m) {
  using namespace scout::python;
  m.doc() = "Scout's trained agent (use scout.Agent)";
  register_errors();
  py::class_<AgentCore>(m, "AgentCore")
      .def(py::init<const std::string&, bool, int, const std::string&>(), py::arg("model"), py::arg("greedy"),
           py::arg("threads"), py::arg("precision"))
      .def_property_readonly("classes", &AgentCore::classes)
      .def_property_readonly("precision", &AgentCore::precision)
      .def_property_readonly("trained_precision", &AgentCore::trained_precision)
      .def_property_readonly("wide_view", &AgentCore::wide_view)
      .def("act", &AgentCore::act, py::arg("pose"), py::arg("seen"), py::arg("revealed"), py::arg("time_step"),
           py::arg("policy_seed"), py::arg("episode"), py::arg("episode_start"), py::arg("patch_px"),
           py::arg("occupied") = py::none(), py::arg("wide_revealed") = py::none(), py::arg("wide_seen") = py::none())
      .def("classify", &AgentCore::classify, py::arg("pose"), py::arg("seen"), py::arg("revealed"),
           py::arg("patch_px"));
  m.def("checkpoint_tensors", &checkpoint_tensors, py::arg("path"));
}
