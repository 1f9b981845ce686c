//! Behaviour of the digital twin against its physics: ripple and misalignment lines on
//! their orders, `measured_torque` as truth plus white noise, gauge placement errors, the
//! gear's torque balance, reproducible noise, the flexspline-fixed rig, the integrator's
//! convergence and extra lines.

use strainwave_analysis::spectrum::amplitude_spectrum;
use strainwave_sim::presets::preset;
use strainwave_sim::scenario::{GaugePlacement, MotionSegment, PlacementTolerance};
use strainwave_sim::{simulate, Recording, Scenario};

fn window(rec: &Recording, name: &str, t0: f64, t1: f64) -> Vec<f64> {
    let t = rec.column("time").unwrap();
    let x = rec.column(name).unwrap();
    t.iter().zip(x).filter(|(t, _)| **t >= t0 && **t < t1).map(|(_, v)| *v).collect()
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// The taghirad preset with a long constant-speed hold for fine spectra.
fn long_hold() -> Scenario {
    let mut s = preset("taghirad").unwrap();
    s.duration_s = 9.0;
    s.motion = vec![MotionSegment::Ramp { to_rad_s: 156.0, duration_s: 0.4 }, MotionSegment::Hold { duration_s: 8.6 }];
    s
}

#[test]
fn ripple_and_misalignment_lines_sit_on_their_orders() {
    let s = long_hold();
    let (rec, _) = simulate(&s).unwrap();
    let (t0, t1) = (1.0, 9.0);
    let y = window(&rec, "measured_torque", t0, t1);
    let spec = amplitude_spectrum(&y, s.sample_rate_hz).unwrap();
    let rel_rate = mean(
        &window(&rec, "true_relative_angle", t0, t1)
            .windows(2)
            .map(|w| (w[1] - w[0]) * s.sample_rate_hz)
            .collect::<Vec<_>>(),
    );
    let out_rate = mean(&window(&rec, "true_output_velocity", t0, t1));
    let tau = std::f64::consts::TAU;
    let f2 = 2.0 * rel_rate.abs() / tau;
    let f4 = 4.0 * rel_rate.abs() / tau;
    let f_mis = out_rate.abs() / tau;
    // The three strongest lines above 0.1 Hz are the 2×, 4× and misalignment lines.
    let peaks = spec.peaks(3, 0.1, 3.0 * spec.resolution_hz);
    let near = |f: f64| peaks.iter().any(|p| (p.freq_hz - f).abs() <= spec.resolution_hz);
    assert!(near(f2), "2x at {f2} Hz not among {peaks:?}");
    assert!(near(f4), "4x at {f4} Hz not among {peaks:?}");
    assert!(near(f_mis), "misalignment at {f_mis} Hz not among {peaks:?}");
    // The relative angle runs 1 % faster than the motor (CS fixed, N = 100).
    let motor_rate = mean(&window(&rec, "true_motor_velocity", t0, t1));
    assert!((rel_rate / motor_rate - 1.01).abs() < 1e-4, "{}", rel_rate / motor_rate);
}

#[test]
fn measured_torque_is_truth_plus_white_noise() {
    let s = preset("taghirad").unwrap();
    let (rec, sim) = simulate(&s).unwrap();
    let m = rec.column("measured_torque").unwrap();
    let parts = ["true_torque", "true_ripple", "true_misalignment"].map(|c| rec.column(c).unwrap());
    let resid: Vec<f64> = (0..m.len()).map(|k| m[k] - parts[0][k] - parts[1][k] - parts[2][k]).collect();
    let floor = sim.sensor().noise_floor_nm();
    assert!(mean(&resid).abs() < 0.1 * floor, "bias {}", mean(&resid));
    let r = rms(&resid);
    assert!((r / floor - 1.0).abs() < 0.1, "residual rms {r} vs floor {floor}");
    // White: lag-1 autocorrelation near zero.
    let ac = resid.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / resid.iter().map(|v| v * v).sum::<f64>();
    assert!(ac.abs() < 0.05, "lag-1 autocorrelation {ac}");
    assert_eq!(sim.clipped_samples(), 0);
}

/// Ripple with meshing and misalignment switched off: only the bridge interference is left.
fn interference_only(mut s: Scenario) -> Scenario {
    s.ripple.amplitude_2x_nm = 0.0;
    s.ripple.amplitude_2x_per_nm = 0.0;
    s.ripple.amplitude_4x_nm = 0.0;
    s.ripple.amplitude_4x_per_nm = 0.0;
    s.sensor.placement_tolerance = PlacementTolerance::default();
    s.sensor.placement.clear();
    s
}

/// Amplitudes of the 2× and 4× components of `y` on the angle `phi`, by a joint
/// least-squares fit of sin/cos at both orders (exact separation, no leakage).
fn order_amplitudes(y: &[f64], phi: &[f64]) -> (f64, f64) {
    let basis = |p: f64| [(2.0 * p).sin(), (2.0 * p).cos(), (4.0 * p).sin(), (4.0 * p).cos(), 1.0];
    let mut a = [[0.0; 5]; 5];
    let mut b = [0.0; 5];
    for (v, p) in y.iter().zip(phi) {
        let f = basis(*p);
        for i in 0..5 {
            b[i] += f[i] * v;
            for j in 0..5 {
                a[i][j] += f[i] * f[j];
            }
        }
    }
    // Gaussian elimination with partial pivoting (5×5, well conditioned).
    for c in 0..5 {
        let p = (c..5).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs())).unwrap();
        a.swap(c, p);
        b.swap(c, p);
        for r in (c + 1)..5 {
            let f = a[r][c] / a[c][c];
            let (top, bottom) = a.split_at_mut(r);
            for (x, y) in bottom[0][c..].iter_mut().zip(&top[c][c..]) {
                *x -= f * y;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 5];
    for c in (0..5).rev() {
        x[c] = (b[c] - ((c + 1)..5).map(|k| a[c][k] * x[k]).sum::<f64>()) / a[c][c];
    }
    (x[0].hypot(x[1]), x[2].hypot(x[3]))
}

fn ripple_lines(s: &Scenario) -> (f64, f64) {
    let (rec, _) = simulate(s).unwrap();
    let y = window(&rec, "true_ripple", 1.0, 9.0);
    let phi = window(&rec, "true_relative_angle", 1.0, 9.0);
    order_amplitudes(&y, &phi)
}

#[test]
fn ideal_placement_cancels_2x_not_4x() {
    let s = interference_only(long_hold());
    let (a2, a4) = ripple_lines(&s);
    assert!(a2 < 1e-12, "2x interference with ideal placement: {a2} N·m");
    assert!(a4 > 0.05, "4x interference must remain: {a4} N·m");
}

#[test]
fn circumferential_error_leaves_two_psi_delta() {
    let mut s = interference_only(long_hold());
    let delta_deg = 0.5;
    // Move the whole rosette at 90° (gauges 2 and 3) by δ.
    for g in [2, 3] {
        s.sensor.placement.push(GaugePlacement {
            gauge: g,
            radial_mm: 0.0,
            circumferential_deg: delta_deg,
            angular_deg: 0.0,
        });
    }
    let (a2, _) = ripple_lines(&s);
    // Expected: arm 3 − arm 4 shear strain off by Ψ·2δ on one of two series gauges,
    // i.e. a bridge residual (K/4)·E·2Ψδ, in N·m through the true gain.
    let (_, sim) = simulate(&Scenario { duration_s: 0.01, ..s.clone() }).unwrap();
    let p = &s.sensor;
    let psi = p.interference_2x.shear_microstrain * 1e-6;
    let delta = delta_deg.to_radians();
    let want_v = p.gauge_factor / 4.0 * p.excitation_v * 2.0 * psi * delta * p.amplifier_gain;
    let want_nm = want_v * sim.sensor().gain_nm_per_v().abs();
    assert!((a2 / want_nm - 1.0).abs() < 0.05, "2x residual {a2} N·m vs 2Ψδ model {want_nm} N·m");
}

#[test]
fn wg_torque_times_ratio_is_output_torque_plus_friction_at_constant_speed() {
    let s = long_hold();
    let (rec, sim) = simulate(&s).unwrap();
    let m = sim.model();
    let i = window(&rec, "true_motor_current", 4.0, 9.0);
    let wm = window(&rec, "true_motor_velocity", 4.0, 9.0);
    let tau = window(&rec, "true_torque", 4.0, 9.0);
    for k in (0..i.len()).step_by(97) {
        // Motor side at constant speed: T_wg = K_t i − motor friction.
        let t_wg = m.torque_constant() * i[k] - m.motor_friction_nm(wm[k]);
        let lhs = m.signed_ratio() * t_wg;
        let rhs = tau[k] + m.gear_friction_nm(wm[k]);
        assert!((lhs - rhs).abs() < 0.02 * rhs.abs().max(0.1), "k={k}: N·T_wg = {lhs}, τ + τ_f = {rhs}");
    }
    // A steady hold: no limit cycle in the transmitted torque.
    let sd = rms(&tau.iter().map(|v| v - mean(&tau)).collect::<Vec<_>>());
    assert!(sd < 1e-3, "torque wanders at constant speed: {sd} N·m rms");
    // And the output torque balances load friction (no external load).
    let wl = mean(&window(&rec, "true_output_velocity", 4.0, 9.0));
    assert!((mean(&tau) - m.load_friction_nm(wl)).abs() < 0.01 * mean(&tau).abs());
}

#[test]
fn same_seed_same_rows_other_seed_other_noise() {
    let s = Scenario { duration_s: 0.5, ..preset("taghirad").unwrap() };
    let (a, _) = simulate(&s).unwrap();
    let (b, _) = simulate(&s).unwrap();
    for (x, y) in a.data.iter().zip(&b.data) {
        assert!(x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()));
    }
    let (c, _) = simulate(&Scenario { seed: 99, ..s }).unwrap();
    assert_ne!(a.column("bridge_voltage"), c.column("bridge_voltage"));
}

