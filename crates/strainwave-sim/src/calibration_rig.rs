//! The Taghirad calibration procedure (Taghirad and Bélanger (1999) §IV): the wave generator is locked,
//! known torques are applied by an arm and weights, loading and unloading in both
//! directions, at several flexspline positions, in a low and a full range, at
//! temperatures from 5 to 35 °C. Quasi-static: the flexspline carries the applied
//! torque; the bridge reads it at a fixed relative angle.
//!
//! Effects put in, each known so the calibration can be checked against it:
//! - gauge-factor temperature coefficient: gain ∝ 1 / (1 + α_K (ϑ − 20 °C));
//! - arm length error per mounting (1σ), so each experiment's applied torque is off by a factor;
//! - zero drift with temperature (V/°C after the amplifier) and the interference offset at
//!   the locked position (the 2× and 4× terms are constant when φ is fixed);
//! - white noise and the ADC.
//!
//! `true_gain` holds each experiment's true N·m/V (output torque per ADC volt), so the
//! spread the procedure creates is known exactly.

use serde::{Deserialize, Serialize};

use crate::error::SimError;
use crate::rng::Rng;
use crate::scenario::Scenario;
use crate::sensors::{ideal_bridge, strain_field};
use strainwave_core::bridge::{PlacementError, SignalChain};

/// Settings of the Taghirad procedure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LockedWgProcedure {
    /// Flexspline (relative-angle) positions of the locked wave generator, degrees.
    pub positions_deg: Vec<f64>,
    /// Largest torque of the low range, fraction of rated.
    pub low_range_fraction: f64,
    /// Weight steps per direction (loading from 0 to the range's top, then unloading).
    pub steps: usize,
    /// Readings averaged per step.
    pub readings_per_step: usize,
    /// Lowest and highest temperature, °C (experiments spread evenly between).
    pub temperature_range_c: (f64, f64),
    /// Gauge-factor temperature coefficient, 1/°C.
    pub gauge_factor_tc_per_c: f64,
    /// Zero drift after the amplifier, V/°C.
    pub zero_drift_v_per_c: f64,
    /// Arm-length error per mounting, 1σ, fraction.
    pub arm_error_fraction: f64,
}

impl Default for LockedWgProcedure {
    fn default() -> Self {
        Self {
            positions_deg: vec![0.0, 45.0, 90.0, 135.0],
            low_range_fraction: 0.25,
            steps: 5,
            readings_per_step: 20,
            temperature_range_c: (5.0, 35.0),
            gauge_factor_tc_per_c: 4e-4,
            zero_drift_v_per_c: 2e-4,
            arm_error_fraction: 0.01,
        }
    }
}

/// Columns of the procedure's recording.
pub const COLUMNS: &[&str] = &[
    "time",
    "experiment",
    "position_deg",
    "temperature_c",
    "range",
    "direction",
    "reference_torque",
    "bridge_voltage",
    "true_gain",
];

/// One row per reading: `COLUMNS` in order.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationRun {
    /// Rows, each `COLUMNS.len()` long.
    pub rows: Vec<Vec<f64>>,
    /// True gain per experiment, N·m/V.
    pub true_gains: Vec<f64>,
}

