//! Golden numbers for the Python comparison tests (python/tests/test_*_numpy.py).
//!
//! ```text
//! calib_golden lstsq IN.csv OUT.csv   solve the least-squares problems in IN, write solutions to OUT
//! calib_golden sea OUT.csv            write the series-elastic dead-weight fixture and our line fit
//! ```
//!
//! IN: blocks of `problem,<m>,<n>` followed by m rows `a_1,…,a_n,b`.
//! OUT (lstsq): one row per problem, `solution,<x_1>,…,<x_n>,<residual norm>`.
//! OUT (sea): rows `row,<deflection_rad>,<torque_nm>` then `fit,<slope>,<intercept>`.
//! Numbers are written in Rust's shortest round-trip form.

#[path = "../tests/calibration_fixture.rs"]
mod fixture;

use std::fmt::Write as _;
use std::process::ExitCode;

use strainwave_analysis::lstsq::{fit_line, lstsq};

fn solve_file(input: &str) -> Result<String, String> {
    let mut lines = input.lines().map(str::trim).filter(|l| !l.is_empty()).enumerate();
    let mut out = String::new();
    while let Some((ln, header)) = lines.next() {
        let h: Vec<&str> = header.split(',').collect();
        if h.len() != 3 || h[0] != "problem" {
            return Err(format!("line {}: expected `problem,<m>,<n>`", ln + 1));
        }
        let m: usize = h[1].parse().map_err(|e| format!("line {}: {e}", ln + 1))?;
        let n: usize = h[2].parse().map_err(|e| format!("line {}: {e}", ln + 1))?;
        let (mut a, mut b) = (Vec::with_capacity(m * n), Vec::with_capacity(m));
        for _ in 0..m {
            let (ln, row) = lines.next().ok_or("unexpected end of input")?;
            let v: Vec<f64> = row
                .split(',')
                .map(|t| t.parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| format!("line {}: {e}", ln + 1))?;
            if v.len() != n + 1 {
                return Err(format!("line {}: expected {} numbers", ln + 1, n + 1));
            }
            a.extend_from_slice(&v[..n]);
            b.push(v[n]);
        }
        let s = lstsq(&a, n, &b).map_err(|e| e.to_string())?;
        out.push_str("solution");
        for x in &s.x {
            write!(out, ",{x:e}").ok();
        }
        writeln!(out, ",{:e}", s.residual_norm).ok();
    }
    Ok(out)
}

fn sea() -> Result<String, String> {
    let t = fixture::sea_torque_nm();
    let (slope, intercept) = fit_line(&fixture::SEA_DEFLECTION_RAD, &t).map_err(|e| e.to_string())?;
    let mut out = String::new();
    for (d, t) in fixture::SEA_DEFLECTION_RAD.iter().zip(&t) {
        writeln!(out, "row,{d:e},{t:e}").ok();
    }
    writeln!(out, "fit,{slope:e},{intercept:e}").ok();
    Ok(out)
}

fn run(args: &[String]) -> Result<(), String> {
    match args {
        [cmd, input, output] if cmd == "lstsq" => {
            let text = std::fs::read_to_string(input).map_err(|e| format!("{input}: {e}"))?;
            let out = solve_file(&text).map_err(|e| format!("{input}: {e}"))?;
            std::fs::write(output, out).map_err(|e| format!("{output}: {e}"))
        }
        [cmd, output] if cmd == "sea" => std::fs::write(output, sea()?).map_err(|e| format!("{output}: {e}")),
        _ => Err("usage: calib_golden lstsq IN.csv OUT.csv | calib_golden sea OUT.csv".into()),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("calib_golden: {e}");
            ExitCode::FAILURE
        }
    }
}
