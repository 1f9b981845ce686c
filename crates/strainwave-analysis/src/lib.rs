//! strainwave-analysis
