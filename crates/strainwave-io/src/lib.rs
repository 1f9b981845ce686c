//! strainwave-io
