//! Behaviour of the bench twin, and the hybrid torque measured on it end to end.

use super::*;

#[test]
fn preset_round_trips_and_validation_names_keys() {
    for name in PRESET_NAMES {
        let s = preset(name).unwrap();
        assert_eq!(BenchScenario::from_toml(&s.to_toml()).unwrap(), s, "{name}");
    }
    let mut s = preset("kit-bench").unwrap();
    s.mechanics.shaft_stiffness_nm_per_rad = -1.0;
    assert!(matches!(s.validate(), Err(SimError::Invalid { key: "mechanics.shaft_stiffness_nm_per_rad", .. })));
    let mut s = preset("kit-bench-sweep").unwrap();
    if let BenchProfile::CurrentSweep { to_hz, .. } = &mut s.profile {
        *to_hz = 10_000.0;
    }
    assert!(matches!(s.validate(), Err(SimError::Invalid { key: "profile.to_hz", .. })));
    let text = KIT_BENCH_TOML.replace("seed = 3", "seed = 3\nbogus = 1");
    assert!(matches!(BenchScenario::from_toml(&text), Err(SimError::Parse { .. })));
}

const SWEEP_COLUMNS: [&str; 6] =
    ["torsion_torque", "accel_torque", "inner_torque", "true_dut_torque", "true_shaft_torque", "true_accel_torque"];

fn sweep(seed: u64, amplitude: f64) -> BenchRecording {
    let mut s = preset("kit-bench-sweep").unwrap();
    s.seed = seed;
    if let BenchProfile::CurrentSweep { amplitude_a, .. } = &mut s.profile {
        *amplitude_a = amplitude;
    }
    simulate_bench(&s, Some(&SWEEP_COLUMNS)).unwrap()
}

/// The headline: calibrate on one sweep (H1 of each path against the bench's online eq.-12
/// torque, as paper §V does against its model), validate on another (other noise, 1.5×
/// the current) against the true air-gap torque. Prints the table of every method.
///
/// `cargo test --release -p strainwave-sim --lib bench::tests::hybrid_fusion_accuracy -- --nocapture`
#[test]
fn hybrid_fusion_accuracy() {
    use strainwave_analysis::bench::{accuracy_report, AccuracyConfig, BenchRecord};
    let fs = preset("kit-bench-sweep").unwrap().sample_rate_hz;
    let cal = sweep(3, 0.1);
    let val = sweep(11, 0.15);
    let rec = |r: &BenchRecording, reference: &str| {
        (
            r.column("torsion_torque").unwrap().to_vec(),
            r.column("accel_torque").unwrap().to_vec(),
            r.column(reference).unwrap().to_vec(),
        )
    };
    let (ct, ca, cr) = rec(&cal, "inner_torque");
    let (vt, va, vr) = rec(&val, "true_dut_torque");
    let report = accuracy_report(
        BenchRecord { torsion: &ct, accel: &ca, reference: &cr },
        BenchRecord { torsion: &vt, accel: &va, reference: &vr },
        fs,
        &AccuracyConfig::kit(fs),
    )
    .unwrap();
    println!("worst |gain error| and |phase error| of T/T_e (H1 vs the true DUT torque, kit-bench-sweep):");
    println!("{}", report.table());
    let whole = report.bands_hz.len() - 1;
    let corrected = &report.row("corrected fusion (FIR)").unwrap().bands[whole];
    assert!(corrected.max_gain_db < 1.0, "{corrected:?}");
    assert!(corrected.max_phase_deg < 5.0, "{corrected:?}");
    // Nearly every bin of 1 Hz … 4 kHz is coherent enough to count.
    let bins = ((4000.0 - 1.0) / report.torsion_frf.freqs_hz[1]) as usize;
    assert!(corrected.bins as f64 > 0.95 * bins as f64, "{} of {bins}", corrected.bins);
    // Each single path and the plain complementary filters fail somewhere in the range.
    for m in ["torsion shaft alone", "accelerometers alone", "complementary, 1st order", "complementary, 2nd order"] {
        let e = &report.row(m).unwrap().bands[whole];
        assert!(e.max_gain_db > 3.0 || e.max_phase_deg > 20.0, "{m}: {e:?}");
    }
}

