use super::*;

#[test]
fn catalogue_example() {
    let k = ThreeSlopeStiffness::new(6.7e4, 1.1e5, 1.2e5, 29.0, 108.0).unwrap();
    let th = k.twist_rad(60.0_f64);
    assert!((th - 7.15e-4).abs() < 5e-7, "{th}");
    assert!((k.twist_rad(-60.0) + th).abs() < 1e-15);
    assert!((k.torque_nm(th) - 60.0).abs() < 1e-9);
}

#[test]
fn continuous_at_breaks_and_invertible() {
    let k = ThreeSlopeStiffness::new(3.1e4, 5.0e4, 5.7e4, 14.0, 48.0).unwrap();
    for i in -400..=400 {
        let t = i as f64 * 0.25;
        let back = k.torque_nm(k.twist_rad(t));
        assert!((back - t).abs() < 1e-9, "{t} -> {back}");
    }
    let eps = 1e-9;
    assert!((k.twist_rad(14.0 + eps) - k.twist_rad(14.0 - eps)).abs() < 1e-12);
    assert!((k.twist_rad(48.0 + eps) - k.twist_rad(48.0 - eps)).abs() < 1e-12);
}

#[test]
fn cubic_closed_form_inverts_both_signs() {
    for k3 in [0.0, 1e3, 5e8, 1e12, -5e8] {
        let c = CubicStiffness::new(1.1e4_f64, k3).unwrap();
        // The softening cubic peaks at 19.9 N·m.
        for i in -39..=39 {
            let t = i as f64 * 0.5;
            let th = c.twist_rad(t);
            assert!((c.torque_nm(th) - t).abs() < 1e-9 * (1.0 + t.abs()), "k3 {k3} t {t}: {}", c.torque_nm(th));
        }
    }
}

#[test]
fn wave_generator_small_torque_is_linear() {
    let wg = WaveGeneratorSoftening::new(2.5_f64, 1.5).unwrap();
    assert!((wg.twist_rad(1e-9) / (1e-9 / 2.5) - 1.0).abs() < 1e-8);
    let soft = WaveGeneratorSoftening::new(2.5_f64, -1.5).unwrap();
    assert!(soft.twist_rad(1.0) > 1.0 / 2.5);
    assert!((soft.torque_nm(soft.twist_rad(0.7)).unwrap() - 0.7).abs() < 1e-12);
}

#[test]
fn hysteresis_loop_width() {
    let h = Hysteresis::new(1e-4_f64, 1e-5).unwrap();
    let z_up = h.update(-1.0, 1e-3);
    let z_down = h.update(1.0, -1e-3);
    let width = h.elastic_twist_rad(0.0, z_up) - h.elastic_twist_rad(0.0, z_down);
    assert!((width - 2e-4).abs() < 1e-12);
    assert_eq!(h.update(0.3, 0.0), 0.3);
}

#[test]
fn rejects_bad_parameters() {
    assert_eq!(ThreeSlopeStiffness::new(1.0, 1.0, 1.0, 5.0, 4.0), Err(Error::NotIncreasing("t2_nm")));
    assert_eq!(ThreeSlopeStiffness::new(0.0, 1.0, 1.0, 1.0, 4.0), Err(Error::NonPositive("k1_nm_per_rad")));
}
