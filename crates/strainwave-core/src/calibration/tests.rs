use super::*;

fn close<T: Real>(a: T, b: f64, tol: f64) -> bool {
    (a.to_f64() - b).abs() <= tol * (1.0 + b.abs())
}

fn gain_and_affine<T: Real>(tol: f64) {
    let g = Calibration::<T, 0>::gain(T::from_f64(6.6)).unwrap();
    assert!(close(g.apply(T::from_f64(2.0), T::from_f64(f64::NAN)).unwrap(), 13.2, tol));
    assert_eq!(g.model(), Model::Gain);
    assert!(g.speed_range_rad_s().is_none());
    let a = Calibration::<T, 0>::affine(T::from_f64(1.572), T::from_f64(-0.0928)).unwrap();
    assert!(close(a.apply(T::from_f64(10.0), T::ZERO).unwrap(), 15.6272, tol));
    let x = a.invert(T::from_f64(15.6272), T::ZERO).unwrap();
    assert!(close(x, 10.0, tol));
    assert_eq!(a.alpha_values(), &[T::from_f64(1.572)]);
    assert_eq!(Calibration::<T, 0>::affine(T::from_f64(f64::NAN), T::ZERO), Err(Error::NonFinite("alpha")));
    assert_eq!(Calibration::<T, 0>::affine(T::ZERO, T::ZERO), Err(Error::OutOfRange("alpha")));
    assert_eq!(a.apply(T::from_f64(f64::INFINITY), T::ZERO), Err(Error::NonFinite("sensor")));
}

#[test]
fn gain_and_affine_f32_f64() {
    gain_and_affine::<f32>(1e-6);
    gain_and_affine::<f64>(1e-13);
}

fn table_case<T: Real>(tol: f64) {
    let f = T::from_f64;
    let sp = [f(-10.0), f(0.0), f(10.0), f(30.0)];
    let al = [f(1.4), f(1.5), f(1.6), f(1.2)];
    let be = [f(0.1), f(0.0), f(-0.1), f(-0.5)];
    let clamp = Calibration::<T, 6>::speed_table(&sp, &al, &be, Extrapolation::Clamp).unwrap();
    let lin = Calibration::<T, 6>::speed_table(&sp, &al, &be, Extrapolation::Linear).unwrap();
    let rej = Calibration::<T, 6>::speed_table(&sp, &al, &be, Extrapolation::Reject).unwrap();
    // On breakpoints the table values are returned exactly.
    for i in 0..4 {
        let (a, b, e) = clamp.coefficients(sp[i]).unwrap();
        assert!(a == al[i] && b == be[i] && !e);
    }
    // Interior: ω = 20 is half way between 10 and 30.
    let (a, b, e) = rej.coefficients(f(20.0)).unwrap();
    assert!(close(a, 1.4, tol) && close(b, -0.3, tol) && !e);
    let (a, _, _) = rej.coefficients(f(-5.0)).unwrap();
    assert!(close(a, 1.45, tol));
    // Below: clamp holds, linear continues the first segment, reject refuses.
    assert_eq!(clamp.coefficients(f(-20.0)).unwrap(), (f(1.4), f(0.1), true));
    let (a, b, e) = lin.coefficients(f(-20.0)).unwrap();
    assert!(close(a, 1.3, tol) && close(b, 0.2, tol) && e);
    assert_eq!(rej.apply(f(1.0), f(-20.0)), Err(Error::OutOfRange("speed_rad_s")));
    // Above.
    let (a, b, _) = lin.coefficients(f(40.0)).unwrap();
    assert!(close(a, 1.0, tol) && close(b, -0.7, tol));
    assert_eq!(clamp.coefficients(f(1e30)).unwrap(), (f(1.2), f(-0.5), true));
    assert_eq!(rej.apply(f(1.0), f(f64::NAN)), Err(Error::NonFinite("speed_rad_s")));
    // Flag.
    let out = clamp.apply_flagged(f(2.0), f(35.0)).unwrap();
    assert!(out.extrapolated && close(out.torque_nm, 1.9, tol));
    assert!(!clamp.apply_flagged(f(2.0), f(30.0)).unwrap().extrapolated);
    // Inverse.
    let t = lin.apply(f(3.0), f(7.0)).unwrap();
    assert!(close(lin.invert(t, f(7.0)).unwrap(), 3.0, tol * 10.0));
    assert_eq!(clamp.speed_breakpoints_rad_s(), &sp);
    assert_eq!(clamp.speed_range_rad_s(), Some((f(-10.0), f(30.0))));
}

#[test]
fn table_f32_f64() {
    table_case::<f32>(1e-6);
    table_case::<f64>(1e-14);
}

