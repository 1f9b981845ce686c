//! Test-bench models: torsion-shaft and accelerometer transfer functions (SPEC §6).