/// The twin's paths are the paper's models: the shaft torque follows eq. 1 and the ideal
/// accelerometer torque `J_S · eq. 6`, both driven by the true air-gap torque.
#[test]
fn twin_paths_follow_the_paper_models() {
    use strainwave_analysis::frf::h1;
    use strainwave_analysis::psd::SpectralConfig;
    use strainwave_core::fusion::{AccelerometerModel, TorsionShaftModel};
    let mut s = preset("kit-bench-sweep").unwrap();
    s.duration_s = 8.0;
    s.profile =
        BenchProfile::CurrentSweep { amplitude_a: 0.1, from_hz: 5.0, to_hz: 8000.0, spacing: SweepSpacing::Log };
    let rec = simulate_bench(&s, Some(&["true_dut_torque", "true_shaft_torque", "true_accel_torque"])).unwrap();
    let m = &s.mechanics;
    // Eq. 1 lumps 2Γ on the shaft: Γ = shaft damping / 2.
    let ts = TorsionShaftModel::new(
        m.rotor_inertia_kg_m2,
        m.brake_inertia_kg_m2,
        m.shaft_stiffness_nm_per_rad,
        m.shaft_damping_nm_s_per_rad / 2.0,
    )
    .unwrap();
    let acc =
        AccelerometerModel::new(m.stator_inertia_kg_m2, m.coupling_stiffness_nm_per_rad, m.stator_damping_nm_s_per_rad)
            .unwrap();
    let cfg = SpectralConfig::new(1 << 14);
    let te = rec.column("true_dut_torque").unwrap();
    let check = |out: &str, lo: f64, hi: f64, model: &dyn Fn(f64) -> (f64, f64)| {
        let f = h1(te, rec.column(out).unwrap(), s.sample_rate_hz, &cfg).unwrap();
        let bins = f.bins_in(lo, hi, 0.99);
        assert!(bins.len() as f64 > 0.9 * (hi - lo) / f.freqs_hz[1], "{out}: {} coherent bins", bins.len());
        let mut worst: f64 = 0.0;
        for k in bins {
            let (re, im) = model(f.freqs_hz[k]);
            let err = ((f.h1[k].re - re).powi(2) + (f.h1[k].im - im).powi(2)).sqrt() / re.hypot(im);
            worst = worst.max(err);
        }
        assert!(worst < MODEL_TOL, "{out}: relative error {worst}");
    };
    check("true_shaft_torque", 10.0, 3000.0, &|f| {
        let g = ts.response(f);
        (g.re, g.im)
    });
    check("true_accel_torque", 60.0, 7000.0, &|f| {
        let g = acc.torque_response(f);
        (g.re, g.im)
    });
}

/// Relative complex error allowed between the twin's H1 and the paper's models (the
/// rotor–housing bearing the models leave out, and the H1 of a chirp).
const MODEL_TOL: f64 = 0.02;

/// The speed ramp: the drive tracks 3200 rpm, nothing clips, the housing vibration
/// cancels in the sum, the orders sit on their lines in the Campbell diagram, and the
/// accelerometers give the 6th electrical order's amplitude and phase where the torsion
/// shaft resonates (Stoß et al. 2022, Figs. 8–9).
#[test]
fn speed_ramp_orders_and_vibration() {
    use strainwave_analysis::campbell::{campbell, order_slice, CampbellConfig, OrderSliceConfig};
    use strainwave_analysis::spectrum::amplitude_spectrum;
    let s = preset("kit-bench").unwrap();
    let fs = s.sample_rate_hz;
    let mut sim = BenchSimulator::new(&s).unwrap();
    let names = [
        "speed_rpm",
        "torsion_torque",
        "accel_1",
        "accel_2",
        "accel_torque",
        "true_dut_torque",
        "true_rotor_speed_rpm",
    ];
    let all = sim.columns();
    let idx: Vec<usize> = names.iter().map(|n| all.iter().position(|c| c == n).unwrap()).collect();
    let mut cols = vec![Vec::new(); names.len()];
    let mut row = Vec::new();
    while sim.next_row(&mut row) {
        for (c, &i) in cols.iter_mut().zip(&idx) {
            c.push(row[i]);
        }
    }
    let [speed, torsion, a1, a2, acc, truth, true_speed] = &cols[..] else { unreachable!() };
    assert_eq!(sim.clipped_samples(), (0, 0));
    let n = true_speed.len();
    let hold = n - fs as usize..n; // the last second: 3200 rpm
    let top = true_speed[hold.clone()].iter().sum::<f64>() / fs;
    assert!((top - 3200.0).abs() < 10.0, "{top}");

    // 120 Hz floor vibration: 2 m/s² on one sensor; in the sum only the 0.2 % gain error
    // (2 mm/s²) over the broadband torque of the speed loop (≈ 1.6 mm/s² a bin): > 46 dB down.
    let one = amplitude_spectrum(&a1[hold.clone()], fs).unwrap().amplitude_at(120.0);
    let sum: Vec<f64> = a1[hold.clone()].iter().zip(&a2[hold.clone()]).map(|(x, y)| 0.5 * (x + y)).collect();
    let leak = amplitude_spectrum(&sum, fs).unwrap().amplitude_at(120.0);
    assert!((one - 2.0).abs() < 0.1, "{one}");
    assert!(leak < 0.005 * one, "{leak}");

    // Campbell of the accelerometer torque: orders 18 (6th el.) and 36 (12th el. + cogging).
    let c = campbell(acc, speed, fs, &CampbellConfig::new(2048, 100.0)).unwrap();
    for order in [18.0, 36.0] {
        let ridge: Vec<_> =
            c.order_ridge(order, 3).into_iter().filter(|p| p.expected_hz > 300.0 && p.expected_hz < 2500.0).collect();
        assert!(ridge.len() > 50, "{order}: {}", ridge.len());
        for p in &ridge {
            assert!((p.peak_hz - p.expected_hz).abs() <= c.resolution_hz(), "order {order}: {p:?}");
        }
    }

    // Order slice of the 6th electrical order (18th mechanical) above 1000 rpm (300 Hz):
    // the accelerometers agree with the truth; the torsion shaft is 10× off at its resonance.
    let cfg = OrderSliceConfig::default();
    let o_true = order_slice(truth, speed, fs, 18.0, &cfg).unwrap();
    let o_acc = order_slice(acc, speed, fs, 18.0, &cfg).unwrap();
    let o_ts = order_slice(torsion, speed, fs, 18.0, &cfg).unwrap();
    let mut checked = 0;
    for i in 0..o_true.speed_rpm.len() {
        let v = o_true.speed_rpm[i];
        if v > 1000.0 {
            let ratio = o_acc.amplitude[i] / o_true.amplitude[i];
            let dphi = (o_acc.phase_rad[i] - o_true.phase_rad[i] + std::f64::consts::PI)
                .rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            assert!((ratio - 1.0).abs() < 0.05 && dphi.abs() < 5f64.to_radians(), "{v} rpm: {ratio} {dphi}");
            checked += 1;
        }
        // 829.3 Hz / 18 · 60 = 2764 rpm.
        if (v - 2764.0).abs() < 15.0 {
            assert!(o_ts.amplitude[i] > 10.0 * o_true.amplitude[i], "{v} rpm: {}", o_ts.amplitude[i]);
        }
    }
    assert!(checked > 60, "{checked}"); // ≈ 270 revolutions above 1000 rpm, a block every 4
}

