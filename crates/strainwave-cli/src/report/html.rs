//! A self-contained HTML report: inline CSS and SVG, no scripts, no network.

use std::fmt::Write as _;

/// A report section: a heading and its HTML body.
#[derive(Debug, Clone)]
pub struct Section {
    /// Heading.
    pub title: String,
    /// Body (trusted HTML built by this crate).
    pub body: String,
}

/// A whole report.
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// Page title.
    pub title: String,
    /// One line under the title.
    pub subtitle: String,
    /// Sections in order.
    pub sections: Vec<Section>,
}

/// Escapes text for HTML.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// An HTML table from a header and rows of cells (text, escaped).
pub fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut s = String::from("<table><thead><tr>");
    for h in header {
        let _ = write!(s, "<th>{}</th>", esc(h));
    }
    s.push_str("</tr></thead><tbody>");
    for r in rows {
        s.push_str("<tr>");
        for c in r {
            let _ = write!(s, "<td>{}</td>", esc(c));
        }
        s.push_str("</tr>");
    }
    s.push_str("</tbody></table>");
    s
}

const STYLE: &str = "body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;max-width:940px;margin:1.5em auto;padding:0 1em;color:#222;line-height:1.45}\
h1{font-size:1.6em;margin-bottom:0}.sub{color:#555;margin-top:.2em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}\
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}\
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}svg.plot{width:100%;height:auto;margin:.5em 0}\
@media print{body{max-width:none}h2{page-break-after:avoid}svg.plot{page-break-inside:avoid}}";

impl Report {
    /// The page as one HTML string.
    pub fn to_html(&self) -> String {
        let mut s = String::new();
        let _ = write!(
            s,
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{}</title><style>{STYLE}</style></head><body><h1>{}</h1><p class=\"sub\">{}</p>",
            esc(&self.title),
            esc(&self.title),
            esc(&self.subtitle)
        );
        for sec in &self.sections {
            let _ = write!(s, "<section><h2>{}</h2>{}</section>", esc(&sec.title), sec.body);
        }
        s.push_str("</body></html>\n");
        s
    }
}
