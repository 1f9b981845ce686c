//! Inline SVG line plots: title, axes with units, ticks, legend, vertical markers.
//! Long series are decimated to min/max pairs per pixel column, so the drawing keeps
//! every peak while staying small.

use std::fmt::Write as _;

/// Colours cycled through the series.
const PALETTE: &[&str] = &["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"];
const WIDTH: f64 = 860.0;
const HEIGHT: f64 = 320.0;
const MARGIN_L: f64 = 70.0;
const MARGIN_R: f64 = 20.0;
const MARGIN_T: f64 = 34.0;
const MARGIN_B: f64 = 48.0;

/// One line of a plot.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates.
    pub y: Vec<f64>,
}

/// A vertical marker with a label (e.g. an expected order line).
#[derive(Debug, Clone)]
pub struct Marker {
    /// Position on the x axis.
    pub x: f64,
    /// Label.
    pub label: String,
}

/// A line plot.
#[derive(Debug, Clone, Default)]
pub struct LinePlot {
    /// Title.
    pub title: String,
    /// X-axis label with unit.
    pub x_label: String,
    /// Y-axis label with unit.
    pub y_label: String,
    /// Lines.
    pub series: Vec<Series>,
    /// Vertical markers.
    pub markers: Vec<Marker>,
    /// Logarithmic y axis (values ≤ 0 are dropped).
    pub log_y: bool,
    /// Optional x range.
    pub x_range: Option<(f64, f64)>,
}

/// `s` with the characters XML gives a meaning escaped.
pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// "Nice" tick positions covering `[lo, hi]`.
pub(crate) fn ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    let span = (hi - lo).abs().max(1e-300);
    let raw = span / target as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= target as f64 + 0.5)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() * step;
    (0..=target * 2 + 2).map(|i| first + i as f64 * step).take_while(|v| *v <= hi + step * 1e-9).collect()
}

/// A tick's label: at most four decimals, trailing zeros dropped (`0.3`, not
/// `0.30000000000000004`); the exponent form outside 1e-3–1e5.
pub(crate) fn fmt_tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.0e}")
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Min/max decimation to about `2 × columns` points, keeping order.
fn decimate(x: &[f64], y: &[f64], columns: usize) -> Vec<(f64, f64)> {
    let pts: Vec<(f64, f64)> =
        x.iter().zip(y).filter(|(a, b)| a.is_finite() && b.is_finite()).map(|(a, b)| (*a, *b)).collect();
    if pts.len() <= 2 * columns {
        return pts;
    }
    let per = pts.len().div_ceil(columns);
    let mut out = Vec::with_capacity(2 * columns + 2);
    for chunk in pts.chunks(per) {
        let (mut lo, mut hi) = (chunk[0], chunk[0]);
        for p in chunk {
            if p.1 < lo.1 {
                lo = *p;
            }
            if p.1 > hi.1 {
                hi = *p;
            }
        }
        if lo.0 <= hi.0 {
            out.push(lo);
            out.push(hi);
        } else {
            out.push(hi);
            out.push(lo);
        }
    }
    out
}

