//! Per-sample inputs and outputs of the canceller, and the flags it raises.

use crate::gear::Gear;
use crate::Real;

/// One value per reference: angles (rad) or velocities (rad/s), as the model's
/// [`PhaseSource`](super::PhaseSource) says. `V` is a scalar, or `[T; J]` for a bank.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReferenceValues<V> {
    /// Relative WG–FS angle `φ` (or its rate).
    pub relative: V,
    /// Output (link) angle (or its rate).
    pub output: V,
    /// Motor (WG) angle (or its rate).
    pub motor: V,
}

impl<V: Copy> ReferenceValues<V> {
    /// All three references.
    ///
    /// ```
    /// use strainwave_core::ripple::ReferenceValues;
    /// let r = ReferenceValues::new(1.01_f64, -0.01, 1.0);
    /// assert_eq!(r.output, -0.01);
    /// ```
    pub fn new(relative: V, output: V, motor: V) -> Self {
        Self { relative, output, motor }
    }

    /// The values in [`Reference::index`](super::Reference::index) order.
    pub fn as_array(&self) -> [V; 3] {
        [self.relative, self.output, self.motor]
    }
}

impl<T: Real> ReferenceValues<T> {
    /// References from the measured motor (WG) and output angles of a joint, rad:
    /// `φ = θ_wg − θ_fs` (wave generator minus flexspline), output, motor. Works on rates too (rad/s).
    ///
    /// ```
    /// use strainwave_core::gear::{FixedElement, Gear};
    /// use strainwave_core::ripple::ReferenceValues;
    /// let gear = Gear::new(100.0_f64, FixedElement::CircularSpline).unwrap();
    /// let r = ReferenceValues::from_gear(&gear, 1.0, gear.output_angle(1.0));
    /// assert!((r.relative - 1.01).abs() < 1e-12);
    /// ```
    pub fn from_gear(gear: &Gear<T>, motor_angle_rad: T, output_angle_rad: T) -> Self {
        Self::new(gear.relative_angle(motor_angle_rad, output_angle_rad), output_angle_rad, motor_angle_rad)
    }
}

/// One sample for one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RippleInput<T: Real> {
    /// Measured torque `T_meas`, N·m.
    pub torque_nm: T,
    /// Crude expected torque `T_exp` (e.g. load inertia × acceleration), N·m; 0 if none.
    pub expected_torque_nm: T,
    /// Reference angles (rad) or velocities (rad/s).
    pub references: ReferenceValues<T>,
    /// Time since the previous sample, s; `None` means one nominal period.
    pub dt_s: Option<T>,
}

impl<T: Real> RippleInput<T> {
    /// A sample with no expected torque and the nominal interval.
    ///
    /// ```
    /// use strainwave_core::ripple::{ReferenceValues, RippleInput};
    /// let s = RippleInput::new(3.2_f32, ReferenceValues::new(0.5, 0.005, 0.495))
    ///     .with_expected_torque(3.0)
    ///     .with_dt(1e-3);
    /// assert_eq!(s.dt_s, Some(1e-3));
    /// ```
    pub fn new(torque_nm: T, references: ReferenceValues<T>) -> Self {
        Self { torque_nm, expected_torque_nm: T::ZERO, references, dt_s: None }
    }

    /// Sets `T_exp`.
    pub fn with_expected_torque(mut self, expected_torque_nm: T) -> Self {
        self.expected_torque_nm = expected_torque_nm;
        self
    }

    /// Sets the interval since the previous sample.
    pub fn with_dt(mut self, dt_s: T) -> Self {
        self.dt_s = Some(dt_s);
        self
    }
}

/// What happened during one step. Several flags can be set at once.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct StepFlags(u16);

impl StepFlags {
    /// Torque or expected torque not finite, or beyond ±10¹² N·m apart: no measurement update.
    pub const MEASUREMENT_SKIPPED: Self = Self(1);
    /// A used reference or `dt_s` not finite (or `dt_s ≤ 0`): the state is untouched and
    /// the next good sample's increment spans the gap.
    pub const ANGLE_SKIPPED: Self = Self(1 << 1);
    /// `dt_s` beyond the gap limit: all oscillators reset, bias variance reinflated.
    pub const GAP_RESET: Self = Self(1 << 2);
    /// A reference jumped (increment beyond `max_angle_step_rad`, or changed by more than
    /// `max_step_change_rad` since the last sample): its orders reset.
    pub const JUMP_RESET: Self = Self(1 << 3);
    /// At least one order is switched off (line above the Nyquist fraction).
    pub const ORDER_OFF: Self = Self(1 << 4);
    /// At least one order is held (line below `hold_below_hz`, e.g. standstill).
    pub const ORDER_HELD: Self = Self(1 << 5);
    /// The covariance went bad (non-finite or negative): the state was reset.
    pub const COVARIANCE_RESET: Self = Self(1 << 6);
    /// The innovation exceeded the load-step NIS limit: the bias took the jump.
    pub const LOAD_STEP: Self = Self(1 << 7);

    /// No flag.
    ///
    /// ```
    /// use strainwave_core::ripple::StepFlags;
    /// let f = StepFlags::empty() | StepFlags::ORDER_HELD;
    /// assert!(f.contains(StepFlags::ORDER_HELD) && !f.contains(StepFlags::ORDER_OFF));
    /// ```
    pub const fn empty() -> Self {
        Self(0)
    }
    /// The flags of raw `bits`.
    pub(crate) const fn from_bits(bits: u16) -> Self {
        Self(bits)
    }
    /// Raw bits.
    pub const fn bits(self) -> u16 {
        self.0
    }
    /// Whether every flag of `other` is set.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
    /// Whether no flag is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// Sets the flags of `other`.
    pub fn insert(&mut self, other: Self) {
        self.0 |= other.0;
    }
}

impl core::ops::BitOr for StepFlags {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        Self(self.0 | rhs.0)
    }
}

/// The state of one order after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OrderStatus {
    /// Predicted, subtracted and updated.
    #[default]
    Active,
    /// Predicted and subtracted, not updated (its line is too slow to tell from load).
    Held,
    /// Line above the Nyquist fraction: zeroed, excluded from prediction and update.
    Off,
}

/// The result of one step for one joint. All estimates are predictions made before
/// `y(k)` was seen, so the clean torque has no added delay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RippleOutput<T: Real> {
    /// Clean torque `T_meas − ripple − misalignment`, N·m.
    pub torque_nm: T,
    /// Predicted ripple: sum of the Relative- and Motor-referenced orders, N·m.
    pub ripple_nm: T,
    /// Predicted misalignment: sum of the Output-referenced orders, N·m.
    pub misalignment_nm: T,
    /// Filtered torque estimate `T_exp + b̂(k|k)` (filtered, lags); equals `torque_nm`
    /// when the model has no bias state.
    pub torque_state_nm: T,
    /// Innovation `e = y − C x̂(k|k−1)`, N·m (with the bias state in `C`).
    pub innovation_nm: T,
    /// Innovation variance `S = R + C P Cᵀ` over the updated states, N·m².
    pub innovation_variance_nm2: T,
    /// Normalized innovation squared `e² / S`; χ²(1) when the model is right.
    pub nis: T,
    /// What happened.
    pub flags: StepFlags,
}
