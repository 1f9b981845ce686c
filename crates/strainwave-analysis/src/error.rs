//! Errors of the analysis crate.

/// Why an analysis could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// Not enough samples.
    #[error("{what}: needs at least {needed} samples, got {got}")]
    TooShort {
        /// Which input.
        what: &'static str,
        /// Samples needed.
        needed: usize,
        /// Samples given.
        got: usize,
    },
    /// A NaN or infinite sample.
    #[error("{what}: sample {index} is not finite")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// Index of the first bad sample.
        index: usize,
    },
    /// A parameter out of range.
    #[error("{what}: {why}")]
    Invalid {
        /// Which parameter.
        what: &'static str,
        /// Why.
        why: String,
    },
}
