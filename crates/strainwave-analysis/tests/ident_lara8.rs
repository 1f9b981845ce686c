//! Real data: joint 3 of the LARA8 arm (`data/lara8/validate.csv`, 250 Hz, motor and
//! link encoders of 2^24 counts per revolution, ratio 101, CHA-25A gear).
//!
//! A model is identified on one half of the run and the link torque estimated from the
//! raw counts on the other half, compared with `joint_torque_current_3`. That column is
//! the controller's torque from the motor current: it **includes friction** (and the
//! stiction at the start and the stop of the sweep), so it is not a torque-sensor reading
//! and no torsion-based estimate can match it closely; the figures below are what a user
//! of this log gets, not an accuracy of the estimator. A reference-free check completes
//! them: the ripple at the first two motor-angle orders in the estimated torque, which the
//! kinematic-error model should remove. The last test models what the current torque
//! holds (friction, rotor inertia) and scores it by a blocked holdout.

use std::path::PathBuf;

use strainwave_analysis::ident::{
    blocked_holdout, fit_compliance, fit_kinematic_error, fit_kinematic_error_on, lstsq_qr, training_rows,
    ComplianceFit, ComplianceFitOptions, ComplianceForm, ComplianceParams, FitMetrics, FrictionFitOptions, JointAngles,
    KinematicBasis, KinematicFit, KinematicFitOptions,
};
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::torsion::{EncoderConfig, EstimatorState, KinematicError, MeshAngle, NoKinematicError};

const COUNTS_PER_REV: u64 = 1 << 24;
const RATIO: f64 = 101.0;
const MOTOR_OFFSET: i64 = -462_313_317;
const LINK_OFFSET: i64 = 1_144_971;
const FS_HZ: f64 = 250.0;
/// CHA-25A catalogue break torques, N·m.
const T1_NM: f64 = 14.0;
const T2_NM: f64 = 48.0;
/// Rated torque used to scale the fits, N·m.
const RATED_NM: f64 = 100.0;

struct Log {
    motor_counts: Vec<i64>,
    link_counts: Vec<i64>,
    torque_nm: Vec<f64>,
}

fn load() -> Option<Log> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/lara8/validate.csv");
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        // The log ships with the repository: a missing file is a failure, not a skip.
        Err(e) => panic!("{} not readable ({e})", path.display()),
    };
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| header.iter().position(|h| h.trim() == name).unwrap_or_else(|| panic!("no column {name}"));
    let (ct, cm, cl, cq) =
        (col("Timestamp"), col("encoder_motorinc_3"), col("encoder_loadinc_3"), col("joint_torque_current_3"));
    let mut log = Log { motor_counts: Vec::new(), link_counts: Vec::new(), torque_nm: Vec::new() };
    let mut last_t = f64::NEG_INFINITY;
    for (i, line) in lines.enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        let num = |c: usize| -> f64 {
            f[c].trim().parse::<f64>().unwrap_or_else(|e| panic!("row {}, column {c}: {e}", i + 2))
        };
        let t = num(ct);
        assert!(t > last_t, "timestamps must increase (row {})", i + 2);
        last_t = t;
        log.motor_counts.push(num(cm).round() as i64);
        log.link_counts.push(num(cl).round() as i64);
        log.torque_nm.push(num(cq));
    }
    Some(log)
}

fn gear() -> Gear<f64> {
    Gear::new(RATIO, FixedElement::CircularSpline).unwrap()
}

/// The joint's encoders in the gear's convention: the motor encoder counts against the WG.
fn encoders() -> (EncoderConfig, EncoderConfig) {
    let m = EncoderConfig::multi_turn(COUNTS_PER_REV).unwrap().with_offset(MOTOR_OFFSET).reversed();
    let l = EncoderConfig::multi_turn(COUNTS_PER_REV).unwrap().with_offset(LINK_OFFSET);
    (m, l)
}

/// Angles in the gear's convention, rad.
fn angles(log: &Log, r: std::ops::Range<usize>) -> (Vec<f64>, Vec<f64>) {
    let step = std::f64::consts::TAU / COUNTS_PER_REV as f64;
    let m = log.motor_counts[r.clone()].iter().map(|c| -((c - MOTOR_OFFSET) as f64) * step).collect();
    let l = log.link_counts[r].iter().map(|c| (c - LINK_OFFSET) as f64 * step).collect();
    (m, l)
}

