// sim/robots.cpp replaces Box2D's profiling timer by one that does nothing (its clock reads were
// most of a robot's tick). This checks that Box2D's own steps call the replacement: should the
// library ever bind its timer internally (a static or differently built Box2D), the physics stays
// correct but twice as slow, and this test says so.
#include <box2d/box2d.h>
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "sim/robots.hpp"

namespace scout::sim {
namespace {

// Makes a step slow: it sleeps when two fixtures start touching, which happens inside the step.
struct SlowContacts : b2ContactListener {
  void BeginContact(b2Contact*) override { std::this_thread::sleep_for(std::chrono::milliseconds(5)); }
};

TEST(Box2DTimer, StepsOfBox2DAreNotTimed) {
  // Links robots.cpp (and its timer) into this program whatever the test filter.
  ASSERT_GT(RobotBatch::wall_margin_px(), 0.0);

  b2World world(b2Vec2(0.0f, 0.0f));
  SlowContacts slow;
  world.SetContactListener(&slow);
  b2CircleShape disc;
  disc.m_radius = 1.0f;
  for (float x : {0.0f, 0.5f}) {  // two overlapping discs
    b2BodyDef def;
    def.type = b2_dynamicBody;
    def.position.Set(x, 0.0f);
    world.CreateBody(&def)->CreateFixture(&disc, 1.0f);
  }
  const auto t0 = std::chrono::steady_clock::now();
  world.Step(1.0f / 60.0f, 8, 3);
  ASSERT_GE(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(5)) << "no contact began in the step";
  // Box2D's own timer would have measured the 5 ms sleep.
  EXPECT_EQ(world.GetProfile().step, 0.0f);
  EXPECT_EQ(world.GetProfile().collide, 0.0f);
}

}  // namespace
}  // namespace scout::sim
