//! Calibration fitting and the figures torque-transducer standards use (DIN 51309 / EURAMET cg-14).
