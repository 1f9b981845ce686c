//! Identification of the kinematic error and the compliance from recorded runs (SPEC §5).
