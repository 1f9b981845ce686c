//! The HTML report and its SVG plots.

pub mod filter;
pub mod heatmap;
pub mod html;
pub mod plot;
pub mod text;
