use super::*;
use strainwave_core::fusion::{AccelerometerModel, CrossoverOrder, TorsionShaftModel};

#[test]
fn spectral_combination_rejects_bad_input() {
    assert!(spectral_combination(&[0.0; 10], &[0.0; 9], 100.0, 10.0).is_err());
    assert!(spectral_combination(&[0.0; 10], &[0.0; 10], 100.0, 50.0).is_err());
    assert!(spectral_combination(&[f64::NAN; 10], &[0.0; 10], 100.0, 10.0).is_err());
    assert!(complementary(&[], &[], &ComplementaryFusion::kit(1000.0).unwrap()).is_err());
}

/// With the models as the paths, the plain complementary fusion is far from flat at the
/// torsion resonance while the corrected fusion is flat: the reason for the correction.
#[test]
fn model_level_flatness() {
    let fs = 20_000.0;
    let (ts, acc) = (TorsionShaftModel::<f64>::kit(), AccelerometerModel::<f64>::kit());
    let h_ts = |f: f64| to_complex(ts.response(f));
    let h_acc = |f: f64| to_complex(acc.torque_response(f));
    let plain = ComplementaryFusion::new(250.0, fs, CrossoverOrder::Second).unwrap();
    let (lp, hp) = plain.responses(ts.resonance_hz());
    let r_plain = to_complex(lp) * h_ts(829.3) + to_complex(hp) * h_acc(829.3);
    assert!(r_plain.norm() > 2.0, "{r_plain}");
    let fused = CorrectedFusion::design(h_ts, h_acc, fs, &CorrectionConfig::new(8191)).unwrap();
    let mut f = 1.0;
    while f < 4000.0 {
        let r = fused.response(f, h_ts(f), h_acc(f));
        assert!((20.0 * r.norm().log10()).abs() < 0.05 && r.arg().to_degrees().abs() < 0.5, "{f}: {r}");
        f *= 1.1;
    }
}
