//! The digital twin of a strain wave gear joint (docs/physics.md §7): motor, gear compliance with
//! hysteresis and friction, load, meshing ripple, misalignment, the flexspline bridge
//! with placement errors, amplifier, ADC, noise, encoders and tachometer.
//!
//! Every run is a [`scenario::Scenario`] (TOML); [`presets`] has the papers' rigs.
//! Recordings carry the measured signals and the truth (`true_*` columns).
//!
//! ```
//! let scenario = strainwave_sim::presets::preset("taghirad").unwrap();
//! let mut sim = strainwave_sim::Simulator::new(&scenario).unwrap();
//! let mut row = Vec::new();
//! assert!(sim.next_row(&mut row));
//! assert_eq!(row.len(), sim.columns().len());
//! ```

pub mod arm;
pub mod bench;
pub mod calibration_rig;
mod check;
pub mod design;
pub mod error;
pub mod joint;
pub mod presets;
pub mod profile;
pub mod rng;
pub mod scenario;
pub mod sensors;
pub mod simulator;

pub use error::SimError;
pub use scenario::Scenario;
pub use simulator::{simulate, Recording, Simulator};
