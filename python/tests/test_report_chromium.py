"""The demo's HTML report in headless Chromium (Debian's `chromium` package): it loads with
no console errors, and every `<svg class="plot">` has a drawing (a `<path>` with a
non-empty `d`, a bounding box of non-zero width and height, visible, stroked or filled,
and inside its plot).

How, with the command line alone (no DevTools client):

- console: Chromium's `--enable-logging=stderr` prints every console message of the page
  as an `INFO:CONSOLE` line whatever its level, and not failed resource loads. The report
  has no scripts, so any console line from it fails the test.
- in the page: a copy of the report in the test's temp dir gets a probe script as the
  first element of `<head>` (the report itself stays script-free). The probe records
  uncaught errors, failed resource loads, CSP violations and `console.error`, and on
  `load` writes the plots' `getBBox()` and client rectangles as JSON into the DOM, which
  `--dump-dom` prints.
- a broken page (missing image, `console.error`, an uncaught error, an empty plot) must
  fail the same checks, so the checks can fail.
- a screenshot of the first screen (1280×900) is saved in the temp dir and its path
  printed; it must not be blank.

Skips when /usr/bin/chromium (or `chromium` on PATH) or cargo is absent.
"""

import json
import os
import re
import shutil
import struct
import subprocess
import tempfile
import zlib

import pytest

WINDOW = (1280, 900)
PROBE_ID = "strainwave-probe"

PROBE = """<script>
(function () {
  var errors = [];
  window.addEventListener('error', function (e) {
    var t = e.target;
    if (t && t !== window && (t.src || t.href)) { errors.push('failed to load ' + (t.src || t.href)); }
    else { errors.push('uncaught: ' + (e.message || String(e.error))); }
  }, true);
  window.addEventListener('unhandledrejection', function (e) { errors.push('unhandled rejection: ' + e.reason); });
  document.addEventListener('securitypolicyviolation', function (e) {
    errors.push('CSP: ' + e.violatedDirective + ' ' + e.blockedURI);
  });
  var original = console.error;
  console.error = function () {
    errors.push('console.error: ' + Array.prototype.join.call(arguments, ' '));
    original.apply(console, arguments);
  };
  window.addEventListener('load', function () {
    var plots = Array.prototype.map.call(document.querySelectorAll('svg.plot'), function (svg) {
      var r = svg.getBoundingClientRect();
      var paths = Array.prototype.map.call(svg.querySelectorAll('path'), function (p) {
        var b = p.getBBox(), c = p.getBoundingClientRect(), s = getComputedStyle(p);
        return {d: (p.getAttribute('d') || '').trim().length, bbox: [b.x, b.y, b.width, b.height],
                client: [c.left, c.top, c.width, c.height], stroke: s.stroke, fill: s.fill,
                visible: s.visibility !== 'hidden' && s.display !== 'none' && parseFloat(s.opacity) > 0};
      });
      return {label: svg.getAttribute('aria-label') || '', rect: [r.left, r.top, r.width, r.height], paths: paths};
    });
    var out = document.createElement('pre');
    out.id = '%s';
    out.textContent = JSON.stringify({errors: errors, plots: plots});
    document.body.appendChild(out);
  });
})();
</script>""" % PROBE_ID

BROKEN = """<!DOCTYPE html><html><head><title>broken</title></head><body>
<img src="no-such-image.png">
<svg class="plot" viewBox="0 0 100 50"><path d="M 0 0" stroke="black"/></svg>
<svg class="plot" viewBox="0 0 100 50"><path d="M 0 10 L 100 10" stroke="black"/></svg>
<svg class="plot" viewBox="0 0 100 50"><path d="M 0 0 L 50 50" stroke="none" fill="none"/></svg>
<svg class="plot" viewBox="0 0 100 50"><rect width="100" height="50"/></svg>
<script>console.error("broken on purpose"); notDefinedAnywhere();</script>
</body></html>"""


def chromium_binary():
    for cand in ("/usr/bin/chromium", shutil.which("chromium")):
        if cand and os.access(cand, os.X_OK):
            return cand
    return None


def run_chromium(url, *extra):
    exe = chromium_binary()
    with tempfile.TemporaryDirectory(prefix="strainwave-chromium-") as profile:
        cmd = [
            exe,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={profile}",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=5000",
            f"--window-size={WINDOW[0]},{WINDOW[1]}",
            *extra,
            url,
        ]
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, f"chromium failed ({res.returncode}):\n{res.stderr[-3000:]}"
    return res


def console_lines(stderr):
    return [line for line in stderr.splitlines() if ":CONSOLE" in line]


