//! Encoder-based link torque: harmonic-drive torsion from motor and link angles, kinematic error, and the streaming estimator (SPEC §5).
