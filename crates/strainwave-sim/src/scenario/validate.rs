//! [`Scenario::validate`]: every value of a scenario checked, the error naming the key.

use super::{ExternalTorque, MotionSegment, Scenario};
use crate::check::{finite as fin, non_negative as nonneg, positive as pos};
use crate::error::SimError;

impl Scenario {
    /// Checks every value; the error names the key.
    pub fn validate(&self) -> Result<(), SimError> {
        crate::check::run_length(self.duration_s, self.sample_rate_hz)?;
        let g = &self.gear;
        crate::check::gear_ratio(g.ratio)?;
        pos(g.rated_torque_nm, "gear.rated_torque_nm")?;
        pos(g.k1_nm_per_rad, "gear.k1_nm_per_rad")?;
        pos(g.k2_nm_per_rad, "gear.k2_nm_per_rad")?;
        pos(g.k3_nm_per_rad, "gear.k3_nm_per_rad")?;
        pos(g.t1_nm, "gear.t1_nm")?;
        pos(g.t2_nm, "gear.t2_nm")?;
        if g.t2_nm <= g.t1_nm {
            return Err(SimError::invalid("gear.t2_nm", "must exceed gear.t1_nm".into()));
        }
        nonneg(g.hysteresis_rad, "gear.hysteresis_rad")?;
        nonneg(g.damping_nm_s_per_rad, "gear.damping_nm_s_per_rad")?;
        nonneg(g.friction_viscous_nm_s_per_rad, "gear.friction_viscous_nm_s_per_rad")?;
        nonneg(g.friction_coulomb_nm, "gear.friction_coulomb_nm")?;
        let m = &self.motor;
        pos(m.inertia_kg_m2, "motor.inertia_kg_m2")?;
        pos(m.torque_constant_nm_per_a, "motor.torque_constant_nm_per_a")?;
        nonneg(m.viscous_nm_s_per_rad, "motor.viscous_nm_s_per_rad")?;
        nonneg(m.coulomb_nm, "motor.coulomb_nm")?;
        pos(m.current_limit_a, "motor.current_limit_a")?;
        pos(m.speed_loop_bandwidth_hz, "motor.speed_loop_bandwidth_hz")?;
        pos(self.load.inertia_kg_m2, "load.inertia_kg_m2")?;
        nonneg(self.load.viscous_nm_s_per_rad, "load.viscous_nm_s_per_rad")?;
        nonneg(self.load.coulomb_nm, "load.coulomb_nm")?;
        let r = &self.ripple;
        for (v, k) in [
            (r.amplitude_2x_nm, "ripple.amplitude_2x_nm"),
            (r.amplitude_2x_per_nm, "ripple.amplitude_2x_per_nm"),
            (r.amplitude_4x_nm, "ripple.amplitude_4x_nm"),
            (r.amplitude_4x_per_nm, "ripple.amplitude_4x_per_nm"),
            (self.misalignment.amplitude_nm, "misalignment.amplitude_nm"),
        ] {
            nonneg(v, k)?;
        }
        fin(r.phase_2x_rad, "ripple.phase_2x_rad")?;
        fin(r.phase_4x_rad, "ripple.phase_4x_rad")?;
        fin(self.misalignment.phase_rad, "misalignment.phase_rad")?;
        for l in &self.extra_lines {
            pos(l.multiple, "extra_lines.multiple")?;
            nonneg(l.amplitude_nm, "extra_lines.amplitude_nm")?;
            fin(l.phase_rad, "extra_lines.phase_rad")?;
        }
        let s = &self.sensor;
        pos(s.gauge_factor, "sensor.gauge_factor")?;
        pos(s.excitation_v, "sensor.excitation_v")?;
        // Foil gauges have K ≈ 2, semiconductor ones up to about 200; bridges run on a few
        // volts; shear moduli of solids stay under 1e12 Pa (diamond's is about 5e11).
        let most = [
            (s.gauge_factor, "sensor.gauge_factor", 1000.0),
            (s.excitation_v, "sensor.excitation_v", 100.0),
            (s.shear_modulus_pa, "sensor.shear_modulus_pa", 1e12),
        ];
        for (v, key, most) in most {
            if v > most {
                return Err(SimError::invalid(key, format!("= {v:e}: at most {most:e}")));
            }
        }
        pos(s.hub_radius_m, "sensor.hub_radius_m")?;
        pos(s.outer_radius_m, "sensor.outer_radius_m")?;
        if s.outer_radius_m <= s.hub_radius_m {
            return Err(SimError::invalid("sensor.outer_radius_m", "must exceed sensor.hub_radius_m".into()));
        }
        pos(s.thickness_m, "sensor.thickness_m")?;
        pos(s.shear_modulus_pa, "sensor.shear_modulus_pa")?;
        // Under that of the softest elastomers (about 1e5 Pa) no diaphragm carries torque.
        if s.shear_modulus_pa < 1e5 {
            return Err(SimError::invalid(
                "sensor.shear_modulus_pa",
                format!("= {:e}: at least 1e5", s.shear_modulus_pa),
            ));
        }
        pos(s.gauge_radius_m, "sensor.gauge_radius_m")?;
        if !(s.hub_radius_m < s.gauge_radius_m && s.gauge_radius_m < s.outer_radius_m) {
            let msg = format!(
                "= {:?} m: the gauges sit on the diaphragm, between `sensor.hub_radius_m` ({:?}) and \
                 `sensor.outer_radius_m` ({:?})",
                s.gauge_radius_m, s.hub_radius_m, s.outer_radius_m
            );
            return Err(SimError::invalid("sensor.gauge_radius_m", msg));
        }
        if s.thickness_m >= s.outer_radius_m - s.hub_radius_m {
            let msg = format!(
                "= {:?} m: a diaphragm is thinner than its width (`sensor.outer_radius_m` − `sensor.hub_radius_m`)",
                s.thickness_m
            );
            return Err(SimError::invalid("sensor.thickness_m", msg));
        }
        for (h, k) in [(&s.interference_2x, "sensor.interference_2x"), (&s.interference_4x, "sensor.interference_4x")] {
            for v in [h.shear_microstrain, h.normal_microstrain, h.common_microstrain, h.phase_rad] {
                fin(v, k)?;
            }
        }
        for p in &s.placement {
            if p.gauge >= 8 {
                return Err(SimError::invalid("sensor.placement.gauge", format!("must be 0..=7, got {}", p.gauge)));
            }
            for v in [p.radial_mm, p.circumferential_deg, p.angular_deg] {
                fin(v, "sensor.placement")?;
            }
            if p.radial_mm * 1e-3 <= -s.gauge_radius_m {
                return Err(SimError::invalid("sensor.placement.radial_mm", "moves a gauge past the centre".into()));
            }
        }
        nonneg(s.placement_tolerance.radial_mm, "sensor.placement_tolerance.radial_mm")?;
        nonneg(s.placement_tolerance.circumferential_deg, "sensor.placement_tolerance.circumferential_deg")?;
        nonneg(s.placement_tolerance.angular_deg, "sensor.placement_tolerance.angular_deg")?;
        if s.placement_tolerance.radial_mm * 1e-3 * 4.0 >= s.gauge_radius_m {
            return Err(SimError::invalid(
                "sensor.placement_tolerance.radial_mm",
                "too large for the gauge radius".into(),
            ));
        }
        pos(s.amplifier_gain, "sensor.amplifier_gain")?;
        if s.adc_bits == 0 || s.adc_bits > 32 {
            return Err(SimError::invalid("sensor.adc_bits", format!("must be 1..=32, got {}", s.adc_bits)));
        }
        pos(s.adc_range_v, "sensor.adc_range_v")?;
        nonneg(s.noise_v_rms, "sensor.noise_v_rms")?;
        let e = &self.encoders;
        if e.motor_counts_per_rev == 0 {
            return Err(SimError::invalid("encoders.motor_counts_per_rev", "must be positive".into()));
        }
        if e.output_counts_per_rev == 0 {
            return Err(SimError::invalid("encoders.output_counts_per_rev", "must be positive".into()));
        }
        nonneg(e.tacho_noise_rad_s, "encoders.tacho_noise_rad_s")?;
        nonneg(e.current_noise_a, "encoders.current_noise_a")?;
        if let Some(n) = e.reference_torque_noise_nm {
            nonneg(n, "encoders.reference_torque_noise_nm")?;
        }
        for (i, seg) in self.motion.iter().enumerate() {
            check_motion(seg).map_err(|e| e.in_entry("motion", i + 1))?;
        }
        for (i, t) in self.external_torque.iter().enumerate() {
            check_external_torque(t).map_err(|e| e.in_entry("external_torque", i + 1))?;
        }
        self.check_nyquist()
    }

