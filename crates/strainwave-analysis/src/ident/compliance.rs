//! The compliance models the fit can produce, their options and results.

use super::*;

/// A kinematic model plus a constant wind-up offset (`θ_k + w0`).
#[derive(Debug, Clone, PartialEq)]
pub struct WithOffset<K> {
    /// The model.
    pub inner: K,
    /// Added offset, rad.
    pub offset_rad: f64,
}

impl<K: KinematicError<f64>> KinematicError<f64> for WithOffset<K> {
    fn kinematic_error_rad(&self, angles: &GearAngles<f64>) -> f64 {
        self.inner.kinematic_error_rad(angles) + self.offset_rad
    }
}

/// The compliance model to fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ComplianceForm {
    /// `τ = K w`.
    Linear,
    /// `τ = k1 w + k3 w³`.
    Cubic,
    /// Catalogue three-slope curve with the break torques fixed.
    ThreeSlope {
        /// First break torque, N·m.
        t1_nm: f64,
        /// Second break torque, N·m.
        t2_nm: f64,
    },
    /// HDA arm: stiffening flexspline and wave generator in series, with this ratio.
    Seed {
        /// Ratio `N`.
        ratio: f64,
    },
    /// Known springs (e.g. the catalogue's): only the zero, the hysteresis and the damping
    /// are fitted. Without any of those the fit only evaluates the model.
    Fixed(ComplianceParams),
}

/// Fitted compliance parameters (plain values; SI units). Serialized as a TOML table
/// tagged `form = "linear" | "cubic" | "three-slope" | "hda"` (older files: `"three_slope"`,
/// `"seed"`, still read).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "form", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ComplianceParams {
    /// Linear stiffness, N·m/rad.
    Linear {
        /// `K`.
        k_nm_per_rad: f64,
    },
    /// Cubic stiffness.
    Cubic {
        /// `k1`, N·m/rad.
        k1_nm_per_rad: f64,
        /// `k3`, N·m/rad³.
        k3_nm_per_rad3: f64,
    },
    /// Three-slope stiffness.
    #[serde(alias = "three_slope")]
    ThreeSlope {
        /// `K1`, N·m/rad.
        k1_nm_per_rad: f64,
        /// `K2`, N·m/rad.
        k2_nm_per_rad: f64,
        /// `K3`, N·m/rad.
        k3_nm_per_rad: f64,
        /// `T1`, N·m.
        t1_nm: f64,
        /// `T2`, N·m.
        t2_nm: f64,
    },
    /// HDA arm springs (the arm's harmonic drive compliance law; `form = "hda"`).
    #[serde(rename = "hda", alias = "seed")]
    Seed {
        /// `K_f0`, N·m/rad.
        flexspline_k0_nm_per_rad: f64,
        /// `C_f`, 1/(N·m).
        flexspline_c_per_nm: f64,
        /// `K_w0` at the WG, N·m/rad.
        wave_generator_k0_nm_per_rad: f64,
        /// `c_w`, 1/(N·m).
        wave_generator_c_per_nm: f64,
        /// `N`.
        ratio: f64,
    },
}

/// Any of the core's compliance models (dispatch by `match`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnyCompliance {
    /// Three-slope (also the linear case).
    ThreeSlope(ThreeSlopeStiffness<f64>),
    /// Cubic.
    Cubic(CubicStiffness<f64>),
    /// HDA arm.
    HdaArm(HdaArmCompliance<f64>),
}

impl Compliance<f64> for AnyCompliance {
    fn twist_rad(&self, torque_nm: f64) -> f64 {
        match self {
            AnyCompliance::ThreeSlope(m) => Compliance::twist_rad(m, torque_nm),
            AnyCompliance::Cubic(m) => m.twist_rad(torque_nm),
            AnyCompliance::HdaArm(m) => m.twist_rad(torque_nm),
        }
    }
    fn compliance_rad_per_nm(&self, torque_nm: f64) -> f64 {
        match self {
            AnyCompliance::ThreeSlope(m) => m.compliance_rad_per_nm(torque_nm),
            AnyCompliance::Cubic(m) => m.compliance_rad_per_nm(torque_nm),
            AnyCompliance::HdaArm(m) => m.compliance_rad_per_nm(torque_nm),
        }
    }
    fn max_twist_rad(&self) -> Option<f64> {
        match self {
            AnyCompliance::ThreeSlope(m) => m.max_twist_rad(),
            AnyCompliance::Cubic(m) => m.max_twist_rad(),
            AnyCompliance::HdaArm(m) => m.max_twist_rad(),
        }
    }
}

