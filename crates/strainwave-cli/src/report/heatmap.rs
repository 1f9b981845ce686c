//! Inline SVG heat maps (Campbell diagrams, spectrograms): a colour-coded dB grid with
//! labelled lines over it.

use std::fmt::Write as _;

use super::plot::{esc, fmt_tick, ticks};

/// A colour-coded grid in dB: `z[i][j]` at `x[i]`, `y[j]` (NaN: not drawn).
pub struct HeatMap {
    /// Title.
    pub title: String,
    /// x axis label with unit.
    pub x_label: String,
    /// y axis label with unit.
    pub y_label: String,
    /// Colour bar label with unit.
    pub z_label: String,
    /// Cell centres on x (equally spaced).
    pub x: Vec<f64>,
    /// Cell centres on y (equally spaced).
    pub y: Vec<f64>,
    /// Values, dB.
    pub z: Vec<Vec<f64>>,
    /// Dynamic range shown, dB.
    pub range_db: f64,
    /// Labelled lines `(label, points)`.
    pub lines: Vec<(String, Vec<(f64, f64)>)>,
}

const W: f64 = 860.0;
const H: f64 = 420.0;
const ML: f64 = 70.0;
const MR: f64 = 90.0;
const MT: f64 = 34.0;
const MB: f64 = 48.0;

/// A viridis-like colour for `t` in 0…1.
fn colour(t: f64) -> String {
    const STOPS: [(f64, f64, f64); 5] =
        [(68.0, 1.0, 84.0), (59.0, 82.0, 139.0), (33.0, 145.0, 140.0), (94.0, 201.0, 98.0), (253.0, 231.0, 37.0)];
    let t = t.clamp(0.0, 1.0) * 4.0;
    let i = (t.floor() as usize).min(3);
    let f = t - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let m = |p: f64, q: f64| (p + (q - p) * f).round() as u8;
    format!("#{:02x}{:02x}{:02x}", m(a.0, b.0), m(a.1, b.1), m(a.2, b.2))
}

/// How far outside the image a line's point may lie, px.
const FAR_PX: f64 = 1e5;

