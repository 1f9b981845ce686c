use super::*;

/// The angles a kinematic-error model may depend on, rad.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GearAngles<T: Real> {
    /// Output (link) angle from its zero, unwrapped.
    pub output_rad: T,
    /// Relative angle `φ = θ_wg − θ_fs`, reduced to `[0, 2π)`.
    pub relative_rad: T,
    /// Motor (WG) angle, reduced to `[0, 2π)`: the WG against the circular spline when it is fixed.
    pub motor_rad: T,
}

impl<T: Real> GearAngles<T> {
    /// The angles from `f64` motor and link angles (gear convention), reducing in `f64`.
    pub fn from_f64(gear: &Gear<T>, motor_angle_rad: f64, link_angle_rad: f64) -> Self {
        let fs = gear.flexspline_angle(T::ONE).to_f64() * link_angle_rad;
        Self {
            output_rad: T::from_f64(link_angle_rad),
            relative_rad: T::from_f64(reduce_tau(motor_angle_rad - fs)),
            motor_rad: T::from_f64(reduce_tau(motor_angle_rad)),
        }
    }
}

/// A model of the kinematic error `θ_k`: the torsion seen at no load, rad.
pub trait KinematicError<T: Real> {
    /// `θ_k` at the given angles, rad.
    fn kinematic_error_rad(&self, angles: &GearAngles<T>) -> T;
}

/// No kinematic error (`θ_k = 0`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NoKinematicError;

impl<T: Real> KinematicError<T> for NoKinematicError {
    fn kinematic_error_rad(&self, _angles: &GearAngles<T>) -> T {
        T::ZERO
    }
}

/// Polynomial kinematic error in the output angle, `θ_k = Σ_i a_i θ^i`, `D` coefficients
/// (order `D − 1`). Not periodic: valid over the angle range it was fitted on only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicPolynomial<T: Real, const D: usize> {
    coefficients: [T; D],
}

impl<T: Real, const D: usize> KinematicPolynomial<T, D> {
    /// From `a_0 … a_{D−1}` (rad per rad^i); all must be finite.
    ///
    /// ```
    /// use strainwave_core::torsion::{GearAngles, KinematicError, KinematicPolynomial};
    /// let p = KinematicPolynomial::new([1e-4_f64, 2e-4]).unwrap();
    /// let a = GearAngles { output_rad: 0.5, ..Default::default() };
    /// assert!((p.kinematic_error_rad(&a) - 2e-4).abs() < 1e-15);
    /// ```
    pub fn new(coefficients: [T; D]) -> Result<Self, Error> {
        for c in coefficients {
            finite(c, "kinematic_polynomial")?;
        }
        Ok(Self { coefficients })
    }

    /// The coefficients `a_0 …`.
    pub fn coefficients(&self) -> &[T; D] {
        &self.coefficients
    }

    /// `θ_k(θ)` by Horner's rule.
    pub fn eval(&self, output_rad: T) -> T {
        self.coefficients.iter().rev().fold(T::ZERO, |acc, &a| acc * output_rad + a)
    }
}

impl<T: Real> KinematicPolynomial<T, 6> {
    /// the HDA-arm paper, Table II: the 5th-order fit `a0 … a5 = −6.5719e−5, 0.0018, 0.032, −0.0017,
    /// 2.6840e−4, −1.2686e−5`, output angle in rad, `θ_k` in rad.
    ///
    /// The paper does not state the range; the polynomial reaches 1.1 rad at `θ = 2π`, so it
    /// can only describe a short stretch (one motor revolution, `2π/N` of output, gives
    /// 0.2 mrad for N = 100). Use it there, or fit a Fourier model.
    ///
    /// ```
    /// use strainwave_core::torsion::KinematicPolynomial;
    /// let p = KinematicPolynomial::<f64, 6>::hda_arm();
    /// assert!((p.eval(0.0) + 6.5719e-5).abs() < 1e-12);
    /// ```
    pub fn hda_arm() -> Self {
        Self { coefficients: [-6.5719e-5, 0.0018, 0.032, -0.0017, 2.6840e-4, -1.2686e-5].map(T::from_f64) }
    }
}

impl<T: Real, const D: usize> KinematicError<T> for KinematicPolynomial<T, D> {
    fn kinematic_error_rad(&self, angles: &GearAngles<T>) -> T {
        self.eval(angles.output_rad)
    }
}