#[test]
fn flexspline_fixed_rig_runs_with_reference_sensor() {
    let s = preset("flexspline-fixed").unwrap();
    let (rec, sim) = simulate(&s).unwrap();
    let r = rec.column("reference_torque").unwrap();
    let t = rec.column("true_torque").unwrap();
    let e: Vec<f64> = r.iter().zip(t).map(|(a, b)| a - b).collect();
    assert!((rms(&e) - 0.02).abs() < 0.002);
    // FS fixed: output angle = θ_wg/(N+1) up to twist; relative angle = motor angle.
    let th = rec.column("true_motor_angle").unwrap();
    let out = rec.column("true_output_angle").unwrap();
    let last = th.len() - 1;
    assert!((out[last] - th[last] / 51.0).abs() < 1e-3, "{} vs {}", out[last], th[last] / 51.0);
    assert_eq!(rec.column("true_relative_angle").unwrap()[last], th[last]);
    // The brake loads the joint: mean transmitted torque is near the 6 N·m drag.
    let tail = window(&rec, "true_torque", 2.0, 10.0);
    assert!(mean(&tail).abs() > 4.0, "{}", mean(&tail));
    assert_eq!(sim.clipped_samples(), 0);
}

#[test]
fn integrator_converges_against_a_finer_step() {
    // Ramps, a reversal and a loaded standstill: the automatic step agrees with a 4× finer one.
    let mut s = preset("taghirad").unwrap();
    s.external_torque = vec![strainwave_sim::scenario::ExternalTorque::Step { at_s: 3.0, torque_nm: 8.0 }];
    let coarse = strainwave_sim::Simulator::new(&s).unwrap().substeps();
    let (a, _) = simulate(&s).unwrap();
    let mut sim = strainwave_sim::Simulator::with_substeps(&s, 4 * coarse).unwrap();
    let mut row = Vec::new();
    let mut fine = Vec::new();
    let i = a.columns.iter().position(|c| *c == "true_torque").unwrap();
    while sim.next_row(&mut row) {
        fine.push(row[i]);
    }
    let coarse_tau = a.column("true_torque").unwrap();
    let err = coarse_tau.iter().zip(&fine).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    // Well below the sensor's white-noise floor (0.016 N·m): at 0.2 × floor the
    // integration error adds 2 % to the noise in quadrature.
    let floor = strainwave_sim::Simulator::new(&s).unwrap().sensor().noise_floor_nm();
    assert!(err < 0.2 * floor, "max |Δτ| between step sizes: {err} N·m, noise floor {floor} N·m");
}