#[test]
fn table_rejects_bad_input() {
    let ok = [0.0, 1.0, 2.0];
    let e = Extrapolation::Clamp;
    assert_eq!(
        Calibration::<f64, 3>::speed_table(&[0.0, 1.0, 1.0], &ok, &ok, e),
        Err(Error::OutOfRange("alpha")) // α = 0 at the first breakpoint
    );
    let a = [1.0, 1.1, 1.2];
    assert_eq!(
        Calibration::<f64, 3>::speed_table(&[0.0, 1.0, 1.0], &a, &ok, e),
        Err(Error::NotIncreasing("speed_rad_s"))
    );
    assert_eq!(
        Calibration::<f64, 3>::speed_table(&[0.0, f64::NAN, 2.0], &a, &ok, e),
        Err(Error::NonFinite("speed_rad_s"))
    );
    assert_eq!(Calibration::<f64, 2>::speed_table(&ok, &a, &ok, e), Err(Error::OutOfRange("speed_rad_s")));
    assert_eq!(Calibration::<f64, 3>::speed_table(&[0.0], &[1.0], &[0.0], e), Err(Error::OutOfRange("speed_rad_s")));
    assert_eq!(Calibration::<f64, 3>::speed_table(&ok, &a[..2], &ok, e), Err(Error::OutOfRange("alpha")));
    assert_eq!(Calibration::<f64, 3>::speed_table(&ok, &a, &ok[..1], e), Err(Error::OutOfRange("beta_nm")));
    // Huge linear extrapolation overflows to ∞: reported, not returned.
    let big =
        Calibration::<f32, 3>::speed_table(&[0.0, 1.0], &[1.0, 1e30], &[0.0, 0.0], Extrapolation::Linear).unwrap();
    assert_eq!(big.apply(1e10, 1e20), Err(Error::NonFinite("torque_nm")));
}

fn polynomial_case<T: Real>(tol: f64) {
    let f = T::from_f64;
    // α = 1.5 + 0.01 ω + 0.001 ω², β = −0.1 − 0.002 ω.
    let al = [f(1.5), f(0.01), f(0.001)];
    let be = [f(-0.1), f(-0.002)];
    let mk = |e| Calibration::<T, 4>::speed_polynomial(&al, &be, f(-5.0), f(5.0), e).unwrap();
    let (clamp, lin, rej) = (mk(Extrapolation::Clamp), mk(Extrapolation::Linear), mk(Extrapolation::Reject));
    let (a, b, e) = rej.coefficients(f(2.0)).unwrap();
    assert!(close(a, 1.524, tol) && close(b, -0.104, tol) && !e);
    // Clamp at ω = 5: α = 1.5 + 0.05 + 0.025.
    let (a, _, e) = clamp.coefficients(f(9.0)).unwrap();
    assert!(close(a, 1.575, tol) && e);
    // Linear: tangent at 5, slope 0.01 + 0.002·5 = 0.02 → α(7) = 1.575 + 0.04.
    let (a, b, _) = lin.coefficients(f(7.0)).unwrap();
    assert!(close(a, 1.615, tol) && close(b, -0.114, tol));
    assert_eq!(rej.coefficients(f(-5.5)), Err(Error::OutOfRange("speed_rad_s")));
    assert_eq!(rej.alpha_values().len(), 3);
    assert_eq!(rej.beta_values_nm()[2], T::ZERO);
}

#[test]
fn polynomial_f32_f64() {
    polynomial_case::<f32>(1e-6);
    polynomial_case::<f64>(1e-14);
}

#[test]
fn polynomial_rejects_bad_input() {
    let e = Extrapolation::Clamp;
    assert_eq!(Calibration::<f64, 2>::speed_polynomial(&[], &[0.0], 0.0, 1.0, e), Err(Error::OutOfRange("alpha")));
    assert_eq!(
        Calibration::<f64, 2>::speed_polynomial(&[1.0, 2.0, 3.0], &[0.0], 0.0, 1.0, e),
        Err(Error::OutOfRange("alpha"))
    );
    assert_eq!(
        Calibration::<f64, 2>::speed_polynomial(&[1.0], &[0.0], 1.0, 1.0, e),
        Err(Error::NotIncreasing("speed_range_rad_s"))
    );
    assert_eq!(
        Calibration::<f64, 2>::speed_polynomial(&[1.0], &[f64::INFINITY], 0.0, 1.0, e),
        Err(Error::NonFinite("beta_nm"))
    );
    assert_eq!(
        Calibration::<f64, 2>::speed_polynomial(&[1.0], &[0.0], f64::NAN, 1.0, e),
        Err(Error::NonFinite("speed_min_rad_s"))
    );
}

#[test]
fn invert_reports_zero_alpha() {
    // α(ω) crosses zero at ω = 1 for this polynomial.
    let c = Calibration::<f64, 2>::speed_polynomial(&[1.0, -1.0], &[0.0], 0.0, 2.0, Extrapolation::Clamp).unwrap();
    assert_eq!(c.invert(1.0, 1.0), Err(Error::OutOfRange("alpha")));
}

#[test]
fn never_panics_on_odd_input() {
    let vals = [0.0, -0.0, 1.0, -1e300, 1e300, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, f64::MIN_POSITIVE];
    let t = Calibration::<f64, 3>::speed_table(&[0.0, 1.0, 2.0], &[1.0, 2.0, 3.0], &[0.0; 3], Extrapolation::Linear)
        .unwrap();
    let p = Calibration::<f64, 3>::speed_polynomial(&[1.0, 2.0], &[0.5], -1.0, 1.0, Extrapolation::Linear).unwrap();
    for &x in &vals {
        for &w in &vals {
            for v in [t.apply(x, w), p.apply(x, w), t.invert(x, w), p.invert(x, w)].into_iter().flatten() {
                assert!(v.is_finite());
            }
        }
    }
}
