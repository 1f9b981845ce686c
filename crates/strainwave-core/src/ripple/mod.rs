//! Oscillator-bank Kalman canceller of torque ripple and misalignment (SPEC §4).