/// The estimator run on raw counts.
fn estimate<K: KinematicError<f64>>(fit: &ComplianceFit, kin: K, log: &Log, r: std::ops::Range<usize>) -> Vec<f64> {
    let (me, le) = encoders();
    let est = fit.estimator_for_counts(gear(), me, le, kin, FS_HZ).unwrap();
    let mut st = EstimatorState::new();
    r.map(|k| est.step_counts(&mut st, log.motor_counts[k], log.link_counts[k]).map_or(f64::NAN, |e| e.link_torque_nm))
        .collect()
}

/// Amplitude of the 1st and 2nd motor-angle orders in a signal after a slow trend.
fn motor_order_ripple(x: &[f64], motor_rad: &[f64]) -> [f64; 2] {
    let n = x.len();
    let mut cols: Vec<Vec<f64>> = (0..=15)
        .map(|d| {
            (0..n)
                .map(|k| {
                    let t = 2.0 * k as f64 / (n - 1) as f64 - 1.0;
                    // Chebyshev polynomials: well conditioned.
                    (d as f64 * t.clamp(-1.0, 1.0).acos()).cos()
                })
                .collect()
        })
        .collect();
    for h in 1..=2 {
        cols.push(motor_rad.iter().map(|m| (h as f64 * m).cos()).collect());
        cols.push(motor_rad.iter().map(|m| (h as f64 * m).sin()).collect());
    }
    let c = lstsq_qr(&cols, x).unwrap();
    [c[16].hypot(c[17]), c[18].hypot(c[19])]
}

struct Report {
    plain: FitMetrics,
    ours: FitMetrics,
    catalogue: FitMetrics,
    /// Motor-order ripple of the wind-up the estimator sees, without / with the kinematic model, rad.
    ripple_plain: [f64; 2],
    ripple_ours: [f64; 2],
}

fn identify_and_estimate(log: &Log, ident: std::ops::Range<usize>, eval: std::ops::Range<usize>) -> Report {
    let g = gear();
    let (mi, li) = angles(log, ident.clone());
    let a = JointAngles { motor_angle_rad: &mi, link_angle_rad: &li, sample_rate_hz: FS_HZ };
    let tq_i = &log.torque_nm[ident];
    let tq_e = &log.torque_nm[eval.clone()];
    // Plain: τ = K (w − w0), K and the zero by least squares, no kinematic model.
    let mut o = ComplianceFitOptions::new(ComplianceForm::Linear, RATED_NM);
    o.windup_offset = true;
    let plain = fit_compliance(&g, &NoKinematicError, &a, tq_i, &o).unwrap();
    // Ours: mesh harmonics of the kinematic error from the loaded half (a slow trend takes
    // up the load), then the catalogue three-slope curve (break torques fixed) and the zero.
    let kopts = KinematicFitOptions { slow_trend_degree: 15, ..Default::default() };
    let basis = KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: 4, mesh_angle: MeshAngle::Motor };
    let kin: KinematicFit = fit_kinematic_error(&g, &a, basis, &kopts).unwrap();
    let mut o = ComplianceFitOptions::new(ComplianceForm::ThreeSlope { t1_nm: T1_NM, t2_nm: T2_NM }, RATED_NM);
    o.windup_offset = true;
    let ours = fit_compliance(&g, &kin, &a, tq_i, &o).unwrap();
    // For comparison: the catalogue's slopes as they are (only the zero fitted).
    let catalogue_params = ComplianceParams::ThreeSlope {
        k1_nm_per_rad: 31e3,
        k2_nm_per_rad: 50e3,
        k3_nm_per_rad: 57e3,
        t1_nm: T1_NM,
        t2_nm: T2_NM,
    };
    let mut o = ComplianceFitOptions::new(ComplianceForm::Fixed(catalogue_params), RATED_NM);
    o.windup_offset = true;
    let catalogue = fit_compliance(&g, &kin, &a, tq_i, &o).unwrap();
    println!("  plain: {:?}", plain.params);
    println!("  ours: {:?}", ours.params);
    println!("  mesh harmonics of the kinematic error (motor angle, rad): {:?}", &kin.coefficients[1..]);
    let est_plain = estimate(&plain, NoKinematicError, log, eval.clone());
    let est_ours = estimate(&ours, kin.clone(), log, eval.clone());
    let est_catalogue = estimate(&catalogue, kin.clone(), log, eval.clone());
    // The counts path agrees with the angle path.
    let (me, le) = angles(log, eval.clone());
    let ae = JointAngles { motor_angle_rad: &me, link_angle_rad: &le, sample_rate_hz: FS_HZ };
    let via_angles = ours.predict(&g, kin.clone(), &ae).unwrap();
    assert!(via_angles.iter().zip(&est_ours).all(|(a, b)| (a - b).abs() < 1e-6));
    // Wind-up without and with the kinematic model on the held-out half.
    let torsion = ae.torsion_rad(&g);
    let w_plain: Vec<f64> = torsion.iter().map(|t| -t).collect();
    let w_ours: Vec<f64> = kin.eval_run(&g, &ae).iter().zip(&torsion).map(|(k, t)| k - t).collect();
    Report {
        plain: FitMetrics::of(&est_plain, tq_e),
        ours: FitMetrics::of(&est_ours, tq_e),
        catalogue: FitMetrics::of(&est_catalogue, tq_e),
        ripple_plain: motor_order_ripple(&w_plain, &me),
        ripple_ours: motor_order_ripple(&w_ours, &me),
    }
}

