//! Sensor design: what a flexspline bridge gives (sensitivity, full scale, resolution,
//! strain at rated torque) and how much 2× and 4× interference survives given the
//! gauge placement tolerances, by Monte Carlo (docs/physics.md §2, Taghirad and Bélanger (1999) §III).
//!
//! Each draw displaces the eight gauges by independent normal errors (1σ = the
//! tolerance), reduces the bridge to its linear kernel and reads the residual line
//! amplitudes exactly from the kernel; residuals are expressed in N·m through that
//! draw's own sensitivity, as a calibrated sensor would show them.

use serde::{Deserialize, Serialize};
use strainwave_core::bridge::{PlacementError, SignalChain};

use crate::error::SimError;
use crate::rng::Rng;
use crate::scenario::{PlacementTolerance, SensorParams};
use crate::sensors::{ideal_bridge, strain_field};

/// A design study: the sensor, the rated torque and the Monte Carlo settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesignConfig {
    /// Rated flexspline torque, N·m.
    pub rated_torque_nm: f64,
    /// The sensor (same section as in a scenario; `placement_tolerance` is the 1σ spread studied).
    pub sensor: SensorParams,
    /// Monte Carlo settings.
    #[serde(default)]
    pub monte_carlo: MonteCarlo,
}

/// Monte Carlo settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MonteCarlo {
    /// Number of draws.
    pub draws: usize,
    /// Random seed.
    pub seed: u64,
}

impl Default for MonteCarlo {
    fn default() -> Self {
        Self { draws: 10_000, seed: 1 }
    }
}

/// Percentiles of a residual line, N·m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 95th percentile.
    pub p95: f64,
    /// 99th percentile.
    pub p99: f64,
}

/// Residual lines for one family of placement errors.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualStudy {
    /// Which errors were drawn (`radial`, `circumferential`, `angular`, `combined`).
    pub errors: &'static str,
    /// 2× residual, N·m.
    pub line_2x_nm: Percentiles,
    /// 4× residual, N·m.
    pub line_4x_nm: Percentiles,
    /// Every draw's 2× residual, N·m (for histograms).
    pub samples_2x_nm: Vec<f64>,
}

/// The design figures.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignReport {
    /// Bridge output per N·m per volt of excitation, mV/V per N·m.
    pub sensitivity_mv_per_v_per_nm: f64,
    /// After the amplifier, V per N·m.
    pub amplified_v_per_nm: f64,
    /// Torque at the ADC range, N·m.
    pub full_scale_nm: f64,
    /// Torque per ADC step, N·m.
    pub resolution_nm: f64,
    /// Principal strain at rated torque, µε.
    pub strain_at_rated_microstrain: f64,
    /// Bridge output at rated torque, mV/V.
    pub output_at_rated_mv_per_v: f64,
    /// 2× and 4× residual with ideal placement, N·m.
    pub ideal_residual_nm: (f64, f64),
    /// Studies: each error type alone, then combined.
    pub studies: Vec<ResidualStudy>,
}

impl DesignReport {
    /// An error naming the key behind the first figure that is not finite: a sensor or
    /// rated torque whose figures overflow is no design (the check of last resort, after
    /// each key's own limits).
    fn finite(&self) -> Result<(), SimError> {
        let rated = [
            ("strain at rated torque", self.strain_at_rated_microstrain),
            ("bridge output at rated torque", self.output_at_rated_mv_per_v),
        ];
        if let Some((what, v)) = rated.into_iter().find(|(_, v)| !v.is_finite()) {
            return Err(SimError::invalid("rated_torque_nm", format!("gives a {what} of {v:?}: check its unit")));
        }
        let mut sensor = vec![
            ("sensitivity", self.sensitivity_mv_per_v_per_nm),
            ("amplified sensitivity", self.amplified_v_per_nm),
            ("full scale", self.full_scale_nm),
            ("resolution", self.resolution_nm),
            ("2× residual", self.ideal_residual_nm.0),
            ("4× residual", self.ideal_residual_nm.1),
        ];
        for s in &self.studies {
            let (a, b) = (&s.line_2x_nm, &s.line_4x_nm);
            sensor.extend([("placement residual", a.p99), ("placement residual", b.p99)]);
        }
        match sensor.into_iter().find(|(_, v)| !v.is_finite()) {
            Some((what, v)) => Err(SimError::invalid("sensor", format!("gives a {what} of {v:?}: check its values"))),
            None => Ok(()),
        }
    }
}

fn percentiles(mut v: Vec<f64>) -> Percentiles {
    v.sort_by(f64::total_cmp);
    let at = |q: f64| {
        if v.is_empty() {
            return f64::NAN;
        }
        let pos = q * (v.len() - 1) as f64;
        let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
        v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
    };
    Percentiles { p50: at(0.5), p90: at(0.9), p95: at(0.95), p99: at(0.99) }
}

impl DesignConfig {
    /// Parses TOML; unknown keys are errors.
    pub fn from_toml(text: &str) -> Result<Self, SimError> {
        let c: Self = toml::from_str(text)
            .map_err(|e| SimError::Parse { message: e.message().to_string(), location: String::new() })?;
        c.validate()?;
        Ok(c)
    }