/// An extra line adds `A sin(n θ + p)` to the sensed torque and to its truth column
/// (`true_ripple` for the relative and motor angles, `true_misalignment` for the
/// output), and nothing else: the dynamics and the other columns stay the same.
#[test]
fn extra_lines_add_to_the_reading_and_its_truth() {
    use strainwave_sim::scenario::{ExtraLine, LineReference};
    let mut base = strainwave_sim::presets::preset("taghirad").unwrap();
    base.duration_s = 0.5;
    let mut with = base.clone();
    with.extra_lines = vec![
        ExtraLine { reference: LineReference::Relative, multiple: 3.0, amplitude_nm: 0.3, phase_rad: 0.9 },
        ExtraLine { reference: LineReference::Output, multiple: 2.0, amplitude_nm: 0.1, phase_rad: 0.0 },
    ];
    let (a, _) = strainwave_sim::simulate(&base).unwrap();
    let (b, _) = strainwave_sim::simulate(&with).unwrap();
    let col = |r: &strainwave_sim::Recording, n: &str| r.column(n).unwrap().to_vec();
    let (phi, out) = (col(&a, "true_relative_angle"), col(&a, "true_output_angle"));
    assert_eq!(phi, col(&b, "true_relative_angle"));
    assert_eq!(col(&a, "true_torque"), col(&b, "true_torque"));
    let (ra, rb) = (col(&a, "true_ripple"), col(&b, "true_ripple"));
    let (ma, mb) = (col(&a, "true_misalignment"), col(&b, "true_misalignment"));
    for k in 0..phi.len() {
        assert!((rb[k] - ra[k] - 0.3 * (3.0 * phi[k] + 0.9).sin()).abs() < 1e-12, "row {k}");
        assert!((mb[k] - ma[k] - 0.1 * (2.0 * out[k]).sin()).abs() < 1e-12, "row {k}");
    }
    // The reading carries it (up to the ADC step, 0.032 N·m).
    let (ta, tb) = (col(&a, "measured_torque"), col(&b, "measured_torque"));
    let worst = (0..phi.len()).map(|k| (tb[k] - ta[k] - (rb[k] - ra[k]) - (mb[k] - ma[k])).abs()).fold(0.0, f64::max);
    assert!(worst < 0.04, "{worst}");
    // A negative amplitude is refused, naming the key.
    with.extra_lines[0].amplitude_nm = -1.0;
    assert!(with.validate().unwrap_err().to_string().contains("extra_lines.amplitude_nm"));
}
