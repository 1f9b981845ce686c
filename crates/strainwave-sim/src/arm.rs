//! The harmonic-drive arm model of seed 002 (SPEC §5): motor, wave-generator and flexspline compliance, link, external torque.