impl CalibrationRun {
    /// Mean of the true gains and their consistency (sample standard deviation / mean).
    pub fn true_gain_and_consistency(&self) -> (f64, f64) {
        let g = &self.true_gains;
        let n = g.len() as f64;
        let mean = g.iter().sum::<f64>() / n;
        let sd = (g.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
        (mean, sd / mean)
    }
}

impl LockedWgProcedure {
    /// Runs the procedure on a scenario's sensor and gear (rated torque sets the ranges).
    pub fn run(&self, s: &Scenario) -> Result<CalibrationRun, SimError> {
        s.validate()?;
        if self.positions_deg.is_empty() || self.positions_deg.iter().any(|p| !p.is_finite()) {
            return Err(SimError::invalid("positions_deg", "needs at least one finite position".into()));
        }
        if self.steps == 0 || self.readings_per_step == 0 {
            return Err(SimError::invalid("steps", "steps and readings_per_step must be positive".into()));
        }
        let p = &s.sensor;
        let mut rng = Rng::new(s.seed ^ 0x0CA1_1B2A);
        let deg = std::f64::consts::PI / 180.0;
        // One placement draw for the sensor, as in the joint simulation.
        let tol = &p.placement_tolerance;
        let errs: [PlacementError<f64>; 8] = std::array::from_fn(|_| PlacementError {
            radial_m: 1e-3 * tol.radial_mm * rng.normal(),
            circumferential_rad: deg * tol.circumferential_deg * rng.normal(),
            angular_rad: deg * tol.angular_deg * rng.normal(),
        });
        let field = strain_field(p)?;
        let bridge = ideal_bridge(p)?.displaced(&errs);
        let chain = SignalChain { amplifier_gain: p.amplifier_gain, adc_bits: p.adc_bits, adc_range_v: p.adc_range_v }
            .validated()?;
        let gear = strainwave_core::gear::Gear::new(s.gear.ratio, s.gear.fixed)?;
        let fs_per_out = gear.flexspline_torque_from_output(1.0);
        let n_exp = self.positions_deg.len() * 2;
        let (t_lo, t_hi) = self.temperature_range_c;
        let mut rows = Vec::new();
        let mut true_gains = Vec::with_capacity(n_exp);
        let dt = 1.0 / s.sample_rate_hz;
        let mut k = 0u64;
        for (e, (pos, range)) in self.positions_deg.iter().flat_map(|p| [(*p, 0usize), (*p, 1usize)]).enumerate() {
            let temp = if n_exp > 1 { t_lo + (t_hi - t_lo) * e as f64 / (n_exp - 1) as f64 } else { t_lo };
            let k_scale = 1.0 + self.gauge_factor_tc_per_c * (temp - 20.0);
            let arm = 1.0 + self.arm_error_fraction * rng.normal();
            let kernel = bridge.kernel(&field);
            let top = s.gear.rated_torque_nm * if range == 0 { self.low_range_fraction } else { 1.0 };
            let phi = pos * deg;
            let s_v_per_out = kernel.sensitivity_v_per_nm() * fs_per_out * p.amplifier_gain * k_scale;
            // The reference is the nominal torque (weight × nominal arm); the real torque is `arm` × it,
            // so the gain that maps the reading to the logged reference is 1 / (arm · s).
            true_gains.push(1.0 / (arm * s_v_per_out));
            let zero_v = self.zero_drift_v_per_c * (temp - 20.0);
            let mut profile = Vec::new();
            for dir in [1.0, -1.0] {
                for i in 0..=self.steps {
                    profile.push((dir, 1.0, dir * top * i as f64 / self.steps as f64));
                }
                for i in (0..self.steps).rev() {
                    profile.push((dir, -1.0, dir * top * i as f64 / self.steps as f64));
                }
            }
            for (dir, loading, nominal) in profile {
                let actual_out = arm * nominal;
                for _ in 0..self.readings_per_step {
                    let u = k_scale * kernel.output_v(fs_per_out * actual_out, phi, false);
                    let v = p.amplifier_gain * u + zero_v + p.noise_v_rms * rng.normal();
                    let (v, _) = chain.quantize(v);
                    rows.push(vec![
                        k as f64 * dt,
                        e as f64,
                        pos,
                        temp,
                        range as f64,
                        dir * loading,
                        nominal,
                        v,
                        1.0 / (arm * s_v_per_out),
                    ]);
                    k += 1;
                }
            }
        }
        Ok(CalibrationRun { rows, true_gains })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_experiments_with_known_gains() {
        let s = crate::presets::preset("taghirad").unwrap();
        let run = LockedWgProcedure::default().run(&s).unwrap();
        assert_eq!(run.true_gains.len(), 8);
        let mean = run.true_gains.iter().sum::<f64>() / 8.0;
        assert!((mean - 6.6).abs() < 0.3, "{mean}");
        // Per experiment: 2 directions × (6 loading + 5 unloading) steps × 20 readings.
        assert_eq!(run.rows.len(), 8 * 2 * 11 * 20);
        assert!(run.rows.iter().all(|r| r.len() == COLUMNS.len() && r.iter().all(|v| v.is_finite())));
    }
}