def probe(html_path):
    """Loads a copy of `html_path` with the probe script first in <head>; returns its JSON."""
    src = html_path.read_text(encoding="utf-8")
    head = re.search(r"<head[^>]*>", src, re.I)
    assert head, f"{html_path}: no <head>"
    page = html_path.with_name(html_path.stem + ".probe.html")
    page.write_text(src[: head.end()] + PROBE + src[head.end() :], encoding="utf-8")
    res = run_chromium(page.as_uri(), "--dump-dom")
    m = re.search(r'<pre id="%s">(.*?)</pre>' % PROBE_ID, res.stdout, re.S)
    assert m, f"probe wrote nothing (page did not finish loading?):\n{res.stdout[-2000:]}"
    text = m.group(1).replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", '"').replace("&amp;", "&")
    return json.loads(text)


def drawing_problems(plots):
    """One message per plot without a drawing; empty when every plot has one."""
    problems = []
    for k, plot in enumerate(plots):
        left, top, width, height = plot["rect"]
        name = f"plot {k} ({plot['label']!r})"
        if width <= 0 or height <= 0:
            problems.append(f"{name}: svg has zero size {plot['rect']}")
            continue
        ok = []
        for p in plot["paths"]:
            bx, by, bw, bh = p["bbox"]
            cx, cy, cw, ch = p["client"]
            painted = p["stroke"] != "none" or p["fill"] != "none"
            inside = cx < left + width and cx + cw > left and cy < top + height and cy + ch > top
            if p["d"] > 0 and bw > 0 and bh > 0 and p["visible"] and painted and inside:
                ok.append(p)
        if not ok:
            problems.append(f"{name}: no visible path with a non-empty d and a non-zero bounding box: {plot['paths']}")
    return problems


def png_size_and_ink(path):
    """(width, height, fraction of pixels that are not near-white) of an 8-bit RGB(A) PNG."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path}: not a PNG"
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    width, height, depth, color, _, _, interlace = ihdr
    assert depth == 8 and color in (2, 6) and interlace == 0, f"{path}: unexpected PNG format {ihdr}"
    bpp = 3 if color == 2 else 4
    raw, stride = zlib.decompress(idat), width * bpp
    prev, ink = bytearray(stride), 0
    for y in range(height):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1 : (y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        ink += sum(1 for x in range(0, stride, bpp) if min(line[x : x + 3]) < 200)
        prev = line
    return width, height, ink / (width * height)


@pytest.fixture(scope="module")
def report(tmp_path_factory, cli):
    if chromium_binary() is None:
        pytest.skip("chromium not installed (apt-get install -y chromium)")
    out = tmp_path_factory.mktemp("demo")
    res = cli("demo", "--out", out)
    if res.returncode != 0:
        pytest.fail(f"strainwave demo failed ({res.returncode}):\n{res.stderr}")
    path = out / "report.html"
    assert path.is_file(), f"demo wrote no {path}"
    return path


def test_report_loads_without_console_errors(report):
    res = run_chromium(report.as_uri(), "--dump-dom")
    assert "<svg" in res.stdout, "the report did not load"
    assert console_lines(res.stderr) == []
    assert probe(report)["errors"] == []


def test_every_plot_has_a_drawing(report):
    plots = probe(report)["plots"]
    in_source = len(re.findall(r"<svg\b[^>]*\bclass=\"plot\"", report.read_text(encoding="utf-8")))
    assert in_source >= 1, "the report has no plots"
    assert len(plots) == in_source
    assert drawing_problems(plots) == []


def test_the_checks_fail_on_a_broken_page(tmp_path):
    if chromium_binary() is None:
        pytest.skip("chromium not installed")
    page = tmp_path / "broken.html"
    page.write_text(BROKEN, encoding="utf-8")
    res = run_chromium(page.as_uri(), "--dump-dom")
    logged = "\n".join(console_lines(res.stderr))
    assert "broken on purpose" in logged and "notDefinedAnywhere" in logged, res.stderr[-2000:]
    result = probe(page)
    errors = "\n".join(result["errors"])
    assert "no-such-image.png" in errors and "broken on purpose" in errors and "notDefinedAnywhere" in errors, errors
    problems = drawing_problems(result["plots"])
    # every plot is broken: a point, a flat line, an unpainted path, no path at all
    assert [p.split(":")[0] for p in problems] == [f"plot {k} ('')" for k in range(4)], problems


def test_screenshot_of_the_first_screen(report):
    shot = report.with_name("report-first-screen.png")
    run_chromium(report.as_uri(), f"--screenshot={shot}", "--hide-scrollbars")
    width, height, ink = png_size_and_ink(shot)
    print(f"\nscreenshot of the report's first screen: {shot}")
    assert (width, height) == WINDOW
    assert ink > 0.01, f"{shot}: the first screen is blank ({ink:.2%} non-white pixels)"
