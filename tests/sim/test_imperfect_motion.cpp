// Physics in the loop for the scenario sections (docs/SCENARIOS.md § Imperfect motion): the real Box2D
// world and the real controller, with the world file's motion errors and pushes. The statistical
// tests state their bounds; each uses thousands of moves, so that a correct implementation fails
// them with a probability far below one in a million, and a wrong scale (a factor of 2 in a
// standard deviation, a missing rotation, a push that never lands) fails them every time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numeric>
#include <vector>

#include "core/random.hpp"
#include "sim/robots.hpp"

namespace scout::sim {
namespace {

// A floor large enough that the tests' moves stay clear of the walls.
const grid::FloorFrame kFloor{64, 64, 0.1};

struct Sample {
  double mean = 0;
  double sd = 0;
};

Sample summarise(const std::vector<double>& v) {
  Sample s;
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  double ss = 0;
  for (double x : v) ss += (x - s.mean) * (x - s.mean);
  s.sd = std::sqrt(ss / static_cast<double>(v.size() - 1));
  return s;
}

// A command of `length` pixels along a random axis and sign, turned back toward the floor's
// centre when the robot is near the middle band's edge, so that no move meets a wall.
grid::Cell interior_command(core::Rng& rng, const grid::Cell& at, int length) {
  const bool horizontal = (rng() >> 63) != 0;
  int sign = (rng() >> 63) != 0 ? 1 : -1;
  const int coordinate = horizontal ? at.x() : at.y();
  if (coordinate < 20) sign = 1;
  if (coordinate > 43) sign = -1;
  return horizontal ? grid::Cell(sign * length, 0) : grid::Cell(0, sign * length);
}

RobotParams noisy(double scale_sd, double heading_sd_deg, worlds::PoseSource pose) {
  RobotParams p;
  p.motion.scale_sd = scale_sd;
  p.motion.heading_sd_deg = heading_sd_deg;
  p.motion.pose = pose;
  // A tight tolerance, so that where a move settles is the motion error, not the controller's slack.
  p.controller.tolerance_px = 0.001;
  return p;
}

void place_all(RobotBatch& batch, core::Rng& rng) {
  for (int i = 0; i < batch.size(); ++i) {
    const grid::Cell start(20 + static_cast<int>(core::uniform_below(rng, 24)),
                           20 + static_cast<int>(core::uniform_below(rng, 24)));
    batch.place(i, start, rng());
  }
}

TEST(ImperfectMotion, AnExactWorldLandsEveryMoveOnItsCommandedCell) {
  // The scenario sections present at their defaults (and the odometry pose, which in an exact
  // world is the true one): thousands of moves, each on its cell's centre.
  RobotParams p;
  p.motion.pose = worlds::PoseSource::Odometry;
  ASSERT_TRUE(p.exact());
  RobotBatch batch(kFloor, p, 100);
  core::Rng rng(5);
  place_all(batch, rng);
  std::vector<grid::Cell> commands(100);
  std::vector<MoveResult> results(100);
  int moves = 0;
  for (int k = 0; k < 20; ++k) {
    std::vector<grid::Cell> targets(100);
    for (int i = 0; i < 100; ++i) {
      commands[i] = interior_command(rng, batch.grid_pose(i), 1 + static_cast<int>(core::uniform_below(rng, 3)));
      targets[i] = batch.grid_pose(i) + commands[i];
    }
    batch.move(commands, results);
    for (int i = 0; i < 100; ++i) {
      ASSERT_TRUE(results[i].settled);
      ASSERT_FALSE(results[i].pushed);
      ASSERT_EQ(batch.grid_pose(i), targets[i]);
      ASSERT_EQ(batch.agent_pose(i), targets[i]);
      ASSERT_LE((batch.position_px(i) - kFloor.cell_centre_px(targets[i])).norm(), p.controller.tolerance_px + 1e-6);
      ++moves;
    }
  }
  EXPECT_EQ(moves, 2000);
}

// Localised robots: each move aims at its cell's centre from where the robot really is, and the
// displacement it makes is s R(theta) times the one it meant, s ~ 1 + N(0, scale_sd^2) and
// theta ~ N(0, heading_sd^2). 2,000 moves of 4 px; the bounds are 4.5 standard errors of each
// estimate (the sample mean's sd / sqrt(n); a sample sd's relative error 1 / sqrt(2 n)).
TEST(ImperfectMotion, LandingErrorsFollowTheWorldFilesScaleAndHeadingDeviations) {
  const double scale_sd = 0.1, heading_sd_deg = 5.0;
  const RobotParams p = noisy(scale_sd, heading_sd_deg, worlds::PoseSource::Localised);
  const int robots = 200, rounds = 10;
  RobotBatch batch(kFloor, p, robots);
  core::Rng rng(11);
  place_all(batch, rng);
  std::vector<double> scale_errors, heading_errors_deg;
  std::vector<grid::Cell> commands(robots);
  std::vector<MoveResult> results(robots);
  for (int k = 0; k < rounds; ++k) {
    std::vector<Eigen::Vector2d> from(robots), meant(robots);
    for (int i = 0; i < robots; ++i) {
      commands[i] = interior_command(rng, batch.grid_pose(i), 4);
      from[i] = batch.position_px(i);
      meant[i] = kFloor.cell_centre_px(batch.grid_pose(i) + commands[i]) - from[i];
    }
    batch.move(commands, results);
    for (int i = 0; i < robots; ++i) {
      ASSERT_TRUE(results[i].settled);
      ASSERT_FALSE(results[i].touched_wall);
      const Eigen::Vector2d made = batch.position_px(i) - from[i];
      scale_errors.push_back(made.norm() / meant[i].norm() - 1.0);
      const double cross = meant[i].x() * made.y() - meant[i].y() * made.x();
      heading_errors_deg.push_back(std::atan2(cross, meant[i].dot(made)) * 180.0 / M_PI);
    }
  }
  const double n = static_cast<double>(scale_errors.size());
  const Sample scale = summarise(scale_errors), heading = summarise(heading_errors_deg);
  std::printf(
      "[ measured ] %zu moves: scale error mean %.4f sd %.4f (world %.3f); heading mean %.3f deg sd %.3f deg "
      "(world %.1f)\n",
      scale_errors.size(), scale.mean, scale.sd, scale_sd, heading.mean, heading.sd, heading_sd_deg);
  EXPECT_LT(std::abs(scale.mean), 4.5 * scale_sd / std::sqrt(n));
  EXPECT_LT(std::abs(heading.mean), 4.5 * heading_sd_deg / std::sqrt(n));
  EXPECT_LT(std::abs(scale.sd / scale_sd - 1.0), 4.5 / std::sqrt(2.0 * n));
  EXPECT_LT(std::abs(heading.sd / heading_sd_deg - 1.0), 4.5 / std::sqrt(2.0 * n));
  // Normal, not merely the right spread: the share within one sd of 0 is 68.3 %, +-4.5 binomial sds.
  const auto within_one_sd = [](const std::vector<double>& v, double sd) {
    return static_cast<double>(std::count_if(v.begin(), v.end(), [sd](double x) { return std::abs(x) < sd; })) /
           static_cast<double>(v.size());
  };
  const double binomial_sd = std::sqrt(0.683 * 0.317 / n);
  EXPECT_NEAR(within_one_sd(scale_errors, scale_sd), 0.683, 4.5 * binomial_sd);
  EXPECT_NEAR(within_one_sd(heading_errors_deg, heading_sd_deg), 0.683, 4.5 * binomial_sd);
}

// Odometry: the agent's pose is the chain of commanded cells, exactly, while the true position
// drifts away from it as a random walk: after k moves of length d the mean squared drift is
// k d^2 (scale_sd^2 + heading_sd^2) to first order. 400 robots; the bound (25 %) is 3.5 standard
// errors of the mean of 400 squared drifts.
TEST(ImperfectMotion, OdometryBelievesTheCommandedCellsWhileTheTruePositionDrifts) {
  const double scale_sd = 0.1, heading_sd_deg = 5.0;
  const RobotParams p = noisy(scale_sd, heading_sd_deg, worlds::PoseSource::Odometry);
  const int robots = 400, moves = 20, d = 2;
  RobotBatch batch(kFloor, p, robots);
  core::Rng rng(23);
  place_all(batch, rng);
  std::vector<grid::Cell> believed(robots), commands(robots);
  for (int i = 0; i < robots; ++i) believed[i] = batch.agent_pose(i);
  std::vector<MoveResult> results(robots);
  std::vector<double> squared_drift(moves + 1, 0.0);
  int true_cell_differs = 0;
  for (int k = 1; k <= moves; ++k) {
    for (int i = 0; i < robots; ++i) {
      commands[i] = interior_command(rng, believed[i], d);
      believed[i] += commands[i];
    }
    batch.move(commands, results);
    for (int i = 0; i < robots; ++i) {
      ASSERT_EQ(batch.agent_pose(i), believed[i]) << "robot " << i << " move " << k;
      ASSERT_EQ(batch.odometry_pose(i), believed[i]);
      squared_drift[k] += (batch.position_px(i) - kFloor.cell_centre_px(believed[i])).squaredNorm() / robots;
      if (k == moves && batch.grid_pose(i) != believed[i]) ++true_cell_differs;
    }
  }
  const double heading_sd = heading_sd_deg * M_PI / 180.0;
  const double per_move = d * d * (scale_sd * scale_sd + heading_sd * heading_sd);
  std::printf(
      "[ measured ] mean squared drift after 1, 10, 20 moves: %.4f %.4f %.4f px^2 (predicted %.4f per move); "
      "%d of %d robots in another cell than they believe\n",
      squared_drift[1], squared_drift[10], squared_drift[20], per_move, true_cell_differs, robots);
  EXPECT_NEAR(squared_drift[20] / (moves * per_move), 1.0, 0.25);
  EXPECT_NEAR(squared_drift[10] / (10 * per_move), 1.0, 0.25);
  EXPECT_GT(true_cell_differs, robots / 4);  // the drift is large enough to matter
}

RobotParams pushed(double probability, double impulse_ns, int max_ticks) {
  RobotParams p;
  p.pushes.probability = probability;
  p.pushes.impulse_ns = impulse_ns;
  p.physics.max_ticks_per_move = max_ticks;
  return p;
}

// Runs `rounds` moves of 2 px for every robot; returns every result and the largest distance
// of a pushed move's trace from its straight path.
struct PushRun {
  std::vector<MoveResult> results;
  std::vector<double> pushed_deviation_px;
  double calm_deviation_px = 0;  // the largest of the moves not pushed
};

PushRun run_pushes(const RobotParams& p, int robots, int rounds, std::uint64_t seed) {
  RobotBatch batch(kFloor, p, robots);
  core::Rng rng(seed);
  place_all(batch, rng);
  PushRun run;
  std::vector<grid::Cell> commands(robots);
  std::vector<MoveResult> results(robots);
  std::vector<std::vector<Eigen::Vector2d>> traces(robots);
  for (int k = 0; k < rounds; ++k) {
    std::vector<Eigen::Vector2d> from(robots);
    for (int i = 0; i < robots; ++i) {
      commands[i] = interior_command(rng, batch.grid_pose(i), 2);
      from[i] = batch.position_px(i);
      traces[i].clear();
    }
    batch.move(commands, results, traces);
    for (int i = 0; i < robots; ++i) {
      run.results.push_back(results[i]);
      const Eigen::Vector2d axis = commands[i].cast<double>().normalized();
      double deviation = 0;
      for (const Eigen::Vector2d& q : traces[i]) {
        const Eigen::Vector2d r = q - from[i];
        deviation = std::max(deviation, std::abs(axis.x() * r.y() - axis.y() * r.x()));
      }
      if (results[i].pushed) {
        run.pushed_deviation_px.push_back(deviation);
      } else {
        run.calm_deviation_px = std::max(run.calm_deviation_px, deviation);
      }
    }
  }
  return run;
}

// Pushes: drawn at the world file's rate, they really move the robot off its path, and the
// controller, which feels them, brings it back onto its cell within the tick limit. A mild push
// (1 N s on 1 kg: 1 m/s, absorbed in 0.1 s) is always recovered within 120 ticks; a strong one
// (8 N s: 8 m/s against the drive's 2, a few pixels) within a 35-tick limit only sometimes, and
// a move that is not ends where the robot is, off its cell.
TEST(ImperfectMotion, PushesLandAtTheirRateAndAreRecoveredWithinTheTickLimit) {
  const PushRun mild = run_pushes(pushed(0.5, 1.0, 120), 200, 10, 31);
  const double n = static_cast<double>(mild.results.size());
  const double pushes = static_cast<double>(
      std::count_if(mild.results.begin(), mild.results.end(), [](const MoveResult& r) { return r.pushed; }));
  EXPECT_NEAR(pushes / n, 0.5, 4.5 * std::sqrt(0.25 / n));
  double pushed_ticks = 0, calm_ticks = 0;
  for (const MoveResult& r : mild.results) {
    EXPECT_TRUE(r.settled) << "a mild push not recovered within 120 ticks";
    (r.pushed ? pushed_ticks : calm_ticks) += r.ticks;
  }
  pushed_ticks /= pushes;
  calm_ticks /= n - pushes;
  std::vector<double> deviation = mild.pushed_deviation_px;
  std::sort(deviation.begin(), deviation.end());
  const double median_deviation = deviation[deviation.size() / 2];
  std::printf(
      "[ measured ] mild pushes: %.0f of %.0f moves pushed; mean ticks %.1f pushed, %.1f not; median "
      "off-path %.2f px\n",
      pushes, n, pushed_ticks, calm_ticks, median_deviation);
  EXPECT_GT(pushed_ticks, calm_ticks + 5);
  EXPECT_GT(median_deviation, 0.1);
  EXPECT_LT(mild.calm_deviation_px, RobotParams{}.controller.tolerance_px + 1e-3)
      << "a move that was not pushed left the straight line from where it began";

  const PushRun strong = run_pushes(pushed(1.0, 8.0, 35), 200, 5, 37);
  const auto recovered =
      std::count_if(strong.results.begin(), strong.results.end(), [](const MoveResult& r) { return r.settled; });
  std::vector<double> strong_deviation = strong.pushed_deviation_px;
  std::sort(strong_deviation.begin(), strong_deviation.end());
  std::printf("[ measured ] strong pushes (8 N s, 35 ticks): %ld of %zu recovered; median off-path %.2f px\n",
              static_cast<long>(recovered), strong.results.size(), strong_deviation[strong_deviation.size() / 2]);
  EXPECT_LT(recovered, static_cast<long>(strong.results.size()));
  EXPECT_GT(recovered, 0);
  EXPECT_GT(strong_deviation[strong_deviation.size() / 2], 1.0);
}

// Pushes toward the walls never carry a robot off the floor: its centre stops within the wall
// margin plus one tick's travel at the fastest a push and the drive together allow.
TEST(ImperfectMotion, PushedRobotsStayOnTheFloor) {
  const RobotParams p = pushed(1.0, 3.0, 120);
  const int robots = 64;
  RobotBatch batch(kFloor, p, robots);
  core::Rng rng(41);
  for (int i = 0; i < robots; ++i) {
    const int edge = static_cast<int>(core::uniform_below(rng, 64));
    batch.place(i, i % 2 ? grid::Cell(edge, i % 4 == 1 ? 0 : 63) : grid::Cell(i % 4 == 0 ? 0 : 63, edge), rng());
  }
  const double fastest_px_per_tick =
      (p.body.max_speed_mps + p.pushes.impulse_ns / p.body.mass_kg) * p.physics.dt_s / kFloor.pixel_size_m;
  std::vector<grid::Cell> commands(robots);
  std::vector<MoveResult> results(robots);
  double worst = 0;
  for (int k = 0; k < 30; ++k) {
    for (int i = 0; i < robots; ++i) commands[i] = interior_command(rng, batch.grid_pose(i), 1);
    batch.move(commands, results);
    for (int i = 0; i < robots; ++i) worst = std::max(worst, results[i].beyond_border_px);
  }
  std::printf("[ measured ] farthest past the border pixels' centres under 3 N s pushes: %.3f px\n", worst);
  EXPECT_LE(worst, RobotBatch::wall_margin_px() + fastest_px_per_tick);
  EXPECT_LT(worst, 0.5) << "the centre left the border pixel";
}

// A robot's motion errors and pushes come from its own seed: the same in a batch of one as in a
// batch of 16, on any number of threads.
TEST(ImperfectMotion, ARobotsMotionDependsOnItsSeedAloneNotOnTheBatch) {
  RobotParams p = noisy(0.2, 10.0, worlds::PoseSource::Odometry);
  p.pushes.probability = 0.5;
  RobotBatch alone(kFloor, p, 1, 1), crowd(kFloor, p, 16, 2);
  core::Rng rng(53);
  std::uint64_t seed5 = 0;
  for (int i = 0; i < 16; ++i) {
    const std::uint64_t seed = rng();
    if (i == 5) seed5 = seed;
    crowd.place(i, {20 + i, 30}, seed);
  }
  alone.place(0, {25, 30}, seed5);
  std::vector<MoveResult> one(1), many(16);
  for (int k = 0; k < 10; ++k) {
    const grid::Cell command = k % 2 ? grid::Cell(0, 2) : grid::Cell(2, 0);
    alone.move(std::vector<grid::Cell>{command}, one);
    crowd.move(std::vector<grid::Cell>(16, command), many);
    ASSERT_EQ(alone.position_px(0), crowd.position_px(5)) << "move " << k;
    ASSERT_EQ(one[0].ticks, many[5].ticks);
    ASSERT_EQ(one[0].pushed, many[5].pushed);
  }
  EXPECT_NE(crowd.position_px(5) - kFloor.cell_centre_px(crowd.agent_pose(5)), Eigen::Vector2d::Zero());
}

// A zero command is no move, in a noisy world as in an exact one: no tick, and the robot stays
// exactly where it is (off its cell's centre, after a noisy move), unpushed.
TEST(ImperfectMotion, AZeroCommandStaysPut) {
  RobotParams p = noisy(0.2, 10.0, worlds::PoseSource::Localised);
  p.pushes.probability = 1.0;
  RobotBatch batch(kFloor, p, 1);
  batch.place(0, {30, 30}, 99);
  std::vector<MoveResult> result(1);
  batch.move(std::vector<grid::Cell>{{3, 0}}, result);
  const Eigen::Vector2d before = batch.position_px(0);
  ASSERT_GT((before - kFloor.cell_centre_px(batch.grid_pose(0))).norm(), 1e-3);
  for (int k = 0; k < 5; ++k) {
    batch.move(std::vector<grid::Cell>{{0, 0}}, result);
    EXPECT_EQ(result[0].ticks, 0);
    EXPECT_FALSE(result[0].pushed);
    EXPECT_EQ(batch.position_px(0), before);
  }
}

// The odometry senses walls: when a move overshoots its border cell and meets the wall, the
// believed position stops with the body, so the cell the robot believes it is in stays next to
// the one it is in (before, the unsensed error kept growing against the wall for the rest of the
// move's ticks, and l ran pixels back into the floor). One move per robot from a fresh start,
// toward the border: the believed and the true centre differ by at most (1 - 1/s) of the way.
TEST(ImperfectMotion, OdometryStaysWithTheRobotWhenAWallStopsIt) {
  const RobotParams p = noisy(0.25, 0.0, worlds::PoseSource::Odometry);
  const int robots = 400;
  RobotBatch batch(kFloor, p, robots);
  core::Rng rng(61);
  for (int i = 0; i < robots; ++i) batch.place(i, {2, 10 + i % 40}, rng());
  std::vector<MoveResult> results(robots);
  batch.move(std::vector<grid::Cell>(robots, grid::Cell(-2, 0)), results);
  int worst = 0, touched = 0, touched_elsewhere = 0;
  for (int i = 0; i < robots; ++i) {
    const int apart = std::abs(batch.odometry_pose(i).x() - batch.grid_pose(i).x());
    worst = std::max(worst, apart);
    touched += results[i].touched_wall ? 1 : 0;
    touched_elsewhere += results[i].touched_wall && apart > 0 ? 1 : 0;
  }
  std::printf(
      "[ measured ] %d of %d moves met the wall, after %d of them the robot believes it is in another cell; "
      "farthest believed cell from the true one: %d px\n",
      touched, robots, touched_elsewhere, worst);
  EXPECT_GT(touched, robots / 10);  // the walls were met
  // Only a large scale (above about 1.4) leaves the believed centre a cell short of the wall: a
  // fifth of the moves that meet it, here. An odometry that went on counting against the wall
  // would put nearly every one of them cells away.
  EXPECT_LE(touched_elsewhere, touched / 2);
  EXPECT_LE(worst, 2);
}

// Pushes come from every direction: a move along an axis is pushed to its left as often as to its
// right (binomial bound, 4.5 sds), and a stronger push carries the robot farther off its path.
TEST(ImperfectMotion, PushesComeFromEveryDirectionAndScaleWithTheirImpulse) {
  const auto sideways = [](double impulse_ns, std::uint64_t seed) {
    RobotParams p;
    p.pushes.probability = 1.0;
    p.pushes.impulse_ns = impulse_ns;
    RobotBatch batch(kFloor, p, 400);
    core::Rng rng(seed);
    for (int i = 0; i < 400; ++i) batch.place(i, {30, 30}, rng());
    std::vector<MoveResult> results(400);
    std::vector<std::vector<Eigen::Vector2d>> traces(400);
    batch.move(std::vector<grid::Cell>(400, grid::Cell(0, 2)), results, traces);
    std::vector<double> off;  // the signed sideways excursion of largest size, per robot
    for (const auto& trace : traces) {
      double extreme = 0;
      for (const Eigen::Vector2d& q : trace)
        if (std::abs(q.x() - 30.5) > std::abs(extreme)) extreme = q.x() - 30.5;
      off.push_back(extreme);
    }
    return off;
  };
  const std::vector<double> mild = sideways(2.0, 71), strong = sideways(6.0, 73);
  const auto left = std::count_if(mild.begin(), mild.end(), [](double x) { return x < 0; });
  EXPECT_NEAR(static_cast<double>(left) / 400.0, 0.5, 4.5 * std::sqrt(0.25 / 400.0));
  const auto mean_size = [](const std::vector<double>& v) {
    double sum = 0;
    for (double x : v) sum += std::abs(x);
    return sum / static_cast<double>(v.size());
  };
  std::printf("[ measured ] pushed to the left %ld of 400; mean sideways excursion %.3f px (2 N s), %.3f px (6 N s)\n",
              static_cast<long>(left), mean_size(mild), mean_size(strong));
  EXPECT_GT(mean_size(strong), 2.0 * mean_size(mild));
}

// Slip zones (docs/SCENARIOS.md § Slip zones): on a zone of slip sigma the wheels carry the body
// (1 - sigma) of what they turn, unsensed. A localised robot in the zone therefore covers
// (1 - sigma) of the way from where it is to its commanded cell's centre, every move, to within
// the controller's tolerance; off the zone every move lands on its cell. An odometry robot in the
// zone believes the commanded cells while its true position lags.
TEST(ImperfectMotion, SlipZonesShortenTheMovesMadeOnThemAndOnlyThose) {
  RobotParams p = noisy(0.0, 0.0, worlds::PoseSource::Localised);
  const double slip = 0.4;
  p.motion.slip_zones = {{0, 0, 32, 64, slip}};  // the floor's left half
  ASSERT_FALSE(p.exact());
  const int robots = 100;
  RobotBatch batch(kFloor, p, robots);
  core::Rng rng(21);
  // Robots 0..49 inside the zone (x in [6, 22)), 50..99 outside it (x in [40, 56)).
  for (int i = 0; i < robots; ++i) {
    const int x = (i < 50 ? 6 : 40) + static_cast<int>(core::uniform_below(rng, 16));
    batch.place(i, {x, 20 + static_cast<int>(core::uniform_below(rng, 24))}, rng());
  }
  std::vector<grid::Cell> commands(robots);
  std::vector<MoveResult> results(robots);
  double worst_in = 0, worst_out = 0, shortest_in = 1e9, longest_in = 0;
  for (int k = 0; k < 20; ++k) {
    std::vector<Eigen::Vector2d> from(robots), aim(robots);
    for (int i = 0; i < robots; ++i) {
      const grid::Cell at = batch.grid_pose(i);
      // Toward the middle of the robot's band, along x or y: the path never leaves its half.
      const int length = 1 + static_cast<int>(core::uniform_below(rng, 3));
      const int middle_x = i < 50 ? 14 : 48;
      commands[i] = (rng() >> 63) != 0 ? grid::Cell(at.x() < middle_x ? length : -length, 0)
                                       : grid::Cell(0, at.y() < 32 ? length : -length);
      from[i] = batch.position_px(i);
      aim[i] = kFloor.cell_centre_px(at + commands[i]);
    }
    batch.move(commands, results);
    for (int i = 0; i < robots; ++i) {
      ASSERT_TRUE(results[i].settled) << "robot " << i;
      const Eigen::Vector2d moved = batch.position_px(i) - from[i];
      const Eigen::Vector2d meant = aim[i] - from[i];
      if (i < 50) {
        worst_in = std::max(worst_in, (moved - (1.0 - slip) * meant).norm());
        shortest_in = std::min(shortest_in, moved.norm() / meant.norm());
        longest_in = std::max(longest_in, moved.norm() / meant.norm());
      } else {
        worst_out = std::max(worst_out, (batch.position_px(i) - aim[i]).norm());
      }
    }
  }
  std::printf(
      "[ measured ] in the zone: worst |moved - (1 - slip) meant| %.5f px, moved/meant in [%.4f, %.4f]; off "
      "it: worst landing error %.5f px\n",
      worst_in, shortest_in, longest_in, worst_out);
  EXPECT_LE(worst_in, (1.0 - slip) * p.controller.tolerance_px + 1e-4);
  EXPECT_LE(worst_out, p.controller.tolerance_px + 1e-6);
  EXPECT_NEAR(shortest_in, 1.0 - slip, 0.01);
  EXPECT_NEAR(longest_in, 1.0 - slip, 0.01);

  // Odometry: ten 1 px moves to the right from (5, 30) on a floor that slips everywhere.
  RobotParams q = noisy(0.0, 0.0, worlds::PoseSource::Odometry);
  q.motion.slip_zones = {{0, 0, 64, 64, 0.3}};
  RobotBatch one(kFloor, q, 1);
  one.place(0, {5, 30}, 1);
  std::vector<MoveResult> result(1);
  for (int k = 0; k < 10; ++k) one.move(std::vector<grid::Cell>{{1, 0}}, result);
  EXPECT_EQ(one.agent_pose(0), grid::Cell(15, 30)) << "the odometry believes the commanded cells";
  EXPECT_NEAR(one.position_px(0).x(), 5.5 + 0.7 * 10, 0.01) << "the body covers 70 % of it";
  EXPECT_EQ(one.grid_pose(0), grid::Cell(12, 30));
}

}  // namespace
}  // namespace scout::sim