impl ComplianceParams {
    /// The core model.
    pub fn model(&self) -> Result<AnyCompliance, AnalysisError> {
        let core = |e: strainwave_core::Error| invalid("compliance.spring", e.to_string());
        Ok(match *self {
            ComplianceParams::Linear { k_nm_per_rad } => {
                AnyCompliance::ThreeSlope(ThreeSlopeStiffness::linear(k_nm_per_rad).map_err(core)?)
            }
            ComplianceParams::Cubic { k1_nm_per_rad, k3_nm_per_rad3 } => {
                AnyCompliance::Cubic(CubicStiffness::new(k1_nm_per_rad, k3_nm_per_rad3).map_err(core)?)
            }
            ComplianceParams::ThreeSlope { k1_nm_per_rad, k2_nm_per_rad, k3_nm_per_rad, t1_nm, t2_nm } => {
                AnyCompliance::ThreeSlope(
                    ThreeSlopeStiffness::new(k1_nm_per_rad, k2_nm_per_rad, k3_nm_per_rad, t1_nm, t2_nm)
                        .map_err(core)?,
                )
            }
            ComplianceParams::Seed {
                flexspline_k0_nm_per_rad,
                flexspline_c_per_nm,
                wave_generator_k0_nm_per_rad,
                wave_generator_c_per_nm,
                ratio,
            } => AnyCompliance::HdaArm(
                HdaArmCompliance::new(
                    FlexsplineStiffening::new(flexspline_k0_nm_per_rad, flexspline_c_per_nm).map_err(core)?,
                    WaveGeneratorSoftening::new(wave_generator_k0_nm_per_rad, wave_generator_c_per_nm).map_err(core)?,
                    ratio,
                )
                .map_err(core)?,
            ),
        })
    }
}

/// The hysteresis model to fit.
#[derive(Debug, Clone, PartialEq)]
pub enum HysteresisForm {
    /// None.
    None,
    /// Dahl law (half width `h`, memory `λ`) with the core's reversal deadband, rad.
    Dahl {
        /// Reversal deadband, rad.
        deadband_rad: f64,
    },
    /// Play operators of these half-widths (rad, at most `MAX_PLAYS`); their weights are fitted.
    Plays {
        /// Half-widths `r_i`, rad.
        half_widths_rad: Vec<f64>,
    },
}

impl HysteresisForm {
    /// Plays with half-widths in a geometric series from `narrowest_rad` (choose it above
    /// the torsion noise, peak to peak) by `factor`.
    pub fn geometric_plays(narrowest_rad: f64, factor: f64, count: usize) -> Self {
        HysteresisForm::Plays { half_widths_rad: (0..count).map(|i| narrowest_rad * factor.powi(i as i32)).collect() }
    }

    pub(super) fn n_params(&self) -> usize {
        match self {
            HysteresisForm::None => 0,
            HysteresisForm::Dahl { .. } => 2,
            HysteresisForm::Plays { half_widths_rad } => half_widths_rad.len(),
        }
    }
}

/// Fitted hysteresis. Serialized tagged `kind = "none" | "dahl" | "plays"`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum FittedHysteresis {
    /// None.
    None,
    /// Dahl law.
    Dahl {
        /// Half loop width `h`, rad.
        half_width_rad: f64,
        /// Memory `λ`, rad.
        memory_rad: f64,
        /// Reversal deadband, rad.
        deadband_rad: f64,
    },
    /// Play operators.
    Plays {
        /// Half-widths `r_i`, rad.
        half_widths_rad: Vec<f64>,
        /// Weights `β_i`, rad.
        weights_rad: Vec<f64>,
    },
}

/// Options of the compliance fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ComplianceFitOptions {
    /// The model.
    pub form: ComplianceForm,
    /// The hysteresis model.
    pub hysteresis: HysteresisForm,
    /// Fit structural damping `c ẇ`.
    pub damping: bool,
    /// Fit a wind-up offset `w0` (when no no-load run fixed the zero).
    pub windup_offset: bool,
    /// Rated torque, N·m: scales the parameters and sets the solver (bracket 4 × rated).
    pub rated_torque_nm: f64,
    /// Levenberg–Marquardt iteration cap.
    pub max_iterations: usize,
    /// Fit on every `decimation`-th sample (≥ 1). Play states and rates are still
    /// computed at the full rate, so the fit stays that of the full-rate estimator; use it
    /// when the load changes slowly against the sample rate (a Dahl fit ignores it).
    pub decimation: usize,
    /// The reference is a motor-current torque: identify friction and rotor inertia with
    /// the compliance (see [`FrictionParams`]). `None`: the reference is the link torque.
    pub friction: Option<FrictionFitOptions>,
    /// Fit on these rows only (0-based, increasing; e.g. the training blocks of a blocked
    /// holdout). States and rates still run over the whole run, which only uses angles.
    pub train_rows: Option<Vec<usize>>,
    /// Levenberg–Marquardt tolerances.
    pub tolerances: LmTolerances,
}

impl ComplianceFitOptions {
    /// Defaults for a form and rated torque: no hysteresis, no damping, no offset, 40 iterations.
    pub fn new(form: ComplianceForm, rated_torque_nm: f64) -> Self {
        Self {
            form,
            hysteresis: HysteresisForm::None,
            damping: false,
            windup_offset: false,
            rated_torque_nm,
            max_iterations: 40,
            decimation: 1,
            friction: None,
            train_rows: None,
            tolerances: LmTolerances::default(),
        }
    }
}

