#pragma once
// Every field of a World, one by one, for the tests that compare two worlds (the to_yaml round
// trips in tests/worlds). The list is held to the struct and to the schema from both sides:
//   - world_members_are_listed() destructures each struct of worlds/world.hpp into exactly as many
//     names as it has members, so a member added there stops this header from compiling until it
//     is listed in for_each_world_field and the count here is raised;
//   - WorldFuzz.TheComparisonCoversEverySchemaField holds the names listed here to world_schema(),
//     the loader's own table, in its order.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "worlds/world.hpp"

namespace scout::testing {

/// Compiles only while each struct has exactly the members named here (see above). `file` and
/// `lines` say where a world was read from, not what it says: for_each_world_field leaves them
/// out, and a test that parses both worlds from the same origin compares them itself.
[[maybe_unused]] inline void world_members_are_listed(const worlds::World& w) {
  [[maybe_unused]] const auto& [file, floor, robot, controller, camera, task, physics, motion, pushes, obstacles, team,
                                seed, lines] = w;
  [[maybe_unused]] const auto& [dataset, split, index, image, pixel_size_m, size_px, layout, clutter, clutter_px,
                                digits] = w.floor;
  [[maybe_unused]] const auto& [radius_m, mass_kg, max_speed_mps, start] = w.robot;
  [[maybe_unused]] const auto& [kp_per_s, tolerance_px] = w.controller;
  [[maybe_unused]] const auto& [patch_px, wide_px, wide_scale] = w.camera;
  [[maybe_unused]] const auto& [episodes, steps, step_px] = w.task;
  [[maybe_unused]] const auto& [dt_s, velocity_iterations, position_iterations, max_ticks_per_move] = w.physics;
  [[maybe_unused]] const auto& [scale_sd, heading_sd_deg, pose, slip_zones] = w.motion;
  [[maybe_unused]] const auto& [probability, impulse_ns, within_ticks, traction_s] = w.pushes;
  [[maybe_unused]] const auto& [boxes, discs, shade, random_boxes, random_box_min_px, random_box_max_px] = w.obstacles;
  [[maybe_unused]] const auto& [robots] = w.team;
}

/// Calls f(dotted name, a's value, b's value) for every field a world file sets, in the order of
/// world_schema() (which is the order to_yaml writes them in).
template <class F>
void for_each_world_field(const worlds::World& a, const worlds::World& b, F&& f) {
  f("floor.dataset", a.floor.dataset, b.floor.dataset);
  f("floor.split", a.floor.split, b.floor.split);
  f("floor.index", a.floor.index, b.floor.index);
  f("floor.image", a.floor.image, b.floor.image);
  f("floor.pixel_size_m", a.floor.pixel_size_m, b.floor.pixel_size_m);
  f("floor.size_px", a.floor.size_px, b.floor.size_px);
  f("floor.layout", a.floor.layout, b.floor.layout);
  f("floor.clutter", a.floor.clutter, b.floor.clutter);
  f("floor.clutter_px", a.floor.clutter_px, b.floor.clutter_px);
  f("floor.digits", a.floor.digits, b.floor.digits);
  f("robot.radius_m", a.robot.radius_m, b.robot.radius_m);
  f("robot.mass_kg", a.robot.mass_kg, b.robot.mass_kg);
  f("robot.max_speed_mps", a.robot.max_speed_mps, b.robot.max_speed_mps);
  f("robot.start", a.robot.start, b.robot.start);
  f("controller.kp_per_s", a.controller.kp_per_s, b.controller.kp_per_s);
  f("controller.tolerance_px", a.controller.tolerance_px, b.controller.tolerance_px);
  f("camera.patch_px", a.camera.patch_px, b.camera.patch_px);
  f("camera.wide_px", a.camera.wide_px, b.camera.wide_px);
  f("camera.wide_scale", a.camera.wide_scale, b.camera.wide_scale);
  f("task.episodes", a.task.episodes, b.task.episodes);
  f("task.steps", a.task.steps, b.task.steps);
  f("task.step_px", a.task.step_px, b.task.step_px);
  f("physics.dt_s", a.physics.dt_s, b.physics.dt_s);
  f("physics.velocity_iterations", a.physics.velocity_iterations, b.physics.velocity_iterations);
  f("physics.position_iterations", a.physics.position_iterations, b.physics.position_iterations);
  f("physics.max_ticks_per_move", a.physics.max_ticks_per_move, b.physics.max_ticks_per_move);
  f("motion.scale_sd", a.motion.scale_sd, b.motion.scale_sd);
  f("motion.heading_sd_deg", a.motion.heading_sd_deg, b.motion.heading_sd_deg);
  f("motion.pose", a.motion.pose, b.motion.pose);
  f("motion.slip_zones", a.motion.slip_zones, b.motion.slip_zones);
  f("pushes.probability", a.pushes.probability, b.pushes.probability);
  f("pushes.impulse_ns", a.pushes.impulse_ns, b.pushes.impulse_ns);
  f("pushes.within_ticks", a.pushes.within_ticks, b.pushes.within_ticks);
  f("pushes.traction_s", a.pushes.traction_s, b.pushes.traction_s);
  f("obstacles.boxes", a.obstacles.boxes, b.obstacles.boxes);
  f("obstacles.discs", a.obstacles.discs, b.obstacles.discs);
  f("obstacles.shade", a.obstacles.shade, b.obstacles.shade);
  f("obstacles.random_boxes", a.obstacles.random_boxes, b.obstacles.random_boxes);
  f("obstacles.random_box_min_px", a.obstacles.random_box_min_px, b.obstacles.random_box_min_px);
  f("obstacles.random_box_max_px", a.obstacles.random_box_max_px, b.obstacles.random_box_max_px);
  f("team.robots", a.team.robots, b.team.robots);
  f("seed", a.seed, b.seed);
}

/// The dotted names for_each_world_field visits, in its order.
inline std::vector<std::string> listed_world_fields() {
  std::vector<std::string> names;
  const worlds::World w;
  for_each_world_field(w, w, [&names](const char* name, const auto&, const auto&) { names.emplace_back(name); });
  return names;
}

/// Every field of `a` equals `b`'s exactly (numbers too: to_yaml writes the shortest text that
/// reads back to the same double); each difference is reported with its field's name.
inline void expect_same_world(const worlds::World& a, const worlds::World& b) {
  for_each_world_field(a, b,
                       [](const char* name, const auto& x, const auto& y) { EXPECT_EQ(x, y) << "field " << name; });
}

}  // namespace scout::testing
