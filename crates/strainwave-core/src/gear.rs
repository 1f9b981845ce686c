//! Strain wave gear (harmonic drive) kinematics and torque relations (docs/physics.md §1).
//!
//! Glossary: WG wave generator (input, on the motor shaft), FS flexspline (thin cup,
//! carries the strain gauges), CS circular spline (rigid ring), `N` the ratio.
//!
//! | fixed element | output | output angle | relative angle `φ = θ_wg − θ_fs` |
//! |---|---|---|---|
//! | CS | FS | `θ_fs = −θ_wg / N` | `θ_wg (1 + 1/N)` |
//! | FS | CS | `θ_cs = θ_wg / (N+1)` | `θ_wg` |
//!
//! Torques: `T_wg = T_fs / N = T_cs / (N+1)` in magnitude. Signs follow the angle
//! relation: the output torque is counted positive in the output's own positive
//! direction, so with the CS fixed a positive WG torque gives a negative output torque.

use crate::error::{positive, Error};
use crate::Real;

/// The ratios a strain wave gear can have: flexspline teeth over the tooth difference
/// (catalogue gears span 30 to 320). Configuration files are held to it.
pub const RATIO_RANGE: core::ops::RangeInclusive<f64> = 1.0..=10_000.0;

/// Which element of the gear is held fixed.
///
/// With the `serde` feature it is the `fixed` value of every configuration file (joint,
/// arm, scenario): `"circular_spline"` or `"flexspline"`, with `"circular-spline"`
/// accepted as an alias.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum FixedElement {
    /// Circular spline fixed, flexspline is the output (usual robot joint).
    #[default]
    #[cfg_attr(feature = "serde", serde(alias = "circular-spline"))]
    CircularSpline,
    /// Flexspline fixed, circular spline is the output (embedded-sensor test rig).
    Flexspline,
}

impl FixedElement {
    /// Its name in files and messages: `circular_spline` or `flexspline`.
    pub fn name(self) -> &'static str {
        match self {
            FixedElement::CircularSpline => "circular_spline",
            FixedElement::Flexspline => "flexspline",
        }
    }
}

/// A strain wave gear: ratio and which element is fixed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gear<T: Real> {
    ratio: T,
    fixed: FixedElement,
}

impl<T: Real> Gear<T> {
    /// A gear with ratio `N > 0` (flexspline teeth / tooth difference, e.g. 50, 100, 160).
    ///
    /// ```
    /// use strainwave_core::gear::{FixedElement, Gear};
    /// let gear = Gear::new(100.0_f64, FixedElement::CircularSpline).unwrap();
    /// assert_eq!(gear.output_angle(100.0), -1.0);
    /// assert!(Gear::new(0.0_f64, FixedElement::Flexspline).is_err());
    /// ```
    pub fn new(ratio: T, fixed: FixedElement) -> Result<Self, Error> {
        positive(ratio, "ratio")?;
        Ok(Self { ratio, fixed })
    }

    /// The ratio `N`.
    pub fn ratio(&self) -> T {
        self.ratio
    }

    /// The fixed element.
    pub fn fixed(&self) -> FixedElement {
        self.fixed
    }

    /// Signed ratio from the WG to the output: `θ_out = θ_wg / n_s`, with
    /// `n_s = −N` (CS fixed) or `N + 1` (FS fixed).
    pub fn signed_ratio(&self) -> T {
        match self.fixed {
            FixedElement::CircularSpline => -self.ratio,
            FixedElement::Flexspline => self.ratio + T::ONE,
        }
    }

    /// Ideal (rigid) output angle for a wave-generator angle, rad.
    pub fn output_angle(&self, wg_angle_rad: T) -> T {
        wg_angle_rad / self.signed_ratio()
    }

    /// Flexspline angle for a measured output angle, rad (0 when the FS is fixed).
    pub fn flexspline_angle(&self, output_angle_rad: T) -> T {
        match self.fixed {
            FixedElement::CircularSpline => output_angle_rad,
            FixedElement::Flexspline => T::ZERO,
        }
    }

