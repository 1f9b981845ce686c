//! Complementary fusion of a torsion-shaft torque and an accelerometer torque (SPEC §6).
