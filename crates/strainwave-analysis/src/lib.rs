//! Offline analysis for strainwave: spectra, fits and smoothers over whole recordings.

pub mod error;
pub mod lines;
pub mod spectrum;
pub mod stats;

pub use error::AnalysisError;
