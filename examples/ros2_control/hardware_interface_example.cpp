// Where the canceller goes in a ros2_control SystemInterface, without ROS: read() gets
// the raw channels from the drive, steps the canceller and publishes the clean torque as
// the joint's effort state; the diagnostic goes to the diagnostics updater. Built in CI:
//   strainwave export-c --config examples/joint-taghirad.toml --out joint_model.h
//   c++ -std=c++17 -I include -I . examples/ros2_control/hardware_interface_example.cpp
//       target/release/libstrainwave_ffi.a -lpthread -ldl -o hw_example   (one line)
#include <cmath>
#include <cstdio>

#include "strainwave_joint.hpp"

#ifndef SW_MODEL_HEADER
#define SW_MODEL_HEADER "joint_model.h"
#endif
#include SW_MODEL_HEADER

// Stand-in for the drive's bus: what a real interface reads over EtherCAT/CAN.
struct DriveReading {
  double time_s, bridge_voltage, motor_angle_rad, output_angle_rad, motor_velocity_rad_s;
};

class JointHardware {  // : public hardware_interface::SystemInterface
 public:
  JointHardware() : canceller_(SW_MODEL) {}

  // on_init(): refuse to start with a bad model.
  bool on_init() {
    if (!canceller_.ok()) std::fprintf(stderr, "strainwave: %s\n", canceller_.init_error());
    return canceller_.ok();
  }

  // read(time, period): one call per control cycle.
  void read(const DriveReading &d) {
    sw_sample s{d.time_s, d.bridge_voltage, d.motor_angle_rad, d.output_angle_rad, d.motor_velocity_rad_s, NAN};
    const double torque = canceller_.step(s);
    // The state interface "effort"; an invalid torque sample (NaN out, flagged) keeps the
    // last good value, and the diagnostic says why.
    if (std::isfinite(torque)) effort_state_ = torque;
  }

  double effort() const { return effort_state_; }
  strainwave::Diagnostic diagnostic() const { return canceller_.diagnostic(); }

 private:
  strainwave::JointCanceller canceller_;
  double effort_state_ = 0.0;
};

int main() {
  JointHardware hw;
  if (!hw.on_init()) return 1;
  // One second at 1 kHz of a joint turning at 10 rad/s (motor) under a steady load.
  const double ratio = 100.0;
  for (int k = 0; k < 1000; k++) {
    const double t = k * 1e-3, motor = 10.0 * t;
    hw.read({t, 1.5 + 0.02 * std::sin(2.0 * motor), motor, motor / ratio, 10.0});
  }
  const strainwave::Diagnostic d = hw.diagnostic();
  std::printf("effort %.4f N·m, diagnostic level %d: %s\n", hw.effort(), static_cast<int>(d.level),
              d.message.c_str());
  // A bad sample is a warning, not a crash.
  hw.read({1.0, NAN, 10.0, 0.1, 10.0});
  std::printf("after a NaN torque sample: level %d: %s\n", static_cast<int>(hw.diagnostic().level),
              hw.diagnostic().message.c_str());
  return std::isfinite(hw.effort()) ? 0 : 1;
}
