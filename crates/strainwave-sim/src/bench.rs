//! The motor test bench of seed 003 (SPEC §6): DUT rotor, torsion shaft, brake, stator housing, accelerometers, PMSM torque.