impl HeatMap {
    /// The SVG.
    pub fn to_svg(&self) -> String {
        let (pw, ph) = (W - ML - MR, H - MT - MB);
        let half = |v: &[f64]| if v.len() > 1 { 0.5 * (v[1] - v[0]) } else { 0.5 };
        let (hx, hy) = (half(&self.x), half(&self.y));
        let (x0, x1) = (self.x.first().copied().unwrap_or(0.0) - hx, self.x.last().copied().unwrap_or(1.0) + hx);
        let (y0, y1) = (self.y.first().copied().unwrap_or(0.0) - hy, self.y.last().copied().unwrap_or(1.0) + hy);
        let sx = |x: f64| ML + (x - x0) / (x1 - x0) * pw;
        let sy = |y: f64| MT + ph - (y - y0) / (y1 - y0) * ph;
        let top = self.z.iter().flatten().copied().filter(|v| v.is_finite()).fold(f64::NEG_INFINITY, f64::max);
        let top = if top.is_finite() { top } else { 0.0 };
        let bottom = top - self.range_db;
        let mut s = String::new();
        let _ = write!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12">"#
        );
        let _ = write!(s, r#"<rect x="0" y="0" width="{W}" height="{H}" fill="white"/>"#);
        let _ = write!(
            s,
            r#"<text x="{}" y="20" text-anchor="middle" font-size="14">{}</text>"#,
            W / 2.0,
            esc(&self.title)
        );
        let _ = write!(s, r##"<rect x="{ML}" y="{MT}" width="{pw}" height="{ph}" fill="#eeeeee"/>"##);
        let cw = pw / self.x.len().max(1) as f64;
        let ch = ph / self.y.len().max(1) as f64;
        for (i, col) in self.z.iter().enumerate() {
            for (j, v) in col.iter().enumerate() {
                if !v.is_finite() {
                    continue;
                }
                let t = (v - bottom) / self.range_db;
                let _ = write!(
                    s,
                    r#"<rect x="{:.2}" y="{:.2}" width="{:.2}" height="{:.2}" fill="{}"/>"#,
                    sx(self.x[i]) - cw / 2.0,
                    sy(self.y[j]) - ch / 2.0,
                    cw + 0.3,
                    ch + 0.3,
                    colour(t)
                );
            }
        }
        // Lines, clipped to the plot.
        let _ = write!(s, r#"<clipPath id="plotarea"><rect x="{ML}" y="{MT}" width="{pw}" height="{ph}"/></clipPath>"#);
        for (label, pts) in &self.lines {
            // A guard, so that the SVG holds only finite, short numbers: callers end their
            // lines at the plot's edge, as pulling a far point in would tilt its line.
            let near = |v: f64| v.clamp(-FAR_PX, FAR_PX);
            let p: Vec<String> = pts
                .iter()
                .filter(|(x, y)| !(x.is_nan() || y.is_nan()))
                .map(|(x, y)| format!("{:.2},{:.2}", near(sx(*x)), near(sy(*y))))
                .collect();
            let _ = write!(
                s,
                r#"<polyline class="order-line" clip-path="url(#plotarea)" points="{}" fill="none" stroke="white" stroke-width="1.2" stroke-dasharray="5,3"/>"#,
                p.join(" ")
            );
            if let Some(&(x, y)) = pts.iter().rev().find(|(x, y)| *x >= x0 && *x <= x1 && *y >= y0 && *y <= y1) {
                let _ = write!(
                    s,
                    r#"<text x="{:.1}" y="{:.1}" fill="white" text-anchor="end">{}</text>"#,
                    sx(x) - 4.0,
                    sy(y) - 4.0,
                    esc(label)
                );
            }
        }
        // Axes.
        let _ = write!(s, r#"<rect x="{ML}" y="{MT}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#);
        for t in ticks(x0, x1, 6) {
            let _ = write!(
                s,
                r#"<line x1="{0:.1}" y1="{1}" x2="{0:.1}" y2="{2}" stroke="black"/><text x="{0:.1}" y="{3}" text-anchor="middle">{4}</text>"#,
                sx(t),
                MT + ph,
                MT + ph + 5.0,
                MT + ph + 18.0,
                fmt_tick(t)
            );
        }
        for t in ticks(y0, y1, 6) {
            let _ = write!(
                s,
                r#"<line x1="{0}" y1="{1:.1}" x2="{2}" y2="{1:.1}" stroke="black"/><text x="{3}" y="{4:.1}" text-anchor="end">{5}</text>"#,
                ML - 5.0,
                sy(t),
                ML,
                ML - 8.0,
                sy(t) + 4.0,
                fmt_tick(t)
            );
        }
        let _ = write!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            ML + pw / 2.0,
            H - 10.0,
            esc(&self.x_label)
        );
        let _ = write!(
            s,
            r#"<text x="16" y="{0}" text-anchor="middle" transform="rotate(-90 16 {0})">{1}</text>"#,
            MT + ph / 2.0,
            esc(&self.y_label)
        );
        // Colour bar.
        let bx = W - MR + 15.0;
        for k in 0..50 {
            let t = k as f64 / 49.0;
            let _ = write!(
                s,
                r#"<rect x="{bx}" y="{:.2}" width="14" height="{:.2}" fill="{}"/>"#,
                MT + ph - (k + 1) as f64 * ph / 50.0,
                ph / 50.0 + 0.3,
                colour(t)
            );
        }
        for (v, y) in [(top, MT + 4.0), (bottom, MT + ph)] {
            let _ = write!(s, r#"<text x="{}" y="{y:.1}">{v:.0}</text>"#, bx + 18.0);
        }
        let _ = write!(
            s,
            r#"<text x="{0}" y="{1}" text-anchor="middle" transform="rotate(-90 {0} {1})">{2}</text>"#,
            W - 12.0,
            MT + ph / 2.0,
            esc(&self.z_label)
        );
        s += "</svg>\n";
        s
    }
}

/// Frequency rows pooled (max) to at most `max_rows` rows, up to `max_hz`.
pub fn pool_freqs(freqs: &[f64], cols: &[Vec<f64>], max_hz: f64, max_rows: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = freqs.iter().take_while(|f| **f <= max_hz).count().max(1);
    let g = n.div_ceil(max_rows).max(1);
    let df = if freqs.len() > 1 { freqs[1] - freqs[0] } else { 1.0 };
    let rows = n.div_ceil(g);
    let y: Vec<f64> = (0..rows).map(|r| freqs[0] + (r as f64 * g as f64 + 0.5 * (g as f64 - 1.0)) * df).collect();
    let z = cols
        .iter()
        .map(|c| {
            (0..rows)
                .map(|r| {
                    c[r * g..((r + 1) * g).min(n)].iter().copied().fold(f64::NAN, |a, b| {
                        if a.is_nan() || b > a {
                            b
                        } else {
                            a
                        }
                    })
                })
                .collect()
        })
        .collect();
    (y, z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tick labels are short decimals: steps of 0.1 s would print `0.30000000000000004`
    /// with `f64`'s own text.
    #[test]
    fn tick_labels_are_short_decimals() {
        let map = HeatMap {
            title: "t".into(),
            x_label: "s".into(),
            y_label: "Hz".into(),
            z_label: "dB".into(),
            x: (0..11).map(|i| i as f64 * 0.1).collect(),
            y: vec![0.0, 1.0],
            z: vec![vec![0.0; 2]; 11],
            range_db: 60.0,
            lines: Vec::new(),
        };
        let svg = map.to_svg();
        assert!(svg.contains(">0.3<") || svg.contains(">0.4<"), "{svg}");
        assert!(!svg.contains("0000000"), "a long tick label");
    }
}