impl LinePlot {
    /// Renders the plot as an `<svg>` element.
    pub fn to_svg(&self) -> String {
        let tf = |v: f64| if self.log_y { v.log10() } else { v };
        let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for s in &self.series {
            let mut pts = decimate(&s.x, &s.y, 900);
            if let Some((a, b)) = self.x_range {
                pts.retain(|p| p.0 >= a && p.0 <= b);
            }
            pts.retain(|p| !self.log_y || p.1 > 0.0);
            series.push((s.name.clone(), pts.into_iter().map(|(x, y)| (x, tf(y))).collect()));
        }
        let all = series.iter().flat_map(|s| s.1.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for p in all {
            x0 = x0.min(p.0);
            x1 = x1.max(p.0);
            y0 = y0.min(p.1);
            y1 = y1.max(p.1);
        }
        if let Some((a, b)) = self.x_range {
            x0 = a;
            x1 = b;
        }
        if !x0.is_finite() {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        }
        if x1 <= x0 {
            x1 = x0 + 1.0;
        }
        if y1 <= y0 {
            y1 = y0 + 1.0;
        }
        let pad = 0.05 * (y1 - y0);
        let (y0, y1) = (y0 - pad, y1 + pad);
        let pw = WIDTH - MARGIN_L - MARGIN_R;
        let ph = HEIGHT - MARGIN_T - MARGIN_B;
        let sx = |x: f64| MARGIN_L + (x - x0) / (x1 - x0) * pw;
        let sy = |y: f64| MARGIN_T + (1.0 - (y - y0) / (y1 - y0)) * ph;

        let mut svg = String::new();
        let _ = write!(
            svg,
            r#"<svg xmlns="http://www.w3.org/2000/svg" class="plot" viewBox="0 0 {WIDTH} {HEIGHT}" role="img" aria-label="{}"><rect x="0" y="0" width="{WIDTH}" height="{HEIGHT}" fill="white"/>"#,
            esc(&self.title)
        );
        let _ = write!(
            svg,
            r#"<text x="{}" y="20" text-anchor="middle" font-size="15" font-weight="bold">{}</text>"#,
            WIDTH / 2.0,
            esc(&self.title)
        );
        // Grid and ticks.
        for t in ticks(x0, x1, 8) {
            let x = sx(t);
            let _ = write!(
                svg,
                r##"<line x1="{x:.1}" y1="{MARGIN_T}" x2="{x:.1}" y2="{:.1}" stroke="#e5e5e5"/>"##,
                MARGIN_T + ph
            );
            let _ = write!(
                svg,
                r#"<text x="{x:.1}" y="{:.1}" text-anchor="middle" font-size="11">{}</text>"#,
                MARGIN_T + ph + 15.0,
                fmt_tick(t)
            );
        }
        for t in ticks(y0, y1, 6) {
            let y = sy(t);
            let label = if self.log_y { fmt_tick(10f64.powf(t)) } else { fmt_tick(t) };
            let _ = write!(
                svg,
                r##"<line x1="{MARGIN_L}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#e5e5e5"/>"##,
                MARGIN_L + pw
            );
            let _ = write!(
                svg,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="end" font-size="11">{label}</text>"#,
                MARGIN_L - 6.0,
                y + 4.0
            );
        }
        let _ = write!(
            svg,
            r#"<rect x="{MARGIN_L}" y="{MARGIN_T}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#
        );
        let _ = write!(
            svg,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="12">{}</text>"#,
            MARGIN_L + pw / 2.0,
            HEIGHT - 10.0,
            esc(&self.x_label)
        );
        let _ = write!(
            svg,
            r#"<text x="16" y="{:.1}" text-anchor="middle" font-size="12" transform="rotate(-90 16 {:.1})">{}</text>"#,
            MARGIN_T + ph / 2.0,
            MARGIN_T + ph / 2.0,
            esc(&self.y_label)
        );
        // Markers, their labels on three rows so that neighbours do not overlap.
        for (i, m) in self.markers.iter().enumerate() {
            if m.x < x0 || m.x > x1 {
                continue;
            }
            let x = sx(m.x);
            let _ = write!(
                svg,
                r##"<line x1="{x:.1}" y1="{MARGIN_T}" x2="{x:.1}" y2="{:.1}" stroke="#555" stroke-dasharray="4 3"/>"##,
                MARGIN_T + ph
            );
            let _ = write!(
                svg,
                r##"<text x="{:.1}" y="{:.1}" font-size="11" fill="#333">{}</text>"##,
                x + 3.0,
                MARGIN_T + 12.0 * (1 + i % 3) as f64,
                esc(&m.label)
            );
        }
        // Lines.
        let _ = write!(svg, r#"<g>"#);
        for (i, (_, pts)) in series.iter().enumerate() {
            if pts.is_empty() {
                continue;
            }
            let mut d = String::with_capacity(pts.len() * 14);
            for (j, p) in pts.iter().enumerate() {
                let _ = write!(d, "{}{:.1},{:.1}", if j == 0 { "M" } else { "L" }, sx(p.0), sy(p.1));
            }
            let _ = write!(
                svg,
                r#"<path d="{d}" fill="none" stroke="{}" stroke-width="1.2"/>"#,
                PALETTE[i % PALETTE.len()]
            );
        }
        svg.push_str("</g>");
        // Legend.
        for (i, (name, _)) in series.iter().enumerate() {
            let y = MARGIN_T + 14.0 + 16.0 * i as f64;
            let x = MARGIN_L + pw - 190.0;
            let _ = write!(
                svg,
                r#"<rect x="{:.1}" y="{:.1}" width="185" height="16" fill="white" fill-opacity="0.85"/>"#,
                x - 4.0,
                y - 11.0
            );
            let _ = write!(
                svg,
                r#"<line x1="{x:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{}" stroke-width="3"/>"#,
                y - 4.0,
                x + 20.0,
                y - 4.0,
                PALETTE[i % PALETTE.len()]
            );
            let _ = write!(svg, r#"<text x="{:.1}" y="{y:.1}" font-size="11">{}</text>"#, x + 26.0, esc(name));
        }
        svg.push_str("</svg>");
        svg
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_axes_legend_and_paths() {
        let p = LinePlot {
            title: "T & <x>".into(),
            x_label: "time (s)".into(),
            y_label: "torque (N·m)".into(),
            series: vec![Series {
                name: "a".into(),
                x: (0..5000).map(|k| k as f64).collect(),
                y: (0..5000).map(|k| (k as f64 * 0.01).sin()).collect(),
            }],
            markers: vec![Marker { x: 100.0, label: "2×".into() }],
            ..Default::default()
        };
        let s = p.to_svg();
        assert!(s.starts_with("<svg") && s.ends_with("</svg>"));
        assert!(s.contains("T &amp; &lt;x&gt;") && s.contains("time (s)") && s.contains("torque (N·m)"));
        assert_eq!(s.matches("<path").count(), 1);
        assert!(s.contains("stroke-dasharray"));
        // Decimated: no more than ~2 points per column.
        assert!(s.matches('L').count() < 2000);
    }

    #[test]
    fn ticks_are_nice() {
        let t = ticks(0.0, 1.0, 5);
        assert_eq!(t.len(), 6);
        assert!(t.iter().zip([0.0, 0.2, 0.4, 0.6, 0.8, 1.0]).all(|(a, b)| (a - b).abs() < 1e-12), "{t:?}");
        assert_eq!(decimate(&[0.0, 1.0], &[f64::NAN, 2.0], 10), vec![(1.0, 2.0)]);
    }
}
