//! Errors of the simulator.

/// A scenario that cannot be simulated.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// TOML that does not parse or has unknown keys / wrong types.
    #[error("{message}{}", if location.is_empty() { String::new() } else { format!(" (at {location})") })]
    Parse {
        /// What the parser said.
        message: String,
        /// `line L, column C`, or empty.
        location: String,
    },
    /// A value out of range; names the key.
    #[error("`{key}` {msg}")]
    Invalid {
        /// Dotted key path.
        key: &'static str,
        /// What is wrong.
        msg: String,
    },
    /// The core rejected a parameter.
    #[error("invalid parameter: {0}")]
    Core(#[from] strainwave_core::Error),
    /// No preset of that name.
    #[error("unknown preset `{0}` (known: {1})")]
    UnknownPreset(String, String),
}

impl SimError {
    /// A value out of range.
    pub fn invalid(key: &'static str, msg: String) -> Self {
        SimError::Invalid { key, msg }
    }

    /// This error, for a value of entry `n` (from 1) of the array of tables `[[name]]`.
    pub fn in_entry(self, name: &str, n: usize) -> Self {
        match self {
            SimError::Invalid { key, msg } => SimError::Invalid { key, msg: format!("{msg} (`[[{name}]]` entry {n})") },
            other => other,
        }
    }
}
