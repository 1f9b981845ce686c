//! The flexspline torque sensor of the twin: gauges with placement errors on the
//! diaphragm strain field, the bridge, amplifier, noise and ADC (docs/physics.md §2).
//!
//! The sensor sees the flexspline torque of `τ + T_mesh + T_mis` (transmitted torque,
//! meshing ripple, misalignment signature) plus the elliptical interference.
//! In the small-strain bridge these add exactly, so with the true gain
//! `g = 1 / (S_fs · (T_fs/T_out) · A)`:
//!
//! ```text
//! g · V = τ + (T_mesh + g·A·U_interf(φ)) + T_mis + g · (noise + quantization)
//!       = true_torque + true_ripple + true_misalignment + noise
//! ```

use strainwave_core::bridge::{
    diaphragm_strain_per_nm, Bridge, BridgeKernel, Interference, Layout, PlacementError, SignalChain, StrainField,
};

use crate::error::SimError;
use crate::rng::Rng;
use crate::scenario::{BridgeModel, InterferenceParams, LayoutName, Scenario, SensorParams};

/// What the bridge produced for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BridgeReading {
    /// ADC reading of the amplified bridge voltage, V.
    pub voltage_v: f64,
    /// Interference in output N·m as the calibrated sensor shows it.
    pub interference_nm: f64,
    /// Whether the ADC clipped.
    pub clipped: bool,
}

/// The sensor model of one run (placement errors drawn once).
#[derive(Debug, Clone)]
pub struct TorqueSensor {
    kernel: BridgeKernel<f64>,
    chain: SignalChain<f64>,
    exact: bool,
    noise_v_rms: f64,
    fs_per_out: f64,
    gain_nm_per_v: f64,
    placement: [PlacementError<f64>; 8],
}

fn interference(p: &InterferenceParams) -> Interference<f64> {
    Interference {
        shear: p.shear_microstrain * 1e-6,
        normal: p.normal_microstrain * 1e-6,
        common: p.common_microstrain * 1e-6,
        phase_rad: p.phase_rad,
    }
}

/// The gauge layout named in the sensor section.
pub fn layout(p: &SensorParams) -> Layout {
    match p.layout {
        LayoutName::FourRosettes => Layout::FourRosettes,
        LayoutName::EightGaugeT => Layout::EightGaugeT,
    }
}

/// The diaphragm strain field of the sensor section.
pub fn strain_field(p: &SensorParams) -> Result<StrainField<f64>, SimError> {
    Ok(StrainField {
        torsion_strain_per_nm: diaphragm_strain_per_nm(
            p.hub_radius_m,
            p.outer_radius_m,
            p.thickness_m,
            p.shear_modulus_pa,
        )?,
        nominal_radius_m: p.gauge_radius_m,
        interference: [interference(&p.interference_2x), interference(&p.interference_4x)],
    })
}

/// The ideal bridge of the sensor section (no placement error).
pub fn ideal_bridge(p: &SensorParams) -> Result<Bridge<f64, 8>, SimError> {
    Ok(Bridge::new(layout(p).gauges(p.gauge_radius_m), p.gauge_factor, p.excitation_v)?)
}

impl TorqueSensor {
    /// Builds the sensor; random placement errors come from `rng`.
    pub fn new(s: &Scenario, fs_per_out: f64, rng: &mut Rng) -> Result<Self, SimError> {
        let p = &s.sensor;
        let deg = std::f64::consts::PI / 180.0;
        let mut placement = [PlacementError::default(); 8];
        let tol = &p.placement_tolerance;
        for e in placement.iter_mut() {
            e.radial_m = 1e-3 * tol.radial_mm * rng.normal();
            e.circumferential_rad = deg * tol.circumferential_deg * rng.normal();
            e.angular_rad = deg * tol.angular_deg * rng.normal();
        }
        for g in &p.placement {
            let e = &mut placement[g.gauge];
            e.radial_m += 1e-3 * g.radial_mm;
            e.circumferential_rad += deg * g.circumferential_deg;
            e.angular_rad += deg * g.angular_deg;
        }
        let bridge = ideal_bridge(p)?.displaced(&placement);
        let field = strain_field(p)?;
        let chain = SignalChain { amplifier_gain: p.amplifier_gain, adc_bits: p.adc_bits, adc_range_v: p.adc_range_v }
            .validated()?;
        let s_fs = sensitive(bridge.sensitivity_v_per_nm(&field))?;
        let gain_nm_per_v = 1.0 / (s_fs * fs_per_out * p.amplifier_gain);
        Ok(Self {
            kernel: bridge.kernel(&field),
            chain,
            exact: p.bridge_model == BridgeModel::Exact,
            noise_v_rms: p.noise_v_rms,
            fs_per_out,
            gain_nm_per_v,
            placement,
        })
    }

    /// True calibration gain of this sensor: output N·m per volt at the ADC.
    pub fn gain_nm_per_v(&self) -> f64 {
        self.gain_nm_per_v
    }

    /// Placement errors drawn for this run.
    pub fn placement(&self) -> &[PlacementError<f64>; 8] {
        &self.placement
    }

    /// White-noise floor of the calibrated torque, N·m rms (amplifier noise and ADC
    /// quantization `LSB/√12`).
    pub fn noise_floor_nm(&self) -> f64 {
        let q = self.chain.lsb_v() / 12f64.sqrt();
        (self.noise_v_rms * self.noise_v_rms + q * q).sqrt() * self.gain_nm_per_v.abs()
    }

    /// Full-scale output torque of the ADC range, N·m.
    pub fn full_scale_nm(&self) -> f64 {
        self.chain.adc_range_v * self.gain_nm_per_v.abs()
    }

    /// One reading: `sensed_out_nm` is `τ + T_mesh + T_mis` (output N·m), `phi` the relative angle.
    pub fn read(&self, sensed_out_nm: f64, relative_angle_rad: f64, rng: &mut Rng) -> BridgeReading {
        let a = self.chain.amplifier_gain;
        let u = self.kernel.output_v(self.fs_per_out * sensed_out_nm, relative_angle_rad, self.exact);
        let u_interf = self.kernel.output_v(0.0, relative_angle_rad, false);
        let noisy = a * u + self.noise_v_rms * rng.normal();
        let (voltage_v, clipped) = self.chain.quantize(noisy);
        BridgeReading { voltage_v, interference_nm: a * u_interf * self.gain_nm_per_v, clipped }
    }
}

/// The bridge's sensitivity `s` (V per N·m), or an error naming the sensor section when it
/// sees no torque (zero or not finite: extreme dimensions or placement).
pub(crate) fn sensitive(s: f64) -> Result<f64, SimError> {
    if !s.is_finite() || s == 0.0 {
        return Err(SimError::invalid(
            "sensor",
            "leaves the bridge with no torque sensitivity (check its dimensions, shear modulus and placement)".into(),
        ));
    }
    Ok(s)
}
