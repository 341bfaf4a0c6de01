#include "tools/run_video.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace scout::tools {

namespace {

// The wider view's coarse map per floor pixel, as env::BatchEnv::reveal_wide paints it and
// grid::expand_blocks writes it out: every floor pixel of a block a look covers takes its mean, the
// latest look winning, at each grid pose. Empty without the wider view.
class CoarseMap {
 public:
  explicit CoarseMap(const RunAnimation& run)
      : run_(run),
        values_(run.wide.px > 0 ? static_cast<std::size_t>(run.frame.area_px()) : 0),
        seen_(values_.size()),
        look_(static_cast<std::size_t>(run.wide.px) * run.wide.px) {}

  void reveal(const grid::Cell& pose) {
    const int px = run_.wide.px, scale = run_.wide.scale;
    const int width = run_.frame.width_px, height = run_.frame.height_px;
    if (px == 0) return;
    render::wide_patch(run_.floor, width, height, run_.wide, {.x = pose.x(), .y = pose.y()}, look_.data());
    const grid::BlockGrid blocks = grid::BlockGrid::over(run_.frame, scale);
    const int x0 = (blocks.block_of(pose.x()) - px / 2) * scale, y0 = (blocks.block_of(pose.y()) - px / 2) * scale;
    for (int y = std::max(y0, 0); y < std::min(y0 + px * scale, height); ++y)
      for (int x = std::max(x0, 0); x < std::min(x0 + px * scale, width); ++x) {
        const std::size_t at = static_cast<std::size_t>(y) * width + x;
        values_[at] = look_[static_cast<std::size_t>((y - y0) / scale) * px + (x - x0) / scale];
        seen_[at] = 1;
      }
  }

  // Points the snapshot at the map (nothing without the wider view).
  void show_in(render::Snapshot& s) const {
    s.wide = run_.wide;
    if (values_.empty()) return;
    s.wide_revealed = values_.data();
    s.wide_seen = seen_.data();
  }

 private:
  const RunAnimation& run_;
  std::vector<std::uint8_t> values_, seen_, look_;
};

// What every frame of the run shows alike: the floor, its scenery and the prediction panel.
render::Snapshot run_snapshot(const RunAnimation& run) {
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
  s.faint_unseen_floor = run.faint_floor;
  return s;
}

// Robot k's disc where its body is, and the cell under its centre (robot 0 through the snapshot's
// own fields, robot k > 0 through teammates[k - 1]).
void show_body(render::Snapshot& s, std::size_t k, const Eigen::Vector2d& b, double radius_px) {
  const render::PixelPose cell{.x = static_cast<int>(std::floor(b.x())), .y = static_cast<int>(std::floor(b.y()))};
  const render::Snapshot::Body disc{.x_px = b.x(), .y_px = b.y(), .radius_px = radius_px};
  if (k == 0) {
    s.robot = cell;
    s.body = disc;
  } else {
    s.teammates[k - 1].robot = cell;
    s.teammates[k - 1].body = disc;
  }
}

}  // namespace

int append_run_frames(render::VideoWriter& video, const RunAnimation& run) {
  const std::span<const learn::RolloutRecord> records = run.records;
  const std::size_t team = records.size();
  grid::RevealMask seen(run.frame);
  CoarseMap coarse(run);
  for (const learn::RolloutRecord& r : records) {
    seen.reveal(grid::camera_window(r.start, run.patch_px, run.frame));
    coarse.reveal(r.start);
  }
  render::Snapshot s = run_snapshot(run);
  coarse.show_in(s);
  s.teammates.resize(team - 1);
  // Robot 0 is drawn through the snapshot's own fields, robot k > 0 through teammates[k - 1].
  auto path_of = [&](std::size_t k) -> std::vector<render::PixelPose>& {
    return k == 0 ? s.path : s.teammates[k - 1].path;
  };
  auto true_path_of = [&](std::size_t k) -> std::vector<render::FloorPoint>& {
    return k == 0 ? s.true_path : s.teammates[k - 1].true_path;
  };
  auto goal_of = [&](std::size_t k) -> std::optional<render::PixelPose>& {
    return k == 0 ? s.goal : s.teammates[k - 1].goal;
  };
  for (std::size_t k = 0; k < team; ++k) path_of(k).push_back({.x = records[k].start.x(), .y = records[k].start.y()});
  int frames = 0;
  std::vector<Eigen::Vector2d> body(team);
  auto draw = [&] {
    s.revealed = seen.data().data();
    for (std::size_t k = 0; k < team; ++k) {
      const Eigen::Vector2d& b = body[k];
      show_body(s, k, b, run.robot_radius_px);
      const render::FloorPoint here{static_cast<float>(b.x()), static_cast<float>(b.y())};
      // Held frames repeat the last point: kept once, so that a long run draws in linear time.
      std::vector<render::FloorPoint>& trail = true_path_of(k);
      if (!run.exact_motion && (trail.empty() || trail.back().x != here.x || trail.back().y != here.y))
        trail.push_back(here);
    }
    video.add(render::draw_snapshot(s));
    ++frames;
  };
  const int goal_hold = std::max(1, static_cast<int>(std::lround(run.fps * 0.4)));
  const int final_hold = std::max(1, static_cast<int>(std::lround(run.fps)));

  std::vector<std::size_t> tick(team, 0);  // tick_path_px[0] is the start
  for (std::size_t k = 0; k < team; ++k)
    body[k] = records[k].tick_path_px.empty() ? run.frame.cell_centre_px(records[k].start) : records[k].tick_path_px[0];
  const std::vector<learn::StepRecord>& steps = records[0].steps;  // a team's robots move at the same steps
  for (std::size_t j = 0; j < steps.size(); ++j) {
    if (j == 0 || steps[j].episode != steps[j - 1].episode) {  // new goals: let them be seen
      for (std::size_t k = 0; k < team; ++k)
        goal_of(k) = render::PixelPose{.x = records[k].steps[j].goal.x(), .y = records[k].steps[j].goal.y()};
      for (int h = 0; h < goal_hold; ++h) draw();
    }
    // The team's robots tick together; one whose move is over holds its place.
    int ticks = 0;
    for (std::size_t k = 0; k < team; ++k) ticks = std::max(ticks, records[k].steps[j].result.ticks);
    for (int t = 0; t < ticks; ++t) {
      for (std::size_t k = 0; k < team; ++k)
        if (t < records[k].steps[j].result.ticks && tick[k] + 1 < records[k].tick_path_px.size())
          body[k] = records[k].tick_path_px[++tick[k]];
      draw();
    }
    // The cameras see their windows once the move is over.
    for (std::size_t k = 0; k < team; ++k) {
      const grid::Cell& pose = records[k].steps[j].grid_pose;
      seen.reveal(grid::camera_window(pose, run.patch_px, run.frame));
      coarse.reveal(pose);
      path_of(k).push_back({.x = pose.x(), .y = pose.y()});
    }
    if (ticks == 0) draw();  // a move that needed no tick still reveals
  }
  for (std::size_t k = 0; k < team; ++k) goal_of(k).reset();
  s.prediction_pending = false;
  for (int h = 0; h < final_hold; ++h) draw();
  return frames;
}

}  // namespace scout::tools
