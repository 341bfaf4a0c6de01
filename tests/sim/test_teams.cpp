// Physics in the loop for several robots on one floor (docs/SCENARIOS.md § Several robots): a
// team's robots share one Box2D world, tick together and collide. No robot's disc ever overlaps
// a teammate's beyond Box2D's contact tolerance, over thousands of moves; a move into a teammate
// ends at contact; a robot whose move is over holds its place; and a team's trajectory depends on
// its own commands alone, not on the batch or the threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "core/random.hpp"
#include "sim/robots.hpp"

namespace scout::sim {
namespace {

const grid::FloorFrame kFloor{28, 28, 0.1};

RobotParams team_of(int k) {
  RobotParams p;
  p.team.robots = k;
  return p;
}

double radius_px(const RobotParams& p) { return p.body.radius_m / kFloor.pixel_size_m; }

// Where robot i was after tick t of the last move: its trace, or, once its move was over (it held
// its place), its last traced position; before any tick, where it started.
Eigen::Vector2d at_tick(const std::vector<Eigen::Vector2d>& trace, const Eigen::Vector2d& start, int t) {
  if (trace.empty()) return start;
  return trace[std::min<std::size_t>(static_cast<std::size_t>(t), trace.size() - 1)];
}

TEST(Teams, NoRobotEverOverlapsATeammate) {
  const int K = 4, teams = 30, robots = K * teams;
  const RobotParams p = team_of(K);
  const double diameter = 2.0 * radius_px(p);
  RobotBatch batch(kFloor, p, robots);
  core::Rng rng(11);
  // Starts clear of each other's bumpers, as env::draw_team_starts draws them.
  const double spacing = 2.0 * RobotBatch::bumper_radius_px(p, kFloor);
  for (int team = 0; team < teams; ++team) {
    std::vector<grid::Cell> placed;
    while (static_cast<int>(placed.size()) < K) {
      const grid::Cell c{static_cast<int>(core::uniform_below(rng, 28)),
                         static_cast<int>(core::uniform_below(rng, 28))};
      if (std::ranges::all_of(placed, [&](const grid::Cell& s) { return (c - s).cast<double>().norm() > spacing; }))
        placed.push_back(c);
    }
    for (int k = 0; k < K; ++k) batch.place(team * K + k, placed[k]);
  }
  std::vector<grid::Cell> commands(robots);
  std::vector<MoveResult> results(robots);
  std::vector<std::vector<Eigen::Vector2d>> traces(robots);
  std::vector<Eigen::Vector2d> starts(robots);
  double closest = 1e9;
  long moves = 0, blocked = 0, contacts_checked = 0;
  for (int step = 0; step < 60; ++step) {
    for (int i = 0; i < robots; ++i) {
      // Moves of up to 4 px along one axis, toward teammates as often as not.
      const int length = static_cast<int>(core::uniform_below(rng, 9)) - 4;
      commands[i] = core::uniform_below(rng, 2) ? grid::Cell(length, 0) : grid::Cell(0, length);
      starts[i] = batch.position_px(i);
      traces[i].clear();
    }
    batch.move(commands, results, traces);
    for (int team = 0; team < teams; ++team) {
      int ticks = 0;
      for (int k = 0; k < K; ++k) ticks = std::max(ticks, results[team * K + k].ticks);
      for (int t = 0; t < ticks; ++t)
        for (int a = team * K; a < (team + 1) * K; ++a)
          for (int b = a + 1; b < (team + 1) * K; ++b) {
            const double d = (at_tick(traces[a], starts[a], t) - at_tick(traces[b], starts[b], t)).norm();
            closest = std::min(closest, d);
            ++contacts_checked;
          }
    }
    for (const MoveResult& r : results) {
      moves += r.ticks > 0;
      blocked += r.blocked;
    }
  }
  std::printf("closest centres %.3f px (diameter %.1f) over %ld moves, %ld blocked\n", closest, diameter, moves,
              blocked);
  EXPECT_GT(moves, 5000);
  EXPECT_GT(blocked, 100) << "the moves should meet teammates often";
  EXPECT_GT(contacts_checked, 100000);
  // Discs touch at a diameter. Teammates meet through bumpers one tick's travel (1/3 px) wider
  // than their discs, so that two robots closing in at full speed stop before their discs meet
  // (within Box2D's slop, 0.05 px here).
  EXPECT_GE(closest, diameter - 0.05);
  EXPECT_LT(closest, diameter + 2.0 / 3.0) << "no pair ever came into contact";
}

TEST(Teams, AMoveIntoATeammateEndsAtContactAndTheTeammateHoldsItsPlace) {
  const RobotParams p = team_of(2);
  const double diameter = 2.0 * radius_px(p);
  RobotBatch batch(kFloor, p, 2);
  batch.place(0, {4, 9});
  batch.place(1, {14, 9});
  std::vector<MoveResult> results(2);
  batch.move(std::vector<grid::Cell>{{10, 0}, {0, 0}}, results);
  EXPECT_TRUE(results[0].blocked);
  EXPECT_FALSE(results[0].settled);
  EXPECT_LT(results[0].ticks, 60) << "the move should end at contact, not at the tick bound";
  EXPECT_TRUE(results[1].settled);
  EXPECT_EQ(results[1].ticks, 0);
  // The standing robot did not budge; the mover stopped short of it, at its bumper: a diameter
  // and up to two ticks' travel (2/3 px) away.
  EXPECT_NEAR(batch.position_px(1).x(), 14.5, 1e-5);
  EXPECT_NEAR(batch.position_px(1).y(), 9.5, 1e-5);
  const double gap = batch.position_px(1).x() - batch.position_px(0).x();
  EXPECT_GE(gap, diameter - 0.05);
  EXPECT_LE(gap, diameter + 2.0 / 3.0);
  EXPECT_NEAR(batch.position_px(0).y(), 9.5, 1e-3);

  // Head on: both are held, neither passes through the other.
  batch.place(0, {4, 20});
  batch.place(1, {14, 20});
  batch.move(std::vector<grid::Cell>{{10, 0}, {-10, 0}}, results);
  EXPECT_TRUE(results[0].blocked);
  EXPECT_TRUE(results[1].blocked);
  EXPECT_LT(batch.position_px(0).x(), batch.position_px(1).x());
  const double head_on_gap = batch.position_px(1).x() - batch.position_px(0).x();
  EXPECT_GE(head_on_gap, diameter - 0.05);
  EXPECT_LE(head_on_gap, diameter + 2.0 / 3.0);
  EXPECT_NEAR(batch.position_px(0).x() + batch.position_px(1).x(), 4.5 + 14.5, 0.1) << "they meet half way";
}

TEST(Teams, RobotsOfDifferentTeamsDoNotInteract) {
  // Robot 0 of team 0 and robot 2 of team 1 on the same cells: no contact across floors.
  RobotBatch batch(kFloor, team_of(2), 4);
  batch.place(0, {5, 5});
  batch.place(1, {20, 20});
  batch.place(2, {9, 5});
  batch.place(3, {20, 5});
  std::vector<MoveResult> results(4);
  batch.move(std::vector<grid::Cell>{{4, 0}, {0, 0}, {-4, 0}, {0, 0}}, results);
  for (int i : {0, 2}) {
    EXPECT_TRUE(results[i].settled) << i;
    EXPECT_FALSE(results[i].blocked) << i;
  }
  EXPECT_EQ(batch.grid_pose(0), grid::Cell(9, 5));
  EXPECT_EQ(batch.grid_pose(2), grid::Cell(5, 5));
}

// A team's positions after a fixed sequence of commands, robot by robot.
std::vector<Eigen::Vector2d> drive(const RobotParams& p, int teams, int threads, int team_to_watch) {
  const int K = p.team.robots;
  RobotBatch batch(kFloor, p, teams * K, threads);
  for (int i = 0; i < teams * K; ++i) batch.place(i, {3 + 7 * (i % K), 3 + 6 * (i % K)}, 100 + i % K);
  core::Rng rng(5);
  std::vector<grid::Cell> commands(teams * K);
  std::vector<MoveResult> results(teams * K);
  std::vector<Eigen::Vector2d> out;
  for (int step = 0; step < 40; ++step) {
    for (int i = 0; i < K; ++i) {
      const int length = static_cast<int>(core::uniform_below(rng, 7)) - 3;
      const grid::Cell c = core::uniform_below(rng, 2) ? grid::Cell(length, 0) : grid::Cell(0, length);
      for (int team = 0; team < teams; ++team) commands[team * K + i] = c;
    }
    batch.move(commands, results);
    for (int k = 0; k < K; ++k) out.push_back(batch.position_px(team_to_watch * K + k));
  }
  return out;
}

TEST(Teams, ATeamsTrajectoryDependsOnItsCommandsAloneNotOnTheBatchOrTheThreads) {
  RobotParams p = team_of(3);
  p.motion.scale_sd = 0.1;  // the perturbed path too
  p.pushes.probability = 0.3;
  const std::vector<Eigen::Vector2d> alone = drive(p, 1, 1, 0);
  EXPECT_EQ(drive(p, 8, 2, 5), alone);
  EXPECT_EQ(drive(p, 8, 1, 7), alone);
  EXPECT_EQ(drive(team_of(3), 1, 1, 0), drive(team_of(3), 6, 2, 4));
}

TEST(Teams, AMemberCountThatMakesNoWholeTeamsIsRefused) {
  EXPECT_THROW(RobotBatch(kFloor, team_of(2), 3), std::invalid_argument);
  RobotBatch batch(kFloor, team_of(2), 4);
  std::vector<MoveResult> results(4);
  EXPECT_THROW(batch.move(std::vector<grid::Cell>(3, grid::Cell::Zero()), results), std::invalid_argument);
}

}  // namespace
}  // namespace scout::sim