#[test]
fn lara8_joint3_half_and_half() {
    let Some(log) = load() else {
        return;
    };
    let n = log.torque_nm.len();
    assert!(n > 1000, "{n} rows");
    let h = n / 2;
    println!(
        "LARA8 joint 3, {n} samples at 250 Hz; reference: joint_torque_current_3 (motor current, includes friction)"
    );
    let mut reports = Vec::new();
    for (name, ident, eval) in [("first half → second", 0..h, h..n), ("second half → first", h..n, 0..h)] {
        println!("identify on the {name}:");
        let r = identify_and_estimate(&log, ident, eval);
        let row = |label: &str, m: &FitMetrics| {
            println!("  {label:<58} R² {:+7.3}  RMS {:6.2} N·m  max {:6.1} N·m", m.r_squared, m.rms, m.max_abs)
        };
        row("plain linear stiffness (K and zero by least squares)", &r.plain);
        row("ours (kinematic error + three slopes, zero)", &r.ours);
        row("catalogue slopes as given + kinematic error (zero only)", &r.catalogue);
        println!(
            "  motor-order ripple of the wind-up, 1×/2×: plain {:.2e}/{:.2e} rad, ours {:.2e}/{:.2e} rad",
            r.ripple_plain[0], r.ripple_plain[1], r.ripple_ours[0], r.ripple_ours[1]
        );
        reports.push(r);
    }
    // Context: the same fits in-sample over the whole run.
    println!("in-sample, whole run:");
    let whole = identify_and_estimate(&log, 0..n, 0..n);
    println!(
        "  plain R² {:.3} RMS {:.2} N·m | ours R² {:.3} RMS {:.2} N·m",
        whole.plain.r_squared, whole.plain.rms, whole.ours.r_squared, whole.ours.rms
    );
    assert!(whole.plain.r_squared > 0.87 && whole.ours.r_squared > whole.plain.r_squared, "{:?}", whole.ours);
    // Floors: the figures measured when this test was written, with a margin. Against a
    // friction-laden current torque every estimate is poor across halves (the first half
    // holds the breakaway at the start, the second the stop); see the module doc.
    let (a, b) = (&reports[0], &reports[1]);
    assert!(a.plain.r_squared > -12.0 && a.plain.rms < 71.0, "{:?}", a.plain);
    assert!(a.ours.r_squared > -7.5 && a.ours.rms < 57.0, "{:?}", a.ours);
    assert!(b.plain.r_squared > -3.2 && b.plain.rms < 54.5, "{:?}", b.plain);
    assert!(b.ours.r_squared > -4.0 && b.ours.rms < 59.5, "{:?}", b.ours);
    // Reference-free: the kinematic model identified on one half removes a third to a half
    // of the motor-order ripple (1× and 2× together) of the other half's wind-up
    // (measured 2.65e-5 → 1.49e-5 rad and 2.24e-5 → 1.47e-5 rad).
    for r in &reports {
        let total = |x: &[f64; 2]| x[0].hypot(x[1]);
        assert!(total(&r.ripple_ours) < 0.75 * total(&r.ripple_plain), "{:?} vs {:?}", r.ripple_ours, r.ripple_plain);
    }
}

