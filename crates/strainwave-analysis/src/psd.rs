//! Welch power spectral density.
