use super::*;

const DEG: f64 = core::f64::consts::PI / 180.0;

fn field(shear2: f64, shear4: f64) -> StrainField<f64> {
    StrainField {
        torsion_strain_per_nm: 7.6e-6,
        nominal_radius_m: 0.015,
        interference: [
            Interference { shear: shear2, normal: 3e-4, common: 2e-4, phase_rad: 0.3 },
            Interference { shear: shear4, normal: 5e-5, common: 3e-5, phase_rad: -0.2 },
        ],
    }
}

fn bridge() -> Bridge<f64, 8> {
    Bridge::new(Layout::FourRosettes.gauges(0.015), 2.0, 10.0).unwrap()
}

/// Amplitude of the `order`× component of `U(φ)` at zero torque (DFT over one turn).
fn amplitude(b: &Bridge<f64, 8>, f: &StrainField<f64>, order: f64) -> f64 {
    let n = 720;
    let (mut re, mut im) = (0.0, 0.0);
    for k in 0..n {
        let phi = k as f64 / n as f64 * core::f64::consts::TAU;
        let u = b.output_v(f, 0.0, phi, false);
        re += u * (order * phi).cos();
        im += u * (order * phi).sin();
    }
    2.0 * (re * re + im * im).sqrt() / n as f64
}

#[test]
fn ideal_sensitivity_is_k_eps_e() {
    let f = field(1e-4, 1e-5);
    let s = bridge().sensitivity_v_per_nm(&f);
    assert!((s - 2.0 * 7.6e-6 * 10.0).abs() < 1e-15, "{s}");
}

#[test]
fn ideal_placement_cancels_2x_not_4x() {
    let f = field(1e-4, 1e-5);
    let b = bridge();
    let a2 = amplitude(&b, &f, 2.0);
    let a4 = amplitude(&b, &f, 4.0);
    assert!(a2 < 1e-15, "2x residual {a2}");
    // 4×: (K/4)·E·(2 S_2 + 2 S_2)/2 … = K E S_2
    assert!((a4 - 2.0 * 10.0 * 1e-5).abs() < 1e-12, "4x {a4}");
}

#[test]
fn circumferential_error_leaves_two_psi_delta() {
    let psi = 1e-4;
    let f = field(psi, 0.0);
    let delta = 0.5 * DEG;
    // Move the rosette at 90° (both of its gauges) by δ.
    let mut errs = [PlacementError::default(); 8];
    errs[2].circumferential_rad = delta;
    errs[3].circumferential_rad = delta;
    let b = bridge().displaced(&errs);
    let a2 = amplitude(&b, &f, 2.0);
    // Residual shear strain in arm 3 − arm 4 is Ψ·2δ/2 (one of two series gauges),
    // expressed as torsional strain equivalent: U = (K/4) E · 2Ψδ.
    let want = 2.0 / 4.0 * 10.0 * 2.0 * psi * delta;
    assert!((a2 - want).abs() / want < 0.01, "{a2} vs {want}");
}

#[test]
fn angular_error_scales_torque_by_cos_2da() {
    let f = StrainField { interference: [Interference::default(); 2], ..field(0.0, 0.0) };
    let da = 2.0 * DEG;
    let errs = [PlacementError { angular_rad: da, ..Default::default() }; 8];
    let b = bridge().displaced(&errs);
    let ratio = b.sensitivity_v_per_nm(&f) / bridge().sensitivity_v_per_nm(&f);
    assert!((ratio - (2.0 * da).cos()).abs() < 1e-12);
}

#[test]
fn kernel_equals_direct_evaluation() {
    let f = field(1e-4, 1e-5);
    let errs: [PlacementError<f64>; 8] = core::array::from_fn(|j| PlacementError {
        radial_m: 1e-4 * (j as f64 - 3.5),
        circumferential_rad: 0.003 * (j as f64 - 2.0),
        angular_rad: -0.002 * (j as f64 - 4.0),
    });
    let b = bridge().displaced(&errs);
    let k = b.kernel(&f);
    assert!((k.sensitivity_v_per_nm() - b.sensitivity_v_per_nm(&f)).abs() < 1e-18);
    for i in 0..200 {
        let phi = i as f64 * 0.37 - 20.0;
        let t = (i as f64 - 100.0) * 0.5;
        for exact in [false, true] {
            let (u1, u2) = (k.output_v(t, phi, exact), b.output_v(&f, t, phi, exact));
            assert!((u1 - u2).abs() < 1e-14, "{u1} {u2}");
        }
    }
}

#[test]
fn order_amplitude_matches_the_dft() {
    let f = field(1e-4, 1e-5);
    let errs: [PlacementError<f64>; 8] = core::array::from_fn(|j| PlacementError {
        circumferential_rad: 0.004 * (j as f64 - 3.0),
        ..Default::default()
    });
    let b = bridge().displaced(&errs);
    let k = b.kernel(&f);
    for h in [1usize, 2] {
        let want = amplitude(&b, &f, 2.0 * h as f64);
        assert!((k.order_amplitude_v(h) - want).abs() < 1e-12 * want.max(1e-9), "h={h}");
    }
    assert_eq!(k.order_amplitude_v(3), 0.0);
}

#[test]
fn exact_matches_small_strain_to_first_order() {
    let e = [1e-4, -1e-4, 1e-4, -1e-4];
    let lin = bridge_ratio_small_strain(2.0, e);
    let ex = bridge_ratio_exact(2.0, e);
    assert!((lin - ex).abs() / lin.abs() < 1e-3);
    assert!(lin != ex);
}

#[test]
fn adc_quantizes_and_clips() {
    let c = SignalChain { amplifier_gain: 1000.0, adc_bits: 12, adc_range_v: 10.0 }.validated().unwrap();
    let (v, clip) = c.quantize(0.0123);
    assert!(!clip && (v - 3.0 * 20.0 / 4096.0).abs() < 1e-12);
    assert!(c.quantize(11.0).1);
    assert!(c.quantize(f64::NAN).1);
    assert_eq!(SignalChain { adc_bits: 0, ..c }.validated(), Err(Error::OutOfRange("adc_bits")));
}
