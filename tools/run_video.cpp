#include "tools/run_video.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace scout::tools {

int append_run_frames(render::VideoWriter& video, const RunAnimation& run) {
  const learn::RolloutRecord& record = *run.record;
  grid::RevealMask seen(run.frame);
  seen.reveal(grid::camera_window(record.start, run.patch_px, run.frame));

  render::Snapshot s;
  s.floor = run.floor;
  s.width_px = run.frame.width_px;
  s.height_px = run.frame.height_px;
  s.patch_px = run.patch_px;
  s.scale = run.scale;
  s.class_probabilities = run.class_probabilities;
  s.prediction_pending = true;
  s.obstacles = run.obstacles;
  s.slip = run.slip;
  s.path.push_back({.x = record.start.x(), .y = record.start.y()});
  int frames = 0;
  auto draw = [&](const Eigen::Vector2d& body_px) {
    s.revealed = seen.data().data();
    s.robot = {.x = static_cast<int>(std::floor(body_px.x())), .y = static_cast<int>(std::floor(body_px.y()))};
    s.body = render::Snapshot::Body{.x_px = body_px.x(), .y_px = body_px.y(), .radius_px = run.robot_radius_px};
    const render::FloorPoint here{static_cast<float>(body_px.x()), static_cast<float>(body_px.y())};
    // Held frames repeat the last point: kept once, so that a long run draws in linear time.
    if (!run.exact_motion && (s.true_path.empty() || s.true_path.back().x != here.x || s.true_path.back().y != here.y))
      s.true_path.push_back(here);
    video.add(render::draw_snapshot(s));
    ++frames;
  };
  const int goal_hold = std::max(1, static_cast<int>(std::lround(run.fps * 0.4)));
  const int final_hold = std::max(1, static_cast<int>(std::lround(run.fps)));

  std::size_t tick = 0;  // tick_path_px[0] is the start
  Eigen::Vector2d body = record.tick_path_px.empty() ? run.frame.cell_centre_px(record.start) : record.tick_path_px[0];
  for (std::size_t k = 0; k < record.steps.size(); ++k) {
    const learn::StepRecord& step = record.steps[k];
    if (k == 0 || step.episode != record.steps[k - 1].episode) {  // a new goal: let it be seen
      s.goal = render::PixelPose{.x = step.goal.x(), .y = step.goal.y()};
      for (int h = 0; h < goal_hold; ++h) draw(body);
    }
    for (int t = 0; t < step.result.ticks && tick + 1 < record.tick_path_px.size(); ++t) {
      body = record.tick_path_px[++tick];
      draw(body);
    }
    // The camera sees its window once the move is over.
    seen.reveal(grid::camera_window(step.grid_pose, run.patch_px, run.frame));
    s.path.push_back({.x = step.grid_pose.x(), .y = step.grid_pose.y()});
    if (step.result.ticks == 0) draw(body);  // a move that needed no tick still reveals
  }
  s.goal.reset();
  s.prediction_pending = false;
  for (int h = 0; h < final_hold; ++h) draw(body);
  return frames;
}

}  // namespace scout::tools
