//! Inner torque of a PMSM from flux linkages (SPEC §6, seed 003 eqs 12–13).