    /// Relative WG–FS angle `φ = θ_wg − θ_fs` from the measured WG (motor) angle and
    /// output angle, rad. The elliptical deformation and the meshing ripple are periodic in it.
    pub fn relative_angle(&self, wg_angle_rad: T, output_angle_rad: T) -> T {
        wg_angle_rad - self.flexspline_angle(output_angle_rad)
    }

    /// Relative angle from the WG angle alone, assuming a rigid gear, rad:
    /// `θ_wg (1 + 1/N)` (CS fixed) or `θ_wg` (FS fixed).
    pub fn relative_angle_rigid(&self, wg_angle_rad: T) -> T {
        self.relative_angle(wg_angle_rad, self.output_angle(wg_angle_rad))
    }

    /// Relative-angle rate from the WG rate for a rigid gear, rad/s.
    pub fn relative_rate_rigid(&self, wg_rate_rad_s: T) -> T {
        self.relative_angle_rigid(wg_rate_rad_s)
    }

    /// Output torque (in the output's positive direction) for a WG torque, ideal gear:
    /// `T_out = n_s T_wg`.
    pub fn output_torque(&self, wg_torque_nm: T) -> T {
        wg_torque_nm * self.signed_ratio()
    }

    /// WG torque needed to deliver an output torque, ideal gear: `T_wg = T_out / n_s`.
    pub fn wg_torque(&self, output_torque_nm: T) -> T {
        output_torque_nm / self.signed_ratio()
    }

    /// Magnitude of the flexspline torque for a WG torque: `|T_fs| = N |T_wg|`
    /// (the flexspline carries `N T_wg` whichever element is fixed).
    pub fn flexspline_torque_magnitude(&self, wg_torque_nm: T) -> T {
        (wg_torque_nm * self.ratio).abs()
    }

    /// Flexspline torque corresponding to an output torque, signed in the output frame:
    /// equal to it when the FS is the output, `T_cs N/(N+1)` when the CS is the output.
    pub fn flexspline_torque_from_output(&self, output_torque_nm: T) -> T {
        match self.fixed {
            FixedElement::CircularSpline => output_torque_nm,
            FixedElement::Flexspline => output_torque_nm * self.ratio / (self.ratio + T::ONE),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOL: f64 = 1e-12;

    #[test]
    fn circular_spline_fixed_kinematics() {
        let g = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
        assert!((g.output_angle(1.0) + 0.01).abs() < TOL);
        assert!((g.relative_angle_rigid(1.0) - 1.01).abs() < TOL);
        // T_wg = T_fs / N
        assert!((g.wg_torque(-40.0) - 0.4).abs() < TOL);
        assert!((g.flexspline_torque_magnitude(0.4) - 40.0).abs() < TOL);
    }

    #[test]
    fn flexspline_fixed_kinematics() {
        let g = Gear::new(50.0, FixedElement::Flexspline).unwrap();
        assert!((g.output_angle(51.0) - 1.0).abs() < TOL);
        assert!((g.relative_angle_rigid(2.0) - 2.0).abs() < TOL);
        // T_wg = T_cs / (N + 1) = T_fs / N
        let t_wg = 0.2;
        let t_cs = g.output_torque(t_wg);
        assert!((t_cs - 10.2).abs() < TOL);
        assert!((g.flexspline_torque_magnitude(t_wg) - 10.0).abs() < TOL);
        assert!((g.flexspline_torque_from_output(t_cs) - 10.0).abs() < TOL);
    }

    #[test]
    fn power_is_conserved() {
        for fixed in [FixedElement::CircularSpline, FixedElement::Flexspline] {
            let g = Gear::new(80.0, fixed).unwrap();
            let (w_wg, t_wg) = (120.0, 0.3);
            let p_out = g.output_torque(t_wg) * g.output_angle(w_wg);
            assert!((p_out - w_wg * t_wg).abs() < TOL);
        }
    }

    #[test]
    fn bad_ratio_is_named() {
        assert_eq!(Gear::new(-1.0f32, FixedElement::CircularSpline), Err(Error::NonPositive("ratio")));
        assert_eq!(Gear::new(f64::NAN, FixedElement::CircularSpline), Err(Error::NonPositive("ratio")));
    }
}
