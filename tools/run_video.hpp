#pragma once
// `scout run --video`: a rollout's frames, one per physics tick.
#include <cstdint>
#include <span>

#include "grid/grid.hpp"
#include "learn/rollout.hpp"
#include "render/camera.hpp"
#include "render/video.hpp"

namespace scout::tools {

/// One run to animate.
struct RunAnimation {
  /// Recorded by RolloutEngine::run (ticks included): one robot's, or a team's robots' in order.
  std::span<const learn::RolloutRecord> records;
  const std::uint8_t* floor = nullptr;  ///< H * W bytes
  grid::FloorFrame frame;
  int patch_px = 6;
  double robot_radius_px = 2.5;
  int scale = 10;
  std::span<const float> class_probabilities;  ///< the final prediction (empty: no panel)
  double fps = 30;
  bool exact_motion = true;                 ///< false: imperfect motion or pushes, and the true path is drawn too
  const std::uint8_t* obstacles = nullptr;  ///< H * W obstacle mask, drawn on every frame; null: none
  const std::uint8_t* slip = nullptr;       ///< H * W slip-zone mask, tinted on every frame; null: none
  bool faint_floor = false;                 ///< the unseen floor shows faintly (a composed floor)
  /// The camera's wider view (px 0: none): its window outlined where the body is, and the coarse
  /// map it has made so far shown where the patch has not been, as in the pictures.
  render::WideView wide{};
};

/// Appends the run's frames to `video`: a short hold on each episode's new goal, then one frame
/// per physics tick with the robot's disc and camera window where the body is, the floor revealed
/// as the camera saw it after each move (with the wider view, the team's coarse map too, made with
/// render::wide_patch, which equals the camera's), the path so far and the goal; at the end a one-second
/// hold on the final picture with the prediction bars, which stay empty until then (the
/// classifier is asked once, after the last move). A team's robots move in the same frames, each
/// in its colour (render::teammate_colour), over what the team has seen. Returns the number of
/// frames added.
int append_run_frames(render::VideoWriter& video, const RunAnimation& run);

}  // namespace scout::tools
