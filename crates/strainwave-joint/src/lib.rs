//! A strain wave gear joint as the tools see it: the joint config file (gear, channels,
//! calibration, canceller settings), the learned-coefficients file, and the canceller run
//! over a whole recording (streaming, or the offline smoother). The encoder torque
//! estimator's jobs too: [`identify`] fits a model file from recorded runs, [`estimate`]
//! runs it over a recording.
//!
//! The command line, the Python package and the C model export all go through this crate,
//! so that they read the same files the same way and give the same numbers. Its errors are
//! the one-line, user-facing messages the command line prints (file, row, key).

pub mod canceller;
pub mod config;
pub mod discover;
pub mod estimate;
pub mod export_c;
pub mod health;
pub mod identify;
pub mod identity;
pub mod learn;
pub mod learned;
pub mod merge;
pub mod one_line;
pub mod row_check;
pub mod run;
pub mod sample_clock;
pub mod smooth;
pub mod toml_error;

pub use config::{JointConfig, MAX_TABLE_LEN};
pub use learned::LearnedFile;
pub use one_line::one_line;
pub use run::{filter_recording, FilterOptions, FilterSummary, OUTPUT_COLUMNS};
pub use run::{DENOISED_COLUMN, SMOOTHED_COLUMNS};