/// A fitted compliance, ready to build an estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct ComplianceFit {
    /// Spring parameters.
    pub params: ComplianceParams,
    /// Hysteresis.
    pub hysteresis: FittedHysteresis,
    /// Structural damping, N·m·s/rad.
    pub damping_nm_s_per_rad: f64,
    /// Wind-up offset `w0`, rad.
    pub windup_offset_rad: f64,
    /// Rated torque the solver is set for, N·m.
    pub rated_torque_nm: f64,
    /// Estimate against the reference on the identification run.
    pub metrics: FitMetrics,
    /// Levenberg–Marquardt iterations (0 for a linear least-squares fit).
    pub iterations: usize,
    /// Why the Levenberg–Marquardt iteration stopped (`None`: a linear least-squares fit).
    pub termination: Option<LmTermination>,
    /// Friction and rotor inertia, when the reference is a motor-current torque.
    pub friction: Option<FrictionParams>,
    /// Fitted parameters with standard errors (from the final Jacobian, or the linear
    /// least-squares covariance). Friction errors are conditional on the spring when
    /// the two are fitted alternately.
    pub parameters: Vec<ParamEstimate>,
}

impl ComplianceFit {
    /// Whether the fit converged (a linear least-squares fit always does).
    pub fn converged(&self) -> bool {
        self.termination.is_none_or(LmTermination::converged)
    }
}

/// An estimator built from fitted models, fed with angles.
pub type FittedEstimator<K> = TorsionEstimator<f64, WithOffset<K>, AnyCompliance>;

impl ComplianceFit {
    /// The streaming estimator with these parameters and a kinematic model.
    pub fn estimator<K: KinematicError<f64>>(
        &self,
        gear: Gear<f64>,
        kinematic: K,
        sample_rate_hz: f64,
    ) -> Result<FittedEstimator<K>, AnalysisError> {
        // Angles are fed directly (`step_angles`); the encoder configurations are unused.
        let enc = EncoderConfig::multi_turn(1 << 20).map_err(|e| invalid("estimator", e.to_string()))?;
        self.estimator_for_counts(gear, enc, enc, kinematic, sample_rate_hz)
    }

    /// The streaming estimator fed with raw encoder counts (see [`EncoderConfig`]).
    pub fn estimator_for_counts<K: KinematicError<f64>>(
        &self,
        gear: Gear<f64>,
        motor_encoder: EncoderConfig,
        link_encoder: EncoderConfig,
        kinematic: K,
        sample_rate_hz: f64,
    ) -> Result<FittedEstimator<K>, AnalysisError> {
        // Each error is labelled with the model file's key of what failed.
        let keyed = |what: &'static str| move |e: strainwave_core::Error| invalid(what, e.to_string());
        let mut est = TorsionEstimator::new(
            gear,
            motor_encoder,
            link_encoder,
            WithOffset { inner: kinematic, offset_rad: self.windup_offset_rad },
            self.params.model()?,
            TorqueSolver::for_rated_torque(self.rated_torque_nm).map_err(keyed("compliance"))?,
        );
        match &self.hysteresis {
            FittedHysteresis::None => {}
            FittedHysteresis::Dahl { half_width_rad, memory_rad, deadband_rad } => {
                est = est
                    .with_hysteresis(
                        Hysteresis::new(*half_width_rad, *memory_rad).map_err(keyed("compliance.hysteresis"))?,
                        *deadband_rad,
                    )
                    .map_err(keyed("compliance.hysteresis"))?;
            }
            FittedHysteresis::Plays { half_widths_rad, weights_rad } => {
                est = est.with_play_hysteresis(
                    PlayHysteresis::new(half_widths_rad, weights_rad).map_err(keyed("compliance.hysteresis"))?,
                );
            }
        }
        if self.damping_nm_s_per_rad != 0.0 {
            est = est.with_damping(self.damping_nm_s_per_rad, sample_rate_hz).map_err(keyed("compliance"))?;
        }
        Ok(est)
    }

    /// The estimated link torque along a run (NaN where the solver fails), N·m.
    pub fn predict<K: KinematicError<f64>>(
        &self,
        gear: &Gear<f64>,
        kinematic: K,
        angles: &JointAngles,
    ) -> Result<Vec<f64>, AnalysisError> {
        let est = self.estimator(*gear, kinematic, angles.sample_rate_hz)?;
        Ok(run_estimator(&est, angles))
    }

    /// The reference the model predicts along a run: the link torque, plus friction and
    /// inertial torque when the fit has them (the motor-current torque), N·m.
    pub fn predict_reference<K: KinematicError<f64>>(
        &self,
        gear: &Gear<f64>,
        kinematic: K,
        angles: &JointAngles,
    ) -> Result<Vec<f64>, AnalysisError> {
        let mut link = self.predict(gear, kinematic, angles)?;
        if let Some(f) = &self.friction {
            let (v, a) = motion_rates(&angles.link_side_motor_angle_rad(gear), angles.sample_rate_hz, f.rate_span)?;
            for ((t, v), a) in link.iter_mut().zip(&v).zip(&a) {
                *t += f.torque_nm(*t, *v, *a);
            }
        }
        Ok(link)
    }
}
