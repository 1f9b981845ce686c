//! The HTML report and its SVG plots.

pub mod calibration;
pub mod health;
pub mod heatmap;
pub mod html;
pub mod plot;
pub mod smoothed;
pub mod streaming;
pub mod text;