    /// Checks the values.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(self.rated_torque_nm.is_finite() && self.rated_torque_nm > 0.0) {
            return Err(SimError::invalid(
                "rated_torque_nm",
                format!("must be positive, got {}", self.rated_torque_nm),
            ));
        }
        if self.monte_carlo.draws == 0 || self.monte_carlo.draws > 10_000_000 {
            return Err(SimError::invalid(
                "monte_carlo.draws",
                format!("must be 1..=10000000, got {}", self.monte_carlo.draws),
            ));
        }
        // Reuse the scenario checks of the sensor section.
        let mut s = crate::presets::preset("taghirad")?;
        s.sensor = self.sensor.clone();
        s.validate()
    }

    /// Computes the design figures and runs the Monte Carlo.
    pub fn evaluate(&self) -> Result<DesignReport, SimError> {
        self.validate()?;
        let p = &self.sensor;
        let field = strain_field(p)?;
        let ideal = ideal_bridge(p)?;
        let k0 = ideal.kernel(&field);
        let s_v_per_nm = crate::sensors::sensitive(k0.sensitivity_v_per_nm())?;
        let chain = SignalChain { amplifier_gain: p.amplifier_gain, adc_bits: p.adc_bits, adc_range_v: p.adc_range_v }
            .validated()?;
        let to_nm = |amp_v: f64, sens: f64| amp_v / sens.abs();
        let ideal_residual_nm =
            (to_nm(k0.order_amplitude_v(1), s_v_per_nm), to_nm(k0.order_amplitude_v(2), s_v_per_nm));
        let tol = &p.placement_tolerance;
        let families: [(&'static str, PlacementTolerance); 4] = [
            ("radial", PlacementTolerance { radial_mm: tol.radial_mm, ..Default::default() }),
            (
                "circumferential",
                PlacementTolerance { circumferential_deg: tol.circumferential_deg, ..Default::default() },
            ),
            ("angular", PlacementTolerance { angular_deg: tol.angular_deg, ..Default::default() }),
            ("combined", tol.clone()),
        ];
        let deg = std::f64::consts::PI / 180.0;
        let mut studies = Vec::with_capacity(4);
        for (name, t) in families {
            let mut rng = Rng::new(self.monte_carlo.seed);
            let mut r2 = Vec::with_capacity(self.monte_carlo.draws);
            let mut r4 = Vec::with_capacity(self.monte_carlo.draws);
            for _ in 0..self.monte_carlo.draws {
                let errs: [PlacementError<f64>; 8] = std::array::from_fn(|_| PlacementError {
                    radial_m: 1e-3 * t.radial_mm * rng.normal(),
                    circumferential_rad: deg * t.circumferential_deg * rng.normal(),
                    angular_rad: deg * t.angular_deg * rng.normal(),
                });
                let k = ideal.displaced(&errs).kernel(&field);
                let s = k.sensitivity_v_per_nm();
                r2.push(to_nm(k.order_amplitude_v(1), s));
                r4.push(to_nm(k.order_amplitude_v(2), s));
            }
            studies.push(ResidualStudy {
                errors: name,
                line_2x_nm: percentiles(r2.clone()),
                line_4x_nm: percentiles(r4),
                samples_2x_nm: r2,
            });
        }
        let report = DesignReport {
            sensitivity_mv_per_v_per_nm: 1e3 * s_v_per_nm / p.excitation_v,
            amplified_v_per_nm: s_v_per_nm * p.amplifier_gain,
            full_scale_nm: chain.full_scale_nm(s_v_per_nm),
            resolution_nm: chain.torque_per_lsb_nm(s_v_per_nm),
            strain_at_rated_microstrain: 1e6 * field.torsion_strain_per_nm * self.rated_torque_nm,
            output_at_rated_mv_per_v: 1e3 * s_v_per_nm * self.rated_torque_nm / p.excitation_v,
            ideal_residual_nm,
            studies,
        };
        report.finite()?;
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> DesignConfig {
        let s = crate::presets::preset("taghirad").unwrap();
        DesignConfig { rated_torque_nm: 40.0, sensor: s.sensor, monte_carlo: MonteCarlo { draws: 2000, seed: 3 } }
    }

    #[test]
    fn taghirad_sensor_sensitivity_and_ideal_cancellation() {
        let r = config().evaluate().unwrap();
        // Gain 6.6 N·m/V after the amplifier (Taghirad and Bélanger (1999) Table I).
        assert!((1.0 / r.amplified_v_per_nm - 6.6).abs() < 0.05, "{}", 1.0 / r.amplified_v_per_nm);
        assert!(r.ideal_residual_nm.0 < 1e-12 && r.ideal_residual_nm.1 > 0.01);
        assert!((r.full_scale_nm - 10.0 / r.amplified_v_per_nm).abs() < 1e-9);
    }

    #[test]
    fn residual_shrinks_with_the_tolerance() {
        let mut c = config();
        let wide = c.evaluate().unwrap();
        c.sensor.placement_tolerance.radial_mm /= 4.0;
        c.sensor.placement_tolerance.circumferential_deg /= 4.0;
        c.sensor.placement_tolerance.angular_deg /= 4.0;
        let tight = c.evaluate().unwrap();
        for (w, t) in wide.studies.iter().zip(&tight.studies) {
            assert!(
                t.line_2x_nm.p95 < 0.5 * w.line_2x_nm.p95,
                "{}: {} vs {}",
                w.errors,
                t.line_2x_nm.p95,
                w.line_2x_nm.p95
            );
        }
    }

    #[test]
    fn circumferential_and_angular_errors_matter_more_than_radial() {
        // Taghirad and Bélanger (1999) §III at equal "placement effort": 0.1 mm radial vs 0.5° (0.12 mm of arc at 14 mm).
        let r = config().evaluate().unwrap();
        let p95 = |name: &str| r.studies.iter().find(|s| s.errors == name).unwrap().line_2x_nm.p95;
        assert!(p95("circumferential") > p95("radial"), "{} {}", p95("circumferential"), p95("radial"));
        assert!(p95("angular") > p95("radial"), "{} {}", p95("angular"), p95("radial"));
    }
}
