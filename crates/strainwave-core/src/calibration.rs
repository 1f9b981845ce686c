//! Applying a calibration in real time: linear and speed-dependent (lookup table interpolated in speed).