/// RK4 with the automatic sub-steps agrees with a 4× finer step on every truth torque
/// (sweep up to 8 kHz and the ramp's harmonics).
#[test]
fn integrator_converges_against_a_finer_step() {
    let mut sweep = preset("kit-bench-sweep").unwrap();
    sweep.duration_s = 1.0;
    sweep.profile =
        BenchProfile::CurrentSweep { amplitude_a: 0.1, from_hz: 100.0, to_hz: 8000.0, spacing: SweepSpacing::Log };
    let mut ramp = preset("kit-bench").unwrap();
    ramp.duration_s = 1.0;
    if let BenchProfile::SpeedRamp { from_rpm, .. } = &mut ramp.profile {
        *from_rpm = 3000.0;
    }
    for s in [sweep, ramp] {
        let auto = BenchSimulator::new(&s).unwrap().substeps();
        let run = |n_sub: u32| {
            let mut sim = BenchSimulator::with_substeps(&s, n_sub).unwrap();
            let cols = sim.columns();
            let idx: Vec<usize> = ["true_shaft_torque", "true_accel_torque", "true_dut_torque"]
                .iter()
                .map(|n| cols.iter().position(|c| c == n).unwrap())
                .collect();
            let mut out = vec![Vec::new(); idx.len()];
            let mut row = Vec::new();
            while sim.next_row(&mut row) {
                for (o, &i) in out.iter_mut().zip(&idx) {
                    o.push(row[i]);
                }
            }
            out
        };
        let (a, b) = (run(auto), run(4 * auto));
        for (x, y) in a.iter().zip(&b) {
            let diff = x.iter().zip(y).map(|(p, q)| (p - q).powi(2)).sum::<f64>().sqrt();
            let norm = y.iter().map(|q| q * q).sum::<f64>().sqrt();
            assert!(diff < 1e-3 * norm, "{}: {diff} vs {norm} ({auto} sub-steps)", s.name);
        }
    }
}

#[test]
fn older_spellings_of_the_profile_and_the_noise_still_load() {
    let text = preset_text("kit-bench").unwrap();
    assert!(text.contains("kind = \"speed-ramp\""));
    let old = text.replace("\"speed-ramp\"", "\"speed_ramp\"").replace("noise_nm =", "noise_nm_rms =");
    assert_eq!(BenchScenario::from_toml(&old).unwrap(), BenchScenario::from_toml(text).unwrap());
}
