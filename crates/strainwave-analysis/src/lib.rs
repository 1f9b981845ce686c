//! Offline analysis for strainwave: spectra, fits and smoothers over whole recordings.

pub mod bench;
pub mod calibration;
pub mod campbell;
pub mod canceller_eval;
mod choice;
pub mod error;
pub mod fir;
pub mod frf;
pub mod ident;
pub mod lines;
pub mod lstsq;
pub mod psd;
pub mod smoother;
pub mod spectrum;
pub mod stats;
pub mod step_lock;
pub mod stft;

pub use error::AnalysisError;
