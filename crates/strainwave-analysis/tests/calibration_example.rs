//! The shipped example calibration file (`examples/calibration.toml`) loads, validates and
//! converts the bridge voltage to torque with its gain.

use std::path::Path;

use strainwave_analysis::calibration::{CalibrationFile, ModelKind};

#[test]
fn the_example_calibration_file_loads_and_applies_its_gain() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/calibration.toml");
    let f = CalibrationFile::load(&path).unwrap();
    assert_eq!(f.model, ModelKind::Gain);
    assert!((f.gain_nm_per_v.unwrap() - 6.611).abs() < 1e-3);
    let cal = f.to_core::<f64, 1>().unwrap();
    assert!((cal.apply(1.5, 0.0).unwrap() - 1.5 * f.gain_nm_per_v.unwrap()).abs() < 1e-12);
    // What `calibrate` would write for it reads back the same.
    assert_eq!(CalibrationFile::from_toml_str(&f.to_toml_string().unwrap()).unwrap(), f);
}