/// Which fast angle the mesh harmonics of [`KinematicFourier`] follow (with the `serde`
/// feature, `"relative"` or `"motor"` in a model file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum MeshAngle {
    /// Relative angle `φ = θ_wg − θ_fs`: errors that travel with the flexspline teeth (docs/physics.md §1).
    #[default]
    Relative,
    /// Motor (WG) angle: errors of the WG itself and, with the CS fixed, of its mesh with the CS.
    Motor,
}

/// Fourier kinematic error, periodic in the output angle and in a mesh angle:
///
/// ```text
/// θ_k = c0 + Σ_{h=1..HO} (a_h cos hθ + b_h sin hθ) + Σ_{h=1..HR} (c_h cos hψ + d_h sin hψ)
/// ```
///
/// `ψ` is the relative or the motor angle ([`MeshAngle`]). The physical error is periodic,
/// so unlike the polynomial it holds over any number of turns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicFourier<T: Real, const HO: usize, const HR: usize> {
    offset_rad: T,
    output: [[T; 2]; HO],
    mesh: [[T; 2]; HR],
    mesh_angle: MeshAngle,
}

/// The default kinematic model: 2 output harmonics and 4 mesh harmonics.
pub type DefaultKinematic<T> = KinematicFourier<T, 2, 4>;

/// `Σ_h (p_h cos hx + q_h sin hx)` by the angle-addition recurrence.
pub(super) fn fourier_sum<T: Real>(x: T, coefs: &[[T; 2]]) -> T {
    if coefs.is_empty() {
        return T::ZERO;
    }
    let (s1, c1) = x.sin_cos();
    let (mut s, mut c) = (s1, c1);
    let mut acc = T::ZERO;
    for pq in coefs {
        acc += pq[0] * c + pq[1] * s;
        let c_next = c * c1 - s * s1;
        s = s * c1 + c * s1;
        c = c_next;
    }
    acc
}

impl<T: Real, const HO: usize, const HR: usize> KinematicFourier<T, HO, HR> {
    /// Offset `c0`, output harmonics `[a_h, b_h]`, mesh harmonics `[c_h, d_h]` (rad), all finite.
    ///
    /// ```
    /// use strainwave_core::torsion::{GearAngles, KinematicError, KinematicFourier, MeshAngle};
    /// let k = KinematicFourier::new(0.0_f64, [[0.0, 1e-4]], [[0.0, 0.0], [2e-5, 0.0]], MeshAngle::Relative).unwrap();
    /// let a = GearAngles { output_rad: core::f64::consts::FRAC_PI_2, relative_rad: 0.0, motor_rad: 0.0 };
    /// assert!((k.kinematic_error_rad(&a) - 1.2e-4).abs() < 1e-15);
    /// ```
    pub fn new(offset_rad: T, output: [[T; 2]; HO], mesh: [[T; 2]; HR], mesh_angle: MeshAngle) -> Result<Self, Error> {
        finite(offset_rad, "kinematic_offset_rad")?;
        for pq in output.iter().chain(mesh.iter()) {
            finite(pq[0], "kinematic_fourier")?;
            finite(pq[1], "kinematic_fourier")?;
        }
        Ok(Self { offset_rad, output, mesh, mesh_angle })
    }

    /// All coefficients zero.
    pub fn zero(mesh_angle: MeshAngle) -> Self {
        Self { offset_rad: T::ZERO, output: [[T::ZERO; 2]; HO], mesh: [[T::ZERO; 2]; HR], mesh_angle }
    }

    /// Offset `c0`, rad.
    pub fn offset_rad(&self) -> T {
        self.offset_rad
    }
    /// Output harmonics `[a_h, b_h]`, rad.
    pub fn output_harmonics(&self) -> &[[T; 2]; HO] {
        &self.output
    }
    /// Mesh harmonics `[c_h, d_h]`, rad.
    pub fn mesh_harmonics(&self) -> &[[T; 2]; HR] {
        &self.mesh
    }
    /// The mesh angle.
    pub fn mesh_angle(&self) -> MeshAngle {
        self.mesh_angle
    }
}

impl<T: Real, const HO: usize, const HR: usize> KinematicError<T> for KinematicFourier<T, HO, HR> {
    fn kinematic_error_rad(&self, angles: &GearAngles<T>) -> T {
        let psi = match self.mesh_angle {
            MeshAngle::Relative => angles.relative_rad,
            MeshAngle::Motor => angles.motor_rad,
        };
        // The output angle is unwrapped; reduce it so f32 keeps its phase after many turns.
        let out = angles.output_rad - T::TAU * (angles.output_rad / T::TAU).floor();
        self.offset_rad + fourier_sum(out, &self.output) + fourier_sum(psi, &self.mesh)
    }
}
