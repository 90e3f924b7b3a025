// The speed controller of seed 000's eq. 2: throttle when the target is above the current
// speed, brake otherwise; holding still; tracking a target in closed loop with the ego model.
#include <gtest/gtest.h>

#include "app/settings.hpp"
#include "control/pid.hpp"
#include "world/ego_model.hpp"

namespace cd {
namespace {

SpeedPid make_pid(const Settings& s) { return SpeedPid(s.control, EgoModel(s.ego), s.world.dt); }

TEST(SpeedPid, ThrottleOnlyWhenTooSlowBrakeOnlyWhenTooFast) {
  Settings s;
  for (double speed : {0.5, 3.0, 8.0, 12.0}) {
    for (double error : {-4.0, -1.0, -0.3, 0.3, 1.0, 4.0}) {
      SCOPED_TRACE(std::to_string(speed) + " " + std::to_string(error));
      SpeedPid pid = make_pid(s);
      Control c = pid.control(speed + error, speed);
      if (error > 0) {
        EXPECT_GT(c.throttle, 0.0);
        EXPECT_EQ(c.brake, 0.0);
      } else {
        EXPECT_EQ(c.throttle, 0.0);
        EXPECT_GT(c.brake, 0.0);
      }
    }
  }
}

TEST(SpeedPid, HoldsTheBrakeWhenAskedToStandAndStanding) {
  Settings s;
  SpeedPid pid = make_pid(s);
  Control c = pid.control(0.0, 0.0);
  EXPECT_EQ(c.throttle, 0.0);
  EXPECT_EQ(c.brake, s.control.hold_brake);
  // A positive target above stop_speed starts the car again at once.
  Control go = pid.control(5.0, 0.0);
  EXPECT_GT(go.throttle, 0.0);
  EXPECT_EQ(go.brake, 0.0);
}

TEST(SpeedPid, TracksATargetWithTheEgoModelAndStopsAgain) {
  Settings s;
  EgoModel model(s.ego);
  SpeedPid pid = make_pid(s);
  double v = 0;
  for (int i = 0; i < 150; ++i) v = model.next_speed(pid.control(8.0, v), v, s.world.dt);
  EXPECT_NEAR(v, 8.0, 0.2) << "15 s after the start";
  // Anti-windup: after 15 s of tracking, a stop request brakes on the next step.
  Control c = pid.control(0.0, v);
  EXPECT_GT(c.brake, 0.0);
  for (int i = 0; i < 60; ++i) v = model.next_speed(pid.control(0.0, v), v, s.world.dt);
  EXPECT_LT(v, 0.1) << "6 s after the stop request";
}

}  // namespace
}  // namespace cd