/// The same log against the current torque with the model of what it holds: link torque
/// plus Coulomb and viscous friction plus rotor inertia × acceleration, identified with
/// a linear spring (the zero fitted, the mesh harmonics from the loaded run), scored by a
/// 5-block holdout beside the plain linear torsion fit on the same split. Measured:
/// R² 0.891 / RMS 22.2 N·m against 0.720 / 35.5 N·m. The halves above fail because each
/// half holds a start or a stop the other never shows; five blocks each see both.
#[test]
fn lara8_joint3_current_torque_model_blocked_holdout() {
    let log = load().expect("log");
    let n = log.torque_nm.len();
    let g = gear();
    let (m, l) = angles(&log, 0..n);
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let q = &log.torque_nm;
    let basis = KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: 4, mesh_angle: MeshAngle::Motor };
    let kopts = KinematicFitOptions { slow_trend_degree: 15, ..Default::default() };
    let mut o = ComplianceFitOptions::new(ComplianceForm::Linear, RATED_NM);
    o.windup_offset = true;
    o.friction = Some(FrictionFitOptions::default());
    let ours = blocked_holdout(q, 5, |_, block| {
        let rows = training_rows(n, block);
        let kin = fit_kinematic_error_on(&g, &a, basis, &kopts, &rows)?;
        let o = ComplianceFitOptions { train_rows: Some(rows), ..o.clone() };
        let fit = fit_compliance(&g, &kin, &a, q, &o)?;
        Ok(fit.predict_reference(&g, kin, &a)?[block.clone()].to_vec())
    })
    .unwrap();
    let torsion = a.torsion_rad(&g);
    let plain = blocked_holdout(q, 5, |_, block| {
        let rows = training_rows(n, block);
        let cols = [rows.iter().map(|&k| torsion[k]).collect(), vec![1.0; rows.len()]];
        let c = lstsq_qr(&cols, &rows.iter().map(|&k| q[k]).collect::<Vec<_>>())?;
        Ok(block.clone().map(|k| c[0] * torsion[k] + c[1]).collect())
    })
    .unwrap();
    println!(
        "5-block holdout vs current torque: ours R² {:.3} RMS {:.2} N·m, plain R² {:.3} RMS {:.2} N·m",
        ours.r_squared, ours.rms, plain.r_squared, plain.rms
    );
    assert!(ours.r_squared > 0.87 && ours.rms < 24.0, "{ours:?}");
    assert!(plain.r_squared < 0.75 && ours.r_squared > plain.r_squared + 0.15, "{plain:?}");
}

/// Training rows that turn one way only (the middle of the sweep), inside a run that
/// also stops: the direction term is the constant there and is dropped, not a rank
/// error (cross-validation folds and holdout blocks meet this).
#[test]
fn kinematic_fit_on_rows_that_turn_one_way() {
    let log = load().expect("log");
    let g = gear();
    let n = log.torque_nm.len();
    let (m, l) = angles(&log, 0..n);
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let kopts = KinematicFitOptions { slow_trend_degree: 15, ..Default::default() };
    let basis = KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: 4, mesh_angle: MeshAngle::Motor };
    let all: Vec<usize> = (0..n).collect();
    let with_stops = fit_kinematic_error_on(&g, &a, basis, &kopts, &all).unwrap();
    assert!(with_stops.direction_offset_rad != 0.0, "the whole run stops and turns: the term is fitted");
    let one_way: Vec<usize> = (400..1400).collect();
    let fit = fit_kinematic_error_on(&g, &a, basis, &kopts, &one_way).unwrap();
    assert_eq!(fit.direction_offset_rad, 0.0);
    // It fits the torsion of those rows as well as the whole run's fit does its own.
    assert!(fit.metrics.r_squared > 0.99 && fit.metrics.samples == one_way.len(), "{:?}", fit.metrics);
    assert!(fit.metrics.rms < 2.0 * with_stops.metrics.rms, "{:?} {:?}", fit.metrics, with_stops.metrics);
}
