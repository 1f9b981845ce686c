//! Hysteresis of the wind-up: the Dahl law and a sum of plays (Maxwell-slip).

use crate::error::{finite, non_negative, positive, Error};
use crate::Real;

/// Hysteresis loss as a Dahl-type state on the wind-up `w` (the same law as the
/// simulator's joint): the elastic twist is `w + h z` with
///
/// ```text
/// dz/dw = (1 − z sgn ẇ) / λ,    |z| ≤ 1
/// exact over a monotone increment Δw:  z = s + (z0 − s) e^(−|Δw|/λ),  s = sgn Δw
/// ```
///
/// `h` is half the loop width in twist (catalogue hysteresis loss = `2h`), `λ` the twist
/// over which the loop closes after a reversal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hysteresis<T: Real> {
    half_width_rad: T,
    memory_rad: T,
}

impl<T: Real> Hysteresis<T> {
    /// Half loop width `h ≥ 0` and memory `λ > 0`, rad.
    ///
    /// ```
    /// use strainwave_core::compliance::Hysteresis;
    /// let h = Hysteresis::new(1.45e-4_f64, 1.45e-4).unwrap();
    /// let z = h.update(0.0, 1e-3); // a long loading stroke saturates z
    /// assert!((z - 1.0).abs() < 1e-2);
    /// ```
    pub fn new(half_width_rad: T, memory_rad: T) -> Result<Self, Error> {
        non_negative(half_width_rad, "half_width_rad")?;
        positive(memory_rad, "memory_rad")?;
        Ok(Self { half_width_rad, memory_rad })
    }

    /// From a catalogue hysteresis loss (full loop width, rad), closing over half of it.
    pub fn from_loss(loss_rad: T) -> Result<Self, Error> {
        non_negative(loss_rad, "hysteresis_loss_rad")?;
        let h = T::HALF * loss_rad;
        Self::new(h, h.max(T::from_f64(1e-12)))
    }

    /// `(h, λ)`.
    pub fn parameters(&self) -> (T, T) {
        (self.half_width_rad, self.memory_rad)
    }

    /// The state after a wind-up increment, exact for a monotone increment.
    pub fn update(&self, z: T, delta_windup_rad: T) -> T {
        if !delta_windup_rad.is_finite() || !z.is_finite() {
            return z.clamp(-T::ONE, T::ONE);
        }
        let s = delta_windup_rad.signum0();
        if s == T::ZERO {
            return z;
        }
        (s + (z - s) * (-delta_windup_rad.abs() / self.memory_rad).exp()).clamp(-T::ONE, T::ONE)
    }

    /// Elastic twist `w + h z`.
    pub fn elastic_twist_rad(&self, windup_rad: T, z: T) -> T {
        windup_rad + self.half_width_rad * z
    }
}

/// Most play operators a [`PlayHysteresis`] can hold.
pub const MAX_PLAYS: usize = 8;

/// Rate-independent hysteresis as a weighted sum of play (backlash) operators on the
/// wind-up — the Maxwell-slip / Prandtl–Ishlinskii model of gear friction:
///
/// ```text
/// p_i ← clamp(p_i, w − r_i, w + r_i)          play of half-width r_i
/// elastic twist = w + Σ_i β_i (w − p_i) / r_i  each term within ±β_i
/// ```
///
/// The loop width once every play slides is `2 Σ β_i` (the catalogue hysteresis loss).
/// Wind-up changes smaller than a play leave it alone, so encoder noise below the
/// narrowest play does not walk the state (unlike a Dahl law). State: one value per play.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlayHysteresis<T: Real> {
    half_widths_rad: [T; MAX_PLAYS],
    weights_rad: [T; MAX_PLAYS],
    count: usize,
}

impl<T: Real> PlayHysteresis<T> {
    /// Plays of half-widths `r_i > 0` with weights `β_i` (rad, finite), at most [`MAX_PLAYS`].
    ///
    /// ```
    /// use strainwave_core::compliance::PlayHysteresis;
    /// let h = PlayHysteresis::new(&[2e-5_f64, 1e-4], &[5e-5, 1e-4]).unwrap();
    /// let mut plays = h.initial_state(0.0);
    /// h.advance(&mut plays, 1e-3); // a long loading stroke: every play slides
    /// assert!((h.offset_rad(&plays, 1e-3) - 1.5e-4).abs() < 1e-15);
    /// assert!(PlayHysteresis::<f64>::new(&[0.0], &[1e-4]).is_err());
    /// ```
    pub fn new(half_widths_rad: &[T], weights_rad: &[T]) -> Result<Self, Error> {
        if half_widths_rad.len() > MAX_PLAYS {
            return Err(Error::OutOfRange("half_widths_rad"));
        }
        if weights_rad.len() != half_widths_rad.len() {
            return Err(Error::OutOfRange("weights_rad"));
        }
        let mut r = [T::ONE; MAX_PLAYS];
        let mut b = [T::ZERO; MAX_PLAYS];
        for (i, (&ri, &bi)) in half_widths_rad.iter().zip(weights_rad).enumerate() {
            r[i] = positive(ri, "half_widths_rad")?;
            b[i] = finite(bi, "weights_rad")?;
        }
        Ok(Self { half_widths_rad: r, weights_rad: b, count: half_widths_rad.len() })
    }

    /// Number of plays.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether there are no plays.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Half-widths `r_i`, rad.
    pub fn half_widths_rad(&self) -> &[T] {
        &self.half_widths_rad[..self.count]
    }

    /// Weights `β_i`, rad.
    pub fn weights_rad(&self) -> &[T] {
        &self.weights_rad[..self.count]
    }

    /// Play state centred on a wind-up (no memory yet).
    pub fn initial_state(&self, windup_rad: T) -> [T; MAX_PLAYS] {
        [windup_rad; MAX_PLAYS]
    }

    /// Moves every play to a new wind-up (exact for any path between samples that is monotone).
    pub fn advance(&self, plays: &mut [T; MAX_PLAYS], windup_rad: T) {
        if !windup_rad.is_finite() {
            return;
        }
        for (p, &r) in plays.iter_mut().zip(&self.half_widths_rad).take(self.count) {
            *p = p.clamp(windup_rad - r, windup_rad + r);
        }
    }

    /// Normalised play deflections `(w − p_i)/r_i ∈ [−1, 1]`.
    pub fn deflections(&self, plays: &[T; MAX_PLAYS], windup_rad: T, out: &mut [T; MAX_PLAYS]) {
        for i in 0..MAX_PLAYS {
            out[i] = if i < self.count { (windup_rad - plays[i]) / self.half_widths_rad[i] } else { T::ZERO };
        }
    }

    /// `Σ β_i (w − p_i) / r_i`, rad: add to the wind-up to get the elastic twist.
    pub fn offset_rad(&self, plays: &[T; MAX_PLAYS], windup_rad: T) -> T {
        (0..self.count)
            .fold(T::ZERO, |acc, i| acc + self.weights_rad[i] * (windup_rad - plays[i]) / self.half_widths_rad[i])
    }
}
