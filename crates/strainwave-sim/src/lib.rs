//! strainwave-sim
