//! The canceller's accuracy table against the twin's
//! truth: the full configuration, commissioned on its own run, meets the targets on the
//! free-motion, standstill/reversal and loaded runs; the paper's 6th-order model absorbs
//! the unknown load.

mod twin;

use strainwave_analysis::canceller_eval::{evaluate, Method};
use twin::{commissioned, run_preset as run, signals};

#[test]
fn commissioned_full_configuration_meets_the_targets_and_the_taghirad_model_absorbs_load() {
    let learned = commissioned(&strainwave_sim::presets::preset("taghirad-commissioning").unwrap());
    // Misalignment 0.8 sin(θ_out + 0.7) = 0.8 sin 0.7 cos θ + 0.8 cos 0.7 sin θ.
    let (a, b) = (0.8 * 0.7f64.sin(), 0.8 * 0.7f64.cos());
    let mis = learned[4].0;
    assert!((mis[0] - a).abs() < 0.02 && (mis[1] - b).abs() < 0.02, "learned misalignment {mis:?}, true [{a}, {b}]");

    for name in ["taghirad", "taghirad-standstill", "taghirad-loaded"] {
        let r = run(name);
        let s = signals(&r);
        let rows = evaluate(
            &s,
            &r.gear,
            r.noise_nm,
            &[Method::Taghirad6th, Method::FullCold, Method::Full],
            0.3,
            Some(&learned),
        )
        .unwrap();
        let (taghirad6, cold, full) = (&rows[0], &rows[1], &rows[2]);
        assert!(full.suppression_db >= 30.0, "{name}: full {:.1} dB", full.suppression_db);
        assert!(
            full.rms_error_nm <= 1.5 * r.noise_nm,
            "{name}: full RMS {:.4} vs floor {:.4}",
            full.rms_error_nm,
            r.noise_nm
        );
        assert_eq!(full.step_delay_samples, Some(0), "{name}");
        // Without commissioning it cannot learn the misalignment in one run, but it must
        // not make things worse by taking load for it.
        assert!(cold.suppression_db > 0.0, "{name}: cold {:.1} dB", cold.suppression_db);
        assert!(full.suppression_db > taghirad6.suppression_db + 30.0, "{name}");
        if name == "taghirad-loaded" {
            assert!(
                taghirad6.suppression_db < -10.0,
                "Taghirad 6th on the loaded run: {:.1} dB",
                taghirad6.suppression_db
            );
        }
    }
}

#[test]
fn full_configuration_needs_learned_coefficients() {
    let r = run("taghirad");
    let err = evaluate(&signals(&r), &r.gear, r.noise_nm, &[Method::Full], 0.3, None).unwrap_err();
    assert!(err.to_string().contains("learned coefficients"), "{err}");
}