    /// The 4× ripple order at the top speed must stay below 0.45 × the sample rate.
    fn check_nyquist(&self) -> Result<(), SimError> {
        let rel_rate = self.top_motor_speed_rad_s() * (1.0 + 1.0 / self.gear.ratio);
        let f4_hz = 4.0 * rel_rate / std::f64::consts::TAU;
        let limit = 0.45 * self.sample_rate_hz;
        if f4_hz > limit {
            return Err(SimError::invalid(
                "sample_rate_hz",
                format!(
                    "{} Hz is too low: the 4× ripple order reaches {:.1} Hz at the profile's top motor speed {:.1} rad/s (needs ≤ 0.45 × sample rate, i.e. ≥ {:.0} Hz)",
                    self.sample_rate_hz,
                    f4_hz,
                    self.top_motor_speed_rad_s(),
                    (f4_hz / 0.45).ceil()
                ),
            ));
        }
        Ok(())
    }
}

/// One `[[motion]]` segment's values.
fn check_motion(seg: &MotionSegment) -> Result<(), SimError> {
    match seg {
        MotionSegment::Ramp { to_rad_s, duration_s } => {
            fin(*to_rad_s, "motion.to_rad_s")?;
            pos(*duration_s, "motion.duration_s")?;
        }
        MotionSegment::Hold { duration_s } => pos(*duration_s, "motion.duration_s")?,
        MotionSegment::Sine { amplitude_rad_s, frequency_hz, duration_s } => {
            fin(*amplitude_rad_s, "motion.amplitude_rad_s")?;
            pos(*frequency_hz, "motion.frequency_hz")?;
            pos(*duration_s, "motion.duration_s")?;
        }
        MotionSegment::Current { current_a, duration_s } => {
            fin(*current_a, "motion.current_a")?;
            pos(*duration_s, "motion.duration_s")?;
        }
    }
    Ok(())
}

/// One `[[external_torque]]` component's values.
fn check_external_torque(t: &ExternalTorque) -> Result<(), SimError> {
    match t {
        ExternalTorque::Step { at_s, torque_nm } => {
            fin(*at_s, "external_torque.at_s")?;
            fin(*torque_nm, "external_torque.torque_nm")?;
        }
        ExternalTorque::Sine { amplitude_nm, frequency_hz, phase_rad, start_s } => {
            fin(*amplitude_nm, "external_torque.amplitude_nm")?;
            nonneg(*frequency_hz, "external_torque.frequency_hz")?;
            fin(*phase_rad, "external_torque.phase_rad")?;
            fin(*start_s, "external_torque.start_s")?;
        }
        ExternalTorque::Ramp { from_s, to_s, torque_nm } => {
            fin(*from_s, "external_torque.from_s")?;
            fin(*to_s, "external_torque.to_s")?;
            fin(*torque_nm, "external_torque.torque_nm")?;
            if to_s <= from_s {
                return Err(SimError::invalid("external_torque.to_s", "must exceed from_s".into()));
            }
        }
    }
    Ok(())
}
