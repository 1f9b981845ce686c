// A header-only C++17 wrapper of the strainwave C ABI for a ros2_control hardware
// interface: one object per joint, owning its fixed-size state (no heap), stepped once
// per control cycle in read(), with the flags turned into a diagnostic level and text
// (the shape of diagnostic_msgs/DiagnosticStatus, without depending on ROS).
#pragma once

#include <cstdint>
#include <string>

#include "strainwave.h"

namespace strainwave {

// Levels as in diagnostic_msgs/DiagnosticStatus.
enum class Level : std::uint8_t { Ok = 0, Warn = 1, Error = 2, Stale = 3 };

struct Diagnostic {
  Level level = Level::Stale;
  std::string message;
};

class JointCanceller {
 public:
  // Checks the model (exported by `strainwave export-c`); ok() tells whether it passed.
  explicit JointCanceller(const sw_model &model) : init_code_(sw_init(&state_, &model)) {}

  bool ok() const { return init_code_ == SW_OK; }
  const char *init_error() const { return sw_error_text(init_code_); }

  // One raw sample in, the clean torque out (N·m). Call it in read(), right after the
  // joint's encoders and torque channel were read, once per sample.
  double step(const sw_sample &sample) {
    last_code_ = sw_step(&state_, &sample, &last_);
    return last_.torque;
  }

  // Restart from the model's priors (after re-homing the encoders).
  void reset() { sw_reset(&state_); }

  const sw_output &output() const { return last_; }

  // The last step as a diagnostic: errors first, then what the canceller could not do.
  Diagnostic diagnostic() const {
    if (init_code_ != SW_OK) return {Level::Error, sw_error_text(init_code_)};
    if (last_code_ != SW_OK) return {Level::Error, sw_error_text(last_code_)};
    const std::uint32_t f = last_.flags;
    std::string m;
    Level level = Level::Ok;
    auto add = [&](std::uint32_t bit, Level l, const char *text) {
      if (!(f & bit)) return;
      if (!m.empty()) m += "; ";
      m += text;
      if (l > level) level = l;
    };
    add(SW_FLAG_COVARIANCE_RESET, Level::Error, "covariance reset");
    add(SW_FLAG_ANGLE_SKIPPED, Level::Warn, "encoder or time sample invalid, sample skipped");
    add(SW_FLAG_MEASUREMENT_SKIPPED, Level::Warn, "torque sample invalid, not used");
    add(SW_FLAG_JUMP_RESET, Level::Warn, "encoder jump, orders restarted");
    add(SW_FLAG_GAP_RESET, Level::Warn, "time gap, canceller restarted");
    add(SW_FLAG_CALIBRATION_EXTRAPOLATED, Level::Warn, "speed outside the calibration range");
    add(SW_FLAG_LOAD_STEP, Level::Ok, "load step");
    add(SW_FLAG_ORDER_HELD, Level::Ok, "order held (slow or standstill)");
    add(SW_FLAG_ORDER_OFF, Level::Ok, "order off (above Nyquist fraction)");
    // The do-no-harm guard: the torque is never worse than raw, but not cleaned either.
    const std::uint32_t g = last_.guard_flags;
    auto add_guard = [&](std::uint32_t bit, Level l, const char *text) {
      if (!(g & bit)) return;
      if (!m.empty()) m += "; ";
      m += text;
      if (l > level) level = l;
    };
    add_guard(SW_GUARD_PASS_THROUGH, Level::Warn, "model does not fit, raw torque passed through");
    add_guard(SW_GUARD_CONTRADICTED, Level::Warn, "an order contradicted by the data, not applied");
    add_guard(SW_GUARD_WITHHELD, Level::Ok, "an order not applied yet (learning)");
    add_guard(SW_GUARD_STANDSTILL_BOUND, Level::Ok, "standstill: correction bounded");
    return {level, m.empty() ? std::string("ok") : m};
  }

 private:
  sw_state state_{};
  sw_output last_{};
  int init_code_ = SW_ERROR_NOT_INITIALIZED;
  int last_code_ = SW_OK;
};

}  // namespace strainwave
